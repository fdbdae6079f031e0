"""Each source's name and terms follow its motion (issue 41, item 4): the loader records the licence
a load states or the nearest LICENSE file's title, retargeted clips lead back to the clip they were
made from, and exports name every source with its terms (glTF inside the file, BVH beside it)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path

import pygltflib

from support.commands import run_modb
from support.data import mocap

CMU_TERMS = "CMU Graphics Lab Motion Capture Database terms"


def first_line(path) -> str:
    return next(line.strip() for line in path.read_text().splitlines() if line.strip())


def version_meta(db, collection: str, name: str) -> dict:
    return db.execute(
        "SELECT v.meta FROM modb.clip_versions v JOIN modb.clips c ON c.id = v.clip_id "
        "WHERE c.collection_id = modb.find_collection(%s) AND c.name = %s "
        "ORDER BY v.version DESC LIMIT 1",
        [collection, name],
    ).fetchone()[0]


def test_sources_and_terms_follow_the_motion_into_exports(fresh_db, db, tmp_path):
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    cmu = mocap("cmu", "16")
    for args in (
        [walk, "--collection", "bandai"],
        [cmu / "16_15.amc", "--asf", cmu / "16.asf", "--collection", "cmu16"],
    ):
        stated = ["--licence", CMU_TERMS] if "cmu16" in args else []
        r = run_modb(fresh_db, "load", *args, *stated, "-q")
        assert r.returncode == 0, r.stderr
    bandai_licence = mocap("bandai-2-dev", "LICENSE")
    meta = version_meta(db, "bandai", walk.stem)
    assert meta["licence"] == first_line(bandai_licence)  # "Attribution-NonCommercial 4.0 ..."
    assert meta["licence_file"] == str(bandai_licence.resolve())
    assert version_meta(db, "cmu16", "16_15")["licence"] == CMU_TERMS

    # a copy in a folder without a licence file above it states none
    alone = tmp_path / "alone.bvh"
    shutil.copy(walk, alone)
    assert run_modb(fresh_db, "load", alone, "--collection", "alone", "-q").returncode == 0
    assert "licence" not in version_meta(db, "alone", "alone")

    # retargeted onto the Bandai rig, exported: the glTF names the CMU capture and its terms
    r = run_modb(fresh_db, "retarget", "cmu16", "--to", f"bandai/{walk.stem}", "--fps", "30",
                 "--collection", "mixed/cmu16", "-q")  # fmt: skip
    assert r.returncode == 0, r.stderr
    glb = tmp_path / "cmu_on_bandai.glb"
    r = run_modb(fresh_db, "export", "mixed/cmu16/16_15", "--out", glb)
    assert r.returncode == 0, r.stderr
    asset = pygltflib.GLTF2().load(str(glb)).asset
    assert asset.copyright == f"cmu16: {CMU_TERMS}"
    # edited after retargeting: a new version of the retargeted clip, still CMU's motion
    r = run_modb(
        fresh_db, "edit", "save", "soft", "--commands", '[{"op": "smooth", "seconds": 0.05}]'
    )
    assert r.returncode == 0, r.stderr
    r = run_modb(fresh_db, "edit", "apply", "soft", "mixed/cmu16/16_15")
    assert r.returncode == 0, r.stderr
    r = run_modb(fresh_db, "export", "mixed/cmu16/16_15", "--out", glb)
    assert r.returncode == 0, r.stderr
    asset = pygltflib.GLTF2().load(str(glb)).asset
    assert asset.copyright == f"cmu16: {CMU_TERMS}"
    (source,) = asset.extras["sources"]
    assert (source["source"], source["licence"]) == ("cmu16", CMU_TERMS)

    # a strip over both: the report counts every snippet once, by its source, and the seams between
    r = run_modb(fresh_db, "collection", "move", "bandai", "mixed")
    assert r.returncode == 0, r.stderr
    out, report = tmp_path / "strip.bvh", tmp_path / "strip.json"
    r = run_modb(fresh_db, "synth", "--to", "0,4", "--seconds", "6", "--collection", "mixed",
                 "--out", out, "--report-json", report, "-q")  # fmt: skip
    assert r.returncode == 0, r.stderr
    written = json.loads(report.read_text())
    origin = {"bandai": first_line(bandai_licence), "cmu16": CMU_TERMS}
    names = []
    for c in written["chain"]:  # the test's own origin of each snippet: its clip's collection
        (path,) = db.execute(
            "SELECT modb.collection_path(collection_id) FROM modb.clips WHERE id = %s",
            [c["clip_id"]],
        ).fetchone()
        names.append("cmu16" if path == "mixed/cmu16" else "mixed/bandai")
    shares = written["sources"]["shares"]
    assert {s["source"]: s["snippets"] for s in shares} == {n: names.count(n) for n in set(names)}
    for s in shares:
        assert s["licence"] == origin[s["source"].split("/")[-1]]
    assert written["sources"]["crossings"] == sum(a != b for a, b in zip(names, names[1:]))
    beside = tmp_path / "strip.bvh.sources.json"  # only for several sources
    assert beside.exists() == (len(shares) > 1)


def test_a_bvh_of_several_sources_gets_them_beside_it_and_elsewhere_says_them(tmp_path, capsys):
    from modb.cli.common import write_motion_file
    from modb.gltf_export import rest_motion
    from modb.loader.bvh import parse_bvh

    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    motion = rest_motion(parse_bvh(walk.read_bytes(), str(walk), "auto").skeleton)
    sources = [
        {
            "source": "mixed/bandai",
            "licence": "Attribution-NonCommercial 4.0 International",
            "snippets": 9,
        },
        {"source": "cmu16", "licence": CMU_TERMS, "snippets": 3},
    ]
    two = dataclasses.replace(motion, meta={"sources": sources})
    assert write_motion_file("synth", two, str(tmp_path / "a.bvh"))
    assert json.loads((tmp_path / "a.bvh.sources.json").read_text()) == {"sources": sources}
    one = dataclasses.replace(motion, meta={"sources": sources[:1]})
    assert write_motion_file("synth", one, str(tmp_path / "b.bvh"))
    assert sorted(os.listdir(tmp_path)) == ["a.bvh", "a.bvh.sources.json", "b.bvh"]
    capsys.readouterr()
    assert write_motion_file("synth", two, "/dev/null")  # a device: nothing put beside it
    assert not os.path.exists("/dev/null.sources.json")
    assert f"cmu16: {CMU_TERMS}" in capsys.readouterr().err


def test_a_licence_file_is_found_from_a_relative_path_and_a_binary_one_passed_over(
    tmp_path, monkeypatch
):
    from modb.loader.folders import DISK
    from modb.loader.licences import licence_of

    data = tmp_path / "dataset" / "data"
    data.mkdir(parents=True)
    (tmp_path / "dataset" / "LICENSE").write_text("\n  My Terms 1.0  \nmore\n")
    (data / "LICENSE").write_bytes(b"\x00\x01binary")  # not a licence text: passed over
    monkeypatch.chdir(data)
    found = licence_of(Path("walk.bvh"), DISK)
    assert found == {
        "licence": "My Terms 1.0",
        "licence_file": str(tmp_path / "dataset" / "LICENSE"),
    }
    assert licence_of(Path("walk.bvh"), DISK, "stated") == {"licence": "stated"}


def test_a_new_version_keeps_the_licence_when_a_sidecar_gives_the_rest(fresh_db, db, tmp_path):
    walk = tmp_path / "walk.bvh"
    text = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh").read_text()
    walk.write_text(text)
    r = run_modb(
        fresh_db, "load", walk, "--collection", "w", "--licence", "Mine", "--no-snippets", "-q"
    )
    assert r.returncode == 0, r.stderr
    # one frame less, and a sidecar: a new version whose meta comes from the sidecar
    head, frames = text.split("MOTION", 1)
    lines = frames.strip("\n").splitlines()
    n = int(lines[0].split(":")[1])
    lines[0] = f"Frames: {n - 1}"
    walk.write_text(head + "MOTION\n" + "\n".join(lines[:-1]) + "\n")
    (tmp_path / "walk.annotations.json").write_text(json.dumps({"tags": ["mine"]}))
    r = run_modb(fresh_db, "load", walk, "--collection", "w", "--no-snippets", "-q")
    assert r.returncode == 0, r.stderr
    metas = db.execute(
        "SELECT v.meta FROM modb.clip_versions v JOIN modb.clips c ON c.id = v.clip_id "
        "WHERE c.name = 'walk' ORDER BY v.version"
    ).fetchall()
    assert [m["licence"] for (m,) in metas] == ["Mine", "Mine"]
    assert metas[-1][0]["tags"] == ["mine"]
