"""Strict JSON: the values made safe and results.json written whole. No heavy imports (the
bench's parent process uses it too)."""
from __future__ import annotations

import json
import math
from pathlib import Path

from pipeline.runtime.atomicfile import write_text


def json_safe(obj):
    """JSON-safe copy: NaN/Inf become None (strict JSON has neither); tuples become lists."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj


def write_json(path: Path, data: dict, rank: int = 0) -> None:
    """Write ``data`` as indented strict JSON, whole or not at all (a reader such as the
    picture process never sees half a file); only on rank 0, the rank that writes the
    run's files (other ranks return)."""
    if rank == 0:
        write_text(path, json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n")
