"""glTF 2.0 out (issue 24): clips and synthesized walks as .glb/.gltf with a skinned character made
from the skeleton. Checked by the Khronos validator (npm gltf-validator, pinned in the web view's
package.json) and read back by three.js's GLTFLoader in Chromium: a SkinnedMesh whose animated
joints stand where the database's forward kinematics (modb.world_positions) puts them."""

from __future__ import annotations

import base64

import numpy as np
import pytest
from support.browser import module_page, serving
from support.commands import run_modb
from support.databases import COLLECTION
from support.gltf_validator import validate
from support.snippet_oracle import motion_world

from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.root_motion import with_root_motion
from modb.synthesis.synth import synthesize

# In the page (its import map has three): load a glTF (from a URL, or the file's bytes in base64),
# play its animation at the given times, and read back every bone's world position.
READ_BACK = """
const [url, base64, times, done] = arguments;
(async () => {
  const THREE = await import('three');
  const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
  const loader = new GLTFLoader();
  const gltf = url ? await loader.loadAsync(url)
    : await loader.parseAsync(Uint8Array.from(atob(base64), (c) => c.charCodeAt(0)).buffer, '');
  const skinned = [];
  gltf.scene.traverse((o) => { if (o.isSkinnedMesh) skinned.push(o); });
  const bones = skinned[0].skeleton.bones;
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(gltf.animations[0]);
  action.setLoop(THREE.LoopOnce);  // the last frame's time must not wrap round to the first
  action.clampWhenFinished = true;
  action.play();
  const positions = times.map((t) => {
    mixer.setTime(t);
    gltf.scene.updateMatrixWorld(true);
    return bones.map((b) => b.getWorldPosition(new THREE.Vector3()).toArray());
  });
  done({ skinned: skinned.length, vertices: skinned[0].geometry.attributes.position.count,
         weights: !!skinned[0].geometry.attributes.skinWeight, names: bones.map((b) => b.name),
         positions });
})().catch((e) => done({ error: String(e) }));
"""


def read_back(browser, address: str, times: list[float], url=None, data: bytes = b"") -> dict:
    browser.get(f"http://{address}/")
    browser.set_script_timeout(60)
    result = browser.execute_async_script(READ_BACK, url, base64.b64encode(data).decode(), times)
    assert "error" not in result, result
    assert result["skinned"] == 1 and result["weights"] and result["vertices"] > 100
    return result


@pytest.fixture(scope="module")
def browser(chromium_driver):
    with module_page(chromium_driver) as driver:
        yield driver


@pytest.mark.parametrize("data", ["cmu", "locomotion"])
def test_a_clip_as_glb_validates_and_three_js_poses_it_as_the_database_does(
    request, browser, tmp_path, data
):
    dsn = request.getfixturevalue(data)
    collection = {"cmu": "cmu/131", "locomotion": COLLECTION}[data]  # (the demo loads CMU too)
    with connect(dsn) as conn:
        clip_id, version, fps, n_frames = conn.execute(
            "SELECT clip_id, version, fps, n_frames FROM modb.current_clips WHERE collection = %s "
            "ORDER BY n_frames DESC, clip_id LIMIT 1",
            [collection],
        ).fetchone()
        frames = sorted({0, 1, n_frames // 3, n_frames // 2, n_frames - 1})
        expected = conn.execute(
            "SELECT frame, joint_index, x, y, z FROM modb.world_positions(%s, %s) "
            "WHERE frame = ANY (%s) ORDER BY frame, joint_index",
            [clip_id, version, frames],
        ).fetchall()
    out = tmp_path / "clip.glb"
    r = run_modb(dsn, "export", str(clip_id), "--out", out)
    assert r.returncode == 0, r.stderr
    issues = validate(out)
    assert issues["numErrors"] == 0, issues["messages"][:5]
    with serving(dsn) as address:
        result = read_back(
            browser,
            address,
            [k / fps for k in frames],
            url=f"/api/clips/{clip_id}/download?format=glb&version={version}",
        )
    ours = np.array(result["positions"])
    theirs = np.array([row[2:] for row in expected]).reshape(len(frames), -1, 3)
    assert ours.shape == theirs.shape
    assert np.abs(ours - theirs).max() < 1e-3


def test_synth_writes_a_walk_as_glb_and_gltf_with_root_motion(locomotion, browser, tmp_path):
    goals = [(0.0, 4.0), (4.0, 4.0)]
    outs = [tmp_path / "walk.glb", tmp_path / "walk.gltf"]
    for out in outs:
        args = ["--to", "0,4", "--to", "4,4", "--seconds", "10", "--out", out, "-q"]
        r = run_modb(locomotion, "synth", *args)
        assert r.returncode == 0, r.stderr
        assert validate(out)["numErrors"] == 0
    with connect(locomotion) as conn:
        strip = with_root_motion(synthesize(conn, goals, 10.0, Settings()).strip)
    positions, _ = motion_world(strip)  # scipy's forward kinematics of the same strip
    frames = [0, strip.n_frames // 2, strip.n_frames - 1]
    with serving(locomotion) as address:
        result = read_back(browser, address, [k / 30 for k in frames], data=outs[0].read_bytes())
    assert result["names"][0] == "joint_Root"
    assert np.abs(np.array(result["positions"]) - positions[frames]).max() < 1e-3
