"""Strict-JSON helper with no heavy imports (the bench's parent process uses it too)."""
from __future__ import annotations

import math


def json_safe(obj):
    """JSON-safe copy: NaN/Inf become None (strict JSON has neither); tuples become lists."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj
