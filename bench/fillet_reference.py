"""Verification study: the global (fillet) peak of No. 05 by a route independent of the
default path (docs/fillet-reference.md). Units: mm, N, MPa.

The default path reads von Mises at the nodes of three pilot-refined P2 meshes (at the
fillet the midpoint of the unaveraged and the nodal-averaged value, docs/design.md §5).
This study instead

- refines only a ball around the fillet's hot spot (or, with --crest, several along the
  fillet's crest where the peak is broad), in a geometric sequence of element sizes (the
  rest of the part keeps one fixed mesh: the journal's bending moment at its root is fixed
  by statics, so the far field only has to carry it);
- solves P2, P3 and (on the coarser balls) P4 displacements on the same meshes;
- takes the peak as the maximum of the FE von Mises stress over the exact fillet surface
  (a torus) inside the balls, sampled densely and refined around the best sample, so the
  answer does not depend on where the mesh happens to have a node;
- checks that the fillet surface inside the ball is the torus (the distance of every
  geometry node there from the torus's centre circle minus rf: a mid-edge node pulled
  straight by geometry/curved.py shows as a negative distance);
- extrapolates each order's sequence (Richardson, order fitted from three levels) and
  compares the limits of the orders with each other.

Run: ``python -m bench.fillet_reference --out results/fillet-reference`` (make reference),
another part with ``--size`` and ``--dim NAME=MM`` (the ball's radius and element sizes
then follow rf: the lengths above × rf / (0.06·h3), as the default path's refinement does),
or one point: ``... --point ORDER H_BALL`` (used by the study itself, one process per
point so that memory is returned between points).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from pipeline.api import configure  # noqa: E402

configure()  # before numpy, PETSc or DOLFINx load (pipeline/runtime/environment.py)

import numpy as np  # noqa: E402

from pipeline.api import refusal  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OWN_FILES = frozenset({"points.jsonl", "reference.json"})  # what it writes into --out
OUTER_FACTOR = 1.3          # the fixed mesh outside the ball: default sizes × this
OUTER_CHECKS = (1.0, 0.77)  # the middle P3 level again with finer outer meshes: the far field's share
BALL_RADIUS_MM = 2.5        # the refined ball around the hot spot (at rf = 0.06·h3: × fillet_scale)
# Element sizes in the ball, ratio 4/3 (at rf = 0.06·h3: × fillet_scale); why the sequence
# stops at 0.128 mm: docs/fillet-reference.md.
# P4 runs on the three coarsest only: it checks P3's limit with another order at about twice
# P3's DOFs.
H_BALLS_MM = (0.4, 0.3, 0.225, 0.17, 0.128)
ORDERS_AT = {2: H_BALLS_MM, 3: H_BALLS_MM, 4: H_BALLS_MM[:3]}
# Richardson's order below which three levels are not converging (as pipeline.post.errorbar's
# P_SINGULAR): their limit is not used.
MIN_ORDER = 0.5


@dataclass(frozen=True)
class Torus:
    """The fillet of the +x journal root: a torus about the journal axis (x axis through
    y = 0, z = zc), centre circle at x = xc of radius R, tube radius r (mm)."""

    xc: float
    zc: float
    R: float
    r: float

    def point(self, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """Surface points: theta from 0 (tangent to the body face x = b1/2) to π/2 (tangent
        to the journal), phi from 0 (straight down) towards +y."""
        x = self.xc - self.r * np.cos(theta)
        ra = self.R - self.r * np.sin(theta)
        return np.column_stack([x, ra * np.sin(phi), self.zc - ra * np.cos(phi)])

    def at(self, theta: float, phi: float) -> tuple[float, float, float]:
        """The one surface point (mm) at (theta, phi)."""
        return tuple(float(c) for c in self.point(np.array([theta]), np.array([phi]))[0])

    def gap(self, p: np.ndarray) -> np.ndarray:
        """Distance of points from the centre circle minus r (mm): 0 on the torus, < 0
        inside the tube (outside the material)."""
        ra = np.hypot(p[:, 1], p[:, 2] - self.zc)
        return np.hypot(p[:, 0] - self.xc, ra - self.R) - self.r


def fillet_torus(d) -> Torus:
    """The fillet of part d as a torus (mm)."""
    return Torus(xc=d.b1 / 2 + d.rf, zc=d.h3 / 2, R=d.dj / 2 + d.rf, r=d.rf)


def von_mises_tensor_field(u, mat):
    """The stress tensor (MPa) in DG(order−1): the space the pipeline's peaks come from."""
    from dolfinx import fem

    from pipeline.api import stress
    mesh = u.function_space.mesh
    order = u.function_space.ufl_element().degree()
    T = fem.TensorFunctionSpace(mesh, ("DG", order - 1))
    s = fem.Function(T)
    s.interpolate(fem.Expression(stress(u, mat), T.element.interpolation_points()))
    return s


