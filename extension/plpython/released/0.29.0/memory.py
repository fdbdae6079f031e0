"""Giving a server process's memory back after a large result (plain Python, server side).

A large edit or retargeting leaves its frames' Python lists and numpy arrays as garbage; freed, much
of that memory stays with the C library's heap. release() collects the garbage, then asks glibc to
hand free heap pages back to the system. (Measured in 0.17.0: a session still grows by about 6 kB
per frame of each large result it makes, outside PostgreSQL's memory contexts and outside Python's
collected objects; the caps on one result bound each call, not a session.)"""

import ctypes
import ctypes.util
import gc

_LIBC = ctypes.util.find_library("c")


def release():
    """Collects garbage and returns the freed heap to the system where the C library can."""
    gc.collect()
    try:
        libc = ctypes.CDLL(_LIBC) if _LIBC else None
        trim = getattr(libc, "malloc_trim", None)  # glibc only
    except OSError:
        trim = None
    if trim is not None:
        trim(0)
