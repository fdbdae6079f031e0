"""numpy arrays <-> PostgreSQL real[] in binary form, without going through Python lists.

Frames are stored as multi-dimensional real[]; these adapters move them as
one buffer each way (PostgreSQL's binary array layout: header, then per element
a 4-byte length and a big-endian float4).
"""

from __future__ import annotations

import struct

import numpy as np
from psycopg import Connection, postgres
from psycopg.adapt import Dumper, Loader
from psycopg.pq import Format

FLOAT4_OID = postgres.types["float4"].oid
FLOAT4_ARRAY_OID = postgres.types["float4"].array_oid
_ELEMENT = np.dtype([("length", ">i4"), ("value", ">f4")])


class Float4ArrayDumper(Dumper):
    """np.ndarray (any shape, at least one element) -> real[] of the same shape."""

    format = Format.BINARY
    oid = FLOAT4_ARRAY_OID

    def dump(self, obj: np.ndarray) -> bytes:
        a = np.asarray(obj, dtype=np.float32)
        if a.size == 0:
            return struct.pack(">iii", 0, 0, FLOAT4_OID)
        header = struct.pack(">iii", a.ndim, 0, FLOAT4_OID) + b"".join(
            struct.pack(">ii", n, 1) for n in a.shape
        )
        body = np.empty(a.size, dtype=_ELEMENT)
        body["length"] = 4
        body["value"] = a.ravel()
        return header + body.tobytes()


class Float4ArrayLoader(Loader):
    """real[] (binary) -> np.ndarray float32 with the array's shape."""

    format = Format.BINARY

    def load(self, data) -> np.ndarray:
        ndim, _flags, _oid = struct.unpack_from(">iii", data, 0)
        if ndim == 0:
            return np.zeros(0, dtype=np.float32)
        shape = tuple(struct.unpack_from(">i", data, 12 + 8 * k)[0] for k in range(ndim))
        body = np.frombuffer(data, dtype=_ELEMENT, offset=12 + 8 * ndim)
        if body.size != int(np.prod(shape)) or np.any(body["length"] != 4):
            raise ValueError("real[] with NULL elements cannot become a numpy array")
        return body["value"].astype(np.float32).reshape(shape)


def register(conn: Connection) -> None:
    conn.adapters.register_dumper(np.ndarray, Float4ArrayDumper)
    conn.adapters.register_loader(FLOAT4_ARRAY_OID, Float4ArrayLoader)