def _stress_at(s, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The stress tensors (n × 3 × 3, MPa) of s at points in the given cells; NaN where the
    pull-back into a curved cell fails (the point is in the cell's hull, not in the cell:
    DOLFINx raises). All at once, or one by one after a failure: never raising, so that no
    rank leaves the collectives that follow while the others wait in them."""
    try:
        return s.eval(points, cells).reshape(-1, 3, 3)
    except RuntimeError:
        out = np.full((len(points), 3, 3), np.nan)
        for i in range(len(points)):
            try:
                out[i] = s.eval(points[i], cells[i:i + 1]).reshape(3, 3)
            except RuntimeError:
                continue
        return out


def von_mises_at(s, tree, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Von Mises (MPa) of the DG stress field s at points (n × 3, mm), evaluated in every
    cell that holds the point: (largest, mean) over those cells; NaN where no cell holds
    it. The stress jumps between cells; their mean is a simple recovered value, the
    largest is what a peak over element nodes sees. Collective: every rank gets all."""
    from dolfinx import geometry
    from mpi4py import MPI
    mesh = s.function_space.mesh
    n_owned = mesh.topology.index_map(3).size_local
    cells = geometry.compute_colliding_cells(mesh, geometry.compute_collisions(tree, points), points)
    idx = np.repeat(np.arange(len(points)), np.diff(cells.offsets))
    cell = cells.array
    keep = cell < n_owned  # each cell once over the ranks
    idx, cell = idx[keep], cell[keep]
    hi = np.full(len(points), -np.inf)
    total = np.zeros(len(points))
    count = np.zeros(len(points))
    if len(idx):
        t = _stress_at(s, points[idx], cell.astype(np.int32))
        ok = np.isfinite(t).all(axis=(1, 2))
        idx, t = idx[ok], t[ok]
        dev = t - np.trace(t, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
        vm = np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))
        np.maximum.at(hi, idx, vm)
        np.add.at(total, idx, vm)
        np.add.at(count, idx, 1)
    for arr, op in ((hi, MPI.MAX), (total, MPI.SUM), (count, MPI.SUM)):
        mesh.comm.Allreduce(MPI.IN_PLACE, arr, op=op)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / count, np.nan)
    return np.where(count > 0, hi, np.nan), mean


def near(points: np.ndarray, centres: np.ndarray, radius: float) -> np.ndarray:
    """Which points (n × 3, mm) lie within ``radius`` (mm) of one of the centres (m × 3)."""
    dist = np.linalg.norm(points[:, None, :] - centres[None, :, :], axis=2)
    return dist.min(axis=1) < radius


