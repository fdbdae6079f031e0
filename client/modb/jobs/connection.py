"""How job workers connect: as the loader role (set at connection; the login role must be a member
of it), so that what they write is the loader's to write, never a superuser's."""

from __future__ import annotations

from psycopg.conninfo import conninfo_to_dict, make_conninfo

LOADER_ROLE = "modb_loader"


def as_loader(conninfo: str) -> str:
    """The connection string with the loader role set at connection."""
    options = conninfo_to_dict(conninfo).get("options") or ""
    return make_conninfo(conninfo, options=f"{options} -c role={LOADER_ROLE}".strip())
