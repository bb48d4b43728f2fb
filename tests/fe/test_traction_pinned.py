"""The tractions the product applies (pipeline/fe/loads.py), sampled facet by facet on a
coarse No. 05 mesh and set against the closed forms of docs/design.md §3 (mm, N, MPa).

How a facet is sampled: with v the indicator of one cell (DG0), ∫ f v ds over the bearing
(or seat) facets is f's integral over that cell's loaded facets. For the product's traction
t and the facet normal n, p = −t·n is the normal pressure the product applies. Its ratio
to ∫ cos θ over the same facets (θ from straight down about the journal axis y = 0,
z = h3/2, measured from the facet's quadrature points) is the pressure's amplitude there:
the same number on every facet exactly when the pressure is proportional to cos θ, whatever
the mesh (the ratio of the integrals of two proportional functions). So the shape is checked
to round-off, and the amplitude against p0 from Q and the geometry to the faceting of the
curved surface, measured on the same mesh as its area against the cylinder's.

Closed forms, journal radius R = dj/2, bearing length L = b6/2 − b1/2 − rf (No. 05: 11 mm),
the lower half of the journal loaded, Q/2 per journal:
- cos θ: the vertical resultant is p0 R L ∫ cos² θ dθ over −π/2..π/2 = p0 R L π/2, so
  p0 = Q/(π R L) = 2Q/(π dj L); the quarter model's half journal (0 ≤ θ ≤ π/2) carries
  Q/4 and a sideways resultant −p0 R L/2, i.e. F_y/F_z = −2/π.
- uniform: p0 = (Q/2)/(dj L), the share over the projected area; F_y/F_z = −1 on the half.
- a band of length Lb: the same with L → Lb, the pressure inside p0·w(x) with w linear in x.
- the seat: p_s = Q / (π/4 (Do² − Di²)) straight down on the annulus Di..Do, its resultant
  at x̄ = ȳ = 4/(3π)·(ro³ − ri³)/(ro² − ri²) on the quarter.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.cpp.mesh import entities_to_geometry

from pipeline.fe.loads import crosshead_loads
from pipeline.fe.meshing import make_mesh
from pipeline.inputs.case import resolve

Q = 10_000.0  # N, No. 05's load
FACTOR = 3.0  # the coarse mesh of tests/fe/test_load_model.py: every check below is exact or scales with its faceting


@pytest.fixture(scope="module")
def meshes():
    """No. 05's quarter and full model on one coarse mesh each (about 1.3 s together)."""
    case = resolve("05", None, {"mesh_factor": FACTOR})
    return case, {model: make_mesh(case.dims, model, case.mesh_spec(FACTOR)) for model in ("quarter", "full")}


class Facets:
    """Per-cell integrals over the facets of one marker (DG0 test function: one entry per
    cell, zero for cells without such a facet), and each cell's x-extent over those facets."""

    def __init__(self, m, name: str):
        mesh = m.mesh
        self.mesh, self.marker = mesh, m.facet_ids[name]
        self.DG = fem.FunctionSpace(mesh, ("DG", 0))
        self.ds = ufl.Measure("ds", domain=mesh, subdomain_data=m.facet_tags)(self.marker)
        self.n, self.x = ufl.FacetNormal(mesh), ufl.SpatialCoordinate(mesh)
        self.area = self.integral(1.0)
        self.on = self.area > 0
        self.xmin, self.xmax = self._extent(m)

    def integral(self, f) -> np.ndarray:
        """∫ f over each cell's facets of the marker (one value per DG0 dof)."""
        v = ufl.TestFunction(self.DG)
        return fem.assemble_vector(fem.form(f * v * self.ds)).array.copy()

    def _extent(self, m) -> tuple[np.ndarray, np.ndarray]:
        """The smallest and largest x (mm) of each cell's marked facets' geometry nodes."""
        mesh = self.mesh
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        f2c = mesh.topology.connectivity(tdim - 1, tdim)
        facets = m.facet_tags.indices[m.facet_tags.values == self.marker]
        nodes = entities_to_geometry(getattr(mesh, "_mesh", mesh), tdim - 1, facets, False)  # the C++ mesh
        x = mesh.geometry.x[nodes][:, :, 0]
        n = len(self.area)
        lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
        cell_dofs = self.DG.dofmap.list.array
        for f, xs in zip(facets, x):
            dof = cell_dofs[f2c.links(f)[0]]
            lo[dof], hi[dof] = min(lo[dof], xs.min()), max(hi[dof], xs.max())
        return lo, hi


def cos_theta(fc: Facets, d):
    """cos θ of a point of the journal: θ from straight down about its axis (y = 0, z = h3/2)."""
    x, zc = fc.x, d.h3 / 2
    return (zc - x[2]) / ufl.sqrt(x[1] ** 2 + (x[2] - zc) ** 2)