def surface_maxima(s, tree, torus: Torus, centres: np.ndarray, radius: float
                   ) -> tuple[tuple[float, ...], ...]:
    """Largest von Mises (MPa) over the fillet surface of the quarter (phi 0..π) inside the
    refined balls (within ``radius`` mm of a centre), of the cells' mean and of their
    largest value at each point: one 1° grid for both, then three finer grids around each
    one's best point. Outside the balls the mesh is the coarse outer one, whose surface
    values are not what the study measures. Returns ((mean, theta, phi), (largest, theta,
    phi), (grid points found in no cell, the largest mean on the 1° grid outside the balls
    or NaN))."""
    th, ph = np.meshgrid(np.radians(np.arange(0.0, 90.01, 1.0)), np.radians(np.arange(0.0, 180.01, 1.0)))
    th, ph = th.ravel(), ph.ravel()
    pts = torus.point(th, ph)
    inside = near(pts, centres, radius)
    largest, mean = von_mises_at(s, tree, pts)
    outside = float(np.nanmax(mean[~inside])) if np.any(~inside) and np.any(np.isfinite(mean[~inside])) else float("nan")
    missing = int(np.isnan(mean).sum())
    largest, mean = np.where(inside, largest, np.nan), np.where(inside, mean, np.nan)
    out = []
    for which, vals in ((1, mean), (0, largest)):
        i = int(np.nanargmax(vals))
        best = (float(vals[i]), float(th[i]), float(ph[i]))
        step = math.radians(1.0)
        for _ in range(3):
            T, P = np.meshgrid(np.clip(best[1] + step * np.linspace(-1, 1, 21), 0, math.pi / 2),
                               np.clip(best[2] + step * np.linspace(-1, 1, 21), 0, math.pi))
            fine_pts = torus.point(T.ravel(), P.ravel())
            fine = np.where(near(fine_pts, centres, radius), von_mises_at(s, tree, fine_pts)[which], np.nan)
            k = int(np.nanargmax(fine))
            if fine[k] > best[0]:
                best = (float(fine[k]), float(T.ravel()[k]), float(P.ravel()[k]))
            step /= 10
        out.append(best)
    return out[0], out[1], (missing, outside)


def fillet_gap(mesh, torus: Torus, d, centres: np.ndarray, radius: float) -> tuple[float, float]:
    """(min, max) over the boundary geometry nodes on the fillet within ``radius`` of one
    of the ``centres`` of their distance from the torus (mm): 0 where gmsh put them on the CAD
    surface; a mid-edge node pulled towards its chord lies inside the tube (< 0)."""
    from dolfinx import cpp
    from dolfinx.mesh import exterior_facet_indices
    from mpi4py import MPI
    mesh.topology.create_connectivity(2, 3)
    facets = exterior_facet_indices(mesh.topology)
    nodes = np.unique(cpp.mesh.entities_to_geometry(mesh._mesh, 2, facets, False).ravel())
    x = mesh.geometry.x[nodes]
    ra = np.hypot(x[:, 1], x[:, 2] - torus.zc)
    tol = 1e-3 * d.rf
    on = ((x[:, 0] > d.b1 / 2 + tol) & (x[:, 0] < d.b1 / 2 + d.rf - tol) & (ra > d.dj / 2 + tol)
          & (ra < d.dj / 2 + d.rf - tol) & (np.abs(x[:, 1]) > tol) & near(x, centres, radius))
    gap = torus.gap(x[on])
    lo = mesh.comm.allreduce(float(gap.min()) if len(gap) else np.inf, op=MPI.MIN)
    hi = mesh.comm.allreduce(float(gap.max()) if len(gap) else -np.inf, op=MPI.MAX)
    return lo, hi


def study_case(size: str, dims: dict[str, float]):
    """The part the study measures: hook number ``size`` with dimensions ``dims`` (mm)
    overriding its table row, at its rated load."""
    from pipeline.api import resolve_case as resolve
    return resolve(size=size, overrides={f"dims.{k}": v for k, v in dims.items()})


