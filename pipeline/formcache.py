"""The form compiler's cache (.venv/jit-cache, see dolfinx_jit_parameters.json): clean-up.

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


def jit_cache_dir() -> Path:
    """The cache directory DOLFINx uses in this working directory."""
    from dolfinx.jit import get_parameters
    return Path(get_parameters()["cache_dir"])
