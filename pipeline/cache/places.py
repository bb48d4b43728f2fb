"""The pilot's refined places kept in the run cache (pipeline/cache/runs.py).

Besides the entry's sha256, reused places are checked against what they must be: the
pilot's mesh factor of the case, a finite point (mm) of three coordinates each, inside a
box of ten times the part's largest dimension, sorted and distinct as the pilot writes
them, and no more bridging places than places.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from pipeline.cache import runs as runcache

REDO = "pilot run again"


@dataclass
class StoredPlaces:
    """The pilot's mesh factor, its places (mm), how many of them were bridged, its time (s)."""

    factor: float
    hotspots: tuple[tuple[float, float, float], ...]
    bridging: int
    time_s: float


def store(name: str, p: StoredPlaces) -> None:
    """Keep the pilot's places ``p`` under ``name``."""
    runcache.store(name, runcache.Entry({"factor": float(p.factor), "bridging": int(p.bridging),
                                         "time_s": float(p.time_s),
                                         "hotspots": [[float(c) for c in q] for q in p.hotspots]}))


def earlier(name: str, factor: float, reach_mm: float) -> StoredPlaces | None:
    """The places stored under ``name`` if they pass the checks above (``factor`` the
    case's pilot factor, ``reach_mm`` the part's largest dimension, mm), else None (a
    failed entry is dropped, with one line)."""
    entry = runcache.load(name, REDO)
    if entry is None:
        return None
    m = entry.meta
    try:
        spots = tuple(tuple(q) for q in m["hotspots"])
        ok = (runcache.finite(m["factor"], m["bridging"], m["time_s"]) and m["factor"] == factor
              and all(len(q) == 3 and runcache.finite(*q) and max(map(abs, q)) <= 10 * reach_mm for q in spots)
              and list(spots) == sorted(set(spots)) and 0 <= m["bridging"] <= len(spots)
              and math.floor(m["bridging"]) == m["bridging"])
    except (KeyError, TypeError, ValueError, IndexError):
        ok = False
    if not ok:
        runcache.reject(name, "places not what a pilot writes", REDO)
        return None
    return StoredPlaces(m["factor"], spots, int(m["bridging"]), m["time_s"])