def bearing(case, m, shape: str, length=None, centre=None):
    """The product's bearing traction (a UFL vector, MPa) and the band it was made for."""
    c = replace(case, model=m.model, bearing_shape=shape, bearing_length_mm=length, bearing_centre_mm=centre)
    band = c.bearing_band()
    lc = crosshead_loads(m, c.dims, Q, "bearing", shape=shape, band=band, order=2)
    t = next(tr.value for tr in lc.tractions if tr.marker == m.facet_ids["journal_bearing"])
    return t, band


def cylinder_area_error(fc: Facets, d, journals: float) -> float:
    """|mesh area / cylinder area − 1| of the loaded lower halves: the faceting of the curved
    surface, the scale of every amplitude's and resultant's error below (``journals``: 0.5
    for the quarter model's half journal, 2 for the full model's two)."""
    L = d.b6 / 2 - d.b1 / 2 - d.rf
    exact = journals * math.pi * d.dj / 2 * L
    return abs(fc.area.sum() / exact - 1.0)


def sides(fc: Facets, model: str):
    """The loaded cells of each journal: x > 0 and, on the full model, x < 0."""
    centre = fc.integral(fc.x[0]) / np.where(fc.on, fc.area, 1.0)
    return [fc.on & (centre > 0)] + ([fc.on & (centre < 0)] if model == "full" else [])


@pytest.mark.parametrize("model", ["quarter", "full"])
@pytest.mark.parametrize("shape", ["cosine", "uniform"])
def test_the_bearing_pressure_is_p0_cos_theta_or_p0_on_every_facet(meshes, model, shape):
    case, ms = meshes
    d, m = case.dims, ms[model]
    fc = Facets(m, "journal_bearing")
    t, band = bearing(case, m, shape)
    p = fc.integral(-ufl.dot(t, fc.n))
    weight = fc.integral(cos_theta(fc, d)) if shape == "cosine" else fc.area
    L = band.length_mm
    p0 = 2 * Q / (math.pi * d.dj * L) if shape == "cosine" else Q / 2 / (d.dj * L)
    faceting = cylinder_area_error(fc, d, 0.5 if model == "quarter" else 2.0)
    assert faceting < 1e-4  # the coarse P2 surface is within 1e-4 of the cylinder's area
    for on in sides(fc, model):
        amplitude = p[on] / weight[on]
        # Shape: one amplitude on every facet, to round-off (a pressure ∝ cos^1.2 θ would
        # spread it by tens of percent between θ = 0 and 90°).
        assert np.ptp(amplitude) <= 1e-9 * amplitude.mean()
        # Magnitude: p0 from Q and the geometry, to the faceting (the product scales p0 by
        # the mesh's own integral, which differs from the cylinder's by that much); 3× for
        # the integrand's weighting of the faceting error and its own quadrature.
        assert amplitude.mean() == pytest.approx(p0, rel=3 * faceting)


@pytest.mark.parametrize("model", ["quarter", "full"])
@pytest.mark.parametrize("shape", ["cosine", "uniform"])
def test_the_bearing_resultant_is_q_half_up_and_its_direction_the_shape_s(meshes, model, shape):
    """Resultant ∫ t ds: z-component Q/4 (quarter) or Q (full) up; no axial part (a normal
    pressure on a cylinder); sideways on the quarter's half journal F_y/F_z = −2/π (cos θ)
    or −1 (uniform), and nothing sideways on the full model's whole journals."""
    case, ms = meshes
    d, m = case.dims, ms[model]
    fc = Facets(m, "journal_bearing")
    t, _ = bearing(case, m, shape)
    F = [float(fem.assemble_scalar(fem.form(t[i] * fc.ds))) for i in range(3)]
    share = 0.25 if model == "quarter" else 1.0
    faceting = cylinder_area_error(fc, d, 0.5 if model == "quarter" else 2.0)
    assert F[2] == pytest.approx(share * Q, rel=1e-9)
    # A normal pressure on a cylinder has no axial part; on the mesh's facets, whose normals
    # tilt out of the cylinder's cross-section, at most max p · ∫ |n_x| ds (a bound from the
    # mesh's geometry alone).
    weight = fc.integral(cos_theta(fc, d)) if shape == "cosine" else fc.area  # p ≤ its amplitude: cos θ ≤ 1
    p_max = np.max(fc.integral(-ufl.dot(t, fc.n))[fc.on] / weight[fc.on])
    tilt = float(fem.assemble_scalar(fem.form(abs(fc.n[0]) * fc.ds)))
    assert abs(F[0]) <= p_max * tilt
    if model == "quarter":
        ratio = -2 / math.pi if shape == "cosine" else -1.0
        assert F[1] / F[2] == pytest.approx(ratio, rel=3 * faceting)
    else:
        assert abs(F[1]) <= 3 * faceting * F[2]


