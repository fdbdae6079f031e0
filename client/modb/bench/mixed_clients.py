"""The clients of `modb bench mixed`, each counting what it sent and what came back.

Writers talk REST to the real `modb serve` with a loader token each, readers are pgbench processes
(the shipped select_next_snippet script, one connection each), avatars are the web view's
WebSocket. Every client stops by itself at the deadline. A writer also notes what each successful
write says it stored (audit rows, clip versions, collections), so the run can be held against the
database afterwards.
"""

from __future__ import annotations

import json
import math
import random
import re
import subprocess
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx

from .scale import PGBENCH, PGBENCH_SCRIPT

HTTP_TIMEOUT_S = 120.0  # a write stuck longer than this is counted as an error (no answer)
AVATAR_CLICK_S = 2.0  # a new goal every 2 s, as a person clicking about
MESSAGE_CHARS = 160  # of an error's message, kept to group and show them

# Audit actions, as the server records them (modb.audit_log.action)
APPLY, RETARGET, META, CREATE, CHANGE, UPLOAD = (
    "edit script apply",
    "retarget",
    "meta",
    "collection create",
    "collection change",
    "upload",
)


def status_class(status: int) -> str:
    return f"{status // 100}xx"


@dataclass
class Tally:
    """One kind of request: how many were sent and how each ended."""

    requests: int = 0
    classes: Counter = field(default_factory=Counter)  # "2xx", "4xx", "5xx": answers
    errors: int = 0  # no answer: a connection error, a timeout, an aborted client
    messages: Counter = field(default_factory=Counter)  # (status or "error", message): not 2xx


@dataclass
class Ledger:
    """Every client's counts (a lock around each update: the clients are threads) and what the
    writers' successful answers say they stored."""

    tallies: dict[tuple[str, str], Tally] = field(default_factory=dict)  # (kind, action)
    audited: Counter = field(default_factory=Counter)  # audit action -> rows the answers imply
    versions: set[tuple[int, int]] = field(default_factory=set)  # (clip, version) answered
    collections_made: int = 0  # 201 answers to collection creates
    extra: Counter = field(default_factory=Counter)  # avatars' choices, readers' transactions
    lock: threading.Lock = field(default_factory=threading.Lock)

    def tally(self, kind: str, action: str) -> Tally:
        return self.tallies.setdefault((kind, action), Tally())

    def answered(self, kind: str, action: str, status: int, message: str = "") -> None:
        with self.lock:
            t = self.tally(kind, action)
            t.requests += 1
            t.classes[status_class(status)] += 1
            if not 200 <= status < 300:
                t.messages[(str(status), message[:MESSAGE_CHARS])] += 1

    def failed(self, kind: str, action: str, message: str, requests: int = 1) -> None:
        with self.lock:
            t = self.tally(kind, action)
            t.requests += requests
            t.errors += requests
            t.messages[("error", message[:MESSAGE_CHARS])] += requests


@dataclass
class Plan:
    """What the writers work on, made before the run."""

    address: str  # host:port of modb serve
    tokens: list[str]  # one loader token per writer
    hot_clips: list[int]  # edited by every writer: their edits collide
    other_clips: list[int]  # resampled, retargeted and annotated
    target_skeleton: int  # retargets go onto it
    upload_file: Path
    smooth_script: str
    resample_scripts: list[str]  # one per frame rate: each new rate makes a new pool
    collection_root: str  # collections are made under it, and moved within it
    seed: int


def _error_text(r: httpx.Response) -> str:
    try:
        body = r.json()
    except ValueError:
        return r.text
    return str(body.get("error", body)) if isinstance(body, dict) else str(body)


