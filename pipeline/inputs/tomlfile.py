"""The one reader of the TOML files a user gives: case files (``--case``) and study files
(``--study``). A case or study file holds a few keys in a few tables, so anything that
is not a small, shallow, regular file is refused with one line (InputError, exit 2)
naming the file, before it can hang the command (a FIFO), read without end (a device),
fill the memory (a huge file) or exhaust the stack (thousands of nested arrays).
"""
from __future__ import annotations

import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from pipeline.errors import InputError

MAX_BYTES = 1 << 20  # 1 MiB: a case or study file is a few hundred bytes
MAX_DEPTH = 16  # tables and arrays inside each other; a study file needs 4 ([sweep], dims, rf, the array)
FILE_KINDS = {stat.S_IFIFO: "a FIFO", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
              stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder"}


def read_toml(path: str | os.PathLike, what: str) -> dict[str, Any]:
    """The TOML document in ``path`` as a dict; ``what`` ("case", "study") starts every
    error line. Raises InputError when the file is missing, not a regular file, larger
    than MAX_BYTES, not UTF-8 TOML, or nests deeper than MAX_DEPTH."""
    path = Path(path)
    text = _read_text(path, what)
    try:
        data = tomllib.loads(text)
    except RecursionError:  # the parser recurses once per nested array or inline table
        raise InputError(_too_deep(path, what)) from None
    except ValueError as exc:  # TOMLDecodeError, or an integer too long to convert
        raise InputError(f"{what}: {path} is not valid TOML: {' '.join(str(exc).split())}") from None
    if depth(data) > MAX_DEPTH:  # dotted keys (a.a.a... = 1) nest without recursing in the parser
        raise InputError(_too_deep(path, what))
    return data


def _read_text(path: Path, what: str) -> str:
    """The text of ``path`` (UTF-8, a leading byte-order mark dropped, as some editors
    write one). The file's kind and size are checked with os.stat before it is opened, and
    it is opened without blocking, so a FIFO put in its place between the two cannot hang
    the open; the descriptor is checked again (fstat) before any byte is read."""
    try:
        kind = _refusal(os.stat(path), path, what)
        if kind:
            raise InputError(kind)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        try:
            kind = _refusal(os.fstat(fd), path, what)
            if kind:
                raise InputError(kind)
            chunks, size = [], 0
            while size <= MAX_BYTES:
                chunk = os.read(fd, MAX_BYTES + 1 - size)
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        finally:
            os.close(fd)
    except FileNotFoundError:
        raise InputError(f"{what}: file not found: {path}") from None
    except OSError as exc:
        raise InputError(f"{what}: cannot read {path}: {exc.strerror or exc}") from None
    if size > MAX_BYTES:  # grew after the stat
        raise InputError(_too_large(path, what, size))
    try:
        return b"".join(chunks).decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what}: cannot read {path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def _refusal(st: os.stat_result, path: Path, what: str) -> str | None:
    """Why a file of status ``st`` is not read, or None: only a regular file of at most
    MAX_BYTES is."""
    if not stat.S_ISREG(st.st_mode):
        kind = FILE_KINDS.get(stat.S_IFMT(st.st_mode), "not a regular file")
        return f"{what}: cannot read {path}: not a regular file ({kind})"
    if st.st_size > MAX_BYTES:
        return _too_large(path, what, st.st_size)
    return None


def _too_large(path: Path, what: str, size: int) -> str:
    return (f"{what}: {path} is larger than {MAX_BYTES // (1 << 20)} MiB ({size} bytes or more); "
            f"a {what} file holds a few keys")


def _too_deep(path: Path, what: str) -> str:
    return (f"{what}: {path} nests tables or arrays more than {MAX_DEPTH} deep; "
            f"a {what} file holds a few keys in a few tables")


def depth(value: Any) -> int:
    """How many tables and arrays lie inside each other in ``value`` (a scalar: 0, a flat
    table: 1), counted without recursion so that no nesting can exhaust the stack."""
    deepest = 0
    todo = [(value, 1)] if isinstance(value, (dict, list)) else []
    while todo:
        item, level = todo.pop()
        deepest = max(deepest, level)
        if deepest > MAX_DEPTH:  # enough to refuse: the rest need not be walked
            return deepest
        children = item.values() if isinstance(item, dict) else item
        todo.extend((c, level + 1) for c in children if isinstance(c, (dict, list)))
    return deepest
