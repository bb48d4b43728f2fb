"""Places on the part: the critical region, the name of the feature a point lies on, and
whether that feature is singular (no finite peak).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from geometry.places import at_journal_root

from pipeline.inputs.case import Case


def critical_region(case: Case) -> Callable[[np.ndarray], np.ndarray]:
    """The ligaments beside the bore: |x| <= di/2 (docs/design.md §5)."""
    half = case.dims.d2 / 2 * (1 + 1e-9)
    return lambda xyz: np.abs(xyz[:, 0]) <= half


KNOWN_FILLET_STEP_DEG = 7.5  # spacing of the a-priori places along the fillet (about the pilot's on No. 05)


def known_raisers(case: Case) -> tuple[tuple[float, float, float], ...]:
    """Places (mm, quarter x, y >= 0) where the part's stresses are known to peak, from the
    dimensions alone: the bore edge in the plane x = 0 on the bottom and top faces (the
    critical peak) and, with a fillet, its middle (45° into the fillet) along the lower
    journal half, every KNOWN_FILLET_STEP_DEG from straight down to horizontal (the bearing
    pushes the journal up, so the root's tension side is below the axis). The alternative
    to a pilot solve for parts shaped like the table's; ``case.want`` picks the peaks."""
    d = case.dims
    places: list[tuple[float, float, float]] = []
    if case.want != "global":
        places += [(0.0, d.d2 / 2, 0.0), (0.0, d.d2 / 2, d.h3)]
    if case.want != "critical" and d.rf > 0:
        s = d.rf * (1 - math.sqrt(0.5))   # 45° into the fillet: in from the torus' centre circle
        x, r = d.b1 / 2 + s, d.dj / 2 + s
        for k in range(int(round(90 / KNOWN_FILLET_STEP_DEG)) + 1):
            t = math.radians(k * KNOWN_FILLET_STEP_DEG)
            places.append((x, r * math.sin(t), d.h3 / 2 - r * math.cos(t)))
    return tuple(places)


def fillet_region(case: Case) -> Callable[[np.ndarray], np.ndarray] | None:
    """The journal's shoulder fillet and a margin of 0.02·h3 around it (the points that
    :func:`describe_location` names "journal shoulder fillet"); None without a fillet."""
    if case.dims.rf <= 0:
        return None
    return lambda xyz: at_journal_root(case.dims, xyz)


def describe_location(case: Case, xyz: tuple[float, float, float]) -> str:
    """Plain-words name of the feature at point xyz (mm), for the report."""
    d = case.dims
    x, y, z = (abs(xyz[0]), abs(xyz[1]), xyz[2])
    r_axis = math.hypot(x, y)
    tol = 0.02 * d.h3
    vertical = "bottom" if z < tol else "top" if z > d.h3 - tol else "mid-height"
    if abs(r_axis - d.d2 / 2) < tol:
        return f"bore edge ({vertical} face)" if vertical != "mid-height" else "bore wall"
    if at_journal_root(d, np.array([xyz], dtype=float))[0]:
        # Without a fillet the journal meets the end face in a sharp re-entrant circle.
        return "journal shoulder fillet" if d.rf > 0 else "journal root (sharp corner, no fillet)"
    if x > d.b1 / 2 + tol:
        return "journal"
    if z > d.h3 - tol and min(abs(r_axis - d.seat_inner / 2), abs(r_axis - d.seat_outer / 2)) < tol:
        return "seat band edge (top face)"
    if x <= d.d2 / 2:
        return f"ligament beside the bore ({vertical})"
    return f"body ({vertical})"


def singular_feature(case: Case, xyz: tuple[float, float, float]) -> str | None:
    """Name of the known stress singularity at point xyz (mm), or None.

    Theory, not numerics: a shoulder without fillet (rf = 0) is a re-entrant 90° edge; the
    boundary of a rigid support patch (support "rigid") is an edge where a displacement
    constraint meets a free surface. Stresses there grow without bound under refinement.
    """
    d = case.dims
    x, y, z = abs(xyz[0]), abs(xyz[1]), xyz[2]
    tol = max(0.03 * d.h3, 1e-9)
    r = math.hypot(y, z - d.h3 / 2)
    if d.rf == 0 and abs(x - d.b1 / 2) < tol and abs(r - d.dj / 2) < tol:
        return "re-entrant edge at the journal shoulder (rf = 0, no fillet)"
    if case.support == "rigid" and x >= d.b1 / 2 + d.rf - tol and abs(r - d.dj / 2) < tol and z <= d.h3 / 2 + tol:
        if abs(x - (d.b1 / 2 + d.rf)) < tol:
            return "edge of the rigid support patch at the fillet run-out"
        if abs(z - d.h3 / 2) < tol:
            return "edge of the rigid support patch at journal mid-height (θ = 90°)"
        if abs(x - d.b6 / 2) < tol:
            return "edge of the rigid support patch at the journal tip"
    return None
