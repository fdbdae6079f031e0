"""`modb collection` and `modb clip`: rename, move and delete collections; delete a clip or one
version, make an older version current again (modb.editing.catalog, as the loader role)."""

from __future__ import annotations

import argparse
import sys

from .common import VERSION, connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    collection = sub.add_parser("collection", help="create, rename, move or delete a collection")
    actions = collection.add_subparsers(dest="action", required=True)
    create = actions.add_parser("create", help="create a collection (and the levels above it)")
    create.add_argument("path", metavar="PATH", help='a path like "bandai/walks"')
    rename = actions.add_parser("rename", help="give a collection a new name (its last part)")
    rename.add_argument("path", metavar="PATH")
    rename.add_argument("new_name", metavar="NAME")
    move = actions.add_parser("move", help="move a collection, with what it holds")
    move.add_argument("path", metavar="PATH")
    move.add_argument(
        "new_parent", metavar="PARENT", help="the new enclosing path ('' for the top)"
    )
    delete = actions.add_parser("delete", help="delete a collection and those below it")
    delete.add_argument("path", metavar="PATH")
    delete.add_argument(
        "--with-clips",
        action="store_true",
        help="delete the clips in it too (else it must be empty)",
    )
    collection.set_defaults(func=run_collection)

    clip = sub.add_parser("clip", help="delete a clip or a version; make an older version current")
    actions = clip.add_subparsers(dest="action", required=True)
    delete = actions.add_parser("delete", help="delete a clip, or one version of it (--version)")
    delete.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    delete.add_argument("--version", type=VERSION, help="only this version")
    restore = actions.add_parser("restore", help="make an older version the current one again")
    restore.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    restore.add_argument("--version", type=VERSION, required=True)
    clip.set_defaults(func=run_clip)


def run_collection(args: argparse.Namespace) -> int:
    from modb.editing import catalog  # numpy, through the loader (90 ms): not for `modb --help`

    with connect(args) as conn, conn.transaction():
        if args.action == "create":
            print(catalog.create_collection(conn, args.path)[1])
        elif args.action == "rename":
            print(catalog.rename_collection(conn, args.path, args.new_name))
        elif args.action == "move":
            print(catalog.move_collection(conn, args.path, args.new_parent))
        else:
            gone = catalog.delete_collection(conn, args.path, args.with_clips)
            print(f"deleted {args.path} ({gone} clips)")
    return 0


def run_clip(args: argparse.Namespace) -> int:
    # numpy, and the loader's snippet cutting (90 ms): not for `modb --help`
    from modb.clips import ClipNotFound, resolve_clip
    from modb.editing import catalog

    with connect(args) as conn, conn.transaction():
        try:
            clip_id = resolve_clip(conn, args.clip)
        except ClipNotFound as e:
            print(f"modb clip: {e}", file=sys.stderr)
            return 2
        if args.action == "restore":
            r = catalog.restore_version(conn, clip_id, args.version)
            print(
                f"clip {clip_id}: version {args.version} is current again as version "
                f"{r.version} ({r.snippets} snippets)"
            )
        elif args.version is not None:
            r = catalog.delete_version(conn, clip_id, args.version)
            print(
                f"clip {clip_id}: deleted version {args.version}; version {r.version} is "
                f"current ({r.snippets} snippets)"
            )
        else:
            print(f"deleted clip {clip_id} ({catalog.delete_clip(conn, clip_id)} versions)")
    return 0