def run_point(order: int, h_ball: float, centres: tuple[tuple[float, float, float], ...], outer: float,
              radius: float, size: str = "05", dims: dict[str, float] | None = None,
              search_radius: float | None = None) -> dict:
    """Mesh with balls of size h_ball (mm) at the centres, solve Pk, measure the fillet
    peak inside them (within ``search_radius`` mm of a centre, default the balls' radius)."""
    from dolfinx import geometry
    from mpi4py import MPI

    from pipeline.api import LevelTask, Material, RunContext, make_mesh, peak, solve_level
    comm = MPI.COMM_WORLD
    # P4 is beyond the orders a case offers (the check refuses it); the study sets it directly.
    case = replace(study_case(size, dims or {}), order=order, solver="pmg", rtol=1e-10)
    d = case.dims
    torus = fillet_torus(d)
    # Sizes inside the mesher are multiplied by the factor: the ball's size is given per factor.
    spec = replace(case.mesh_spec(outer), hotspots=tuple(centres), size_hotspot=h_ball / outer,
                   hotspot_radius=radius)
    cs = np.array(centres, dtype=float).reshape(-1, 3)
    t0 = time.perf_counter()
    m = make_mesh(d, case.model, spec, comm=comm)
    t_mesh = time.perf_counter() - t0
    gap_min, gap_max = fillet_gap(m.mesh, torus, d, cs, radius)
    lv = solve_level(case, LevelTask(outer, keep_fields=True), RunContext(comm=comm), load_mesh=lambda: m)
    u, vm = lv.fields
    in_fillet = lambda p: (p[:, 0] > d.b1 / 2 - 0.5) & (p[:, 0] < d.b1 / 2 + d.rf + 0.5)  # noqa: E731
    nodal = peak(vm, in_fillet)
    s = von_mises_tensor_field(u, Material(E=case.E_MPa, nu=case.nu))
    tree = geometry.BoundingBoxTree(m.mesh, m.mesh.topology.dim)
    (value, theta, phi), (value_hi, theta_hi, phi_hi), (missing, outside) = surface_maxima(
        s, tree, torus, cs, radius if search_radius is None else search_radius)
    where = torus.at(theta, phi)
    return {"size": size, "dims_mm": dims or {},
            "order": order, "h_ball_mm": h_ball, "outer_factor": outer, "ball_radius_mm": radius,
            "ball_centre_mm": list(centres[0]), "ball_centres_mm": [list(c) for c in centres],
            "dofs": lv.dofs, "cells": lv.cells, "surface_peak_outside_balls_MPa": outside,
            "iterations": lv.iterations, "surface_peak_MPa": value, "surface_peak_cellmax_MPa": value_hi,
            "cellmax_theta_deg": math.degrees(theta_hi), "cellmax_phi_deg": math.degrees(phi_hi),
            "theta_deg": math.degrees(theta),
            "phi_deg": math.degrees(phi), "surface_peak_at_mm": list(where),
            "peak_from_centre_mm": float(np.linalg.norm(cs - np.array(where), axis=1).min()),
            "nodal_peak_MPa": nodal.value_MPa, "nodal_peak_at_mm": list(nodal.location_mm),
            "samples_outside_mesh": missing, "torus_gap_min_mm": gap_min, "torus_gap_max_mm": gap_max,
            "jacobian_ratio": m.jacobian_ratio, "time_mesh_s": t_mesh,
            "time_solve_s": lv.timings["assemble"] + lv.timings["solve"], "ranks": comm.size}


def richardson(h: list[float], f: list[float]) -> dict:
    """Limit of f(h) = f0 + C h^p from the last three levels of a sequence with a constant
    ratio: p = ln((f1−f2)/(f2−f3)) / ln(ratio); NaN when the differences change sign
    (not monotone: no order can be fitted) or do not shrink by an order of at least
    MIN_ORDER (equal steps give p = 0 and a limit at infinity: noise, not convergence)."""
    nan = {"order": float("nan"), "limit_MPa": float("nan"), "levels": 3}
    f1, f2, f3 = f[-3:]
    ratio = h[-3] / h[-2]
    e12, e23 = f1 - f2, f2 - f3
    if e12 == 0 or e23 == 0 or e12 * e23 < 0:
        return nan
    p = math.log(e12 / e23) / math.log(ratio)
    if p < MIN_ORDER:
        return dict(nan, order=p)
    limit = f3 - e23 / (ratio ** p - 1)
    return {"order": p, "limit_MPa": limit, "levels": 3}


