"""The pilot: a coarse solve that finds where the stress raisers are, so that the
requested mesh is refined there.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np
from mpi4py import MPI
from geometry.meshspec import fillet_scale
from geometry.places import at_journal_root

from pipeline.analysis.context import RunContext, quiet
from pipeline.analysis.level import LevelTask, solve_level
from pipeline.inputs.case import Case
from pipeline.post.features import critical_region, known_raisers
from pipeline.post.peaks import NodeReadings, hot_spots

PILOT_RATIO = 2.2  # the pilot mesh: every size of the case's mesh × this
PILOT_FRACTION = 0.85  # pilot values this close to a peak (global or critical) are refined
PILOT_SEPARATION = 0.04  # × h3 (mm): refined places closer than this are one place
PILOT_ROUNDING = 0.01  # × h3 (mm): the grid the places are rounded to
PILOT_LIMIT = 12  # refined places per peak, at most (at rf = RF_PER_H·h3 or more)
BRIDGE_REACH = 3.0  # × the separation: journal-root places this close are neighbours on one crest
BRIDGE_COVER = 0.9  # × the ball radius: how far a point between neighbours may be from a place


def pilot_factor(case: Case) -> float:
    """The pilot's mesh factor: PILOT_RATIO × the case's, but no coarser than the factor at
    which the fillet elements are as large as the fillet radius (4 with the default sizes),
    and never finer than the case's own mesh.

    Why: the pilot must see the features it is to find; a much coarser pilot has fillet
    elements larger than rf and misses the bore-edge place (docs/decisions/0009-pilot-places.md).
    """
    f = case.mesh_factor * PILOT_RATIO
    if case.dims.rf > 0:
        # The default fillet size, whatever the case wants: the cap also keeps the pilot fine
        # enough to see the bore-edge places.
        fillet = replace(case, want="both").mesh_spec(1.0).size_fillet
        f = min(f, max(case.mesh_factor, case.dims.rf / fillet))
    return f


PILOT, KNOWN = "pilot", "known"  # where a run's refined places come from


@dataclass
class Pilot:
    """Where the run's meshes are refined (mm) and what finding the places cost (s): found
    by a coarse solve (``source`` PILOT, on a mesh ``factor`` × the default sizes) or taken
    from the dimensions (KNOWN, no solve, ``factor`` None)."""

    factor: float | None
    hotspots: tuple[tuple[float, float, float], ...]
    time_s: float
    source: str = PILOT
    bridging: int = 0  # of the hotspots, how many were added between the found ones (bridged)


def refinement_places(case: Case, ctx: RunContext = RunContext()) -> Pilot:
    """The places a run refines: for the critical peak alone (``want`` critical) the two
    bore edges in the plane x = 0, known from the dimensions; otherwise the pilot's.

    Why: the critical peak sits at a bore edge on every row of the size table, and there
    the known places give the pilot's critical peak within 0.07 % at half the DOFs and
    half the time
    (docs/decisions/0013-critical-peak-known-places.md); the pilot's value for that scene is only the
    extra places along the same edges. analysis.analyse checks on the requested mesh that
    the critical peak did fall inside the known places' refinement and runs the pilot
    where it did not (an unusual part).
    """
    if case.want != "critical":
        return pilot(case, ctx)
    known = known_places(case)
    ctx.say(
        f"no pilot: refining near the {len(known.hotspots)} bore edges in x = 0, known from the dimensions: "
        f"{', '.join(_fmt(q) for q in known.hotspots)} mm")
    return known


def known_places(case: Case) -> Pilot:
    """The places the case's wanted peaks are known to sit at, from the dimensions alone
    (features.known_raisers), as refinement places found without a solve."""
    return Pilot(factor=None, hotspots=known_raisers(case), time_s=0.0, source=KNOWN)


def inside_refinement(place_mm: Sequence[float], pl: Pilot, radius_mm: float) -> bool:
    """Whether a point (mm) lies within ``radius_mm`` of one of the refined places or of
    their mirror images in x = 0 and y = 0 (the meshes refine all four quadrants)."""
    x, y, z = place_mm
    return any(math.dist((abs(x), abs(y), z), q) <= radius_mm for q in pl.hotspots)


def pilot(case: Case, ctx: RunContext = RunContext()) -> Pilot:
    """Find the global and the critical peak on a mesh PILOT_RATIO times coarser than the case's.

    Why: the peak at the shoulder fillet sits in a stress gradient of ~2/rf; with P2 the
    element-to-element jump of the stress there is 20 % at rf/4 (the default fillet size)
    and the maximum over element nodes scattered by ±1.5 % from mesh to mesh. Refining the
    whole fillet ring to rf/15 costs ~1 M DOFs; refining a ball around the peak costs ~20 k.
    The pilot says where the ball goes; every level of the error bar then uses the same
    balls, sizes scaled with the level like every other size.
    """
    t0 = time.perf_counter()
    say = ctx.say
    # Its mesh and solve say nothing: the line below says what the pilot found.
    lv = solve_level(case, LevelTask(factor=pilot_factor(case), keep_fields=True, reuse=False), replace(ctx, say=quiet))
    vm = lv.fields[1]
    d = case.dims
    scale = fillet_scale(d)

    def lengths(per_h3: float, pts: np.ndarray) -> np.ndarray:
        # On the journal root the places' lengths follow rf like their balls (MeshSpec).
        return per_h3 * d.h3 * np.where(at_journal_root(d, np.reshape(pts, (-1, 3))), scale, 1.0)

    def separation(pts: np.ndarray) -> np.ndarray:
        return lengths(PILOT_SEPARATION, pts)

    # Places closer together along the fillet at a small rf: as many as the same stretch
    # of the ridge needs (within a limit on the size fields gmsh evaluates).
    limit = min(math.ceil(PILOT_LIMIT / min(scale, 1.0) - 1e-9), 4 * PILOT_LIMIT)
    # Only the places of the peaks the run is asked for (case.want).
    # Within 15 % of the global peak's level (at the fillet the midpoint of its two
    # readings), not of the largest element-node value: on the coarse pilot mesh that can
    # over-read the fillet at one node, and the rest of the crest then falls below the
    # threshold (docs/decisions/0009-pilot-places.md).
    level = threshold_level(lv.readings)
    spots = hot_spots(vm, PILOT_FRACTION * level, separation, limit) if case.want != "critical" else []
    if case.want != "global":
        spots += [q for q in hot_spots(vm, PILOT_FRACTION * lv.critical.unaveraged.value_MPa, separation,
                                       PILOT_LIMIT, critical_region(case))
                  if all(math.dist(q, s) >= separation(np.array(q))[0] for s in spots)]
    # The pilot's peaks differ in the last digits between runs on 1 and 2 ranks (and
    # between runs when gmsh's high-order optimiser was used); the balls then moved and
    # the refined meshes differed. Rounded to 0.01·h3 (0.25 mm on No. 05, well inside the
    # 0.6 mm ball; on the journal root × fillet_scale like the ball) and sorted, so that
    # pilots differing in the last digits give the same refined meshes.
    grids = [float(g) for g in lengths(PILOT_ROUNDING, np.array(spots))] if spots else []
    spots = sorted({tuple(round(c / g) * g + 0.0 for c in q) for q, g in zip(spots, grids)})
    found_here = len(spots)
    spots = bridged(spots, d, case.mesh_spec().hotspot_radius, BRIDGE_REACH * PILOT_SEPARATION * d.h3 * scale)
    dt = time.perf_counter() - t0
    say(f"pilot ×{lv.factor:.3g}: {lv.dofs} DOFs; refining near {found_here} places within "
        f"{100 * (1 - PILOT_FRACTION):.0f} % of a peak and {len(spots) - found_here} between them on the fillet's "
        f"crest: {', '.join(_fmt(q) for q in spots)} mm ({dt:.2f} s)")
    return Pilot(factor=lv.factor, hotspots=tuple(spots), time_s=dt, bridging=len(spots) - found_here)


def threshold_level(r: NodeReadings) -> float:
    """The level (MPa) the pilot's places are chosen within PILOT_FRACTION of: the midpoint
    of the largest unaveraged and the largest averaged reading over the nodes read by their
    midpoint (the fillet's), or the largest unaveraged reading elsewhere if that is larger.
    Not the reported global peak (the midpoint of one node's two readings), which lies lower
    on the coarse pilot mesh: with it No. 05's pilot refined 30 places instead of 21 and every
    mesh had 11 % more DOFs, for no better peak (docs/decisions/0035-reported-value-node-by-node.md).
    Collective over MPI."""
    def top(values: np.ndarray, mask: np.ndarray) -> float:
        return r.space.mesh.comm.allreduce(float(values[mask].max()) if mask.any() else -np.inf, op=MPI.MAX)
    fillet = 0.5 * (top(r.unaveraged, r.midpoint) + top(r.averaged, r.midpoint))
    return max(fillet, top(r.unaveraged, ~r.midpoint))


def bridged(spots: Sequence[tuple[float, float, float]], d, radius_mm: float,
            reach_mm: float) -> list[tuple[float, float, float]]:
    """``spots`` (mm) and places added on the segment between every two journal-root
    places less than ``reach_mm`` apart, wherever a point of it lies more than BRIDGE_COVER
    × ``radius_mm`` (their balls' radius) from every place; sorted.

    Why: the pilot's places along the fillet's crest are its mesh's nodes, up to 2.8 times
    the separation apart, so their balls left gaps on the crest, and a coarse error-bar
    mesh's element-node peak sat in a gap (No. 05 at rf = 0.5 mm: 0.39 and 0.63 mm from
    the nearest place, the balls 0.2 mm; docs/decisions/0010-refinement-lengths.md). The points are found from
    the rounded places, so every rank adds the same ones.
    """
    pts = [np.asarray(q, dtype=float) for q in spots]
    on_root = at_journal_root(d, np.reshape(np.asarray(spots, dtype=float), (-1, 3))) if spots else []
    root = [q for q, r in zip(pts, on_root) if r]
    cover = BRIDGE_COVER * radius_mm
    for i, a in enumerate(root):
        for b in root[i + 1:]:
            gap = float(np.linalg.norm(b - a))
            if gap > reach_mm or gap <= 2 * cover:
                continue
            # Walk along the segment; a point that no ball covers becomes a place.
            for t in np.linspace(0.0, 1.0, math.ceil(gap / (0.1 * cover)) + 1)[1:-1]:
                q = a + t * (b - a)
                if min(float(np.linalg.norm(q - p)) for p in pts) > cover:
                    pts.append(q)
    return sorted(tuple(float(c) for c in q) for q in pts)


def _fmt(p: Sequence[float]) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in p) + ")"
