"""MoDB for PostgreSQL: the Python client.

    modb.motion      the motion data model (Skeleton, Motion) every part shares
    modb.clips       clips read back from the database; modb.bvh_export and modb.gltf_export
                     write them as BVH and glTF
    modb.output      where every file modb writes goes (open_output)
    modb.validation  numbers checked against their range (options, settings)
    modb.loader      BVH and ASF/AMC files read and stored
    modb.database    the embedded cluster, connections, which database a command uses
    modb.synthesis   the Avatar, strips synthesized toward goals, their quality, transition graphs
    modb.cli         the `modb` command, one module per subcommand, and what it prints
    modb.bench       the benchmarks of `modb bench`, one module each
    modb.demo        the real capture `modb demo` loads
    modb.web         `modb serve`

`modb.connect`, `modb.Avatar` and `modb.Settings` are the entry points of the Python API (imported
on first use, so `import modb` stays light).
"""

from importlib import import_module

from .version import __version__

_API = {
    "connect": "modb.database.connection",
    "Avatar": "modb.synthesis.avatar",
    "Settings": "modb.synthesis.chain",
}

__all__ = ["Avatar", "Settings", "__version__", "connect"]


def __getattr__(name: str):
    if name in _API:
        return getattr(import_module(_API[name]), name)
    raise AttributeError(f"module 'modb' has no attribute {name!r}")