def sequence_summary(seq: list[dict]) -> dict:
    """One order's sequence (coarsest first): its values, their range, the mean and spread
    of the finest three, and Richardson's limit where the last three are monotone."""
    h = [r["h_ball_mm"] for r in seq]
    f = [r["surface_peak_MPa"] for r in seq]
    fine = f[-3:]
    return {"h_mm": h, "surface_peak_MPa": f, "nodal_peak_MPa": [r["nodal_peak_MPa"] for r in seq],
            "dofs": [r["dofs"] for r in seq], "min_MPa": min(f), "max_MPa": max(f),
            "finest_three_mean_MPa": sum(fine) / 3, "finest_three_spread_MPa": max(fine) - min(fine),
            "richardson": richardson(h, f)}


def reference_value(fits: dict[int, dict], far_field: list[float] = ()) -> dict | None:
    """The reference (MPa): the mean of P3's finest three levels and of the far-field
    checks (the same ball on finer outer meshes); its band covers every P3 value, P4's mean
    (another order on the same meshes) and P3's Richardson limit when there is one. None
    without a P3 sequence."""
    if 3 not in fits:
        return None
    p3 = fits[3]
    core = p3["surface_peak_MPa"][-3:] + list(far_field)
    value = sum(core) / len(core)
    covered = p3["surface_peak_MPa"] + list(far_field)
    how = "mean of P3's finest three ball sizes"
    if far_field:
        how += " and of the finer far-field meshes"
    how += "; band covers every P3 value"
    if 4 in fits:
        covered.append(fits[4]["finest_three_mean_MPa"])
        how += " and P4's mean"
    lim = p3["richardson"]["limit_MPa"]
    if math.isfinite(lim):
        covered.append(lim)
        how += " and P3's Richardson limit"
    band = max(abs(v - value) for v in covered)
    return {"value_MPa": value, "band_MPa": band, "how": how}


def spawn(args: list[str], ranks: int) -> dict:
    """One point in its own process (on ``ranks`` MPI ranks); its JSON line back."""
    from bench.point import mpirun_prefix
    cmd = [*mpirun_prefix(ranks), sys.executable, "-m", "bench.fillet_reference", *args]
    out = subprocess.run(cmd, cwd=ROOT, env=dict(os.environ), capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"point {args} failed:\n{out.stderr[-2000:]}")
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("POINT ")][-1]
    return json.loads(line[len("POINT "):])


def _parser() -> argparse.ArgumentParser:
    """The study's options: where it writes, its ranks, the ball and outer mesh, the orders,
    and one point (--point, with --centre) for the process the study spawns per point."""
    p = argparse.ArgumentParser(prog="python -m bench.fillet_reference", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("results/fillet-reference"))
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--size", default="05", help="hook number (default 05)")
    p.add_argument("--dim", action="append", default=[], metavar="NAME=MM",
                   help="override one dimension of the size's row, mm (repeatable)")
    p.add_argument("--radius", type=float, help="ball radius, mm (default 2.5 × fillet_scale)")
    p.add_argument("--outer", type=float, default=OUTER_FACTOR)
    p.add_argument("--orders", default="2,3,4")
    p.add_argument("--point", nargs=2, metavar=("ORDER", "H_BALL"))
    p.add_argument("--centre", help="x,y,z of the ball (mm), or several x,y,z;x,y,z;...; "
                   "default: found by a P3 probe")
    p.add_argument("--ball-sizes", type=int, metavar="N",
                   help="only the N coarsest ball sizes of each order (default: all)")
    p.add_argument("--search-radius", type=float, metavar="MM",
                   help="one point: look for the peak within this distance of a centre (default: the ball radius)")
    p.add_argument("--crest", metavar="PHI0,PHI1,N",
                   help="N balls along the fillet's crest from PHI0 to PHI1 degrees around the journal "
                        "(0 straight down), at the probe's angle across the fillet, instead of one at "
                        "the probe's peak: for a crest broader than one ball")
    return p