class Writer:
    """One REST writer: a seeded mix of writes until the deadline."""

    # action -> weight in the mix
    MIX = {
        "edit same clip": 4,
        "resample": 3,
        "retarget": 1,
        "annotate": 2,
        "collection create": 1,
        "collection move": 1,
        "upload": 1,
    }

    def __init__(self, index: int, plan: Plan, ledger: Ledger) -> None:
        self.index, self.plan, self.ledger = index, plan, ledger
        self.rng = random.Random(plan.seed * 1000 + index)
        self.made: list[str] = []  # collections this writer made and has not moved yet
        self.serial = 0

    def run(self, until: float) -> None:
        actions, weights = zip(*self.MIX.items())
        headers = {"Authorization": f"Bearer {self.plan.tokens[self.index]}"}
        with httpx.Client(
            base_url=f"http://{self.plan.address}", headers=headers, timeout=HTTP_TIMEOUT_S
        ) as client:
            # every kind once first, even past the deadline (a short run still writes each),
            # then the weighted mix
            first = self.rng.sample(actions, len(actions))
            while first or time.monotonic() < until:
                action = first.pop() if first else self.rng.choices(actions, weights)[0]
                self.serial += 1
                try:
                    getattr(self, "_" + action.replace(" ", "_"))(client)
                except httpx.HTTPError as e:
                    self.ledger.failed("writer", action, f"{type(e).__name__}: {e}")

    def _send(self, client: httpx.Client, action: str, method: str, url: str, **kw) -> Any:
        """The request, counted; the answer's JSON body when it is a 2xx, else None."""
        r = client.request(method, url, **kw)
        self.ledger.answered("writer", action, r.status_code, _error_text(r))
        if not r.is_success:
            return None
        return r.json()

    def _note(self, audit_action: str, rows: int = 1, versions=()) -> None:
        with self.ledger.lock:
            self.ledger.audited[audit_action] += rows
            self.ledger.versions.update(versions)

    def _apply(self, client: httpx.Client, action: str, script: str, clip: int) -> None:
        body = self._send(
            client, action, "POST", f"/api/edit-scripts/{script}/apply", json={"clips": [clip]}
        )
        if body is not None:
            self._note(APPLY, versions=[(r["clip_id"], r["version"]) for r in body["results"]])

    def _edit_same_clip(self, client: httpx.Client) -> None:
        clip = self.rng.choice(self.plan.hot_clips)
        self._apply(client, "edit same clip", self.plan.smooth_script, clip)

    def _resample(self, client: httpx.Client) -> None:
        script = self.rng.choice(self.plan.resample_scripts)
        self._apply(client, "resample", script, self.rng.choice(self.plan.other_clips))

    def _retarget(self, client: httpx.Client) -> None:
        body = self._send(
            client,
            "retarget",
            "POST",
            f"/api/clips/{self.rng.choice(self.plan.other_clips)}/retarget",
            json={
                "skeleton": self.plan.target_skeleton,
                "fps": self.rng.choice([20, 24, 25, 30, 48, 50, 60]),
                "collection": f"{self.plan.collection_root}/retargets",
            },
        )
        if body is not None:
            self._note(RETARGET, versions=[(body["clip_id"], body["version"])])

    def _annotate(self, client: httpx.Client) -> None:
        clip = self.rng.choice(self.plan.hot_clips + self.plan.other_clips)
        url = f"/api/clips/{clip}/versions/1/meta"
        read = client.get(url)
        if not read.is_success:
            self.ledger.answered("writer", "annotate (read)", read.status_code, _error_text(read))
            return
        meta = read.json()["meta"] or {}
        last = max(0, read.json()["n_frames"] - 1)
        start = self.rng.randrange(last + 1)
        annotations = [*meta.get("annotations", [])][-20:]  # bounded: the meta stays small
        annotations.append(
            {"name": f"w{self.index}-{self.serial}", "start": start, "end": min(last, start + 10)}
        )
        body = self._send(
            client,
            "annotate",
            "PUT",
            url,
            json={"meta": {**meta, "annotations": annotations}},
            headers={"If-Match": read.headers.get("etag", "")},
        )
        if body is not None:
            self._note(META)

    def _collection_create(self, client: httpx.Client) -> None:
        path = f"{self.plan.collection_root}/made/w{self.index}-{self.serial}"
        r = client.post("/api/collections", json={"path": path})
        self.ledger.answered("writer", "collection create", r.status_code, _error_text(r))
        if r.is_success:
            self._note(CREATE)
            self.made.append(path)
            if r.status_code == 201:
                with self.ledger.lock:
                    self.ledger.collections_made += 1

    def _collection_move(self, client: httpx.Client) -> None:
        if not self.made:
            self._collection_create(client)
            return
        path = self.made.pop()
        body = self._send(
            client,
            "collection move",
            "PATCH",
            f"/api/collections/{path}",
            json={"parent": f"{self.plan.collection_root}/moved"},
        )
        if body is not None:
            self._note(CHANGE)

    def _upload(self, client: httpx.Client) -> None:
        name = f"w{self.index}-{self.serial}-{self.plan.upload_file.name}"
        r = client.post(
            "/api/uploads",
            data={"collection": f"{self.plan.collection_root}/uploads"},
            files=[("file", (name, self.plan.upload_file.read_bytes(), "text/plain"))],
        )
        self.ledger.answered("writer", "upload", r.status_code, _error_text(r))
        try:
            results = r.json().get("results", [])
        except ValueError:
            return
        loaded = [x for x in results if x.get("status") == "loaded"]
        self._note(UPLOAD, len(loaded), [(x["clip_id"], x["version"]) for x in loaded])


