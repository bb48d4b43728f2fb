"""Section results: what the FE field says about the quantities the hand formulas compute.

The formulas (docs/design.md §4) give a *nominal* stress in the ligaments beside the bore:
beam bending over the height (approximate method) and curved-bar bending across the
ligament's width (exact method). Here the FE solution gives the same quantities:

- the section force N (N) and bending moment M (N·mm) on the critical section, the plane
  x = 0 over both ligaments (|y| from di/2 to b1/2, full height), taken from the reactions
  of the symmetry plane (R = K u − f at its constrained DOFs). That is exact for the
  discrete solution: the moment equals the statics of the applied loads to solver
  tolerance, where integrating the element stresses over the facets would carry their
  discretisation error;
- the linearised membrane and membrane-plus-bending stress of σ_xx along lines through
  the section (ASME-style stress linearisation): over the height at the bore edge and at
  mid-ligament (the approximate method's stress), and across the ligament width at
  mid-height (the exact method's stress);
- the journal's nominal bending stress at its root (the plane x = b1/2) and the fillet's
  concentration factor Kt = global peak / nominal, with Peterson's chart value for a
  shouldered round bar in bending beside it;
- for each hand formula, the same section quantities under that formula's own journal
  load position (:func:`formula_load_sections`), so that formula and FE differ in their
  theory only, not in where the load sits.

Sign convention: σ_xx > 0 in tension; M = ∫ σ_xx (z − h/2) dA, so a crosshead sagging
under its load (bottom in tension) has M < 0. Units: mm, N, MPa.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from dolfinx import fem, geometry
from mpi4py import MPI

from geometry.table import Dimensions, model_share
from pipeline.fe.elasticity import Material, stress
from pipeline.fe.solve import Solution
from pipeline.inputs.case import Case

LINE_POINTS = 81  # samples along a linearisation line (Simpson's rule needs an odd count)


@dataclass(frozen=True)
class Linearised:
    """σ_xx along a line through a section (MPa): membrane, bending (at the line's start),
    their sum there, and the sampled profile (position along the line, mm; σ_xx, MPa)."""

    membrane_MPa: float
    bending_MPa: float
    membrane_plus_bending_MPa: float
    peak_on_line_MPa: float
    position_mm: list[float]
    sigma_xx_MPa: list[float]


def linearise(s: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """(membrane, bending) of a profile s(t), t from 0 to L (mm): the mean, and the linear
    part's value at t = 0: σ_m = (1/L)∫s dt, σ_b = (6/L²)∫ s (L/2 − t) dt. Exact for a
    linear profile (Simpson's rule on equally spaced points)."""
    L = float(t[-1] - t[0])
    tt = t - t[0]
    w = np.ones(len(t))
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    dt = L / (len(t) - 1)
    integral = lambda f: float(dt / 3 * np.dot(w, f))  # noqa: E731
    return integral(s) / L, 6.0 / L ** 2 * integral(s * (L / 2 - tt))


@dataclass
class SigmaXX:
    """σ_xx (MPa) of a solution in the discontinuous space of the peaks, with the search
    tree to evaluate it at points: made once for all the lines of a section."""

    field: fem.Function
    tree: object


def sigma_xx_field(u: fem.Function, mat: Material) -> SigmaXX:
    mesh = u.function_space.mesh
    order = u.function_space.ufl_element().degree()
    W = fem.FunctionSpace(mesh, ("DG", max(order - 1, 0)))
    sxx = fem.Function(W)
    sxx.interpolate(fem.Expression(stress(u, mat)[0, 0], W.element.interpolation_points()))
    return SigmaXX(sxx, geometry.BoundingBoxTree(mesh, mesh.topology.dim))


def sigma_xx_at(s: SigmaXX, points: np.ndarray) -> np.ndarray:
    """σ_xx (MPa) at ``points`` (n × 3, mm). Collective; every rank gets all values.

    A curved cell whose hull holds a point need not hold the point itself, and then
    DOLFINx's pull-back into it fails (RuntimeError, Newton's method): the value comes
    from the next cell that holds the point, or stays NaN. The error is never raised, so
    that no rank leaves the collective below while the others wait in it."""
    sxx, mesh = s.field, s.field.function_space.mesh
    cells = geometry.compute_colliding_cells(mesh, geometry.compute_collisions(s.tree, points), points)
    local = np.full(len(points), np.nan)
    for i in range(len(points)):
        for cell in cells.links(i):
            try:
                local[i] = sxx.eval(points[i], np.array([cell], dtype=np.int32))[0]
                break
            except RuntimeError:
                continue
    found = mesh.comm.allgather(local)
    values = np.full(len(points), np.nan)
    for part in found:  # the first rank that holds a point gives its value
        values = np.where(np.isnan(values), part, values)
    return values


def linearised_line(sxx: SigmaXX, start: np.ndarray, end: np.ndarray) -> Linearised:
    """σ_xx sampled from ``start`` to ``end`` (mm) and linearised (:func:`linearise`)."""
    t = np.linspace(0.0, float(np.linalg.norm(end - start)), LINE_POINTS)
    pts = start + np.outer(t / t[-1], end - start)
    s = sigma_xx_at(sxx, pts)
    m, b = linearise(s, t)
    return Linearised(membrane_MPa=m, bending_MPa=b, membrane_plus_bending_MPa=m + b,
                      peak_on_line_MPa=float(np.max(np.abs(s))),
                      position_mm=[float(v) for v in t], sigma_xx_MPa=[float(v) for v in s])


def plane_resultants(sol: Solution, constraint: int, lever_axis: int, centre_mm: float,
                     outward_sign: float = -1.0) -> tuple[float, float]:
    """(N in N, M in N·mm) carried across a constrained plane normal to x: from the x-part of
    the reactions of ``constraint``, N = Σ σ_xx dA and M = Σ σ_xx (c − centre) dA with c the
    coordinate ``lever_axis`` (1 = y, 2 = z). The reaction is the force the constraint puts
    on the body; the section force is its opposite when the body lies on the +x side
    (``outward_sign`` −1: outward normal −x), itself when on the −x side."""
    V = sol.u.function_space
    dofs = sol.bc_dofs[constraint]
    n_owned = len(sol.reaction)
    dofs = dofs[(dofs < n_owned) & (dofs % 3 == 0)]
    c = V.tabulate_dof_coordinates()[dofs // 3, lever_axis]
    R = sol.reaction[dofs]
    comm = V.mesh.comm
    n_loc, m_loc = outward_sign * float(R.sum()), outward_sign * float(np.dot(R, c - centre_mm))
    return comm.allreduce(n_loc, op=MPI.SUM), comm.allreduce(m_loc, op=MPI.SUM)


def ligament_resultants(sol: Solution, symmetry_x: int, d: Dimensions, share: float) -> tuple[float, float]:
    """(N in N, M in N·mm) on the whole critical section x = 0 (both ligaments), from the
    reactions of constraint ``symmetry_x`` (u_x = 0 on x = 0) of a model carrying ``share``
    of the part (a quarter holds half the section: y >= 0)."""
    N, M = plane_resultants(sol, symmetry_x, lever_axis=2, centre_mm=d.h3 / 2)
    halves = 2.0 if share == 0.25 else 1.0
    return halves * N, halves * M


def journal_nominal(d: Dimensions, load_N: float, bearing_centre_mm: float | None = None) -> tuple[float, float]:
    """(M in N·mm, σ in MPa): the journal's bending moment at its root x = b1/2 from the
    support resultant Q/2 at the bearing band's middle ``bearing_centre_mm`` (mm from x = 0;
    None: the middle of the whole bearing surface, b1/2 + rf to b6/2), and 32 M / (π dj³)."""
    centre = (d.b1 / 2 + d.rf + d.b6 / 2) / 2 if bearing_centre_mm is None else bearing_centre_mm
    lever = centre - d.b1 / 2
    M = load_N / 2 * lever
    return M, 32.0 * M / (math.pi * d.dj ** 3)


def peterson_kt_bending(D: float, d: float, r: float) -> float:
    """Kt of a stepped round bar in bending with a shoulder fillet (Peterson's chart,
    as fitted in Pilkey & Pilkey, *Peterson's Stress Concentration Factors*, 3rd ed.,
    chart 3.10: Kt = C1 + C2 (2t/D) + C3 (2t/D)² + C4 (2t/D)³, t = (D − d)/2, valid for
    0.1 ≤ t/r ≤ 20). Nominal stress: 32 M / (π d³)."""
    t = (D - d) / 2
    q = t / r
    if not 0.1 <= q <= 20:
        raise ValueError(f"Peterson's fit holds for 0.1 <= t/r <= 20, got {q:.3g}")
    s = math.sqrt(q)
    if q <= 2.0:
        c = (0.947 + 1.206 * s - 0.131 * q, 0.022 - 3.405 * s + 0.915 * q,
             0.869 + 1.777 * s - 0.555 * q, -0.810 + 0.422 * s - 0.260 * q)
    else:
        c = (1.232 + 0.832 * s - 0.008 * q, -3.813 + 0.968 * s - 0.260 * q,
             7.423 - 4.868 * s + 0.869 * q, -3.839 + 3.070 * s - 0.600 * q)
    x = 2 * t / D
    return c[0] + c[1] * x + c[2] * x ** 2 + c[3] * x ** 3


def ligament_sections(sol: Solution, mat: Material, d: Dimensions, share: float, symmetry_x: int | None) -> dict:
    """The critical section's resultants and nominal stress (quarter model: ``symmetry_x``
    the constraint of x = 0, else None) and the linearised lines through the ligament, as
    results.json blocks (N, N·mm, MPa, mm)."""
    u = sol.u
    w, h = d.b1 - d.d2, d.h3  # both ligaments' width, and the height
    eps = 1e-7 * d.b6  # start lines just inside the part
    lig_mid = (d.d2 / 2 + d.b1 / 2) / 2
    sxx = sigma_xx_field(u, mat)
    lines = {
        "bore_edge_height": linearised_line(sxx, np.array([eps, d.d2 / 2 + eps, eps]),
                                  np.array([eps, d.d2 / 2 + eps, h - eps])),
        "mid_ligament_height": linearised_line(sxx, np.array([eps, lig_mid, eps]), np.array([eps, lig_mid, h - eps])),
        "ligament_width_mid_height": linearised_line(sxx, np.array([eps, d.d2 / 2 + eps, h / 2]),
                                           np.array([eps, d.b1 / 2 - eps, h / 2])),
    }
    out: dict = {"lines": {k: asdict(v) for k, v in lines.items()}}
    if symmetry_x is not None:
        N, M = ligament_resultants(sol, symmetry_x, d, share)
        out["critical_section"] = {
            "N_N": N, "M_Nmm": M, "width_mm": w, "height_mm": h,
            "membrane_MPa": N / (w * h), "bending_MPa": 6.0 * abs(M) / (w * h ** 2),
            "nominal_MPa": N / (w * h) + 6.0 * abs(M) / (w * h ** 2),
            "method": "reactions of the symmetry plane x = 0 (exact for the discrete solution)"}
    return out


def section_results(sol: Solution, mat: Material, case: Case, symmetry_x: int | None, global_peak_MPa: float) -> dict:
    """Everything above for one solved mesh of ``case`` (its part, load, model and journal
    load's centre), as a results.json block (docs/design.md §7); ``symmetry_x``: the index
    of the symmetry plane x = 0's constraint (None: the full model)."""
    d, centre = case.dims, case.bearing_band().centre_mm
    out = ligament_sections(sol, mat, d, model_share(case.model), symmetry_x)
    Mj, s_nom = journal_nominal(d, case.load_N, centre)
    root: dict = {"M_Nmm": Mj, "nominal_MPa": s_nom, "Kt": global_peak_MPa / s_nom, "load_at_mm": centre}
    if d.rf > 0:
        try:
            root["Kt_peterson"] = peterson_kt_bending(D=d.h3, d=d.dj, r=d.rf)
            root["peterson_note"] = (
                f"Peterson's shouldered round bar in bending with D = h3 = {d.h3:g} mm, d = dj = "
                f"{d.dj:g} mm, r = rf = {d.rf:g} mm; the real shoulder is the rectangular body "
                f"({d.b1:g} mm wide, {d.h3:g} mm high), stiffer than a round shoulder of diameter h3, "
                "and the journal is loaded by a distributed bearing pressure, not a pure moment: "
                "a plausibility check, not a prediction")
        except ValueError as exc:
            root["peterson_note"] = str(exc)
    out["journal_root"] = root
    return out


# The FE figure beside each formula: the nominal stress of the section x = 0 from its force
# and moment (the quarter model's symmetry-plane reactions), or on the full model, which has
# no such plane, σ_xx over the height at mid-ligament, linearised.
NOMINAL_QUANTITY = "FE nominal stress of the section x = 0, N/(w·h) + 6|M|/(w·h²), from the symmetry plane's reactions"
LINE_QUANTITY = "FE σ_xx over the height at mid-ligament, x = 0, linearised: membrane + bending"


@dataclass(frozen=True)
class FormulaLoad:
    """A hand formula (``which``) at its own load position: its stress at its own span and
    at the FE load's position (MPa), the band the FE load was put on and the formula's own
    position (mm from x = 0)."""

    which: str
    formula_MPa: float
    formula_at_fe_load_MPa: float
    band_mm: tuple[float, float]
    own_position_mm: float


def formula_load_sections(sol: Solution, mat: Material, case: Case, symmetry_x: int | None,
                          formula: FormulaLoad) -> dict:
    """One formula's row of the like-with-like table (MPa, N, N·mm, mm): the FE section
    quantities of ``sol``, solved with the journal load on the formula's band (as near as
    the journal allows to the formula's own position), beside the formula at its own span
    and at the FE load's position (2 × the band's middle). The FE figure is of the beam's
    kind for both formulas: the exact formula's curved bar is another theory of the same
    section, which is what the row shows."""
    which, formula_MPa, formula_at_fe_load_MPa = formula.which, formula.formula_MPa, formula.formula_at_fe_load_MPa
    band_mm, own_position_mm = formula.band_mm, formula.own_position_mm
    full = ligament_sections(sol, mat, case.dims, model_share(case.model), symmetry_x)
    lines = {k: {q: v[q] for q in ("membrane_MPa", "bending_MPa", "membrane_plus_bending_MPa", "peak_on_line_MPa")}
             for k, v in full["lines"].items()}
    cs = full.get("critical_section")
    fe, quantity = ((cs["nominal_MPa"], NOMINAL_QUANTITY) if cs is not None else
                    (lines["mid_ligament_height"]["membrane_plus_bending_MPa"], LINE_QUANTITY))
    out = {"formula": which, "formula_MPa": formula_MPa, "formula_load_at_mm": own_position_mm,
           "fe_load_band_mm": list(band_mm), "fe_load_at_mm": (band_mm[0] + band_mm[1]) / 2,
           "formula_at_fe_load_MPa": formula_at_fe_load_MPa,
           "fe_MPa": fe, "fe_quantity": quantity, "lines": lines}
    if "critical_section" in full:
        out["critical_section"] = {k: v for k, v in full["critical_section"].items() if k != "method"}
    return out
