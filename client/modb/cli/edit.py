"""`modb edit`: edit scripts (modb.edit_scripts): save one, list them, apply one to clips or
collections (modb.apply_edit_script: a new version per clip, in one transaction)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from psycopg.types.json import Jsonb

from . import as_job
from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    edit = sub.add_parser(
        "edit", help="edit scripts: save, list, apply (each result a new version)"
    )
    actions = edit.add_subparsers(dest="action", required=True)
    save = actions.add_parser("save", help="store a script (replacing one of that name)")
    save.add_argument("name", metavar="NAME")
    given = save.add_mutually_exclusive_group(required=True)
    given.add_argument("--file", type=Path, help="a JSON file holding the list of commands")
    given.add_argument("--commands", metavar="JSON", help='the list, e.g. \'[{"op": "mirror"}]\'')
    save.add_argument("--comment", help="what the script is for")
    actions.add_parser("list", help="every stored script")
    apply = actions.add_parser("apply", help="apply a script to clips and collections")
    apply.add_argument("name", metavar="NAME")
    apply.add_argument(
        "targets",
        nargs="+",
        metavar="TARGET",
        help="a clip (id, name, collection/name) or a collection",
    )
    as_job.add_options(apply, "apply")
    edit.set_defaults(func=run)


def _commands(args: argparse.Namespace) -> list:
    where = str(args.file) if args.file else "--commands"
    try:
        text = args.file.read_text() if args.file else args.commands
        commands = json.loads(text)
    except OSError as e:
        raise SystemExit(f"modb edit: {where}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise SystemExit(f"modb edit: {where}:{e.lineno}: not JSON: {e.msg}") from None
    from modb_kernel.edits import script_errors  # the check the database's trigger runs

    problems = script_errors(commands)
    if problems:
        raise SystemExit(f"modb edit: {where}: " + "; ".join(problems))
    return commands


def run(args: argparse.Namespace) -> int:
    from modb.clips import ClipNotFound, clips_in  # numpy (60 ms): not for `modb --help`

    with connect(args) as conn:
        if args.action == "save":
            commands = _commands(args)
            conn.execute(
                "INSERT INTO modb.edit_scripts (name, commands, comment) VALUES (%s, %s, %s) "
                "ON CONFLICT (name) DO UPDATE SET commands = EXCLUDED.commands, "
                "comment = EXCLUDED.comment",
                [args.name, Jsonb(commands), args.comment],
            )
            print(f"saved {args.name!r}: {len(commands)} commands")
            return 0
        if args.action == "list":
            for name, commands, comment in conn.execute(
                "SELECT name, commands, comment FROM modb.edit_scripts ORDER BY name"
            ):
                # rows stored before 0.17.0 checked scripts may hold anything: list them anyway
                listed = commands if isinstance(commands, list) else [commands]
                ops = ", ".join(
                    str(c.get("op", "?")) if isinstance(c, dict) else "?" for c in listed
                )
                print(f"{name}: {ops}" + (f"  ({comment})" if comment else ""))
            return 0
        try:
            # A clip named twice, or named and in a named collection, is edited once.
            clips = list(dict.fromkeys(c for t in args.targets for c in clips_in(conn, t)))
        except ClipNotFound as e:
            print(f"modb edit: {e}", file=sys.stderr)
            return 2
        as_a_job = as_job.usable(conn, args, "edit apply", "0.20.0")
        if as_a_job is None:
            return 2
        if as_a_job:
            arguments = {"script": args.name, "clips": clips}
            done = as_job.run(conn, args, "edit apply", "apply_edit_script", arguments)
            if done is None or isinstance(done, int):
                return done or 0
            rows = [(c["clip_id"], c["version"], c["n_frames"], c["snippets"])
                    for c in done.result["clips"]]  # fmt: skip
        else:
            with conn.transaction():
                rows = conn.execute(
                    "SELECT * FROM modb.apply_edit_script(%s, %s)", [args.name, clips]
                ).fetchall()
    from modb.editing.script_notes import messages, version_notes

    with connect(args) as conn:
        for clip_id, version, frames, snippets in rows:
            print(f"clip {clip_id}: version {version} ({frames} frames, {snippets} snippets)")
            for message in messages(version_notes(conn, clip_id, version)):
                print(f"  {message}")  # an ik target out of reach: the nearest point, its distance
    return 0
