"""Work that a run can reuse from an earlier one: meshes, the pilot's refined places,
solutions (pipeline/cache/solutions.py) and the error-bar meshes' results (pipeline/cache/levels.py).

A mesh depends only on the part, the model and the mesh spec (sizes, factor, order,
refined places) and on the meshing code; the pilot's places depend on those and on what
shapes the stress field (support, Poisson's ratio, element order, solver), not on the
load, Young's modulus or the allowable (linear elasticity, traction loads). So a run that
changes only load, E or the allowable reuses both, and its solutions too, scaled.

Entries live in .venv/cache/runs (pickles and JSON written by this tool only), each
written to a temporary name and renamed, so concurrent runs never read half a file; at
most MAX_BYTES are kept (the least recently used go first). The key includes a hash of the
geometry and meshing source code, so a changed mesher never reuses an old mesh.
``CROSSHEAD_NO_CACHE=1`` turns the cache off (the tests do: they test the mesher itself);
``make clean-cache`` empties it.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import pickle
from pathlib import Path
from typing import Any

from pipeline.runtime.atomicfile import replacing
from pipeline.cache.codekey import code_key
from pipeline.runtime.environment import CACHE_HOME

ROOT = CACHE_HOME / "runs"
# Bounded by bytes, not entries: a variant keeps about eight (its pilot's places, four
# meshes of ~6 MB, a solution, two error-bar results), so the 60 entries kept before held
# less than a study of every size (about 150 entries, 0.6 GB), and its re-run at another
# allowable found nothing left to reuse.
MAX_BYTES = 2 * 1024 ** 3


def enabled() -> bool:
    return os.environ.get("CROSSHEAD_NO_CACHE", "") in ("", "0")


def key(kind: str, **parts: Any) -> str:
    """A file-name key for ``kind`` from JSON-able parts (dataclasses become dicts)."""
    def plain(v):
        return dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
    text = json.dumps({k: plain(v) for k, v in parts.items()}, sort_keys=True, default=str)
    return f"{kind}-{hashlib.sha1((text + code_key()).encode()).hexdigest()[:20]}"


def load(name: str) -> Any | None:
    """The entry ``name`` if present (and marks it used), else None."""
    if not enabled():
        return None
    path = ROOT / f"{name}.pickle"
    try:
        with open(path, "rb") as f:
            value = pickle.load(f)
        os.utime(path)
        return value
    except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError):
        return None


def store(name: str, value: Any) -> None:
    """Keep ``value`` under ``name`` (atomic), then drop the least recently used entries
    beyond MAX_BYTES in all."""
    if not enabled():
        return
    try:
        ROOT.mkdir(parents=True, exist_ok=True)
        with replacing(ROOT / f"{name}.pickle", "wb") as f:
            pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)
    except OSError:
        return  # a cache that cannot be written only costs time
    entries = []
    for p in ROOT.glob("*.pickle"):
        try:
            st = p.stat()
        except OSError:  # removed by another run meanwhile
            continue
        entries.append((st.st_mtime_ns, st.st_size, p))
    total = 0
    for _, size, p in sorted(entries, key=lambda e: e[0], reverse=True):  # newest first
        total += size
        if total > MAX_BYTES:
            p.unlink(missing_ok=True)
