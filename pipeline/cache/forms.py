"""The form compiler's cache (.venv/cache/fenics, see pipeline/runtime/environment.py): clean-up.

FFCx claims a form by creating ``<module>.c`` and marks it done with ``<module>.c.cached``.
A run killed while compiling leaves the claim without the mark, and every later run that
needs that form waits for the mark, then stops with "JIT compilation timed out" (DOLFINx's
timeout, 10 s). Seen here after a bench was stopped during its warm-up: every P3 point
failed.
"""
from __future__ import annotations

import time
from pathlib import Path

STALE_AFTER_S = 300.0  # a claim this old without its mark is from a dead compile (they take < 30 s)


def remove_interrupted(cache_dir: Path, stale_after_s: float = STALE_AFTER_S,
                       now: float | None = None) -> list[Path]:
    """Delete the claims (``*.c`` without ``*.c.cached``) older than ``stale_after_s`` seconds
    in ``cache_dir``; return them. Younger claims may belong to a compile that is running."""
    cache_dir = Path(cache_dir)
    if not cache_dir.is_dir():
        return []
    now = time.time() if now is None else now
    removed = []
    for c_file in cache_dir.glob("*.c"):
        if c_file.with_suffix(".c.cached").exists():
            continue
        try:
            if now - c_file.stat().st_mtime > stale_after_s:
                c_file.unlink()
                removed.append(c_file)
        except FileNotFoundError:  # another process cleaned or finished it meanwhile
            continue
    return removed


def claims_since(cache_dir: Path, since: float) -> list[Path]:
    """Claims (``*.c`` without ``*.c.cached``) made at or after ``since`` (epoch s): the
    compiles this process started, when it is stopped midway (pipeline.runtime.interrupts)."""
    found = []
    for c_file in Path(cache_dir).glob("*.c"):
        try:
            if not c_file.with_suffix(".c.cached").exists() and c_file.stat().st_mtime >= since:
                found.append(c_file)
        except FileNotFoundError:
            continue
    return found


def jit_cache_dir() -> Path:
    """The cache directory DOLFINx uses (pipeline/runtime/environment.py sets where)."""
    from dolfinx.jit import get_parameters
    return Path(get_parameters()["cache_dir"])
