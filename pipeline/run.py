"""One analysis, case → geometry → mesh → solve → post-process → outputs (mm, N, MPa).

``run`` solves the case on the requested mesh and on coarser meshes (every size ×ratio,
×ratio², …) so that each peak it reports carries a Richardson/GCI error bar; the
finest (requested) mesh is the one whose fields are written. Stages talk through the
dataclasses below and files in the output folder; nothing is kept in module state.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from mpi4py import MPI

from . import analytic
from .case import Case
from .convergence import Estimate, estimate, representative_size
from .crosshead import crosshead_loads, equilibrium
from .errors import NumericalError
from .mesh_io import ImportedMesh, Mesher, given_or_new, make_mesh, make_meshes, owners
from .post import Peak, hot_spots, peak, von_mises
from .solve import Material, solve

Progress = Callable[[str], None]
Hotspots = Sequence[tuple[float, float, float]]

PILOT_RATIO = 2.2  # the pilot mesh: every size of the case's mesh × this
PILOT_FRACTION = 0.85  # pilot values this close to a peak (global or critical) are refined
PILOT_SEPARATION = 0.04  # × h3 (mm): refined places closer than this are one place
PILOT_LIMIT = 12  # refined places per peak, at most


@dataclass
class Level:
    """The result of one mesh: peaks (MPa, mm), sizes, solver data, times (s)."""

    factor: float
    dofs: int
    cells: int
    peak: Peak
    critical: Peak
    iterations: int
    residual_rel: float
    seat_force_N: float
    support_force_N: float
    equilibrium_error_N: float
    constraint_reaction_N: float
    jacobian_ratio: float
    timings: dict[str, float]
    fields: tuple | None = None  # (u, von_mises) on the requested mesh only


def critical_region(case: Case) -> Callable[[np.ndarray], np.ndarray]:
    """The ligaments beside the bore: |x| <= di/2 (DESIGN §5)."""
    half = case.dims.d2 / 2 * (1 + 1e-9)
    return lambda xyz: np.abs(xyz[:, 0]) <= half


def solve_level(case: Case, factor: float, msh_path: Path | None = None,
                keep_fields: bool = False, comm=MPI.COMM_WORLD,
                progress: Progress | None = None, hotspots: Hotspots = (),
                load_mesh: Callable[[], ImportedMesh] | None = None,
                mesher: Mesher | None = None) -> Level:
    """Build, mesh and solve the case with every mesh size times ``factor``; find the peaks.

    ``load_mesh``: that mesh made already (see :func:`analyse`); factor, msh_path and
    hotspots are then only the mesh's description. ``mesher``: this process's
    mesh_io.Mesher of the case's part, if it has one. Raises NumericalError if the mesh has
    an inverted element, the solver fails, the result is not finite, or the loads do not
    balance to 1e-6·Q.
    """
    say = progress or (lambda s: None)
    if load_mesh is None:
        m = make_mesh(case.dims, case.model, case.mesh_spec(factor, hotspots), comm=comm, msh_path=msh_path,
                      mesher=mesher)
    else:
        m = load_mesh()
    say(f"mesh ×{factor:.3g}: {m.mesh.topology.index_map(3).size_global} tets, "
        f"geometry {m.timings['geometry']:.2f} s, mesh {m.timings['mesh']:.2f} s, "
        f"import {m.timings['import']:.2f} s")
    if not m.jacobian_ratio > 0:
        raise NumericalError(f"mesh: a curved element is inverted (worst det J ratio {m.jacobian_ratio:.3g}) "
                             f"at mesh factor {factor:.3g}; try a slightly different --mesh-factor")
    mat = Material(E=case.E_MPa, nu=case.nu)
    lc = crosshead_loads(m, case.dims, case.load_N, case.support)
    sol = solve(m.mesh, m.facet_tags, case.order, mat, lc.tractions, lc.constraints,
                solver=case.solver, rtol=case.rtol)
    support, eq_err, point_r = equilibrium(lc, sol.reactions)
    limit = 1e-6 * case.load_N
    if not (eq_err <= limit and point_r <= limit):
        raise NumericalError(f"loads out of balance: equilibrium error {eq_err:.3g} N, "
                             f"constraint reaction {point_r:.3g} N (limit {limit:.3g} N)")
    t0 = time.perf_counter()
    vm = von_mises(sol.u, mat)
    pk = peak(vm)
    crit = peak(vm, critical_region(case))
    t_post = time.perf_counter() - t0
    timings = dict(m.timings, **sol.timings, post=t_post)
    say(f"solve ×{factor:.3g}: {sol.dofs} DOFs, {sol.iterations} iterations ({case.solver}), "
        f"assemble {sol.timings['assemble']:.2f} s, solve {sol.timings['solve']:.2f} s; "
        f"peak {pk.value_MPa:.2f} MPa, critical {crit.value_MPa:.2f} MPa")
    return Level(factor=factor, dofs=sol.dofs, cells=m.mesh.topology.index_map(3).size_global,
                 peak=pk, critical=crit, iterations=sol.iterations,
                 residual_rel=sol.residual_rel, seat_force_N=lc.seat_force_z_N,
                 support_force_N=support, equilibrium_error_N=eq_err,
                 constraint_reaction_N=point_r, jacobian_ratio=m.jacobian_ratio,
                 timings=timings, fields=(sol.u, vm) if keep_fields else None)


def describe_location(case: Case, xyz: tuple[float, float, float]) -> str:
    """Plain-words name of the feature at point xyz (mm), for the report."""
    d = case.dims
    x, y, z = (abs(xyz[0]), abs(xyz[1]), xyz[2])
    r_axis = math.hypot(x, y)
    tol = 0.02 * d.h3
    vertical = "bottom" if z < tol else "top" if z > d.h3 - tol else "mid-height"
    if abs(r_axis - d.d2 / 2) < tol:
        return f"bore edge ({vertical} face)" if vertical != "mid-height" else "bore wall"
    if d.b1 / 2 - tol <= x <= d.b1 / 2 + d.rf + tol and x >= d.b1 / 2 - tol and \
            math.hypot(y, z - d.h3 / 2) < d.dj / 2 + d.rf + tol and d.rf > 0:
        return "journal shoulder fillet"
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


def estimate_levels(levels: list[Level], case: Case, attr: str) -> Estimate:
    """Error estimate of one peak ("peak" or "critical") over levels given finest first."""
    values = [getattr(lv, attr).value_MPa for lv in levels]
    h = [representative_size(lv.dofs) for lv in levels]
    return estimate(values, h, p_formal=float(case.order))


def pilot_factor(case: Case) -> float:
    """The pilot's mesh factor: PILOT_RATIO × the case's, but no coarser than the factor at
    which the fillet elements are as large as the fillet radius (4 with the default sizes),
    and never finer than the case's own mesh.

    Why: the pilot must see the features it is to find. At mesh factor 4 an uncapped
    pilot (×8.8) had fillet elements twice rf and missed the bore-edge place: critical
    peak +2.05 % (make bench).
    """
    f = case.mesh_factor * PILOT_RATIO
    if case.dims.rf > 0:
        f = min(f, max(case.mesh_factor, case.dims.rf / case.mesh_spec(1.0).size_fillet))
    return f


@dataclass
class Pilot:
    """A coarse solve that only says where the peaks are (mm), and what it cost (s)."""

    factor: float
    hotspots: tuple[tuple[float, float, float], ...]
    time_s: float


def pilot(case: Case, comm=MPI.COMM_WORLD, progress: Progress | None = None,
          mesher: Mesher | None = None) -> Pilot:
    """Find the global and the critical peak on a mesh PILOT_RATIO times coarser than the case's.

    Why: the peak at the shoulder fillet sits in a stress gradient of ~2/rf; with P2 the
    element-to-element jump of the stress there is 20 % at rf/4 (the default fillet size)
    and the maximum over element nodes scattered by ±1.5 % from mesh to mesh. Refining the
    whole fillet ring to rf/15 costs ~1 M DOFs; refining a ball around the peak costs ~20 k.
    The pilot says where the ball goes; every level of the error bar then uses the same
    balls, sizes scaled with the level like every other size.
    """
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    lv = solve_level(case, pilot_factor(case), comm=comm, keep_fields=True, mesher=mesher)
    vm = lv.fields[1]
    sep = PILOT_SEPARATION * case.dims.h3
    spots = hot_spots(vm, PILOT_FRACTION * lv.peak.value_MPa, sep, PILOT_LIMIT)
    spots += [q for q in hot_spots(vm, PILOT_FRACTION * lv.critical.value_MPa, sep, PILOT_LIMIT,
                                   critical_region(case))
              if all(math.dist(q, s) >= sep for s in spots)]
    # The pilot's peaks differ in the last digits between runs on 1 and 2 ranks (and
    # between runs when gmsh's high-order optimiser was used); the balls then moved and
    # the refined meshes differed. Rounded to 0.01·h3 (0.25 mm on No. 05, well inside the 0.6 mm ball) and sorted, so
    # that pilots differing in the last digits give the same refined meshes.
    grid = 1e-2 * case.dims.h3
    spots = sorted({tuple(round(c / grid) * grid + 0.0 for c in q) for q in spots})
    dt = time.perf_counter() - t0
    say(f"pilot ×{lv.factor:.3g}: {lv.dofs} DOFs; refining near {len(spots)} places within "
        f"{100 * (1 - PILOT_FRACTION):.0f} % of a peak: {', '.join(_fmt(q) for q in spots)} mm ({dt:.2f} s)")
    return Pilot(factor=lv.factor, hotspots=tuple(spots), time_s=dt)


def _fmt(p: Sequence[float]) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in p) + ")"


def analyse(case: Case, levels: int = 3, ratio: float = 1.3, msh_path: Path | None = None,
            progress: Progress | None = None, comm=MPI.COMM_WORLD,
            pl: Pilot | None = None,
            on_requested: Callable[[Level], None] | None = None,
            mesher: Mesher | None = None) -> tuple[list[Level], Pilot]:
    """Solve on ``levels`` meshes, the requested one and coarser by ``ratio`` each; finest first.

    A pilot solve first puts refinement where the peaks are (see :func:`pilot`). Then all
    meshes are made at once, one per rank (gmsh is serial; see mesh_io.make_meshes). The
    requested mesh is solved on every rank and handed to ``on_requested`` (which may start
    work that runs beside what follows: the picture). The coarser meshes are then solved
    side by side, each on one rank (see :func:`error_bar_ranks`). ``mesher``: this
    process's mesh_io.Mesher of the case's part, if it has one (else one for the pilot
    and the meshes).
    """
    with given_or_new(mesher, case.dims, case.model) as m:
        pl = pl or pilot(case, comm=comm, progress=progress, mesher=m)
        factors = [case.mesh_factor * ratio ** k for k in range(levels)]
        on = error_bar_ranks(factors, comm.size)
        t0 = time.perf_counter()
        loaders = make_meshes(case.dims, case.model, [case.mesh_spec(f, pl.hotspots) for f in factors],
                              comm=comm, msh_paths=[msh_path] + [None] * (levels - 1), solve_on=on,
                              mesher=m)
    say = progress or (lambda s: None)
    if comm.size > 1 and levels > 1:
        say(f"meshes ×{', ×'.join(f'{f:.3g}' for f in factors)} made on {min(comm.size, levels)} ranks at once "
            f"({time.perf_counter() - t0:.2f} s)")
    fine = solve_level(case, factors[0], keep_fields=True, comm=comm, progress=progress, load_mesh=loaders[0])
    if on_requested is not None:
        on_requested(fine)
    mine: list[tuple[int, Level]] = []
    error = None
    for k in range(1, levels):
        if on[k] == comm.rank and error is None:
            try:
                mine.append((k, solve_level(case, factors[k], comm=MPI.COMM_SELF, load_mesh=loaders[k],
                                            progress=progress if comm.rank == 0 else None)))
            except Exception as exc:  # re-raised on every rank below
                error = (k, exc)
    _wait_idle(comm)
    gathered = comm.allgather((mine, error))
    errors = [e for _, e in gathered if e is not None]
    if errors:
        raise min(errors, key=lambda e: e[0])[1]
    out = [fine] + [lv for _, lv in sorted((kl for m, _ in gathered for kl in m), key=lambda kl: kl[0])]
    for k in range(1, levels):
        if on[k] != 0:  # rank 0 printed its own
            lv = out[k]
            say(f"mesh ×{lv.factor:.3g} (rank {on[k]}): {lv.dofs} DOFs, {lv.iterations} iterations; "
                f"peak {lv.peak.value_MPa:.2f} MPa, critical {lv.critical.value_MPa:.2f} MPa")
    return out, pl


def _wait_idle(comm) -> None:
    """Wait for every rank, sleeping instead of spinning.

    Why: a rank waiting in a blocking MPI call spins at 100 % of a core (Open MPI's default),
    the core that the picture process and the other ranks' solves need.
    """
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.002)


def error_bar_ranks(factors: Sequence[float], ranks: int) -> list[int | None]:
    """Where each mesh of the error bar is solved: the requested one (first) on all ranks
    (None); the coarser ones each on one rank, the largest first to the least loaded rank
    (cost factor⁻³), counting ranks from the last, so that rank 0, which also starts the
    picture, gets the least.

    Why: 2 ranks solving the x1.3 and then the x1.69 mesh together, beside the picture
    process, made make run (No. 05, 2 ranks) take 20.44 s (median of 5); one mesh per rank,
    18.51 s (5 runs interleaved with those).
    """
    who = owners([f ** -3 for f in factors[1:]], ranks)
    return [None] + [ranks - 1 - r for r in who]


def pct(a: float, b: float) -> float:
    """Percentage difference of a relative to b."""
    return 100.0 * (a - b) / b


def build_results(case: Case, levels: list[Level], timings: dict[str, float],
                  comm=MPI.COMM_WORLD, pl: Pilot | None = None) -> dict:
    """The results.json content of DESIGN §7 from the solved levels (finest first)."""
    fine = levels[0]
    hand = analytic.hand_results(case.dims, case.load_N, case.approximate_span_mm,
                                 case.exact_span_mm)
    est_peak = estimate_levels(levels, case, "peak") if len(levels) >= 3 else None
    est_crit = estimate_levels(levels, case, "critical") if len(levels) >= 3 else None

    def peak_block(p: Peak, est: Estimate | None) -> dict:
        block = {"value_MPa": p.value_MPa, "location_mm": list(p.location_mm),
                 "feature": describe_location(case, p.location_mm)}
        singular = singular_feature(case, p.location_mm)
        if est is not None:
            block["error_estimate"] = est.as_dict()
            if est.status == "singular" and singular is None:
                singular = f"{block['feature']} (values do not converge under refinement)"
        if singular is not None:
            block["singular_feature"] = singular
            if est is not None:
                # Not a converged number, whatever the fit of a few meshes says.
                block["error_estimate"].update(status="singular", extrapolated=None, band=None,
                                               gci_fine=None, error_fine=None)
        return block

    ex, ap = hand.exact, hand.approximate
    fe = {
        "peak_MPa": fine.peak.value_MPa,
        "peak_location_mm": list(fine.peak.location_mm),
        "critical_peak_MPa": fine.critical.value_MPa,
        "critical_location_mm": list(fine.critical.location_mm),
        "peak": peak_block(fine.peak, est_peak),
        "critical": peak_block(fine.critical, est_crit),
        "dofs": fine.dofs, "cells": fine.cells, "order": case.order,
        "model": case.model, "support": case.support, "solver": case.solver,
        "iterations": fine.iterations, "residual_rel": fine.residual_rel,
        "equilibrium_error_N": fine.equilibrium_error_N,
        "constraint_reaction_N": fine.constraint_reaction_N,
        "seat_force_N": fine.seat_force_N, "support_force_N": fine.support_force_N,
        "model_load_share": 0.25 if case.model == "quarter" else 1.0,
        "mesh_min_jacobian_ratio": fine.jacobian_ratio,
        "safety_factor": case.allowable_MPa / fine.peak.value_MPa,
        "critical_safety_factor": case.allowable_MPa / fine.critical.value_MPa,
        "mpi_ranks": comm.size,
        "refined_at_mm": [] if pl is None else [list(p) for p in pl.hotspots],
        "pilot_mesh_factor": None if pl is None else pl.factor,
        "pilot_fraction": PILOT_FRACTION,
        "levels": [{"mesh_factor": lv.factor, "dofs": lv.dofs, "cells": lv.cells,
                    "peak_MPa": lv.peak.value_MPa, "critical_peak_MPa": lv.critical.value_MPa,
                    "iterations": lv.iterations, "time_s": sum(lv.timings.values())}
                   for lv in levels],
    }
    return {
        "units": {"length": "mm", "force": "N", "stress": "MPa"},
        "case": case.as_dict(),
        "analytic": {
            "approximate_MPa": ap.sigma_MPa, "exact_MPa": ex.sigma_MPa,
            "approximate_span_mm": ap.span_mm, "exact_span_mm": ex.span_mm,
            "approximate_terms": {"lever_mm": ap.lever_mm, "Me_Nmm": ap.Me_Nmm},
            "exact_terms": {"N1_N": ex.N1_N, "M1_Nmm": ex.M1_Nmm, "N2_N": ex.N2_N,
                            "M2_Nmm": ex.M2_Nmm, "R_mm": ex.R_mm, "F_mm2": ex.F_mm2,
                            "W_mm3": ex.W_mm3},
            "consistent_span": {
                "approximate_at_exact_span_MPa": hand.approximate_at_exact_span.sigma_MPa,
                "exact_at_approximate_span_MPa": hand.exact_at_approximate_span.sigma_MPa},
            "paper_MPa": {"approximate": 37.8, "exact": 43.75, "fe_catia": 42.10},
        },
        "fe": fe,
        "comparison_pct": {
            "critical_vs_exact": pct(fine.critical.value_MPa, ex.sigma_MPa),
            "critical_vs_approximate": pct(fine.critical.value_MPa, ap.sigma_MPa),
            "peak_vs_exact": pct(fine.peak.value_MPa, ex.sigma_MPa),
            "peak_vs_approximate": pct(fine.peak.value_MPa, ap.sigma_MPa),
        },
        "timings_s": timings,
    }


def sum_timings(levels: list[Level], pl: Pilot | None = None) -> dict[str, float]:
    """Per-stage times (s): the requested mesh's stages, the pilot's and the error-bar meshes' totals."""
    stages = ("geometry", "mesh", "import", "assemble", "solve", "post")
    out = {k: levels[0].timings.get(k, 0.0) for k in stages}
    if pl is not None:
        out["pilot"] = pl.time_s
    out["error_bar_meshes"] = sum(sum(lv.timings.values()) for lv in levels[1:])
    return out
