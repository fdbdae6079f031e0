"""A graph of models prepared as the server starts, so that the avatar page's first switch to it
is as quick as the next ones (issue 62: 2.6-3.3 s on a new server, 0.07-0.1 s warm).

One graph, the one the page offers first (`modb demo`'s, else the first by name): its models are
read and prepared in a thread of their own (modb_kernel.prepared_models keeps them for the
process), the server answering meanwhile. A session that starts on that graph before it is done
waits for it rather than preparing the same models a second time beside it.
"""

from __future__ import annotations

import logging
import threading

from modb.demo import MODEL_GRAPH
from modb.jobs.kernel_database import WorkerDatabase
from modb_kernel import model_synthesis as MS

from .api import MODEL_GRAPHS

log = logging.getLogger("modb.web")

WAIT_SECONDS = 30.0  # a session waits at most this long for the preparation under way

_underway: dict[str, threading.Event] = {}  # graph -> set once its preparation ended


def prepare(pool) -> threading.Thread | None:
    """Starts preparing the first graph of models in a daemon thread (None: the database has
    none). A graph that cannot be prepared is logged and left to the session that asks for it,
    which says why."""
    with pool.connection() as conn:
        found = conn.execute(MODEL_GRAPHS, [MODEL_GRAPH]).fetchone()  # the page's first
    if found is None:
        return None
    graph = found[0]
    done = _underway[graph] = threading.Event()  # this start's (a server started again: anew)

    def run() -> None:
        try:
            with pool.connection() as conn:
                MS.load(WorkerDatabase(conn), graph)
        except Exception as e:  # the session that asks for it will say why
            log.warning("the graph of models %r was not prepared at start: %s", graph, e)
        finally:
            done.set()

    thread = threading.Thread(target=run, daemon=True, name="modb-prepare-models")
    thread.start()
    return thread


def wait_for(graph: str) -> None:
    """Returns once the graph's preparation at start (if any) has ended, or after WAIT_SECONDS."""
    done = _underway.get(graph)
    if done is not None:
        done.wait(WAIT_SECONDS)
