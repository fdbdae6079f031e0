#!/usr/bin/env python3
"""Assemble modb--<version>.sql and the upgrade scripts from sql/*.sql.

The kernel package (plpython/modb_kernel/, shared with the client) is not in the scripts: it is
installed beside modb.so once per version as the package modb_kernel_<version> (extension/Makefile),
and a line '#@modb_kernel MODULE...' in a PL/Python body becomes a prelude that imports that
package, found without SPI from where PostgreSQL's $libdir is (SPI would make the functions unusable
in parallel queries), and the modules named; the body reads it as `kernel`. So the server runs the
code of the installed extension version, never files from the repository or a virtualenv, and two
databases of one server at two versions each run their own. Each script starts by importing the
whole package (a DO block), so CREATE EXTENSION and ALTER EXTENSION UPDATE fail at once, saying what
to install, on a server that lacks it. {{STANDARD_JOINTS}} and {{FEATURES}} become SQL arrays of
the kernel's constants, and --c-header writes the C code's count of standard joints
(src/standard_joints.h) from the same list.

sql/*.sql holds one fragment per subject (header, roles, errors in words, validation, tables, clip
rules, collections, catalogue edits, kinematics, generations, snippets, snippet blocks, standard
joints, quaternion angles, match profiles, shipped profiles, annotations and segments, match plan,
continuity ratio, match box, objective, graphs, graph cost-to-go, motion primitives, selection,
synthesis, privileges, checks of model documents, access and audit, the check of graphs of models,
motion models, what model listings read, graphs of models, retargeting, edit scripts, checks of
stored documents), each object defined in one only, built in file-name order: an object
after what it names when it is created (CREATE EXTENSION does not check function bodies, but a
type, a constraint, a trigger, an operator or a SQL-standard body, BEGIN ATOMIC or RETURN, does),
and 90_privileges.sql's grants on all tables and sequences reach those made before it only
(access_tokens and audit_log, after it, must stay closed to modb_reader).

Upgrade scripts come from sql/upgrades/OLD--NEW.sql: hand-written steps whose '--@include FILE'
lines pull in fragments of sql/, and every other PL/Python function re-created (with its COMMENT)
with NEW's prelude: at a '--@functions' line, so that the steps after it run NEW's code (a data
migration), else at the end. A fragment is included whole: one whose objects are all new in NEW, or
one that can run again over the old version, made only of CREATE OR REPLACE, COMMENT, GRANT and
upserts: 77_match_profiles_shipped.sql, 79_match_plan.sql, 80_match_continuity_ratio.sql,
85_graph_cost_to_go.sql, 86_selection.sql, 89_synthesis.sql, 90_privileges.sql,
94_model_graph_problem.sql. A changed function of another fragment is re-created by a hand-written
step.

Releasing a version freezes its scripts: modb--NEW.sql and modb--OLD--NEW.sql, as built, go into
sql/released/ under a first line saying they are generated and frozen and the command that made
them, and sql/upgrades/OLD--NEW.sql is deleted, so later edits of sql/ cannot change a released
script (the Makefile refuses an upgrade source whose script is released). A released script is what
installs; sql/*.sql is the working copy of the next version. The release then deletes
modb--OLD.sql (never modb--0.1.0.sql) once `compare_chain.py --versions OLD` shows that the chain
installs the same catalogue: PostgreSQL installs `CREATE EXTENSION modb VERSION 'OLD'` as 0.1.0 and
the upgrades, so sql/released/ holds the first install script, every upgrade script and the newest
install script.

Releasing a version also freezes its kernel: plpython/modb_kernel/ is copied to
plpython/released/VERSION/, which the Makefile installs from then on (every released version's
kernel stays installed: old versions are created by the upgrade tests, and one server may hold
databases at several versions). Until 0.23.0 the kernel was pasted into every PL/Python function;
those frozen scripts still carry it.
"""

import functools
import pathlib
import re
import sys

HERE = pathlib.Path(__file__).resolve().parent
KERNEL = HERE / "plpython" / "modb_kernel"

