"""Loads and supports of the crosshead (docs/design.md §3), in terms of pipeline.fe.solve (mm, N, MPa).

Seat: uniform pressure on the seat annulus, total Q down. Support "bearing": normal
pressure on the lower half of each journal's bearing surface, p0·cos θ (shape "cosine")
or p0 (shape "uniform"), resultant Q/2 up per journal, over the whole bearing surface or
over a band of it along the journal axis (the side plate's thickness and position). Each
pressure is scaled by its integral over the actual (faceted or curved) mesh so the loads
balance to round-off; the single vertical point constraint then carries (numerically)
nothing. Support "rigid": u_z = 0 on the lower journal halves.

A band is a window on the journal's existing bearing facets (an indicator of the axial
coordinate at the quadrature points), so the mesh and the stiffness matrix do not depend
on the load model: only the right-hand side does.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from geometry.table import Dimensions, model_share

from pipeline.inputs.case import BearingBand
from pipeline.inputs.choices import BEARING_SHAPES, SUPPORTS
from pipeline.errors import NumericalError
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


def crosshead_loads(m: ImportedMesh, d: Dimensions, load_N: float, support: str,
                    shape: str = "cosine", band: BearingBand | None = None, order: int = 2) -> LoadCase:
    """Seat pressure, journal support and rigid-motion constraints for model m.

    load_N is the total hook load Q on the whole part; the quarter model carries Q/4.
    ``shape`` and ``band`` (mm along x; None: the whole bearing surface) are the bearing
    pressure's, support "bearing" only; ``order`` is the displacement's element order, whose
    load vector a band is balanced on.
    """
    mesh = m.mesh
    share = model_share(m.model)
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
        if shape not in BEARING_SHAPES:
            raise ValueError(f"bearing shape must be one of {BEARING_SHAPES}, got {shape!r}")
        if band is None or band.whole:
            bearing_t, support_fz = _bearing_traction(mesh, ds, bearing_id, d, q_part, shape,
                                                      both_journals=m.model == "full")
        else:
            bearing_t, support_fz = _band_traction(m, ds, d, q_part, shape, band, order)
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


def _unit_pressure(mesh, d: Dimensions, shape: str) -> ufl.core.expr.Expr:
    """The bearing traction per unit p0 (a UFL vector): −p n on the lower half of the
    journal, p = cos θ (θ from straight down about the journal axis y = 0, z = h/2) or 1."""
    n = ufl.FacetNormal(mesh)
    if shape == "uniform":
        # The journal_bearing facets are the lower half already: a constant normal pressure,
        # whose vertical part per unit projected area (dj × length) is p0 everywhere.
        return -n
    x = ufl.SpatialCoordinate(mesh)
    zc = fem.Constant(mesh, d.h3 / 2)  # a Constant too: the form must not depend on the size
    r = ufl.sqrt(x[1] ** 2 + (x[2] - zc) ** 2)
    cos_t = ufl.max_value((zc - x[2]) / r, 0.0)
    return -cos_t * n  # pointing up on the lower half


def _bearing_traction(mesh, ds: ufl.Measure, bearing_id: int, d: Dimensions, q_part: float,
                      shape: str = "cosine", both_journals: bool = False) -> tuple[ufl.core.expr.Expr, float]:
    """The journals' bearing pressure (``shape``) on the whole of their lower halves as a
    traction (MPa), p0 chosen so that its z-resultant over the mesh's own bearing facets is
    q_part (N) up, and with ``both_journals`` (the full model) q_part/2 on each: a mesh that
    is not mirror-symmetric would otherwise load one journal more, by about 1e-6 of Q/2
    with the default mesh. Returns the traction and its resultant (N)."""
    unit = _unit_pressure(mesh, d, shape)
    if not both_journals:
        unit_fz = _integral(mesh, unit[2], ds(bearing_id))
        p0 = fem.Constant(mesh, q_part / unit_fz)
        bearing_t = p0 * unit
        return bearing_t, _integral(mesh, bearing_t[2], ds(bearing_id))
    x = ufl.SpatialCoordinate(mesh)
    terms = []
    for side in (ufl.gt(x[0], 0.0), ufl.lt(x[0], 0.0)):
        on_side = ufl.conditional(side, 1.0, 0.0) * unit  # no bearing facet reaches x = 0
        p0 = fem.Constant(mesh, q_part / 2 / _integral(mesh, on_side[2], ds(bearing_id)))
        terms.append(p0 * on_side)
    bearing_t = terms[0] + terms[1]
    return bearing_t, _integral(mesh, bearing_t[2], ds(bearing_id))


def _band_traction(m: ImportedMesh, ds: ufl.Measure, d: Dimensions, q_part: float, shape: str,
                   band: BearingBand, order: int) -> tuple[ufl.core.expr.Expr, float]:
    """The bearing pressure on the band a ≤ |x| ≤ b of each journal of mesh m as a traction
    (MPa), and its z-resultant (N): q_part up, half on each journal of the full model.

    The band cuts facets, and an indicator of x at the quadrature points puts the discrete
    resultant neither at exactly the wanted force nor at the band's middle c. So each
    journal's pressure is p0·w(x)·(its shape) with w = 1 + β (|x| − c), and p0 and β are
    fitted on the load vector itself (the displacement's space, the solve's quadrature):
    its z-forces sum to the journal's share, and their moment about x = c vanishes. The
    section moments then are exactly those of a load at c (docs/design.md §3). p0 and β
    are Constants, so the form, and its quadrature, is the same whatever their values: the
    load vector is linear in them, and two assemblies give every coefficient."""
    mesh, bearing_id, both_journals = m.mesh, m.facet_ids["journal_bearing"], m.model == "full"
    x = ufl.SpatialCoordinate(mesh)
    a, b, c = (fem.Constant(mesh, v) for v in (band.start_mm, band.end_mm, band.centre_mm))
    unit = _unit_pressure(mesh, d, shape)
    sides = (1.0, -1.0) if both_journals else (1.0,)  # the journals at x > 0 and x < 0
    p0 = [fem.Constant(mesh, 0.0) for _ in sides]
    beta = [fem.Constant(mesh, 0.0) for _ in sides]
    terms = []
    for s_, p, bt in zip(sides, p0, beta):
        xs = s_ * x[0]  # the distance from x = 0 along this journal
        inside = ufl.conditional(ufl.And(ufl.ge(xs, a), ufl.le(xs, b)), 1.0, 0.0)
        terms.append(p * inside * (1.0 + bt * (xs - c)) * unit)
    traction = sum(terms[1:], terms[0])
    V = fem.VectorFunctionSpace(mesh, ("Lagrange", order))
    v = ufl.TestFunction(V)
    form = fem.form(ufl.inner(traction, v) * ds(bearing_id))
    xdof = V.tabulate_dof_coordinates()[:V.dofmap.index_map.size_local, 0]

    def z_force_and_moment() -> np.ndarray:
        """Per journal: Σ f_z (N) and Σ f_z (|x| − c) (N·mm) of the load vector as it stands."""
        f = assemble_vector(form)
        f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fz = f.array_r[2::3][:len(xdof)]
        f.destroy()
        out = []
        for s_ in sides:
            on = s_ * xdof > 0
            out += [fz[on].sum(), np.dot(fz[on], s_ * xdof[on] - band.centre_mm)]
        return mesh.comm.allreduce(np.array(out), op=MPI.SUM)

    for p in p0:
        p.value = 1.0
    plain = z_force_and_moment()  # w = 1
    for bt in beta:
        bt.value = 1.0
    tilted = z_force_and_moment() - plain  # the part β multiplies
    share = q_part / len(sides)
    for i, (p, bt) in enumerate(zip(p0, beta)):
        F0, M0, F1, M1 = plain[2 * i], plain[2 * i + 1], tilted[2 * i], tilted[2 * i + 1]
        if not (F0 > 0 and M1 > 0):
            raise NumericalError(f"bearing: the band {band.start_mm:g} to {band.end_mm:g} mm holds no part of the "
                                 "journal's mesh; give a longer --bearing-length or a finer mesh")
        bt.value = -M0 / M1
        # The weight must stay a pressure (w > 0 over the band): a band only a facet or two
        # wide would need a pull at one end to put its resultant at c.
        if min(1.0 + bt.value * (band.start_mm - band.centre_mm), 1.0 + bt.value * (band.end_mm - band.centre_mm)) <= 0:
            raise NumericalError(f"bearing: the band {band.start_mm:g} to {band.end_mm:g} mm is too narrow for this "
                                 "mesh to carry its load at the band's middle; give a longer --bearing-length or a "
                                 "finer mesh")
        p.value = share / (F0 + bt.value * F1)
    # The resultant the solve's load vector carries (N): the fitted constants applied.
    return traction, float(z_force_and_moment()[0::2].sum())


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
