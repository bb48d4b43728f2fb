"""Work that a run can reuse from an earlier one: meshes (pipeline/cache/meshes.py), the
pilot's refined places (pipeline/cache/places.py), solutions (pipeline/cache/solutions.py)
and the error-bar meshes' results (pipeline/cache/levels.py).

A mesh depends only on the part, the model and the mesh spec (sizes, factor, order,
refined places) and on the meshing code; the pilot's places depend on those and on what
shapes the stress field (support, Poisson's ratio, element order, solver), not on the
load, Young's modulus or the allowable (linear elasticity, traction loads). So a run that
changes only load, E or the allowable reuses both, and its solutions too, scaled.

Nothing read from the cache is trusted. An entry is one file ``<name>.entry`` in
.venv/cache/runs: a first line ``crosshead-cache-entry 1 <sha256> <header bytes> <payload
bytes>``, a JSON header (the entry's name, its plain numbers and the list of its arrays:
name, dtype, shape) and the arrays' raw bytes. Reading it runs no code (no pickle; JSON and
numpy buffers of a few fixed dtypes only); the sha256 of header and payload is checked on
every read; only a regular file of at most MAX_ENTRY_BYTES is opened (no symlink, FIFO,
device or folder: lstat first, then ``O_NOFOLLOW | O_NONBLOCK`` and fstat), and the name in
it must be the one asked for.
Each kind then checks what it reads against what it must be (its module says how). An
entry that fails is removed and the run says so in one line on stderr naming the file,
then computes the work again; a cache that cannot be read or written costs time and one
line, never the run.

Entries are written to a temporary name and renamed, so concurrent runs never read half
a file; at most MAX_BYTES are kept, the least recently used going first (an entry read
counts as used). The key includes the code key (pipeline/cache/codekey.py), so other code
never reuses an entry. ``CROSSHEAD_NO_CACHE=1`` turns the cache off (the tests do: they
test the mesher itself); ``make clean-cache`` empties it.
"""
from __future__ import annotations

import contextlib
import dataclasses
import errno
import functools
import hashlib
import json
import math
import os
import stat
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.runtime.atomicfile import replacing
from pipeline.cache.codekey import code_key
from pipeline.runtime.environment import CACHE_HOME

ROOT = CACHE_HOME / "runs"
# Bounded by bytes, not entries: a variant keeps about eight (its pilot's places, four
# meshes of ~6 MB, a solution, two error-bar results), and a study of every size about
# 150 entries (0.6 GB): its re-run at another allowable finds them all.
MAX_BYTES = 2 * 1024 ** 3
MAX_ENTRY_BYTES = 512 * 1024 ** 2  # the largest entry read or written (bytes): the fine meshes' solutions
SUFFIX = ".entry"
MAGIC = "crosshead-cache-entry"
VERSION = 1
FIRST_LINE_MAX = 160  # bytes: magic, version, a sha256 and two lengths fit well within
# The only array types an entry holds: numbers, never objects.
DTYPES = ("<f8", "<i8", "<i4", "|u1")
# Errors of the cache folder itself, not of one entry: one line says them for the run.
FOLDER_ERRORS = (errno.EACCES, errno.EPERM, errno.ENOTDIR, errno.EIO)


@dataclass
class Entry:
    """What an entry holds: plain JSON numbers and strings (``meta``) and numeric arrays;
    read back, the sha256 its file was checked against (what an entry derived from it
    records, pipeline/cache/levels.py)."""

    meta: dict[str, Any]
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    sha256: str = ""


class Corrupt(Exception):
    """An entry that is not what this tool writes, or not whole: the reason, in a few words."""


def enabled() -> bool:
    return os.environ.get("CROSSHEAD_NO_CACHE", "") in ("", "0")


def key(kind: str, **parts: Any) -> str:
    """A file-name key for ``kind`` from JSON-able parts (dataclasses become dicts)."""
    def plain(v):
        return dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
    text = json.dumps({k: plain(v) for k, v in parts.items()}, sort_keys=True, default=str)
    return f"{kind}-{hashlib.sha1((text + code_key()).encode()).hexdigest()[:20]}"


def path_of(name: str) -> Path:
    """The file of entry ``name``."""
    return ROOT / f"{name}{SUFFIX}"


