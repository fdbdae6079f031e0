"""The one error type a malformed input raises: it names the file, the line and what to do."""

from __future__ import annotations


class MotionFileError(Exception):
    def __init__(self, path: str, line: int | None, message: str, hint: str = ""):
        self.path = path
        self.line = line
        self.message = message
        self.hint = hint
        where = f"{path}:{line}" if line else path
        super().__init__(f"{where}: {message}" + (f" ({hint})" if hint else ""))
