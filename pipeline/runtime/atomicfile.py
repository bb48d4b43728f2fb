"""Files written whole or not at all: a reader (the picture process, a resumed sweep, a
second run reading the cache) never sees half a file, and a failed write leaves the old one."""
from __future__ import annotations

import contextlib
import hashlib
import os
from pathlib import Path
from typing import IO, Iterator


@contextlib.contextmanager
def replacing(path: str | os.PathLike, mode: str = "w", **open_kw) -> Iterator[IO]:
    """Open a hidden file of this process beside ``path``; when the block ends without an
    error it replaces ``path`` in one step (``os.replace``, atomic within a file system),
    and on an error it is removed and the error goes on."""
    path = Path(path)
    tmp = path.with_name(f".{_short(path.name)}.{os.getpid()}.tmp")
    try:
        with open(tmp, mode, **open_kw) as f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _short(name: str, room: int = 200) -> str:
    """``name``, or for one longer than ``room`` bytes its start and a hash of it: the hidden
    name must fit the file system's 255 bytes with its pid and suffix."""
    raw = os.fsencode(name)
    if len(raw) <= room:
        return name
    return os.fsdecode(raw[:room - 13].decode("utf-8", errors="ignore").encode()) + "~" + \
        hashlib.sha256(raw).hexdigest()[:12]


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all (:func:`replacing`)."""
    with replacing(path, "w", encoding="utf-8") as f:
        f.write(text)
