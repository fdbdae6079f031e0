"""The Khronos glTF validator (npm gltf-validator, pinned in the web package.json), run by node."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from .data import REPO

NODE_MODULES = REPO / "client" / "modb" / "web" / "node_modules"
VALIDATE = """
const fs = require('fs');
require(process.argv[1]).validateBytes(new Uint8Array(fs.readFileSync(process.argv[2])))
  .then((r) => console.log(JSON.stringify(r.issues)));
"""


def validate(path: Path) -> dict:
    """The validator's issues: numErrors, numWarnings, messages."""
    if not (shutil.which("node") and (NODE_MODULES / "gltf-validator").is_dir()):
        pytest.skip("node and the pinned gltf-validator are not installed (`make setup` does)")
    out = subprocess.run(
        ["node", "-e", VALIDATE, str(NODE_MODULES / "gltf-validator"), str(path)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)