def main(argv: list[str] | None = None) -> int:
    """The study (or, with --point, one of its points): the ball's centre, each order's
    sequence of ball sizes, the far-field checks, then reference.json and a summary."""
    a = _parser().parse_args(argv)
    dims = _parse_dims(a.dim)
    scale = _scale(a.size, dims)
    radius = a.radius if a.radius is not None else _scaled(BALL_RADIUS_MM, scale)
    if a.point:
        return _print_point(a, dims, radius)
    why = refusal(Path(a.out), OWN_FILES)
    if why is not None:
        sys.stderr.write(why + "\n")
        return 2
    study = _Study.open(a.out, radius=radius, ranks=a.ranks, size=a.size, dims=dims)
    centres = _ball_centres(study, a.centre, a.outer, a.crest)
    orders = [int(o) for o in a.orders.split(",")]
    rows = _sequences(study, orders, a.outer, centres, scale, a.ball_sizes)
    far_field = _far_field(study, orders, centres, scale)
    fits = _fits(rows, orders)
    ref = reference_value(fits, [r["surface_peak_MPa"] for r in far_field])
    _write_reference(study.out / "reference.json", centres, a.outer, radius, ref, far_field, fits, rows,
                     a.size, dims)
    for order, fit in fits.items():
        study.say(f"P{order}: finest three {fit['finest_three_mean_MPa']:.3f} MPa (spread {fit['finest_three_spread_MPa']:.3f}), "
                  f"all levels {fit['min_MPa']:.3f}..{fit['max_MPa']:.3f} MPa; Richardson {fit['richardson']}")
    if ref:
        study.say(f"reference: {ref['value_MPa']:.2f} ± {ref['band_MPa']:.2f} MPa "
                  f"({100 * ref['band_MPa'] / ref['value_MPa']:.2f} %), "
                  f"{ref['how']}")
    return 0


def _parse_dims(items: list[str]) -> dict[str, float]:
    """--dim NAME=MM options as a dict (mm)."""
    out = {}
    for item in items:
        name, _, value = item.partition("=")
        out[name.strip()] = float(value)
    return out


def _scale(size: str, dims: dict[str, float]) -> float:
    """How the ball's lengths scale for this part: rf / (0.06·h3), as the default path's
    refinement near the journal root (geometry.meshspec.fillet_scale)."""
    from geometry.meshspec import fillet_scale
    return fillet_scale(study_case(size, dims).dims)


Centres = tuple[tuple[float, float, float], ...]


def _parse_centres(text: str) -> Centres:
    """The ball centres x,y,z;x,y,z;... (mm) from their command-line form."""
    return tuple(tuple(float(c) for c in one.split(",")) for one in text.split(";") if one.strip())


def _print_point(a: argparse.Namespace, dims: dict[str, float], radius: float) -> int:
    """Solve the one point --point asks for and print its row as a ``POINT`` JSON line
    (rank 0): the line :func:`spawn` reads back."""
    r = run_point(int(a.point[0]), float(a.point[1]), _parse_centres(a.centre), a.outer, radius, a.size, dims,
                  search_radius=a.search_radius)
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        print("POINT " + json.dumps(r), flush=True)
    return 0