def say(line: str) -> None:
    """One line on stderr: what the cache did instead of what was asked (never fatal)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(line + "\n")
        sys.stderr.flush()


@functools.cache
def say_once(line: str) -> None:
    """:func:`say`, once per process for each line: a folder that cannot be read or
    written fails every entry of a run alike, and one line says it."""
    say(line)


def encode(name: str, entry: Entry) -> bytes:
    """The bytes of entry ``name``: first line, JSON header, raw arrays (see the module)."""
    arrays = [(k, np.ascontiguousarray(a)) for k, a in entry.arrays.items()]
    for k, a in arrays:
        if a.dtype.str not in DTYPES:
            raise TypeError(f"cache entry {name}: array {k} of type {a.dtype.str} (allowed: {DTYPES})")
    header = json.dumps({"name": name, "meta": entry.meta,
                         "arrays": [[k, a.dtype.str, list(a.shape)] for k, a in arrays]},
                        allow_nan=False, sort_keys=True).encode()
    payload = b"".join(a.tobytes() for _, a in arrays)
    digest = hashlib.sha256(header + payload).hexdigest()
    return f"{MAGIC} {VERSION} {digest} {len(header)} {len(payload)}\n".encode() + header + payload


def decode(name: str, data: bytes | bytearray) -> Entry:
    """The entry in ``data``; raises Corrupt unless it is whole, unaltered (sha256) and
    entry ``name``. The arrays are views of ``data`` (writable if it is a bytearray)."""
    end = bytes(data[:FIRST_LINE_MAX]).find(b"\n")
    if end < 0:
        raise Corrupt("not a cache entry")
    fields = bytes(data[:end]).decode("ascii", "replace").split(" ")
    if len(fields) != 5 or fields[0] != MAGIC:
        raise Corrupt("not a cache entry")
    if fields[1] != str(VERSION):
        raise Corrupt(f"format {fields[1][:8]!r}, not {VERSION}")
    digest, n_header, n_payload = fields[2], fields[3], fields[4]
    if not (n_header.isdigit() and n_payload.isdigit()):
        raise Corrupt("not a cache entry")
    start, n_header, n_payload = end + 1, int(n_header), int(n_payload)
    if start + n_header + n_payload != len(data):
        raise Corrupt(f"{len(data)} bytes, not the {start + n_header + n_payload} it says (truncated?)")
    body = memoryview(data)[start:]
    if hashlib.sha256(body).hexdigest() != digest:
        raise Corrupt("sha256 differs")
    try:
        header = json.loads(bytes(body[:n_header]))
        if header["name"] != name:
            raise Corrupt(f"it is entry {str(header['name'])[:60]!r}")
        meta, listed = header["meta"], header["arrays"]
        if not isinstance(meta, dict):
            raise Corrupt("no numbers")
        arrays, offset = {}, start + n_header
        for k, dtype, shape in listed:
            if dtype not in DTYPES or not all(isinstance(n, int) and n >= 0 for n in shape):
                raise Corrupt(f"array {k}: {dtype} {shape}")
            size = math.prod(shape) * np.dtype(dtype).itemsize
            if offset + size > len(data):
                raise Corrupt(f"array {k} runs past the end")
            arrays[k] = np.frombuffer(data, dtype=dtype, count=math.prod(shape), offset=offset).reshape(shape)
            offset += size
        if offset != len(data):
            raise Corrupt("bytes left over after the arrays")
    except (ValueError, KeyError, TypeError, IndexError, RecursionError) as exc:
        raise Corrupt(f"header unreadable: {type(exc).__name__}") from None
    return Entry(meta=meta, arrays=arrays, sha256=digest)


def digest(name: str) -> str | None:
    """The sha256 entry ``name``'s first line gives (its file's content is checked against
    it when the entry is read, :func:`load`), or None when there is no such entry to read."""
    if not enabled():
        return None
    try:
        data = read_regular(path_of(name), MAX_ENTRY_BYTES)
    except (Corrupt, OSError):
        return None
    if data is None:
        return None
    fields = bytes(data[:FIRST_LINE_MAX]).split(b"\n", 1)[0].decode("ascii", "replace").split(" ")
    return fields[2] if len(fields) == 5 and fields[0] == MAGIC else None


def read_regular(path: Path, limit: int) -> bytearray | None:
    """The bytes of ``path`` if it is a regular file (not followed through a symlink, not a
    FIFO, device or folder) of at most ``limit`` bytes; None if there is none. Raises
    Corrupt for anything else there, OSError if it cannot be read. Never blocks or opens a
    device: lstat first, then O_NOFOLLOW | O_NONBLOCK and fstat against a swap meanwhile."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(mode):
        raise Corrupt("a symbolic link, not a file")
    if not stat.S_ISREG(mode):
        raise Corrupt("a folder, not a file" if stat.S_ISDIR(mode) else "not a regular file")
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:  # replaced since the lstat? The flags and fstat still refuse all but a regular file.
        fd = os.open(path, flags)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise Corrupt("a symbolic link, not a file") from None
        if exc.errno in (errno.ENXIO, errno.ENODEV, errno.EISDIR):
            raise Corrupt("not a regular file") from None
        raise
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise Corrupt("a folder, not a file" if stat.S_ISDIR(st.st_mode) else "not a regular file")
        if st.st_size > limit:
            raise Corrupt(f"{st.st_size} bytes, above the bound of {limit}")
        data = bytearray(st.st_size)
        view, got = memoryview(data), 0
        while got < st.st_size:
            n = os.readv(fd, [view[got:]])
            if n == 0:
                raise Corrupt("shorter than its size (cut while read?)")
            got += n
        if os.read(fd, 1):
            raise Corrupt("longer than its size (written while read?)")
        with contextlib.suppress(OSError):
            os.utime(fd)  # used now: the last to be evicted
        return data
    finally:
        os.close(fd)


