"""Loads and supports of the crosshead (docs/design.md §3), in terms of pipeline.fe.solve (mm, N, MPa).

Seat: uniform pressure on the seat annulus, total Q down. Support "bearing": normal
pressure p0·cos θ on the lower half of each journal's bearing surface, resultant Q/2 up
per journal. Each pressure is scaled by its integral over the actual (faceted or curved)
mesh so the loads balance to round-off; the single vertical point constraint then
carries (numerically) nothing. Support "rigid": u_z = 0 on the lower journal halves.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from geometry.table import Dimensions

from pipeline.inputs.choices import SUPPORTS
from pipeline.fe.elasticity import Constraint, Traction
from pipeline.fe.meshing import ImportedMesh


@dataclass
class LoadCase:
    """Tractions and constraints for one model, with the resultants they carry (N)."""

    tractions: list[Traction]
    constraints: list[Constraint]
    seat_force_z_N: float
    support_force_z_N: float
    point_constraint_index: int | None  # index in constraints of the rigid-motion point(s)
    rigid_patch_index: int | None


def _integral(mesh, expr, ds_marker) -> float:
    value = fem.assemble_scalar(fem.form(expr * ds_marker))
    return mesh.comm.allreduce(value, op=MPI.SUM)


def crosshead_loads(m: ImportedMesh, d: Dimensions, load_N: float, support: str) -> LoadCase:
    """Seat pressure, journal support and rigid-motion constraints for model m.

    load_N is the total hook load Q on the whole part; the quarter model carries Q/4.
    """
    mesh = m.mesh
    share = 0.25 if m.model == "quarter" else 1.0
    q_part = load_N * share
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=m.facet_tags)
    seat_id, bearing_id = m.facet_ids["seat"], m.facet_ids["journal_bearing"]
    seat_t, seat_fz = _seat_traction(mesh, ds, seat_id, q_part)
    tractions = [Traction(seat_id, seat_t)]

    constraints: list[Constraint] = []
    if m.model == "quarter":
        constraints.append(Constraint(component=0, marker=m.facet_ids["symmetry_x"]))
        constraints.append(Constraint(component=1, marker=m.facet_ids["symmetry_y"]))
    rigid_idx = point_idx = None
    if support == "bearing":
        bearing_t, support_fz = _bearing_traction(mesh, ds, bearing_id, d, q_part)
        tractions.append(Traction(bearing_id, bearing_t))
        constraints += _point_supports(m, d)
        point_idx = len(constraints) - 1
    elif support == "rigid":
        constraints.append(Constraint(component=2, marker=bearing_id))
        rigid_idx = len(constraints) - 1
        support_fz = float("nan")  # known only after the solve, from the reaction
        if m.model == "full":
            constraints += _in_plane_point_constraints(m, d)
    else:
        raise ValueError(f"support must be one of {SUPPORTS}, got {support!r}")
    return LoadCase(tractions=tractions, constraints=constraints, seat_force_z_N=seat_fz,
                    support_force_z_N=support_fz, point_constraint_index=point_idx,
                    rigid_patch_index=rigid_idx)


def _seat_traction(mesh, ds: ufl.Measure, seat_id: int, q_part: float) -> tuple[ufl.core.expr.Expr, float]:
    """The seat's uniform pressure as a traction (MPa), p_s chosen so that its z-resultant
    over the mesh's own seat facets is -q_part (N); and that resultant (N)."""
    seat_area = _integral(mesh, fem.Constant(mesh, 1.0), ds(seat_id))
    # Pressures as fem.Constant, not Python floats: a float is baked into the form, so every
    # mesh (with its own scaled pressure) would get a new form and a fresh C compile.
    p_seat = fem.Constant(mesh, q_part / seat_area)
    seat_t = ufl.as_vector((0.0, 0.0, -p_seat))
    return seat_t, _integral(mesh, seat_t[2], ds(seat_id))


def _bearing_traction(mesh, ds: ufl.Measure, bearing_id: int, d: Dimensions,
                      q_part: float) -> tuple[ufl.core.expr.Expr, float]:
    """The journals' bearing pressure p0·cos θ on their lower halves as a traction (MPa),
    p0 chosen so that its z-resultant over the mesh's own bearing facets is q_part (N) up;
    and that resultant (N)."""
    n = ufl.FacetNormal(mesh)
    x = ufl.SpatialCoordinate(mesh)
    # cos θ with θ measured from straight down about the journal axis (y=0, z=h/2).
    zc = fem.Constant(mesh, d.h3 / 2)  # a Constant too: the form must not depend on the size
    r = ufl.sqrt(x[1] ** 2 + (x[2] - zc) ** 2)
    cos_t = ufl.max_value((zc - x[2]) / r, 0.0)
    shape = -cos_t * n  # traction per unit p0: -p n, pointing up on the lower half
    unit_fz = _integral(mesh, shape[2], ds(bearing_id))
    p0 = fem.Constant(mesh, q_part / unit_fz)
    bearing_t = p0 * shape
    return bearing_t, _integral(mesh, bearing_t[2], ds(bearing_id))


def _point_supports(m: ImportedMesh, d: Dimensions) -> list[Constraint]:
    """The point constraints that remove the rigid-body motion the bearing pressure leaves
    free; u_z at all points comes last (its reaction is the one equilibrium reports)."""
    pts, tol = m.constraint_points, 1e-6 * d.b6
    if m.model == "quarter":
        return [Constraint(component=2, points=pts, tol=tol)]
    # Statically determinate: u_x at (0, ±a, 0), u_y at (a, 0, 0), u_z at all three.
    return [*_in_plane_point_constraints(m, d), Constraint(component=2, points=pts, tol=tol)]


def _in_plane_point_constraints(m: ImportedMesh, d: Dimensions) -> list[Constraint]:
    """u_x at (0, ±a, 0) and u_y at (a, 0, 0) of the full part: they remove the rigid motion
    in the x-y plane (two translations and the turn about z), which the full part has no
    symmetry planes to fix."""
    pts, tol = m.constraint_points, 1e-6 * d.b6
    return [Constraint(component=0, points=pts[:2], tol=tol),
            Constraint(component=1, points=pts[2:], tol=tol)]


def equilibrium(lc: LoadCase, reactions: list[np.ndarray]) -> tuple[float, float, float]:
    """(support_force_z_N, equilibrium_error_N, constraint_reaction_N) after a solve.

    equilibrium_error_N = |seat resultant + support resultant| in z; constraint_reaction_N
    is the z-force the rigid-motion point constraint carries (should be ~0 for bearing).
    """
    support = lc.support_force_z_N
    if lc.rigid_patch_index is not None:
        support = float(reactions[lc.rigid_patch_index][2])
    point = 0.0
    if lc.point_constraint_index is not None:
        point = float(abs(reactions[lc.point_constraint_index][2]))
    return support, abs(lc.seat_force_z_N + support), point
