"""What several commands share: the connection the global options name, the argparse types of
numeric options (bounded: no NaN, infinities or values beyond a stated range), and checking and
writing output files."""

from __future__ import annotations

import argparse
import json
import os
import sys

import psycopg

from modb.database.dsn import resolve
from modb.loader.limits import FPS_RANGE
from modb.output import output_target
from modb.provenance import credits
from modb.validation import checked_number, number_range


def connect(args: argparse.Namespace) -> psycopg.Connection:
    """The database `--dsn` names (or $MODB_DSN, libpq's environment, the embedded cluster)."""
    return connect_to(args.dsn, args.verbose)


def connect_to(dsn: str | None, verbose: bool = False) -> psycopg.Connection:
    """The database `dsn` names (None: $MODB_DSN, libpq's environment, the embedded cluster);
    `verbose` says which on stderr."""
    # numpy, for modb's arrays (60 ms): not for `modb --help`
    from modb.database.connection import connect

    conninfo, origin = resolve(dsn)
    if verbose:
        print(f"database: {origin}", file=sys.stderr)
    return connect(conninfo)


class Number:
    """An argparse type: a finite number from `least` (excluded if `above`) to `most`, a whole one
    if `whole`. Anything else (NaN, inf, 1e308, text) is refused with the range named, and argparse
    names the option: "argument --seconds: must be a number greater than 0 and at most 3600
    seconds, got 'inf'"."""

    def __init__(
        self, least: float, most: float, *, above: bool = False, whole: bool = False, unit=""
    ) -> None:
        self.bounds = (least, most, above, whole, unit)
        self.least, self.most, self.above, self.unit = least, most, above, unit

    @property
    def span(self) -> str:
        """The range for a help text: '1-65535', '0-2 seconds', 'more than 0, at most 3600 s'."""
        unit = f" {self.unit}" if self.unit else ""
        least, most = (str(v) if self.bounds[3] else f"{v:g}" for v in (self.least, self.most))
        if self.above:
            return f"more than {least}, at most {most}{unit}"
        return f"{least}-{most}{unit}"

    def __call__(self, text: str):
        try:
            value = int(text) if self.bounds[3] else float(text)
            return checked_number("value", value, *self.bounds)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be {number_range(*self.bounds)}, got {text!r:.100}"
            ) from None

    def __repr__(self) -> str:
        return f"Number({number_range(*self.bounds)})"


def whole(least: int, most: int, unit: str = "") -> Number:
    return Number(least, most, whole=True, unit=unit)


def positive(most: float, unit: str = "") -> Number:
    """More than 0, at most `most`."""
    return Number(0.0, most, above=True, unit=unit)


SEED = whole(0, 2**32 - 1)  # a random seed
VERSION = whole(1, 2**31 - 1)  # clip versions are int
PORT = whole(1, 65535)  # a TCP port


FPS = Number(*FPS_RANGE, unit="fps")  # a frame rate to write a file at


def writable(command: str, path: str | None) -> bool:
    """Whether `path` (`-`: standard output; None: nothing to write) can be written, checked before
    any work is done: a directory or a folder that does not exist is refused at once, with the
    reason on stderr. How it is written is modb.output.open_output's."""
    if path is None:
        return True
    try:
        output_target(path, allow_stdout=True)
    except OSError as e:
        where = f" ({e.filename})" if e.filename not in (None, path) else ""
        print(f"modb {command}: cannot write {path}: {e.strerror or e}{where}", file=sys.stderr)
        return False
    return True


SOURCES_SUFFIX = ".sources.json"  # beside a BVH file of several sources: each with its terms


def write_bvh_file(command: str, motion, path: str) -> bool:
    """Writes `motion` to `path` (`-`: standard output); if it cannot, False, with the reason on
    stderr. A motion of several sources (meta["sources"]) gets FILE.sources.json beside a regular
    file (BVH has no place for them); written elsewhere, they are said on stderr."""
    from modb.bvh_export import write_bvh_file  # numpy (70 ms): not for `modb --help`

    sources = motion.meta.get("sources") or []
    try:
        write_bvh_file(motion, path, allow_stdout=True)
    except BrokenPipeError:
        raise  # the reader left early (`modb export X | head`): main() exits 0
    except OSError as e:
        print(f"modb {command}: cannot write {path}: {e.strerror or e}", file=sys.stderr)
        return False
    beside = path != "-" and os.path.isfile(path)
    try:
        if beside and len(sources) > 1:
            with open(path + SOURCES_SUFFIX, "w", encoding="utf-8") as f:
                json.dump({"sources": sources}, f, indent=2)
        elif beside and os.path.isfile(path + SOURCES_SUFFIX):
            os.remove(path + SOURCES_SUFFIX)  # an earlier strip's: not this one's sources
    except OSError as e:
        print(
            f"modb {command}: wrote {path}, but not its sources in {path}{SOURCES_SUFFIX}: "
            f"{e.strerror or e}",
            file=sys.stderr,
        )
        return False
    if len(sources) > 1 and not beside:
        print(f"modb {command}: the motion's sources and their terms: {credits(sources)}",
              file=sys.stderr)  # fmt: skip
    return True


def motion_format(path: str, asked: str | None = None) -> str:
    """bvh or gltf: as asked, else by the file name (.glb, .gltf), else bvh."""
    from modb.gltf_export import is_gltf_name  # numpy and pygltflib (110 ms)

    return asked or ("gltf" if is_gltf_name(path) else "bvh")


def write_motion_file(command: str, motion, path: str, fmt: str = "bvh") -> bool:
    """Writes `motion` to `path` as BVH or glTF (`-`: standard output; glTF there is .glb); if it
    cannot, False, with the reason on stderr."""
    if fmt == "bvh":
        return write_bvh_file(command, motion, path)
    from modb.gltf_export import write_gltf_file  # numpy and pygltflib (110 ms)

    try:
        write_gltf_file(motion, path, allow_stdout=True)
    except BrokenPipeError:
        raise
    except ValueError as e:  # a skeleton without bones to draw
        print(f"modb {command}: cannot write {path} as glTF: {e}", file=sys.stderr)
        return False
    except OSError as e:
        print(f"modb {command}: cannot write {path}: {e.strerror or e}", file=sys.stderr)
        return False
    return True
