"""Giving a server process's memory back after a large result (plain Python, server side).

A large edit or retargeting leaves its frames' Python lists and numpy arrays as garbage; freed, most
of that memory stays with the C library's heap (the blocks are too scattered to shrink it), so a
session's size would keep the largest result it ever made, growing with fragmentation. release()
collects the garbage, then asks glibc to hand free heap pages back to the system."""

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
