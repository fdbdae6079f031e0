"""The loader is the bottom layer of the client: it reads files into the shared motion model and
stores them, and imports (directly or through what it imports) nothing of the client above it, so
no import cycle runs between the two (one did: modb.loader.sidecars -> modb.editing -> modb.loader).
Read from the source with ast, imports inside functions included.

Nor does any import cycle run within the three packages (client, loader, kernel): a module in one
cannot be imported first without the other half-made (cli.main <-> cli.bench was one)."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

# What the loader may reach: the package's light __init__ and its version, the motion model, the
# numeric kernel.
ALLOWED = {"modb", "modb.version", "modb.motion"}


def _imports(module: str) -> set[str]:
    """The modules of modb and modb_kernel that `module`'s source imports anywhere in it."""
    spec = importlib.util.find_spec(module)
    tree = ast.parse(open(spec.origin).read())
    package = module if spec.submodule_search_locations else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        found |= {n for n in names if n.split(".")[0] in ("modb", "modb_kernel") and _is_module(n)}
    return found


def _is_module(name: str) -> bool:
    """A module, not a name defined in one (`from modb.motion import Motion`)."""
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def reachable(start: str) -> set[str]:
    """Every module of ours that importing `start` can bring in."""
    seen, todo = set(), [start]
    while todo:
        module = todo.pop()
        if module not in seen:
            seen.add(module)
            todo += _imports(module)
    return seen


def _loader_modules() -> list[str]:
    folder = importlib.util.find_spec("modb.loader").submodule_search_locations[0]
    return [f"modb.loader.{p.stem}" for p in Path(folder).glob("[!_]*.py")]


def test_the_loader_reaches_only_the_motion_model_and_the_kernel():
    modules = _loader_modules()
    assert "modb.loader.sidecars" in modules and "modb.loader.sources" in modules
    above = {
        (module, m)
        for module in modules
        for m in reachable(module)
        if not (m in ALLOWED or m.startswith(("modb.loader", "modb_kernel")))
    }
    assert not above, f"the loader reaches the client above it: {sorted(above)}"


def test_the_check_sees_an_import_inside_a_function():
    # modb.cli.load imports the loader inside its function: the walk must see that
    assert "modb.loader.ingest" in reachable("modb.cli.load")


# The package each source folder is imported as (setup.py's package_dir).
SOURCES = {
    "modb": "client/modb",
    "modb.loader": "loader",
    "modb_kernel": "extension/plpython/modb_kernel",
}
REPO = Path(__file__).resolve().parents[1]


def _source_modules() -> dict[str, Path]:
    """Every module of the three packages, by dotted name, read from the source tree."""
    modules = {}
    for package, folder in SOURCES.items():
        for path in (REPO / folder).rglob("*.py"):
            parts = path.relative_to(REPO / folder).with_suffix("").parts
            if "node_modules" in parts or (package == "modb" and parts[0] == "loader"):
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join((package, *parts))] = path
    return modules


def _runtime_imports(node: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """The import statements anywhere under `node` (module top, functions, classes) that run:
    those under `if TYPE_CHECKING:` never do."""
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return [node]
    found = []
    for field, value in ast.iter_fields(node):
        skipped = (
            field == "body"
            and isinstance(node, ast.If)
            and "TYPE_CHECKING" in ast.unparse(node.test)
        )
        for child in value if isinstance(value, list) else [value]:
            if isinstance(child, ast.AST) and not skipped:
                found += _runtime_imports(child)
    return found


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of ours that running it imports. Importing a.b.c also runs the
    packages a and a.b, except those the importer is inside (they ran before it)."""
    modules = _source_modules()
    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        outside = {module.rsplit(".", k)[0] for k in range(module.count(".") + 1)}
        targets = set()
        for node in _runtime_imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                named = [a.name for a in node.names]
            else:
                base = importlib.util.resolve_name("." * node.level + (node.module or ""), package)
                named = [base] + [f"{base}.{a.name}" for a in node.names]
            for name in named:
                parts = name.split(".")
                targets |= {".".join(parts[:k]) for k in range(1, len(parts) + 1)}
        graph[module] = {t for t in targets if t in modules and t not in outside}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of `graph` as [a, b, ..., a], or None."""
    state: dict[str, str] = {}  # "open" while on the path, "done" after
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = "open"
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return path[path.index(nxt) :] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = "done"
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_the_import_graph_has_no_cycle():
    graph = import_graph()
    assert {"modb.cli.main", "modb.loader.ingest", "modb_kernel.quaternion"} <= graph.keys()
    assert "modb.loader.ingest" in graph["modb.cli.load"]  # imported inside load_paths
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_check_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None