def load(name: str, redo: str) -> Entry | None:
    """Entry ``name``, whole and unaltered, or None: if there is none, if the cache is off,
    or if it fails (then it is dropped and one line says so, ending with ``redo``, what the
    run does instead, e.g. "solved again")."""
    if not enabled():
        return None
    path = path_of(name)
    try:
        data = read_regular(path, MAX_ENTRY_BYTES)
        return None if data is None else decode(name, data)
    except Corrupt as exc:
        reject(name, str(exc), redo)
    except OSError as exc:
        if exc.errno in FOLDER_ERRORS:
            say_once(f"cache: {ROOT} cannot be read ({_os_reason(exc)}); the run goes on without it")
        else:
            say(f"cache: {path} cannot be read ({_os_reason(exc)}); {redo}")
    return None


def reject(name: str, why: str, redo: str) -> None:
    """Drop entry ``name`` (a file or link is removed, an empty folder too; nothing else is
    touched) and say in one line that it failed its check, why, and what the run does instead."""
    path = path_of(name)
    with contextlib.suppress(OSError):
        if stat.S_ISDIR(os.lstat(path).st_mode):
            os.rmdir(path)  # only if empty: a folder of something else stays
        else:
            path.unlink()
    say(f"cache: {path} failed its check ({why}); {redo}")


def store(name: str, entry: Entry) -> None:
    """Keep ``entry`` under ``name`` (atomic), then drop the least recently used entries
    beyond MAX_BYTES in all. A write that fails says one line and the run goes on."""
    if not enabled():
        return
    path = path_of(name)
    try:
        data = encode(name, entry)
    except (TypeError, ValueError) as exc:  # a number JSON cannot hold, an array of objects
        say(f"cache: {path} not kept ({exc})")
        return
    if len(data) > min(MAX_ENTRY_BYTES, MAX_BYTES):
        return  # larger than the cache may hold: kept, it would evict everything else
    try:
        ROOT.mkdir(parents=True, exist_ok=True)
        if os.path.isdir(path):
            return  # a folder where the entry goes: reading it has said so (load)
        with replacing(path, "wb") as f:
            f.write(data)
    except OSError as exc:
        say_once(f"cache: cannot write into {ROOT} ({_os_reason(exc)}); the run goes on without keeping its work")
        return
    evict(MAX_BYTES)


def evict(max_bytes: int) -> list[Path]:
    """Remove the least recently used entries until the rest hold at most ``max_bytes``
    (bytes); an entry that does not fit is removed and the older ones that still fit stay.
    Returns what was removed. Only regular ``*.entry`` files are counted or removed."""
    try:
        listing = list(os.scandir(ROOT))
    except OSError:
        return []
    entries = []
    for e in listing:
        try:
            if e.name.endswith(SUFFIX) and e.is_file(follow_symlinks=False):
                st = e.stat(follow_symlinks=False)
                entries.append((st.st_mtime_ns, st.st_size, Path(e.path)))
        except OSError:  # removed by another run meanwhile
            continue
    kept, removed = 0, []
    for _, size, p in sorted(entries, key=lambda e: e[0], reverse=True):  # newest first
        if kept + size <= max_bytes:
            kept += size
            continue
        with contextlib.suppress(OSError):
            p.unlink()
            removed.append(p)
    return removed


def finite(*values: Any) -> bool:
    """Whether every value is a real (not bool) finite number: a check of stored numbers."""
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in values)


def _os_reason(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__
