"""What the wheel holds, found in the source tree rather than listed by hand (the rest of the build
is in pyproject.toml). The three top-level folders are one distribution: the client (`modb`), the
loader (imported as `modb.loader`) and the numeric kernel the server's PL/Python shares
(`modb_kernel`)."""

import sys
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE_DIRS = {
    "modb": "client/modb",
    "modb.loader": "loader",
    "modb_kernel": "extension/plpython/modb_kernel",
}
# The three.js modules the web view's pages import, and what those import (tests/test_wheel.py
# follows every import from the installed server, so a page that needs another fails there), from
# the copy `make setup` pins (npm ci): 2 MB of the npm package's 24.
THREE_FILES = [
    "LICENSE",
    "build/three.module.js",
    "build/three.core.js",
    "examples/jsm/controls/OrbitControls.js",
    "examples/jsm/controls/TransformControls.js",
    "examples/jsm/loaders/GLTFLoader.js",
    "examples/jsm/utils/BufferGeometryUtils.js",
    "examples/jsm/utils/SkeletonUtils.js",
]
# Files read at run time, by the package (folder) that holds them.
DATA = {
    "modb": ["py.typed"],
    "modb_kernel": ["py.typed"],
    "modb.bench": ["*.pgbench"],  # the pgbench script `modb bench scale` runs
    "modb.jobs": ["*.sql"],  # the job tables and the view modb.jobs (`modb worker --init`)
    "modb.web.static": ["*"],  # the pages, scripts and style of `modb serve`
}
THREE = Path(__file__).parent / "client" / "modb" / "web" / "node_modules" / "three"
missing = [f for f in THREE_FILES if not (THREE / f).exists()]
if missing:
    sys.exit(f"setup.py: three.js is not in {THREE.parent} (no {missing[0]}): run `make setup`")
for path in THREE_FILES:
    folder, _, name = f"web/node_modules/three/{path}".rpartition("/")
    DATA.setdefault("modb." + folder.replace("/", "."), []).append(name)


def found(package: str) -> list[str]:
    """The package and every package below it in its folder (npm's folders aside)."""
    below = find_packages(PACKAGE_DIRS[package], exclude=["*node_modules*"])
    return [package] + [f"{package}.{p}" for p in below]


packages = [p for top in PACKAGE_DIRS for p in found(top)]
data_folders = [p for p in DATA if p not in packages]  # namespace packages: setuptools' rule
setup(
    packages=packages + data_folders,
    package_dir=PACKAGE_DIRS,
    package_data=DATA,
)
