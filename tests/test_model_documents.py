"""Motion model documents are checked where they are written (issue 58, 1): every writer (SQL, a
REST replace, `modb model import`) is refused, in words naming the field, a document that would
break a listing, a sample or a synthesis; a new version never carries an acceleration tree drawn
from other data. On a copy of conftest's cmu16_walks (CMU 16's step models). The broken documents
are the campaign's: each made from the stored model by the test, not by the code under test."""

from __future__ import annotations

import copy
import json
import os

import numpy as np
import psycopg
import pytest
from psycopg.types.json import Jsonb
from support.commands import run_modb_here as modb

from modb.database.connection import connect

MODEL = "cmu16_left_step"


@pytest.fixture(scope="module")
def dsn(cmu16_walks):
    with cmu16_walks(f"model_documents_{os.getpid()}") as dsn:
        yield dsn


@pytest.fixture(scope="module")
def model(dsn) -> tuple[int, dict, dict]:
    with connect(dsn) as conn:
        return conn.execute(
            "SELECT id, data, meta FROM modb.models WHERE name = %s AND version = 1", [MODEL]
        ).fetchone()


def _set(path: str, value):
    def change(doc: dict) -> None:
        *parents, last = path.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value

    return change


def _drop(key: str):
    return lambda doc: doc.pop(key)


def _covariance(value: float, row: int = 0, col: int = 0):
    return _set(f"mixture.covariances.0.{row}.{col}", value)


# (what is wrong, how the stored model is changed, a word the refusal must hold)
BROKEN = [
    ("empty", lambda d: d.clear(), '"fps"'),
    ("no mixture", _drop("mixture"), '"mixture"'),
    ("fps 0", _set("fps", 0), '"fps"'),
    ("fps -30", _set("fps", -30), '"fps"'),
    ("fps as text", _set("fps", "30"), '"fps"'),
    ("fps 1e6", _set("fps", 1e6), '"fps"'),
    ("one frame", _set("n_frames", 1), '"n_frames"'),
    ("joints miscounted", _set("n_joints", 3), '"joints"'),
    ("translated out of range", _set("translated", [999]), '"translated"'),
    ("keyframe past the end", _set("keyframes", [0, 10_000]), '"keyframes"'),
    ("1e308 in an eigenvector", _set("spatial.components.0.0", 1e308), "spatial.components"),
    ("an eigenvector not of unit length", _set("spatial.components.0.0", 5.0),
     "spatial.components"),  # fmt: skip
    ("a text in the mean", _set("spatial.mean.3", "x"), "spatial.mean"),
    ("temporal mean cut short", lambda d: d["temporal"]["mean"].pop(), "temporal.mean"),
    ("zero weights", lambda d: d["mixture"].update(weights=[0.0] * len(d["mixture"]["weights"])),
     "mixture.weights"),  # fmt: skip
    ("weights not summing to 1", lambda d: d["mixture"]["weights"].__setitem__(0, 5.0),
     "mixture.weights"),  # fmt: skip
    ("a negative variance", _covariance(-1.0), "positive definite"),
    ("an asymmetric covariance", _covariance(0.5, 0, 1), "symmetric"),
    ("means of another dimension", lambda d: [m.pop() for m in d["mixture"]["means"]],
     "mixture.means"),  # fmt: skip
    ("lever arm 0", _set("spatial.weights.0", 0.0), "spatial.weights"),
    ("a joint limit of 400 degrees", _set("limits.degrees.0", 400.0), "limits.degrees"),
    ("a stance height as text", _set("stance", {"toe": "4 cm"}), "stance.toe"),
    ("a stance of another point", _set("stance", {"heel": 0.04}), '"stance"'),
]


def _broken(data: dict, change) -> dict:
    doc = copy.deepcopy(data)
    change(doc)
    return doc


def test_the_stored_models_pass_and_the_check_finds_each_broken_one(dsn, model):
    _, data, _ = model
    with connect(dsn) as conn:
        for (name,) in conn.execute("SELECT name FROM modb.models ORDER BY id").fetchall():
            assert conn.execute(
                "SELECT modb.model_document_problems(data) FROM modb.models WHERE name = %s "
                "ORDER BY version DESC LIMIT 1", [name]
            ).fetchone()[0] == [], name  # fmt: skip
        for what, change, word in BROKEN:
            (problems,) = conn.execute(
                "SELECT modb.model_document_problems(%s)", [Jsonb(_broken(data, change))]
            ).fetchone()
            assert len(problems) == 1 and word in problems[0], (what, problems)


