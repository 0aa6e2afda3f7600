"""Program texts: bytes decoded so that every byte round-trips, and their newlines."""
from __future__ import annotations

from pathlib import Path

from ..core.diagnostics import P105, P106, P107, PostprocError


def decode(data: bytes, path: str) -> str:
    if not data.strip():
        raise PostprocError("empty file", path, 1, 1, P105)
    if b"\x00" in data[:65536]:
        raise PostprocError("binary file (NUL bytes), not a robot program", path, 1, 1, P106)
    # latin-1 maps every byte to one character: whatever the file's encoding, bytes round-trip
    return data.decode("latin-1")


def read_text(path: str | Path) -> str:
    """A program file's text (latin-1: every byte round-trips); P107 when it cannot be read."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, P107) from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, P107) from None
    return decode(data, str(path))


def newline(text: str) -> str:
    crlf = text.count("\r\n")
    return "\r\n" if crlf and crlf >= text.count("\n") - crlf else "\n"