_PROCESSED = re.compile(r"number of transactions actually processed: (\d+)")
_FAILED = re.compile(r"number of failed transactions: (\d+)")


def read_loop(dsn: str, low: int, high: int, until: float, ledger: Ledger) -> None:
    """One reader: pgbench with one connection running the shipped select_next_snippet script
    until the deadline, started again if an error aborts it (each abort counted as an error)."""
    while (left := until - time.monotonic()) >= 1.0:
        out = subprocess.run(
            [
                PGBENCH,
                "-n",
                "-M",
                "prepared",
                "-c",
                "1",
                "-T",
                str(int(left)),
                "-f",
                str(PGBENCH_SCRIPT),
                "-D",
                f"low={low}",
                "-D",
                f"high={high}",
                dsn,
            ],  # fmt: skip
            capture_output=True,
            text=True,
        )
        processed = _PROCESSED.search(out.stdout)
        failed = _FAILED.search(out.stdout)
        done = int(processed.group(1)) if processed else 0
        with ledger.lock:
            t = ledger.tally("reader", "select_next_snippet")
            t.requests += done
            t.classes["ok"] += done
            ledger.extra["pgbench runs"] += 1
        if failed and int(failed.group(1)):
            ledger.failed("reader", "select_next_snippet", "failed (retried) transactions",
                          int(failed.group(1)))  # fmt: skip
        if out.returncode != 0:
            why = [ln for ln in out.stderr.splitlines() if "abort" in ln or "ERROR" in ln]
            ledger.failed("reader", "select_next_snippet", (why or [out.stderr.strip()])[-1])
            if not processed:
                time.sleep(0.5)  # it could not even start: do not spin


def avatar_walk(address: str, index: int, seed: int, until: float, ledger: Ledger) -> None:
    """One avatar page: the WebSocket, a goal clicked every AVATAR_CLICK_S seconds, every message
    read. A goal is a request; its answer is the `goals` message, `refused` or `stopped` (an
    error, with its message), or nothing before the socket closes."""
    from websockets.exceptions import WebSocketException
    from websockets.sync.client import connect

    rng = random.Random(seed * 1000 + 500 + index)
    pending = 0  # goals sent and not answered yet
    try:
        with connect(
            f"ws://{address}/ws/avatar", origin=f"http://{address}", open_timeout=30
        ) as ws:
            ready = _message(ws.recv(timeout=30))
            if ready.get("type") != "ready":
                ledger.failed("avatar", "connect", f"first message {ready.get('type')!r}")
                return
            ledger.answered("avatar", "connect", 200)
            click = 0.0
            while (now := time.monotonic()) < until:
                if now >= click:
                    angle, metres = rng.uniform(0, 6.283), rng.uniform(2.0, 8.0)
                    ws.send(json.dumps({"type": "goal", "x": metres * math.cos(angle),
                                    "z": metres * math.sin(angle)}))  # fmt: skip
                    pending += 1
                    click = now + AVATAR_CLICK_S
                try:
                    message = _message(ws.recv(timeout=max(0.01, min(click, until) - now)))
                except TimeoutError:
                    continue
                kind = message.get("type")
                if kind == "goals" and pending:
                    pending -= 1
                    ledger.answered("avatar", "goal", 200)
                elif kind == "refused" and pending:
                    pending -= 1
                    ledger.answered("avatar", "goal", 400, str(message.get("message")))
                elif kind == "stopped":  # the walk ended on an error; the next goal starts one
                    ledger.failed("avatar", "walk stopped", str(message.get("message")))
                elif kind == "choice":
                    with ledger.lock:
                        ledger.extra["avatar choices"] += 1
    except (WebSocketException, OSError, TimeoutError) as e:
        ledger.failed("avatar", "goal", f"{type(e).__name__}: {e}", max(pending, 1))
        return
    if pending:  # sent in the last moments: not an error, but not an answer either
        with ledger.lock:
            ledger.extra["avatar goals unanswered at the end"] += pending
            ledger.tally("avatar", "goal").requests += pending


def _message(text: str | bytes) -> dict[str, Any]:
    value = json.loads(text)
    return value if isinstance(value, dict) else {}