@pytest.mark.parametrize("shape", ["cosine", "uniform"])
@pytest.mark.parametrize("length, centre", [(8.0, 30.0), (5.0, 31.0)])
def test_a_band_is_the_shape_inside_nothing_outside_and_p0_of_its_length(meshes, shape, length, centre):
    """A band a ≤ x ≤ b (bearing_length_mm, bearing_centre_mm): on the facets wholly inside it
    the pressure is p0·w(x)·(cos θ or 1) with w linear in x (the product's tilt that puts the
    discrete resultant at the band's middle), exactly; on the facets wholly outside, none;
    and p0 = w's value at the middle lies between Q/4 over the inside facets' weighted area
    with and without the facets the band's ends cut (which the product samples at its
    quadrature points), i.e. the closed form 2Q/(π dj Lb) or (Q/2)/(dj Lb) to the cut."""
    case, ms = meshes
    d, m = case.dims, ms["quarter"]
    fc = Facets(m, "journal_bearing")
    t, band = bearing(case, m, shape, length, centre)
    p = fc.integral(-ufl.dot(t, fc.n))
    cos = cos_theta(fc, d) if shape == "cosine" else 1.0
    weight = fc.integral(cos)
    inside = fc.on & (fc.xmin >= band.start_mm) & (fc.xmax <= band.end_mm)
    outside = fc.on & ((fc.xmax <= band.start_mm) | (fc.xmin >= band.end_mm))
    cut = fc.on & ~inside & ~outside
    assert inside.sum() >= 4 and cut.any()  # four points over-determine the line's two
    assert np.all(p[outside] == 0.0)
    # Inside: the amplitude at the cos-weighted centroid x̄ of each facet is linear in x̄
    # (w is linear, so ∫ w cos / ∫ cos = w(x̄) exactly): residual at round-off.
    xbar = fc.integral(fc.x[0] * cos)[inside] / weight[inside]
    amplitude = p[inside] / weight[inside]
    A = np.column_stack([np.ones_like(xbar), xbar - band.centre_mm])
    (p0, slope), *_ = np.linalg.lstsq(A, amplitude, rcond=None)
    assert np.max(np.abs(A @ [p0, slope] - amplitude)) <= 1e-9 * p0
    # The tilt is a correction of the cut facets' sampling, not a second load model.
    assert abs(slope) * band.length_mm / 2 <= 0.05 * p0
    # p0 between the bounds the cut facets set: their weighted vertical area fully loaded
    # or fully unloaded (the product's resultant is Q/4, tests/fe/test_load_model.py).
    w = 1.0 + slope / p0 * (fc.x[0] - band.centre_mm)
    lift = fc.integral(-w * cos * fc.n[2])
    lo, hi = Q / 4 / lift[inside | cut].sum(), Q / 4 / lift[inside].sum()
    assert lo <= p0 <= hi
    closed = 2 * Q / (math.pi * d.dj * band.length_mm) if shape == "cosine" else Q / 2 / (d.dj * band.length_mm)
    assert lo <= closed * (1 + 1e-3) and closed * (1 - 1e-3) <= hi  # the closed form lies in the same bounds


@pytest.mark.parametrize("model", ["quarter", "full"])
def test_the_seat_pressure_is_q_over_the_annulus_straight_down(meshes, model):
    """Seat: (0, 0, −p_s) on every seat facet with p_s = Q/(π/4 (Do² − Di²)) (No. 05: Di = 25,
    Do = 37 mm, 17.11 MPa) to the faceting of the annulus' arcs; resultant −Q/4 (quarter) or
    −Q (full); on the quarter, at the quarter annulus' centroid x̄ = ȳ = 4/(3π)·(ro³ − ri³)/(ro² − ri²)."""
    case, ms = meshes
    d, m = case.dims, ms[model]
    lc = crosshead_loads(m, d, Q, "bearing")
    t = next(tr.value for tr in lc.tractions if tr.marker == m.facet_ids["seat"])
    fc = Facets(m, "seat")
    ri, ro = d.seat_inner / 2, d.seat_outer / 2
    share = 0.25 if model == "quarter" else 1.0
    annulus = share * math.pi * (ro ** 2 - ri ** 2)
    faceting = abs(fc.area.sum() / annulus - 1.0)
    assert faceting < 1e-4
    on = fc.on
    pressure = -fc.integral(t[2])[on] / fc.area[on]
    assert np.ptp(pressure) <= 1e-9 * pressure.mean()
    assert pressure.mean() == pytest.approx(Q / (math.pi / 4 * (d.seat_outer ** 2 - d.seat_inner ** 2)), rel=3 * faceting)
    for i in (0, 1):
        # ∫ (t_i + 1) − area, not ∫ t_i: a component that is exactly 0 makes an empty form.
        assert np.all(np.abs(fc.integral(t[i] + 1.0) - fc.area) <= 1e-12 * Q)
    Fz = float(fem.assemble_scalar(fem.form(t[2] * fc.ds)))
    assert Fz == pytest.approx(-share * Q, rel=1e-9)
    assert lc.seat_force_z_N == pytest.approx(-share * Q, rel=1e-9)
    if model == "quarter":
        centroid = 4 / (3 * math.pi) * (ro ** 3 - ri ** 3) / (ro ** 2 - ri ** 2)
        for i in (0, 1):
            lever = float(fem.assemble_scalar(fem.form(t[2] * fc.x[i] * fc.ds))) / Fz
            assert lever == pytest.approx(centroid, rel=3 * faceting)