def test_sql_inserts_of_broken_documents_are_refused_and_nothing_is_stored(dsn, model):
    _, data, _ = model
    with connect(dsn) as conn:
        before = conn.execute("SELECT count(*) FROM modb.models").fetchone()[0]
        for what, change, word in BROKEN:
            with pytest.raises(psycopg.errors.CheckViolation) as refused:
                with conn.transaction():
                    conn.execute(
                        "INSERT INTO modb.models (name, kind, data) "
                        "VALUES ('broken', 'motion_primitive', %s)",
                        [Jsonb(_broken(data, change))],
                    )
            message = refused.value.diag.message_primary
            assert message.startswith('motion model "broken" is not stored: '), (what, message)
            assert word in message, (what, message)
        # another kind of document is the writer's, but not without bounds
        junk = {"junk": "x" * (17 * 1024 * 1024)}
        with pytest.raises(psycopg.errors.CheckViolation, match="more than the 16 MB"):
            with conn.transaction():
                conn.execute(
                    "INSERT INTO modb.models (name, kind, data) VALUES ('junk', 'notes', %s)",
                    [Jsonb(junk)],
                )
        with pytest.raises(psycopg.errors.CheckViolation, match="more than the 16 MB"):
            with conn.transaction():
                conn.execute(
                    "INSERT INTO modb.models (name, kind, data) "
                    "VALUES ('junk', 'motion_primitive', %s)", [Jsonb({**data, **junk})],
                )  # fmt: skip
        assert conn.execute("SELECT count(*) FROM modb.models").fetchone()[0] == before


def _tree_of(conn, ident: int):
    return conn.execute("SELECT meta->'tree' FROM modb.models WHERE id = %s", [ident]).fetchone()[0]


def test_a_new_version_never_carries_a_tree_of_other_data(dsn, model, tmp_path):
    ident, data, meta = model
    assert meta["tree"]["mixture_md5"]  # a build stamps its tree
    other = copy.deepcopy(data)
    other["mixture"]["means"] = (np.asarray(other["mixture"]["means"]) + 0.5).tolist()
    with connect(dsn) as conn:
        # SQL: a copy of the tree beside other data is refused, saying what to do
        with pytest.raises(psycopg.errors.CheckViolation, match="drawn from another mixture"):
            with conn.transaction():
                conn.execute(
                    "INSERT INTO modb.models (name, kind, data, meta) "
                    "SELECT name, kind, %s, meta FROM modb.models WHERE id = %s",
                    [Jsonb(other), ident],
                )
        # the same data: the tree is its own
        with conn.transaction():
            (same,) = conn.execute(
                "INSERT INTO modb.models (name, kind, data, meta) "
                "SELECT name, kind, data, meta FROM modb.models WHERE id = %s RETURNING id",
                [ident],
            ).fetchone()
        assert _tree_of(conn, same) == meta["tree"]
    # an exported file imports with its tree; one whose mixture was changed, without it
    r = modb(dsn, "model", "export", MODEL, "--version", "1", "--out", tmp_path / "m.json")
    assert r.returncode == 0, r.stderr
    exported = json.loads((tmp_path / "m.json").read_text())
    r = modb(dsn, "model", "import", tmp_path / "m.json", "--name", "kept_tree")
    assert r.returncode == 0 and "with its acceleration tree" in r.stdout, r.stdout + r.stderr
    exported["data"] = other
    (tmp_path / "other.json").write_text(json.dumps(exported))
    r = modb(dsn, "model", "import", tmp_path / "other.json", "--name", "no_tree")
    assert r.returncode == 0 and "no tree (`modb model tree no_tree`" in r.stdout, r.stdout
    with connect(dsn) as conn:
        (kept,) = conn.execute("SELECT id FROM modb.models WHERE name = 'kept_tree'").fetchone()
        (dropped,) = conn.execute("SELECT id FROM modb.models WHERE name = 'no_tree'").fetchone()
        assert _tree_of(conn, kept) == meta["tree"] and _tree_of(conn, dropped) is None
    # a broken file is refused naming the field, nothing stored
    exported["data"] = _broken(data, _set("fps", 0))
    (tmp_path / "broken.json").write_text(json.dumps(exported))
    r = modb(dsn, "model", "import", tmp_path / "broken.json", "--name", "never")
    assert r.returncode != 0 and '"fps" must be a number from 1 to 1000' in r.stderr, r.stderr
    with connect(dsn) as conn:
        never = conn.execute("SELECT count(*) FROM modb.models WHERE name = 'never'").fetchone()
        assert never == (0,)


