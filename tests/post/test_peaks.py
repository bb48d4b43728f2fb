"""The two nodal readings of a peak (pipeline/post/peaks.py) and the error bar of their midpoint
(pipeline/post/errorbar.py), against closed forms (mm, MPa).

A quadratic displacement has a linear stress field, which P2 (and P3) reproduce exactly in
every element: the unaveraged and the averaged nodal stresses then both equal the closed
form at every node, and their peaks equal its maximum. A wrong pairing of the DG and CG
nodes of a cell, or counting a node's cells wrongly, breaks that equality.
"""
from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem
from dolfinx.mesh import CellType, create_box
from mpi4py import MPI

import pipeline.fe.elasticity as pe
import pipeline.post.peaks as pp
from pipeline.post.errorbar import Estimate, with_bracket

MAT = pe.Material(E=210_000.0, nu=0.3)
MU, LAM = MAT.lame
A = 1e-3  # 1/mm: displacement gradient scale


def displacement(x: np.ndarray) -> np.ndarray:
    """u (mm) = A·(x² + y·z, x·y, z² − x·z) on points x (3, n)."""
    return A * np.vstack([x[0] ** 2 + x[1] * x[2], x[0] * x[1], x[2] ** 2 - x[0] * x[2]])


def von_mises_exact(p: np.ndarray) -> np.ndarray:
    """Closed-form von Mises (MPa) of :func:`displacement` at points p (n, 3)."""
    x, y, z = p.T
    g = np.zeros((len(p), 3, 3))           # grad u / A: row i = d u_i / d(x, y, z)
    g[:, 0] = np.column_stack([2 * x, z, y])
    g[:, 1] = np.column_stack([y, x, 0 * x])
    g[:, 2] = np.column_stack([-z, 0 * x, 2 * z - x])
    eps = 0.5 * A * (g + g.transpose(0, 2, 1))
    tr = np.trace(eps, axis1=1, axis2=2)
    s = 2 * MU * eps + LAM * tr[:, None, None] * np.eye(3)
    dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))


@pytest.mark.parametrize("order", [2, 3])
def test_linear_stress_both_readings_exact(order):
    """At every node both readings equal the closed form, so the reported value does, and
    the peak is the closed form's maximum, at a corner of the box."""
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.5])], [4, 3, 3],
                      CellType.tetrahedron)
    V = fem.VectorFunctionSpace(mesh, ("CG", order))
    u = fem.Function(V)
    u.interpolate(displacement)
    r = pp.node_readings(u, MAT, lambda xyz: xyz[:, 0] > 1.0)   # the midpoint on half the box
    exact = von_mises_exact(r.xyz)
    for values in (r.averaged, r.unaveraged, r.reported):
        assert np.max(np.abs(values - exact)) <= 1e-9 * np.max(exact)
    both = pp.node_peak(r)
    corners = np.array([[i, j, k] for i in (0, 2.0) for j in (0, 1.0) for k in (0, 1.5)])
    top = von_mises_exact(corners).max()   # a convex function of a linear field peaks at a corner
    assert both.unaveraged.value_MPa == pytest.approx(top, rel=1e-9)
    assert both.averaged.value_MPa == pytest.approx(top, rel=1e-9)
    assert both.half_width_MPa <= 1e-9 * top
    assert np.any(np.all(np.isclose(corners, both.location_mm), axis=1))


def test_jump_between_elements_is_averaged():
    """u_x = A·max(x − 1, 0) on a mesh with a layer of vertices at x = 1: the stress is zero
    on x < 1 and constant on x > 1, exactly in every P2 element. A node inside either side
    reads that side's value both ways; a node on x = 1 has cells of both sides, so its
    unaveraged reading (the largest element-node value) is the right side's and its averaged
    von Mises lies strictly between 0 and the right side's."""
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [4, 2, 2],
                      CellType.tetrahedron)
    V = fem.VectorFunctionSpace(mesh, ("CG", 2))
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([A * np.maximum(x[0] - 1.0, 0.0), 0 * x[0], 0 * x[0]]))
    r = pp.node_readings(u, MAT, None)
    vals, xyz = r.averaged, r.xyz
    s_xx, s_yy = (2 * MU + LAM) * A, LAM * A
    right = abs(s_xx - s_yy)                      # uniaxial strain: von Mises = |σ_xx − σ_yy|
    on, inside_right = np.abs(xyz[:, 0] - 1.0) < 1e-12, xyz[:, 0] > 1.0 + 1e-12
    assert np.allclose(vals[inside_right], right, rtol=1e-9)
    assert np.allclose(vals[~on & ~inside_right], 0.0, atol=1e-9 * right)
    assert np.allclose(r.unaveraged[inside_right | on], right, rtol=1e-9)
    assert np.allclose(r.unaveraged[~on & ~inside_right], 0.0, atol=1e-9 * right)
    if on.any():
        assert np.all((vals[on] > 0.01 * right) & (vals[on] < 0.99 * right)), vals[on] / right
    both = pp.node_peak(r)
    assert both.unaveraged.value_MPa == pytest.approx(right, rel=1e-9)
    assert both.averaged.value_MPa == pytest.approx(right, rel=1e-9)


def test_p1_unaveraged_reading_is_the_largest_cell_value_at_the_node():
    """P1: each cell's stress is one constant (DG0); a node's unaveraged reading is the
    largest constant of the cells that have the node. The jump of the test above, in P1:
    the nodes on x = 1 read the right side's value, those left of it zero."""
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [4, 2, 2],
                      CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 1)))
    u.interpolate(lambda x: np.vstack([A * np.maximum(x[0] - 1.0, 0.0), 0 * x[0], 0 * x[0]]))
    r = pp.node_readings(u, MAT, None)
    right = abs((2 * MU + LAM) * A - LAM * A)
    left = r.xyz[:, 0] < 1.0 - 1e-12
    assert np.allclose(r.unaveraged[~left], right, rtol=1e-9)
    assert np.allclose(r.unaveraged[left], 0.0, atol=1e-9 * right)


def _estimate(band):
    return Estimate(values=(100.0, 101.0, 102.0), h=(1.0, 1.2, 1.44), status="converged", order_observed=2.0,
                    order_used=2.0, extrapolated=99.0, gci_fine=None if band is None else band / 100.0,
                    band=band, error_fine=0.01)


@pytest.mark.parametrize("trend, half, band", [(0.5, 0.2, 0.5), (0.2, 0.5, 0.5)])
def test_band_is_the_larger_of_trend_and_half_gap(trend, half, band):
    est = with_bracket(_estimate(trend), half)
    assert est.band == band and est.gci_fine == pytest.approx(band / 100.0)
    assert est.band_trend == trend and est.bracket == half


def test_no_band_stays_no_band():
    est = with_bracket(_estimate(None), 0.3)
    assert est.band is None and est.bracket == 0.3


def test_rules():
    a, b = pp.Peak(110.0, (1.0, 2.0, 3.0)), pp.Peak(106.0, (1.0, 2.0, 3.0))
    assert pp.NodalPeak(a, b, pp.MIDPOINT).value_MPa == 108.0
    assert pp.NodalPeak(a, b, pp.UNAVERAGED).value_MPa == 110.0
    assert pp.NodalPeak(a, b).half_width_MPa == 2.0
    assert pp.NodalPeak(a, b).location_mm == (1.0, 2.0, 3.0)
