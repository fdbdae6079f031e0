"""`modb model`: statistical motion models of a primitive (functional PCA and a Gaussian mixture of
its aligned examples), kept in versions in modb.models: build, list, show, delete, export, import,
sample, tree."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import psycopg

from . import as_job
from .common import Number, connect, writable

SEED = Number(0, 2**31 - 1, whole=True)
VERSION = Number(1, 2**31 - 1, whole=True)
SAMPLES = Number(1, 1000, whole=True)
VARIANCE = Number(0.5, 0.999, unit="share of the variance")


def add_parser(sub: argparse._SubParsersAction) -> None:
    model = sub.add_parser(
        "model", help="statistical motion models of a primitive: build, list, show, sample, ..."
    )
    actions = model.add_subparsers(dest="action", required=True, metavar="ACTION")
    build = actions.add_parser(
        "build", help="build a model of a primitive's aligned examples (a new version)"
    )
    build.add_argument("name", metavar="NAME")
    build.add_argument(
        "--collection", required=True, help="the collection whose examples it learns"
    )
    build.add_argument("--primitive", required=True, help="a segment name, e.g. left_step")
    build.add_argument("--seed", type=SEED, default=0, help="the mixture's and tree's seed (0)")
    build.add_argument("--variance", type=VARIANCE, default=0.95,
                       help="the share of the variance the PCAs keep (0.95)")  # fmt: skip
    build.add_argument("--report-json", metavar="FILE",
                       help="measure the model's quality and write the report here (the "
                       "measuring takes about twice as long as the build itself)")  # fmt: skip
    build.add_argument("-q", "--quiet", action="store_true", help="no progress")
    as_job.add_options(build, "build")
    listing = actions.add_parser("list", help="the models, each version, and whether it is stale")
    listing.add_argument("--collection", help="only those built from this collection")
    show = actions.add_parser("show", help="one model's version: what it holds, how it was built")
    show.add_argument("name", metavar="NAME")
    show.add_argument("--version", type=VERSION, help="the version (default: the latest)")
    delete = actions.add_parser("delete", help="delete a model's version, or every version")
    delete.add_argument("name", metavar="NAME")
    delete.add_argument("--version", type=VERSION, help="only this version")
    export = actions.add_parser("export", help="write a model's version as a JSON file")
    export.add_argument("name", metavar="NAME")
    export.add_argument("--version", type=VERSION, help="the version (default: the latest)")
    export.add_argument("--out", required=True, metavar="FILE", help="the JSON file ('-': stdout)")
    imported = actions.add_parser("import", help="store an exported model as a new version")
    imported.add_argument("file", metavar="FILE")
    imported.add_argument("--name", help="store it under this name (default: its own)")
    sample = actions.add_parser("sample", help="draw motions from a model, as BVH or glb")
    sample.add_argument("name", metavar="NAME")
    sample.add_argument("-n", type=SAMPLES, default=10, help="how many (1-1000; 10)")
    sample.add_argument("--seed", type=SEED, default=0, help="the same seed, the same motions (0)")
    sample.add_argument("--version", type=VERSION, help="the version (default: the latest)")
    sample.add_argument("--out", required=True, metavar="FILE",
                        help="FILE.bvh: one file per sample, FILE_01.bvh ...; FILE.glb or "
                        ".gltf: one animation per sample")  # fmt: skip
    tree = actions.add_parser("tree", help="rebuild a model's acceleration tree (in its meta)")
    tree.add_argument("name", metavar="NAME")
    tree.add_argument("--version", type=VERSION, help="the version (default: the latest)")
    tree.add_argument("--seed", type=SEED, default=0, help="the samples' seed (0)")
    graph = actions.add_parser(
        "graph",
        help="graphs of models: NAME --collection C builds the models of the character's "
        "primitives the collection lacks and the graph of them; list, show NAME, export NAME "
        "--out FILE, import FILE, delete NAME",
    )
    graph.add_argument("target", metavar="NAME|list|show|export|import|delete")
    graph.add_argument("argument", nargs="?", metavar="NAME|FILE")
    graph.add_argument("--collection",
                       help="NAME: the collection whose primitives (modb annotate --steps) it "
                       "models and joins")  # fmt: skip
    graph.add_argument("--out", metavar="FILE", help="export: the JSON file ('-': stdout)")
    graph.add_argument("--name", help="import: store it under this name (default: its own)")
    graph.add_argument("--model", action="append", metavar="MODEL",
                       help="NAME: use this model for its primitive where the collection has "
                       "several (repeatable)")  # fmt: skip
    graph.add_argument("--seed", type=SEED, default=0,
                       help="NAME: the seed of the models it builds (0)")  # fmt: skip
    graph.add_argument("-q", "--quiet", action="store_true", help="NAME: no progress")
    as_job.add_options(graph, "NAME --collection C")
    model.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.models.graphs import GraphError
    from modb.models.store import BadModelFile, ModelNotFound

    with connect(args) as conn:
        if args.action != "list" and not _has_models(conn):
            return 2
        try:
            return ACTIONS[args.action](conn, args)
        except (ModelNotFound, BadModelFile, GraphError) as e:
            print(f"modb model {args.action}: {e}", file=sys.stderr)
            return 2


def _has_models(conn: psycopg.Connection) -> bool:
    if conn.execute("SELECT to_regproc('modb.sample_motion') IS NOT NULL").fetchone()[0]:
        return True
    print("modb model: the database's modb extension is older than 0.22.0: ALTER EXTENSION modb "
          "UPDATE", file=sys.stderr)  # fmt: skip
    return False


def _build(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from modb.models.examples import NoExamples
    from modb.models.pipeline import STAGES, build_model

    if not writable("model build", args.report_json):  # before a version is stored
        return 2
    as_a_job = as_job.usable(conn, args, "model build", "0.22.0")
    if as_a_job is None:
        return 2
    report = args.report_json is not None
    if as_a_job:
        arguments = {"name": args.name, "collection": args.collection, "primitive": args.primitive,
                     "seed": args.seed, "variance": args.variance, "report": report}  # fmt: skip
        done = as_job.run(conn, args, "model build", "build_model", arguments)
        if done is None or isinstance(done, int):
            return done or 0
        made = done.result
    else:
        bar = None if args.quiet else tqdm(total=len(STAGES) - (not report), unit=" stages",
                                           file=sys.stderr, leave=False)  # fmt: skip

        def say(line: str) -> None:
            if bar is not None:
                bar.write(line, file=sys.stderr)

        try:
            made = build_model(conn, args.name, args.collection, args.primitive, args.seed,
                               args.variance, report, say,
                               lambda done, total: bar and bar.update(done - bar.n))  # fmt: skip
        except NoExamples as e:
            print(f"modb model build: {e}", file=sys.stderr)
            return 2
        except psycopg.Error as e:
            hint = e.diag.message_hint
            print(f"modb model build: {e.diag.message_primary}" + (f" ({hint})" if hint else ""),
                  file=sys.stderr)  # fmt: skip
            return 2
        finally:
            if bar is not None:
                bar.close()
    print(
        f"model {made['name']} version {made['version']} (id {made['id']}): {made['primitive']} "
        f"of {made['collection']}, {made['examples']} examples, {made['spatial_components']} "
        f"spatial + {made['temporal_components']} temporal components, "
        f"{made['mixture_components']} {made['covariance']} Gaussians"
    )
    if report:
        Path(args.report_json).write_text(json.dumps(made["report"], indent=2) + "\n")
        verdict = "meets" if made["report"]["pass"] else "misses"
        print(f"report: {args.report_json} ({verdict} the quality targets)")
    return 0


def _list(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import listing

    if not conn.execute("SELECT to_regclass('modb.model_status') IS NOT NULL").fetchone()[0]:
        return 0 if _has_models(conn) else 2
    for m in listing(conn, args.collection):
        print(
            f"{m['name']} v{m['version']}{' (latest)' if m['latest'] else ''}: {m['primitive']} "
            f"of {m['collection'] or '(collection deleted)'}, {m['examples']} examples, "
            f"{m['components']} Gaussians, {'tree' if m['has_tree'] else 'no tree'}, "
            f"{m['created_at']}" + (f"; stale: {m['stale']}" if m["stale"] else "")
        )
    return 0


def _show(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import brief

    print(json.dumps(brief(conn, args.name, args.version), indent=2))
    return 0


def _delete(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import ModelNotFound, delete

    with conn.transaction():
        n = delete(conn, args.name, args.version)
    if n == 0:
        raise ModelNotFound(f'no motion model "{args.name}"'
                            + (f" version {args.version}" if args.version else ""))  # fmt: skip
    print(f"deleted {n} version{'s' if n != 1 else ''} of model {args.name}")
    return 0


def _export(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import dumps, export_document
    from modb.output import open_output

    document = export_document(conn, args.name, args.version)
    with open_output(args.out, "w", allow_stdout=True) as f:
        f.write(dumps(document) + "\n")
    if args.out != "-":
        print(f"model {document['name']} version {document['version']}: {args.out}")
    return 0


def _import(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import BadModelFile, import_document

    try:
        document = json.loads(Path(args.file).read_text())
    except (OSError, UnicodeDecodeError) as e:
        raise BadModelFile(f"{args.file}: {e}") from None
    except json.JSONDecodeError as e:
        raise BadModelFile(f"{args.file}: line {e.lineno}: not JSON ({e.msg})") from None
    try:
        with conn.transaction():
            ident, version, name, tree_kept = import_document(conn, document, args.name)
    except BadModelFile as e:
        raise BadModelFile(f"{args.file}: {e}") from None
    tree = "its acceleration tree" if tree_kept else f"no tree (`modb model tree {name}` draws one)"
    print(f"model {name} version {version} (id {ident}) from {args.file}, with {tree}")
    return 0


def _sample(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.samples import numbered, write_samples

    first = numbered(args.out, 1, args.n) if args.out.lower().endswith(".bvh") else args.out
    if not writable("model sample", first):  # before any sampling
        return 2
    try:
        written = write_samples(conn, args.name, args.n, args.seed, args.version, args.out)
    except ValueError as e:
        print(f"modb model sample: {e}", file=sys.stderr)
        return 2
    except psycopg.Error as e:
        print(f"modb model sample: {e.diag.message_primary}", file=sys.stderr)
        return 2
    print(f"{args.n} samples of model {args.name} (seed {args.seed}): " + ", ".join(written))
    return 0


def _tree(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models.store import rebuild_tree
    from modb.models.tree import shape

    with conn.transaction():
        tree = rebuild_tree(conn, args.name, args.version, args.seed)
    s = shape(tree)
    print(f"model {args.name}: tree of {s['samples']} samples, {s['nodes']} nodes, "
          f"{s['leaves']} leaves, depth {s['depth']}")  # fmt: skip
    return 0


def _graph(conn: psycopg.Connection, args: argparse.Namespace) -> int:
    from modb.models import graphs as G
    from modb.output import open_output

    action, argument = args.target, args.argument
    if action == "list":
        for g in G.listing(conn):
            print(g.describe())
        return 0
    if action in ("show", "export", "import", "delete") and argument is None:
        what = "FILE" if action == "import" else "NAME"
        raise G.GraphError(f"say which: modb model graph {action} {what}")
    if action == "show":
        g = G.load(conn, argument)
        print(g.describe())
        print(json.dumps(g.data, indent=2))
    elif action == "export":
        if not args.out:
            raise G.GraphError("export: say where with --out FILE ('-': standard output)")
        document = G.export_document(conn, argument)
        with open_output(args.out, "w", allow_stdout=True) as f:
            f.write(json.dumps(document, indent=2) + "\n")
        if args.out != "-":
            print(f"graph of models {argument}: {args.out}")
    elif action == "import":
        try:
            document = json.loads(Path(argument).read_text())
        except (OSError, UnicodeDecodeError) as e:
            raise G.GraphError(f"{argument}: {e}") from None
        except json.JSONDecodeError as e:
            raise G.GraphError(f"{argument}: line {e.lineno}: not JSON ({e.msg})") from None
        print(G.import_document(conn, document, args.name).describe())
    elif action == "delete":
        G.delete(conn, argument)
        print(f"deleted graph of models {argument}")
    else:
        if argument is not None or not args.collection:
            raise G.GraphError("build a graph with: modb model graph NAME --collection C")
        return _family(conn, args, action)
    return 0


def family_graph(conn: psycopg.Connection, args: argparse.Namespace, name: str
                 ) -> dict[str, Any] | int:  # fmt: skip
    """The family graph NAME of args.collection: the models it lacks, then the graph, as a job where
    the database runs them (args: --model, --seed, -q, --background, --after), else here. What
    modb.models.family.build_family returns, or an exit status (queued, or failed: said why)."""
    from modb.models.family import build_family

    as_a_job = as_job.usable(conn, args, "model graph", "0.22.0")
    if as_a_job is None:
        return 2
    arguments = {"name": name, "collection": args.collection, "chosen": args.model or [],
                 "seed": args.seed}  # fmt: skip
    if as_a_job:
        done = as_job.run(conn, args, "model graph", "build_family", arguments)
        return done.result if done is not None and not isinstance(done, int) else done or 0
    return build_family(conn, **arguments, say=lambda line: None if args.quiet else print(
        line, file=sys.stderr))  # fmt: skip


def _family(conn: psycopg.Connection, args: argparse.Namespace, name: str) -> int:
    from modb.models.family import summary

    made = family_graph(conn, args, name)
    if isinstance(made, int):
        return made
    for line in summary(made):
        print(line)
    return 0


def _graph_refused(run_graph):
    """The database's refusal of a broken graph, in its words."""

    def wrapped(conn: psycopg.Connection, args: argparse.Namespace) -> int:
        try:
            return run_graph(conn, args)
        except psycopg.Error as e:
            hint = e.diag.message_hint
            print(f"modb model graph: {e.diag.message_primary}" + (f" ({hint})" if hint else ""),
                  file=sys.stderr)  # fmt: skip
            return 2

    return wrapped


ACTIONS = {"build": _build, "list": _list, "show": _show, "delete": _delete, "export": _export,
           "import": _import, "sample": _sample, "tree": _tree,
           "graph": _graph_refused(_graph)}  # fmt: skip