@dataclass
class _Study:
    """The study's folder and the rows of points.jsonl, which an interrupted or repeated
    study reuses instead of solving them again; progress lines are stamped with the
    seconds since ``started`` (perf_counter, s)."""

    out: Path
    radius: float   # the ball radius (mm) every point of this study uses
    ranks: int      # MPI ranks per point process
    done: list[dict]
    started: float
    size: str = "05"                                   # the part: hook number
    dims: dict[str, float] = field(default_factory=dict)  # and its dimensions overridden, mm

    @classmethod
    def open(cls, out: Path, radius: float, ranks: int, size: str = "05",
             dims: dict[str, float] | None = None) -> _Study:
        """Create ``out`` if needed and read the rows earlier runs left in points.jsonl."""
        out.mkdir(parents=True, exist_ok=True)
        log = out / "points.jsonl"
        done = [json.loads(ln) for ln in log.read_text().splitlines()] if log.exists() else []
        return cls(out=out, radius=radius, ranks=ranks, done=done, started=time.perf_counter(),
                   size=size, dims=dict(dims or {}))

    def say(self, msg: str) -> None:
        """One progress line, stamped with the study's elapsed time."""
        print(f"[{time.perf_counter() - self.started:8.1f} s] {msg}", flush=True)

    def point(self, order: int, h: float, outer: float, centres: Centres) -> tuple[dict, bool]:
        """The point's row: from points.jsonl when an earlier run made it, else solved now
        (in its own process) and appended there. Second: whether it was solved now."""
        for r in self.done:
            # Rows written before the study took other parts have no size: they are No. 05's.
            known = tuple(tuple(c) for c in r.get("ball_centres_mm", [r["ball_centre_mm"]]))
            if (r["order"], r["h_ball_mm"], r["outer_factor"], r["ball_radius_mm"], known,
                    r.get("size", "05"), r.get("dims_mm", {})) \
                    == (order, h, outer, self.radius, centres, self.size, self.dims):
                return r, False
        r = spawn(self.args(order, h, outer, centres), self.ranks)
        self.done.append(r)
        with (self.out / "points.jsonl").open("a") as f:
            f.write(json.dumps(r) + "\n")
        return r, True

    def args(self, order: int, h: float, outer: float, centres: Centres) -> list[str]:
        """The command line of this study's point process: order, ball size h (mm), ball
        centres (mm), outer mesh factor, and the study's ball radius (mm) and part."""
        return ["--point", str(order), str(h), "--centre", ";".join(",".join(map(str, c)) for c in centres),
                "--outer", str(outer), "--radius", str(self.radius), "--size", self.size,
                *[f"--dim={k}={v}" for k, v in sorted(self.dims.items())]]


def _ball_centres(study: _Study, given: str | None, outer: float, crest: str | None) -> Centres:
    """Where the balls go (mm): --centre when given, else the surface maximum of a P3
    solution on the unrefined mesh (a ball of the fillet's own size at a point of the
    fillet changes nothing there), or with ``crest`` (PHI0,PHI1,N in degrees) N points
    along the fillet at the probe's angle across it. The probe is not kept in
    points.jsonl: its centre is a guess, and it is cheap."""
    if given:
        return _parse_centres(given)
    case = study_case(study.size, study.dims)
    probe_centre = fillet_torus(case.dims).at(math.radians(45), math.radians(40))
    h0 = case.mesh_spec(outer).size_fillet * outer
    # The probe's "ball" covers the whole fillet, so its maximum is over all of it.
    # The probe looks for the peak over the whole fillet, not only inside its ball.
    probe = spawn([*study.args(3, h0, outer, (probe_centre,)), "--search-radius", "inf"], study.ranks)
    centre = tuple(probe["surface_peak_at_mm"])
    study.say(f"probe P3: surface peak {probe['surface_peak_MPa']:.2f} MPa at theta {probe['theta_deg']:.1f}°, "
              f"phi {probe['phi_deg']:.1f}° → ball centre ({centre[0]:.3f}, {centre[1]:.3f}, {centre[2]:.3f}) mm")
    if not crest:
        return (centre,)
    phi0, phi1, n = (float(v) for v in crest.split(","))
    torus = fillet_torus(case.dims)
    theta = math.radians(probe["theta_deg"])
    centres = tuple(torus.at(theta, math.radians(ph)) for ph in np.linspace(phi0, phi1, int(n)))
    study.say(f"{len(centres)} balls along the crest at theta {probe['theta_deg']:.1f}°, phi {phi0:g}..{phi1:g}°")
    return tuple(tuple(round(c, 6) for c in q) for q in centres)