# The Python put before a PL/Python function's body (see the docstring): the version's installed
# package, found without SPI from where PostgreSQL's own $libdir is (beside the postgres binary's
# folder, as PostgreSQL computes it), then the modules the body names. {package} and {version} are
# filled in; the body reads the package as `kernel`.
PRELUDE = """\
import sys
kernel = sys.modules.get({package!r})
if kernel is None:
    import importlib.util, os
    folder = os.path.join(os.path.dirname(os.path.dirname(os.path.realpath("/proc/self/exe"))),
                          "lib", {package!r})
    if not os.path.isfile(os.path.join(folder, "__init__.py")):
        plpy.error("modb {version}'s kernel is not installed on this server: no " + folder,
                   hint="Install the extension's files as modb.so was installed (make -C extension "
                        "install): the package {package} goes into the folder of modb.so.")
    spec = importlib.util.spec_from_file_location({package!r}, os.path.join(folder, "__init__.py"),
                                                  submodule_search_locations=[folder])
    kernel = importlib.util.module_from_spec(spec)
    sys.modules[{package!r}] = kernel
    try:
        spec.loader.exec_module(kernel)
    except BaseException:
        del sys.modules[{package!r}]
        raise"""

# At the top of the install script and of each upgrade script: the whole package imported, so that
# CREATE EXTENSION or ALTER EXTENSION UPDATE fails at once, saying what to install, where the kernel
# is missing or incomplete.
KERNEL_CHECK = """\
-- modb {version} runs the kernel installed beside modb.so ({package}): fail now if it is not there.
DO LANGUAGE plpython3u $py$
{prelude}
import importlib, pkgutil
for module in pkgutil.walk_packages(kernel.__path__, {package!r} + "."):
    importlib.import_module(module.name)
$py$;
"""

# A PL/Python function's definition and the COMMENT right after it (an upgrade re-creates both).
PLPYTHON_FUNCTION = re.compile(
    r"^CREATE OR REPLACE FUNCTION .*?^\$py\$;\n(?:COMMENT ON FUNCTION .*?';\n)?", re.S | re.M
)


@functools.cache
def kernel_constants() -> dict:
    """The names joints.py defines (plain constants, no imports)."""
    namespace: dict = {}
    exec((KERNEL / "joints.py").read_text(), namespace)
    return namespace


def _sql_array(names) -> str:
    return "ARRAY[" + ", ".join(f"'{n}'" for n in names) + "]"


def _constants() -> dict:
    joints = kernel_constants()
    return {
        "{{STANDARD_JOINTS}}": _sql_array(joints["STANDARD_JOINTS"]),
        "{{FEATURES}}": _sql_array(joints["FEATURES"]),
    }


def feature_range(name: str) -> tuple[float, float]:
    """Where a feature's values lie (metres, m/s, rotation-matrix entries): the block directory's
    fixed 8-bit scale (src/block_directory.c), physical so that it does not drift as data arrives.
    Values beyond it still count, at the end codes."""
    quantity = name.split(".")[1]
    if quantity.startswith("R"):
        return (-1.0, 1.0)
    if quantity.startswith("v"):
        return (-8.0, 8.0)
    if name == "pelvis.y":
        return (0.0, 2.5)
    return (-2.5, 2.5)


def c_header() -> str:
    """src/standard_joints.h: the standard joints and features for C, from the kernel's lists."""
    joints = kernel_constants()["STANDARD_JOINTS"]
    names = ", ".join(f'"{name}"' for name in joints)
    features = kernel_constants()["FEATURES"]
    ranges = ", ".join("{%g, %g}" % feature_range(name) for name in features)
    return (
        "/* Generated by extension/build_sql.py --c-header from plpython/modb_kernel/joints.py;"
        " do not edit. */\n"
        f"#define N_JOINTS {len(joints)}\t/* len(STANDARD_JOINTS) */\n"
        f"#define N_FEATURES {len(features)}\t/* len(FEATURES) */\n"
        f"#define STANDARD_JOINT_NAMES {{{names}}}\n"
        f"#define FEATURE_RANGES {{{ranges}}}\n"
    )


def package(version: str) -> str:
    """The kernel's package name in the server: one per version, so versions never mix."""
    return "modb_kernel_" + version.replace(".", "_")


