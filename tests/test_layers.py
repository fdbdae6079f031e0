"""The loader is the bottom layer of the client: it reads files into the shared motion model and
stores them, and imports (directly or through what it imports) nothing of the client above it, so
no import cycle runs between the two (one did: modb.loader.sidecars -> modb.editing -> modb.loader).
Read from the source with ast, imports inside functions included."""

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
    assert "modb.loader.sources" in reachable("modb.cli.load")
