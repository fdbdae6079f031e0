"""Motion models prepared once per process (issue 62): a model's documents read, parsed and prepared
for the search (step_search.StepModel) the first time a process needs them, then kept, so that the
next synthesis from models starts at once: the next modb.synthesize_from_models call of a server
backend, the next avatar session of the web server (which imports this kernel).

An entry is found by where its model lives (the cluster's system identifier and the database's oid:
a standby shares its primary's) and its id, and is served only while its row is unchanged: its
version and the row versions (xmin and ctid) of the model and of its skeleton. A tree rebuilt (meta
changes in place) or a skeleton's joint map edited changes them (a new version is a new row: a new
id), so a call reads the keys first (a few bytes a model), then the documents of the models it
holds no current entry for; an entry found changed is dropped then. (xmin alone would miss a row
changed twice in one transaction; the pair does not: the earlier version keeps its slot until that
transaction ends.)

Bounded: at most MAX_MODELS models and MAX_MEGABYTES of their documents' JSON text (prepared, a
model holds about 1.2x its text's size: its tree's samples as arrays), the least recently used
dropped first, but never one the call at hand wants: a graph larger than the bounds is held whole
until another call needs the room (Bandai's walking with six hand actions: 11 models, 76 MB).
A StepModel is read-only once made, so syntheses running at once (the web server's
avatar sessions run in threads) share it; the table is guarded by a lock, and a model two threads
miss at once is prepared by both (the last one kept). An action node's ActionModel is made once
per prepared model too (action_model)."""

import json
import threading
import weakref
from collections import OrderedDict
from dataclasses import dataclass

from .database import Statement
from .action_search import ActionModel
from .step_search import Rig, StepModel

MAX_MODELS = 32
MAX_MEGABYTES = 64.0

# A model row's identity as a call sees it; its documents are read with the same columns, so an
# entry is kept under the row versions its documents came from.
_ROW_VERSIONS = """m.version, concat_ws(' ', m.xmin, m.ctid) AS row_version,
       concat_ws(' ', s.id, s.xmin, s.ctid) AS skeleton_version"""
KEYS = Statement(
    f"""SELECT m.id, {_ROW_VERSIONS}, m.meta ? 'tree' AS has_tree,
               (SELECT system_identifier FROM pg_control_system())::text || '/'
               || (SELECT oid FROM pg_database WHERE datname = current_database())::text AS place
          FROM modb.models m JOIN modb.skeletons s ON s.id = m.skeleton_id
         WHERE m.id = ANY ($1)""",
    ("bigint[]",),
)
DOCUMENTS = Statement(
    f"""SELECT m.id, m.name, {_ROW_VERSIONS}, m.data::text AS data,
               (m.meta->'tree')::text AS tree,
               s.hierarchy::text AS hierarchy, s.joint_map::text AS joint_map
          FROM modb.models m JOIN modb.skeletons s ON s.id = m.skeleton_id
         WHERE m.id = ANY ($1)
         ORDER BY m.id""",
    ("bigint[]",),
)


@dataclass
class Entry:
    key: tuple  # (version, row version, skeleton row version)
    model: StepModel
    megabytes: float  # its documents' JSON text
    reads: int = 1  # times this process read its documents (again after the row changed)
    served: int = 0  # calls it served without reading them


class PreparedModels:
    """The process's prepared models (one table for all threads)."""

    def __init__(self, max_models=MAX_MODELS, max_megabytes=MAX_MEGABYTES):
        self.max_models, self.max_megabytes = max_models, max_megabytes
        self._entries = OrderedDict()  # (place, id) -> Entry, the least recently used first
        self._lock = threading.Lock()
        self.dropped_stale = self.evicted = 0

    def step_models(self, db, keys, interrupts=None):
        """id -> StepModel for the rows of KEYS (id -> row), read and prepared where this process
        holds none current (an id whose row is gone by then is left out); interrupts: called
        before each model is prepared (model_synthesis.load passes its own). ValueError where a
        skeleton or a model cannot be prepared."""
        found, missing = {}, {}  # missing: id -> times read before (its changed entry's)
        with self._lock:
            for ident, row in keys.items():
                where = (row["place"], ident)
                entry = self._entries.get(where)
                if entry is not None and entry.key == _key(row):
                    entry.served += 1
                    self._entries.move_to_end(where)
                    found[ident] = entry.model
                    continue
                if entry is not None:  # rebuilt or replaced since: never served again
                    del self._entries[where]
                    self.dropped_stale += 1
                missing[ident] = entry.reads if entry is not None else 0
        if not missing:
            return found
        wanted = {(row["place"], i) for i, row in keys.items()}  # kept whatever the bounds
        rigs = {}  # skeleton's row version -> Rig: the models of one skeleton share one
        for row in db.run(DOCUMENTS, [sorted(missing)]):
            if interrupts is not None:
                interrupts()
            ident, skeleton = row["id"], row["skeleton_version"]
            if skeleton not in rigs:
                rigs[skeleton] = Rig({"hierarchy": json.loads(row["hierarchy"]),
                                      "joint_map": json.loads(row["joint_map"])})  # fmt: skip
            document = json.loads(row["data"])
            document["name"], document["version"] = row["name"], row["version"]
            tree = json.loads(row["tree"]) if row["tree"] else None
            found[ident] = model = StepModel(document, tree, rigs[skeleton])
            megabytes = (len(row["data"]) + len(row["tree"] or "")) / 1e6
            entry = Entry(_key(row), model, megabytes, reads=missing[ident] + 1)
            where = (keys[ident]["place"], ident)
            with self._lock:
                self._entries[where] = entry
                self._entries.move_to_end(where)
                self._evict(wanted)
        return found

    def _evict(self, wanted):
        """The least recently used entries dropped until the table is within its bounds, never
        one the call at hand wants (`wanted`): a graph whose models pass the bounds is held whole
        (the call holds them anyway), else each call would read again what the last one dropped."""
        total = sum(e.megabytes for e in self._entries.values())
        for where in [w for w in self._entries if w not in wanted]:  # the least recent first
            if len(self._entries) <= self.max_models and total <= self.max_megabytes:
                break
            total -= self._entries.pop(where).megabytes
            self.evicted += 1

    def rows(self):
        """[(model id, name, version, reads, served, megabytes)] of the models held, by id."""
        with self._lock:
            entries = [(ident, e) for (_, ident), e in self._entries.items()]
        return sorted((ident, e.model.model["name"], e.key[0], e.reads, e.served,
                       round(e.megabytes, 3)) for ident, e in entries)  # fmt: skip

    def clear(self):
        with self._lock:
            self._entries.clear()


def _key(row):
    return (row["version"], row["row_version"], row["skeleton_version"])


PREPARED = PreparedModels()  # the process's


_ACTIONS = weakref.WeakKeyDictionary()  # a prepared StepModel -> its ActionModel
_ACTIONS_LOCK = threading.Lock()


def action_model(model):
    """The ActionModel of a prepared model (an action node's), made once while the model is held
    (it keeps features of its own: 20 ms a model); read-only as the model is."""
    with _ACTIONS_LOCK:
        found = _ACTIONS.get(model)
    if found is None:
        found = ActionModel(model.model, model.tree, model.rig)
        with _ACTIONS_LOCK:
            _ACTIONS[model] = found
    return found
