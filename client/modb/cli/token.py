"""`modb token`: access tokens for writes (and, with `modb serve --require-token`, reads) through
the REST interface."""

from __future__ import annotations

import argparse
import sys

from modb.access.tokens import TokenError, create, list_tokens, revoke

from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    token = sub.add_parser(
        "token", help="access tokens for the REST interface: create, list, revoke"
    )
    actions = token.add_subparsers(dest="action", required=True)
    create = actions.add_parser("create", help="make a token (shown once: keep it)")
    create.add_argument("name", help="who or what holds it (the audit log names it)")
    create.add_argument(
        "--role",
        choices=["loader", "reader"],
        default="reader",
        help="loader: may upload and edit; reader: may read (default)",
    )
    actions.add_parser("list", help="every token: name, role, made, revoked")
    revoke = actions.add_parser("revoke", help="stop a token working (its name stays, for the log)")
    revoke.add_argument("name")
    token.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        if args.action == "create":
            try:
                token = create(conn, args.name, args.role)
            except TokenError as e:
                print(f"modb token create: {e}", file=sys.stderr)
                return 2
            print(
                f"modb token create: token {args.name!r} ({args.role}); it is shown this once, the "
                f"database keeps only its sha256:",
                file=sys.stderr,
            )
            print(token)
            return 0
        if args.action == "list":
            rows = list_tokens(conn)
            if not rows:
                print("no tokens (`modb token create NAME --role loader|reader` makes one)")
            for t in rows:
                state = f"revoked {t.revoked_at:%Y-%m-%d %H:%M}" if t.revoked_at else "live"
                print(
                    f"{t.name:<24} {t.role:<7} made {t.created_at:%Y-%m-%d %H:%M} by "
                    f"{t.created_by}  {state}"
                )
            return 0
        if not revoke(conn, args.name):
            print(f"modb token revoke: no live token named {args.name!r}", file=sys.stderr)
            return 1
        print(f"modb token revoke: {args.name!r} no longer works", file=sys.stderr)
        return 0
