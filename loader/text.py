"""Reading a motion file's text: its bytes (for the sha256) and its lines, whatever the encoding."""

from __future__ import annotations


def read_lines(path: str) -> tuple[bytes, list[str]]:
    with open(path, "rb") as f:
        raw = f.read()
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark is not part of the first keyword
    except UnicodeDecodeError:
        text = raw.decode("latin-1")  # old exporters write Latin-1 joint names
    return raw, text.splitlines()