KERNEL_LINE = re.compile(r"^#@modb_kernel(.*)$", re.M)


def _kernel_imports(match: re.Match, version: str) -> str:
    modules = match.group(1).split()
    if not modules:
        sys.exit("build_sql.py: '#@modb_kernel' names no module: list the modules the body uses")
    missing = [m for m in modules if not (KERNEL / f"{m.replace('.', '/')}.py").exists()]
    if missing:
        sys.exit(f"build_sql.py: '#@modb_kernel' names modules the kernel lacks: {missing}")
    lines = [PRELUDE.format(package=package(version), version=version)]
    lines += [f"import {package(version)}.{m}" for m in modules]
    return "\n".join(lines)


LIBRARY_CHECK = """-- modb {version} runs the modb.so built with it: fail now on an older one.
DO $$
BEGIN
    IF string_to_array(modb.library_version(), '.')::int[] < '{{{parts}}}'::int[] THEN
        RAISE EXCEPTION 'modb {version} needs the modb.so installed with it; this session runs %',
                        modb.library_version()
            USING ERRCODE = 'object_not_in_prerequisite_state',
                  HINT = 'Restart the server (the embedded one: modb db stop, then modb db start; '
                         'your own: pg_ctl restart or systemctl restart postgresql@15-main), '
                         'then run this again in a new session.';
    END IF;
END
$$;"""


def library_check(version: str) -> str:
    return LIBRARY_CHECK.format(version=version, parts=version.replace(".", ","))


def _expand(text: str, version: str) -> str:
    text = KERNEL_LINE.sub(lambda m: _kernel_imports(m, version), text)
    text = text.replace("{{VERSION}}", version).replace("{{LIBRARY_CHECK}}", library_check(version))
    for placeholder, value in _constants().items():
        text = text.replace(placeholder, value)
    return text


def kernel_check(version: str) -> str:
    prelude = PRELUDE.format(package=package(version), version=version)
    return KERNEL_CHECK.format(version=version, package=package(version), prelude=prelude)


def build(version: str) -> str:
    files = sorted((HERE / "sql").glob("*.sql"))
    parts = [f"-- {path.name}\n{_expand(path.read_text(), version)}" for path in files]
    parts.insert(1, kernel_check(version))  # after 00_header.sql's guard
    return "\n".join(parts)


def build_upgrade(source: pathlib.Path) -> str:
    version = source.stem.split("--")[1]
    parts = [
        f"\\echo Use \"ALTER EXTENSION modb UPDATE TO '{version}'\" to load this file. \\quit\n",
        kernel_check(version),
    ]
    if "--@include 01_library.sql" not in source.read_text().splitlines():
        parts.append(library_check(version))  # modb.library_version exists from 0.29.0
    included = set()
    steps = source.read_text().splitlines()
    if "--@functions" not in steps:
        steps.append("--@functions")
    for line in steps:
        if line.startswith("--@include "):
            name = line.split(maxsplit=1)[1]
            included.add(name)
            parts.append(f"-- {name}\n" + _expand((HERE / "sql" / name).read_text(), version))
        elif line == "--@functions":
            parts.append(f"-- PL/Python functions re-created with the {version} kernel")
            for path in sorted((HERE / "sql").glob("*.sql")):
                if path.name not in included:
                    parts.extend(
                        _expand(m.group(0), version)
                        for m in PLPYTHON_FUNCTION.finditer(path.read_text())
                    )
        else:
            parts.append(_expand(line, version))
    return "\n".join(parts)


if __name__ == "__main__":
    if sys.argv[1:] == ["--c-header"]:
        sys.stdout.write(c_header())
    elif len(sys.argv) == 2:
        sys.stdout.write(build(sys.argv[1]))
    elif len(sys.argv) == 3 and sys.argv[1] == "--upgrade":
        sys.stdout.write(build_upgrade(pathlib.Path(sys.argv[2])))
    else:
        sys.exit(
            "usage: build_sql.py VERSION > modb--VERSION.sql\n"
            "       build_sql.py --upgrade sql/upgrades/OLD--NEW.sql > modb--OLD--NEW.sql\n"
            "       build_sql.py --c-header > src/standard_joints.h"
        )
