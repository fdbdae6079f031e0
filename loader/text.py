"""A motion file's lines from its bytes, whatever the encoding."""

from __future__ import annotations

import codecs


def lines_of(raw: bytes) -> list[str]:
    """The file's lines, numbered as editors and `grep -n` number them.

    Lines end at LF, CRLF or CR only: str.splitlines would also break at form feeds and at
    Latin-1's byte 0x85, and every line number reported after one would be off.
    """
    text = None
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):  # saved as "Unicode"
        try:
            text = raw.decode("utf-16")
        except UnicodeDecodeError:
            text = None
    if text is None:
        try:
            text = raw.decode("utf-8-sig")  # a byte-order mark is not part of the first keyword
        except UnicodeDecodeError:
            text = raw.decode("latin-1")  # old exporters write Latin-1 joint names
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    if lines[-1] == "":  # the last line's line break ends it, it starts no line
        lines.pop()
    return lines