def _sequences(study: _Study, orders: list[int], outer: float, centres: Centres,
               scale: float = 1.0, count: int | None = None) -> list[dict]:
    """Every order's rows over its ball sizes (ORDERS_AT × ``scale``, coarsest first; the
    ``count`` coarsest only, if given), the outer mesh fixed at ``outer``; a line for each
    point solved now."""
    rows = []
    for order in orders:
        for h in (_scaled(h0, scale) for h0 in ORDERS_AT[order][:count]):
            r, new = study.point(order, h, outer, centres)
            rows.append(r)
            if new:
                study.say(f"P{order} h {h:.3f} mm: {r['dofs']} DOFs, surface peak {r['surface_peak_MPa']:.3f} MPa "
                          f"(cell max {r['surface_peak_cellmax_MPa']:.3f}) "
                          f"(θ {r['theta_deg']:.1f}°, φ {r['phi_deg']:.1f}°), nodal {r['nodal_peak_MPa']:.3f} MPa, "
                          f"torus gap {r['torus_gap_min_mm']:.1e}..{r['torus_gap_max_mm']:.1e} mm, "
                          f"mesh {r['time_mesh_s']:.1f} s, solve {r['time_solve_s']:.1f} s; "
                          f"outside the balls {r['surface_peak_outside_balls_MPa']:.3f} MPa")
    return rows


def _scaled(h: float, scale: float) -> float:
    """A length of the ball (its element size or radius, mm) × scale, rounded to 1e-6 mm so
    that it reads back the same from points.jsonl (and No. 05's lengths stay 0.4, 2.5, ...)."""
    return round(h * scale, 6)


def _far_field(study: _Study, orders: list[int], centres: Centres, scale: float = 1.0) -> list[dict]:
    """The far field's share: the middle P3 level again with the finer meshes outside the
    ball of OUTER_CHECKS (none without P3); a line for each point solved now."""
    h_mid = _scaled(H_BALLS_MM[2], scale)
    far_field = []
    for outer in (OUTER_CHECKS if 3 in orders else ()):
        r, new = study.point(3, h_mid, outer, centres)
        far_field.append(r)
        if new:
            study.say(f"far field: P3 h {h_mid} mm with the outer mesh ×{outer}: {r['dofs']} DOFs, "
                      f"surface peak {r['surface_peak_MPa']:.3f} MPa, solve {r['time_solve_s']:.1f} s")
    return far_field


def _fits(rows: list[dict], orders: list[int]) -> dict[int, dict]:
    """Each order's sequence summary (coarsest ball first), for the orders with at least
    the three levels Richardson's extrapolation needs."""
    return {order: sequence_summary(sorted((r for r in rows if r["order"] == order), key=lambda r: -r["h_ball_mm"]))
            for order in orders if sum(r["order"] == order for r in rows) >= 3}


def _write_reference(path: Path, centres: Centres, outer: float, radius: float, ref: dict | None,
                     far_field: list[dict], fits: dict[int, dict], rows: list[dict], size: str = "05",
                     dims: dict[str, float] | None = None) -> None:
    """reference.json: the part (size, dimensions overridden, mm), the ball (centre and
    radius, mm), the outer mesh factor, the reference value, the far-field checks, each
    order's sequence and every point's row."""
    path.write_text(json.dumps({"size": size, "dims_mm": dims or {}, "centre_mm": centres[0],
                                "centres_mm": centres, "outer_factor": outer,
                                "ball_radius_mm": radius, "reference": ref,
                                "far_field": [{k: r[k] for k in ("outer_factor", "h_ball_mm", "dofs", "surface_peak_MPa")}
                                              for r in far_field],
                                "sequences": fits, "points": rows}, indent=1) + "\n")


if __name__ == "__main__":
    sys.exit(main())
