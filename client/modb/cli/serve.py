"""`modb serve`: the web view (three.js) and its JSON endpoints."""

from __future__ import annotations

import argparse
import sys

from modb.database.dsn import resolve
from modb.web.guard import WILDCARD_ADDRESSES, is_loopback

from .common import PORT, whole

UPLOAD_MB = whole(1, 4096)
AVATARS = whole(1, 10000)

PLAY_SWITCH_INTERVAL_SECONDS = 0.001


def add_parser(sub: argparse._SubParsersAction) -> None:
    serve = sub.add_parser(
        "serve", help="browse the database in the web browser (three.js) and JSON endpoints"
    )
    serve.add_argument("--port", type=PORT, default=8765, help=f"port, {PORT.span} (default 8765)")
    serve.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only)",
    )
    serve.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="also answer requests that name this server NAME (e.g. the machine's DNS name when "
        "--host 0.0.0.0); repeatable",
    )
    serve.add_argument(
        "--require-token",
        action="store_true",
        help="reads need a token too (writes always do: `modb token create NAME --role loader`)",
    )
    serve.add_argument(
        "--max-upload-mb",
        type=UPLOAD_MB,
        default=100,
        metavar="MB",
        help=f"the largest upload accepted ({UPLOAD_MB.span}; default 100)",
    )
    serve.add_argument(
        "--write-user",
        default="modb_web",
        metavar="ROLE",
        help="the login role writes run as: a member of modb_loader, not a superuser (default "
        "modb_web, which the embedded database has)",
    )
    serve.add_argument(
        "--standby",
        action="append",
        default=[],
        metavar="CONNINFO",
        help="a hot standby of the database to run avatar sessions on (spread by their number; "
        "the primary when none has replayed what the session needs); repeatable. Default: the "
        "embedded database's standbys (`modb db replica add`)",
    )
    serve.add_argument(
        "--max-avatars",
        type=AVATARS,
        metavar="N",
        help=f"avatar pages open at once ({AVATARS.span}); default 8 for each database node (the "
        "primary and every standby). Each walking avatar takes a connection on its node and about "
        "1.5%% of a core here",
    )
    serve.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # the web server stack (uvicorn, Starlette) and numpy (about 400 ms): not for `modb --help`
    import uvicorn

    # Avatars' play threads wait on threads that synthesize (models) or place (snippets): on a busy
    # machine the default 5 ms turns of the interpreter lock make a frame late; 1 ms ones do not.
    sys.setswitchinterval(PLAY_SWITCH_INTERVAL_SECONDS)

    from modb.database.read_nodes import ReadNodes
    from modb.web.app import ThreeMissing, create_app
    from modb.web.avatar_socket import MAX_MESSAGE_BYTES, default_max_avatars

    conninfo, origin = resolve(args.dsn)
    if args.standby:
        nodes = ReadNodes(conninfo, [(f"standby{i + 1}", d) for i, d in enumerate(args.standby)])
    elif origin.startswith("embedded"):
        nodes = ReadNodes.embedded(conninfo)
    else:
        nodes = ReadNodes(conninfo)
    max_avatars = args.max_avatars or default_max_avatars(nodes)
    try:
        app = create_app(
            conninfo,
            args.host,
            args.port,
            tuple(args.allow_host),
            require_token=args.require_token,
            max_upload_mb=args.max_upload_mb,
            writer_role=args.write_user,
            nodes=nodes,
            max_avatars=max_avatars,
            warn=lambda message: print(f"modb serve: warning: {message}", file=sys.stderr),
        )
    except ThreeMissing as e:
        print(f"modb serve: {e}", file=sys.stderr)
        return 2
    if not is_loopback(args.host):
        print(
            f"modb serve: listening on {args.host}, beyond this machine: anyone who can reach it "
            f"can read the "
            f"database. It answers requests that name it as 127.0.0.1, localhost"
            + (f", {args.host}" if args.host not in WILDCARD_ADDRESSES else "")
            + "".join(f", {h}" for h in args.allow_host)
            + " (more with --allow-host NAME)",
            file=sys.stderr,
        )
    shown = f"[{args.host}]" if ":" in args.host else args.host
    print(
        f"modb serve: http://{shown}:{args.port}/  (database: {origin}; {nodes.describe()}, "
        f"at most {max_avatars} at once; Ctrl-C stops)",
        file=sys.stderr,
    )
    # A WebSocket message past 16 times the socket's own limit is not even buffered (uvicorn's
    # default is 16 MiB); one between the two is answered `refused`.
    uvicorn.run(
        app,
        host=args.host,
        port=args.port,
        log_level="warning",
        ws_max_size=16 * MAX_MESSAGE_BYTES,
    )
    return 0
