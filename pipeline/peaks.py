"""Post-processing: von Mises in a discontinuous space and its peaks (mm, MPa).

Peaks are taken over element-nodal values without averaging (docs/design.md §5): for P2
displacements the stress is interpolated into discontinuous P1, for Pk into DG(k−1).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from dolfinx import fem

from .elasticity import Material, von_mises_expr


@dataclass(frozen=True)
class Peak:
    """A peak von Mises stress (MPa) and where it sits ([x, y, z], mm)."""

    value_MPa: float
    location_mm: tuple[float, float, float]


def von_mises(u: fem.Function, mat: Material) -> fem.Function:
    """Von Mises stress (MPa) interpolated into DG(order−1) (DG0 for P1)."""
    mesh = u.function_space.mesh
    order = u.function_space.ufl_element().degree()
    W = fem.FunctionSpace(mesh, ("DG", max(order - 1, 0)))
    vm = fem.Function(W, name="von_mises_MPa")
    vm.interpolate(fem.Expression(von_mises_expr(u, mat), W.element.interpolation_points()))
    if not np.all(np.isfinite(vm.x.array)):
        from .errors import NumericalError
        raise NumericalError("the von Mises stress contains NaN or Inf")
    return vm


def _owned(vm: fem.Function, region: Callable[[np.ndarray], np.ndarray] | None
           ) -> tuple[np.ndarray, np.ndarray]:
    """This rank's owned values of vm (MPa) and their coordinates (mm) inside ``region``."""
    W = vm.function_space
    n_owned = W.dofmap.index_map.size_local * W.dofmap.index_map_bs
    xyz = W.tabulate_dof_coordinates()[:n_owned]
    vals = vm.x.array[:n_owned]
    if region is None:
        return vals, xyz
    mask = region(xyz)
    return vals[mask], xyz[mask]


def peak(vm: fem.Function, region: Callable[[np.ndarray], np.ndarray] | None = None) -> Peak:
    """Largest nodal value of vm over the DOFs whose coordinates satisfy ``region``.

    region takes an (n, 3) array of points (mm) and returns a boolean mask. Collective
    over MPI; every rank gets the same answer.
    """
    vals, xyz = _owned(vm, region)
    if len(vals):
        i = int(np.argmax(vals))
        local = (float(vals[i]), tuple(float(c) for c in xyz[i]))
    else:
        local = (-np.inf, (np.nan, np.nan, np.nan))
    all_peaks = vm.function_space.mesh.comm.allgather(local)
    # Ties broken by coordinates so the answer does not depend on the partition.
    best = max(all_peaks, key=lambda p: (p[0], p[1]))
    return Peak(value_MPa=best[0], location_mm=best[1])


def hot_spots(vm: fem.Function, threshold_MPa: float, separation_mm: float, limit: int,
              region: Callable[[np.ndarray], np.ndarray] | None = None) -> list[tuple[float, float, float]]:
    """Points (mm) over ``region`` where vm is at least threshold_MPa: the highest first, each
    at least separation_mm from those before, at most ``limit`` of them.

    On a coarse mesh the peak of one feature can swap with a nearly equal one elsewhere
    (the bore's top and bottom edges differ by ~1 %), so every near-peak place is kept.
    Collective over MPI; every rank gets the same list.
    """
    vals, xyz = _owned(vm, region)
    keep = vals >= threshold_MPa
    cand = vm.function_space.mesh.comm.allgather((vals[keep], xyz[keep]))
    v = np.concatenate([c[0] for c in cand])
    p = np.concatenate([c[1] for c in cand]).reshape(-1, 3)
    # Values rounded to 1e-6 of the threshold before ordering: 1 and 2 MPI ranks differ by
    # ~1e-9 (solver tolerance), and the greedy choice must not depend on that.
    vq = np.round(v / threshold_MPa, 6) if threshold_MPa > 0 else v
    chosen: list[np.ndarray] = []
    for i in np.lexsort((p[:, 2], p[:, 1], p[:, 0], -vq)):
        if len(chosen) == limit:
            break
        if all(np.linalg.norm(p[i] - q) >= separation_mm for q in chosen):
            chosen.append(p[i])
    return [tuple(float(c) for c in q) for q in chosen]
