#!/usr/bin/env python3
"""Assemble the install script modb--<version>.sql from sql/*.sql and the PL/Python kernel.

The kernel package (plpython/modb_kernel/*.py) is embedded in the script as the
body of modb._kernel_load(), so the server runs exactly the code of the installed
extension version, never files from the repository or a virtualenv. A line
'#@modb_kernel' in a PL/Python body becomes a prelude binding `kernel` to it.
"""
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent

PRELUDE = """kernel = GD.get({key!r})
if kernel is None:
    plpy.execute("SELECT modb._kernel_load()")
    kernel = GD[{key!r}]"""

LOADER = '''
CREATE FUNCTION modb._kernel_load()
RETURNS void
LANGUAGE plpython3u VOLATILE STRICT PARALLEL SAFE
AS $py$
# Registers the embedded kernel as package {package} (named by version, so an ALTER
# EXTENSION UPDATE in a live session never mixes the modules of two versions) and
# caches it in GD, where every PL/Python function of the extension finds it.
import importlib, importlib.abc, importlib.util, sys
SOURCES = {sources}
PACKAGE = {package!r}

class EmbeddedKernel(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, name, path=None, target=None):
        key = "modb_kernel" + name[len(PACKAGE):] if name.split(".")[0] == PACKAGE else None
        if key not in SOURCES:
            return None
        return importlib.util.spec_from_loader(name, self, is_package=(key == "modb_kernel"))

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        key = "modb_kernel" + module.__name__[len(PACKAGE):]
        filename = "<modb {version}>/" + key.replace(".", "/") + ".py"
        exec(compile(SOURCES[key], filename, "exec"), module.__dict__)

if not any(getattr(f, "modb_package", None) == PACKAGE for f in sys.meta_path):
    finder = EmbeddedKernel()
    finder.modb_package = PACKAGE
    sys.meta_path.insert(0, finder)
package = importlib.import_module(PACKAGE)
for key in SOURCES:
    if key != "modb_kernel":
        importlib.import_module(PACKAGE + key[len("modb_kernel"):])
GD[{key!r}] = package
$py$;
COMMENT ON FUNCTION modb._kernel_load() IS 'Internal: loads the PL/Python kernel embedded in this extension version into the session';
'''


def kernel_sources() -> dict:
    sources = {}
    for path in sorted((HERE / "plpython" / "modb_kernel").glob("*.py")):
        name = "modb_kernel" if path.stem == "__init__" else "modb_kernel." + path.stem
        sources[name] = path.read_text()
    return sources


def build(version: str) -> str:
    key = "modb_kernel"  # the installed version's kernel; an upgrade script ends by reloading it
    package = "modb_kernel_" + version.replace(".", "_")
    sources = kernel_sources()
    body = "{\n" + "".join(f"    {k!r}: {v!r},\n" for k, v in sources.items()) + "}"
    parts = []
    for i, path in enumerate(sorted((HERE / "sql").glob("*.sql"))):
        text = path.read_text().replace("#@modb_kernel", PRELUDE.format(key=key))
        parts.append(f"-- {path.name}\n{text}")
        if i == 0:  # after the header: the kernel loader, which later files' functions call
            parts.append(LOADER.format(sources=body, package=package, version=version, key=key))
    script = "\n".join(parts)
    if "$py$" in "".join(sources.values()):
        sys.exit("build_sql.py: a kernel source contains '$py$', which would end the function body")
    return script


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: build_sql.py VERSION > modb--VERSION.sql")
    sys.stdout.write(build(sys.argv[1]))