def test_rest_replaces_are_checked_and_drop_the_old_tree(dsn, model):
    import httpx
    from support.browser import serving

    ident, data, meta = model
    r = modb(dsn, "token", "create", "documents-loader", "--role", "loader")
    assert r.returncode == 0, r.stderr
    token = {"Authorization": f"Bearer {r.stdout.strip()}"}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        refused = (({"data": {}}, '"fps"'),
                   ({"data": _broken(data, _set("fps", 0))}, '"fps"'),
                   ({"data": _broken(data, _covariance(-1.0))}, "positive definite"))  # fmt: skip
        for body, word in refused:
            answer = client.put(f"/api/models/{ident}", json=body, headers=token)
            assert answer.status_code == 400 and word in answer.json()["error"], answer.text
        other = copy.deepcopy(data)
        other["settings"] = {**other.get("settings", {}), "note": "replaced"}
        other["mixture"]["means"] = (np.asarray(other["mixture"]["means"]) * 0.5).tolist()
        answer = client.put(f"/api/models/{ident}", json={"data": other}, headers=token)
        assert answer.status_code == 201, answer.text
        replaced = answer.json()["id"]
        # meta alone changes in place: the tree stays, the note joins it
        answer = client.put(f"/api/models/{ident}", json={"meta": {**meta, "note": 1}},
                            headers=token)  # fmt: skip
        assert answer.status_code == 200 and answer.json()["id"] == ident, answer.text
        noted = ident
        shown = client.get(f"/api/motion-models/{MODEL}", headers=token)
        assert shown.status_code == 200, shown.text
    with connect(dsn) as conn:
        assert _tree_of(conn, replaced) is None  # new data: the old tree is not its own
        assert _tree_of(conn, noted) == meta["tree"]  # the same data: its tree kept


def _toast_blocks(conn) -> int:
    conn.execute("SELECT pg_stat_force_next_flush()")
    conn.execute("SELECT 1")  # the flush happens as this connection goes idle
    conn.execute("SELECT pg_stat_clear_snapshot()")
    (blocks,) = conn.execute(
        "SELECT coalesce(toast_blks_read, 0) + coalesce(toast_blks_hit, 0) "
        "FROM pg_statio_all_tables WHERE relid = 'modb.models'::regclass"
    ).fetchone()
    return blocks


def test_a_listing_reads_no_model_document(dsn):
    """Issue 58, 10: listing versions and their staleness reads none of the documents (0.7 MB of
    data and 4.5 MB of tree each): the columns the database keeps, and the inputs' rows."""
    from modb.models.store import listing

    with connect(dsn) as conn:
        conn.autocommit = True
        conn.execute(
            "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
            "SELECT 'many ' || k, m.kind, m.skeleton_id, m.collection_id, m.data, m.meta "
            "FROM modb.models m, generate_series(1, 5) k WHERE m.name = %s AND m.version = 1",
            [MODEL],
        )
        before = _toast_blocks(conn)
        listed = listing(conn)
        read = _toast_blocks(conn) - before
        # the same figures the documents give, read from them here
        documents = {(r[0], r[1]): r[2:] for r in conn.execute(
            "SELECT name, version, jsonb_array_length(data->'inputs'), "
            "jsonb_array_length(data->'mixture'->'weights'), meta ? 'tree', data->>'primitive' "
            "FROM modb.models WHERE kind = 'motion_primitive'")}  # fmt: skip
    assert read == 0, f"the listing read {read} blocks of model documents"
    assert len(listed) == len(documents) >= 7
    for row in listed:
        expected = documents[(row["name"], row["version"])]
        got = (row["examples"], row["components"], row["has_tree"], row["primitive"])
        assert got == expected, (row["name"], got, expected)
