"""Each error-bar estimator (pipeline/post/errorbar.py) on synthetic data whose answer is
worked out here from the method's published definition, not from the code (MPa).

- Three meshes: Celik et al. (2008), "Procedure for estimation and reporting of uncertainty
  due to discretization in CFD applications", J. Fluids Eng. 130: p = ln(e32/e21)/ln r for a
  constant ratio r, f_ext = f1 + (f1 − f2)/(r^p − 1), GCI = Fs·|e21/f1|/(r^p − 1) with
  Roache's Fs = 1.25 (Fs = 3 when the order is not trusted), the band GCI·|f1|.
- Four or more meshes: Eça & Hoekstra (2014), "A procedure for the estimation of the
  numerical uncertainty of CFD calculations based on grid refinement studies", J. Comput.
  Phys. 262: a weighted least-squares fit f = f0 + C·h^p (weights ∝ 1/h), the standard
  deviation of the fit σ = √(n·Σ w r² / (n − k)) over k fitted parameters, and the band
  U = Fs·|f1 − f0| + σ + |f1 − f_fit(h1)|, Fs = 1.25 when the data are smooth (σ below the
  mean change per mesh and the order in [0.5, p_formal]), else 3.
- Two readings (docs/design.md §5): both readings fitted with one limit f0 and one order;
  σ over the 2n data; the band of their midpoint as above with f_fit(h1) the mean of the
  two fitted readings at the finest mesh.
- Settled peaks: the band SETTLED_BAND = 0.15 % of the value (docs/decisions/0033-settled-band.md).

The weighted least squares below is written out in the test (normal equations of two or
three parameters), not taken from the product.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.post.errorbar import (estimate, least_squares_estimate, observed_order, representative_size,
                                    three_mesh_estimate, two_reading_estimate, verdict_against, with_bracket)

H3 = [1.0, 1.3, 1.69]  # a run's three meshes: ratio 1.3 (sizes relative to the finest)
H5 = [1.0, 1.2, 1.44, 1.728, 2.0736]  # five meshes at ratio 1.2


def weighted_fit(h: np.ndarray, y_by_reading: list[np.ndarray], p: float) -> tuple[float, list[float], float]:
    """Least squares of y_j = f0 + C_j h^p (one f0, one C per reading) with weights w_i =
    (1/h_i)/Σ(1/h), minimising Σ_j Σ_i w_i (f0 + C_j h_i^p − y_ji)²; returns (f0, [C_j], that
    minimum), from the normal equations."""
    w = (1 / h) / np.sum(1 / h)
    x = h ** p
    m = len(y_by_reading)
    # Unknowns (f0, C_1..C_m): normal matrix and right-hand side, term by term.
    N = np.zeros((m + 1, m + 1))
    b = np.zeros(m + 1)
    for j, y in enumerate(y_by_reading):
        N[0, 0] += w.sum()
        N[0, j + 1] = N[j + 1, 0] = np.sum(w * x)
        N[j + 1, j + 1] = np.sum(w * x * x)
        b[0] += np.sum(w * y)
        b[j + 1] = np.sum(w * x * y)
    sol = np.linalg.solve(N, b)
    f0, C = sol[0], list(sol[1:])
    res = sum(np.sum(w * (f0 + c * x - y) ** 2) for c, y in zip(C, y_by_reading))
    return float(f0), [float(c) for c in C], float(res)


# ---------------------------------------------------------------------------------------
# Three meshes
# ---------------------------------------------------------------------------------------

def test_three_meshes_order_limit_band_and_error_are_celik_s():
    """f = 80 + 3 h^1.6: p = 1.6, f_ext = 80, band 1.25·|f1 − f2|/(1.3^1.6 − 1), error |f1 − 80|/80."""
    f = [80.0 + 3.0 * h ** 1.6 for h in H3]
    est = three_mesh_estimate(f, H3, p_formal=2.0)
    r = 1.3
    p = math.log((f[2] - f[1]) / (f[1] - f[0])) / math.log(r)
    assert p == pytest.approx(1.6, abs=1e-12)  # the definition, on this data
    assert est.status == "converged"
    assert est.order_observed == pytest.approx(p, rel=1e-9) and est.order_used == pytest.approx(p, rel=1e-9)
    ext = f[0] + (f[0] - f[1]) / (r ** p - 1)
    assert est.extrapolated == pytest.approx(ext, rel=1e-12) and ext == pytest.approx(80.0, rel=1e-12)
    band = 1.25 * abs(f[1] - f[0]) / (r ** p - 1)
    assert est.band == pytest.approx(band, rel=1e-9)
    assert est.gci_fine == pytest.approx(band / f[0], rel=1e-9)
    assert est.error_fine == pytest.approx(abs(f[0] - 80.0) / 80.0, rel=1e-9)


def test_three_meshes_above_the_formal_order_use_the_formal_order_for_the_band():
    """p = 3 > p_formal = 2 (within 2·p_formal: Fs stays 1.25): extrapolation and band
    with r^2, not r^3: band 1.25·|e21|/(1.3² − 1)."""
    f = [80.0 + 3.0 * h ** 3 for h in H3]
    est = three_mesh_estimate(f, H3, p_formal=2.0)
    assert est.order_observed == pytest.approx(3.0, abs=1e-9) and est.order_used == 2.0
    e21 = f[1] - f[0]
    assert est.band == pytest.approx(1.25 * e21 / (1.3 ** 2 - 1), rel=1e-9)
    assert est.extrapolated == pytest.approx(f[0] - e21 / (1.3 ** 2 - 1), rel=1e-12)


def test_three_meshes_far_above_the_formal_order_take_fs_3():
    """p = 4.5 > 2·p_formal = 4: the coarsest mesh is off the trend; Fs = 3."""
    f = [80.0 + 0.5 * h ** 4.5 for h in H3]
    est = three_mesh_estimate(f, H3, p_formal=2.0)
    assert est.order_observed == pytest.approx(4.5, abs=1e-9)
    assert est.band == pytest.approx(3.0 * (f[1] - f[0]) / (1.3 ** 2 - 1), rel=1e-9)


def test_three_meshes_just_within_twice_the_formal_order_keep_fs_1_25():
    """p = 3.9 ≤ 4: Fs = 1.25 (the boundary of Fs = 3 is p > 2·p_formal)."""
    f = [80.0 + 0.5 * h ** 3.9 for h in H3]
    est = three_mesh_estimate(f, H3, p_formal=2.0)
    assert est.band == pytest.approx(1.25 * (f[1] - f[0]) / (1.3 ** 2 - 1), rel=1e-9)


def test_unequal_ratios_solve_celik_s_equation():
    """h = 1, 1.25, 1.9 and f = 3 + 2 h^1.7: Celik's p·ln r21 = ln|e32/e21| + ln((r21^p − 1)/(r32^p − 1))
    holds at p = 1.7, and the solver finds that root."""
    h = [1.0, 1.25, 1.9]
    f = [3.0 + 2.0 * x ** 1.7 for x in h]
    p = observed_order(f, h)
    r21, r32 = 1.25, 1.9 / 1.25
    lhs = 1.7 * math.log(r21)
    rhs = math.log((f[2] - f[1]) / (f[1] - f[0])) + math.log((r21 ** 1.7 - 1) / (r32 ** 1.7 - 1))
    assert lhs == pytest.approx(rhs, abs=1e-12)  # 1.7 is the root of the equation
    assert p == pytest.approx(1.7, abs=1e-9)


def test_slow_falling_values_are_unsettled_with_the_largest_change_as_band():
    """p = 0.4, below the 0.5 an order must reach to be trusted (P_SINGULAR), and not growing
    like a singularity: no extrapolation, band = max |change|."""
    f = [50.0 + 5.0 * h ** 0.4 for h in H3]   # falling under refinement at p = 0.4
    est = three_mesh_estimate(f, H3, p_formal=2.0)
    assert est.status == "unsettled" and est.order_observed == pytest.approx(0.4, abs=1e-9)
    assert est.extrapolated == f[0] and est.band == pytest.approx(f[2] - f[1], rel=1e-12)


def test_a_settled_peak_gets_its_measured_band():
    """Three meshes within 0.1 % of each other: band 0.15 % of the finest value
    (docs/decisions/0033-settled-band.md), no order."""
    f = [66.22, 66.23, 66.26]
    est = estimate(f, H3, p_formal=2.0)
    assert est.status == "settled" and est.order_observed is None
    assert est.band == pytest.approx(1.5e-3 * 66.22, rel=1e-12)
    # Just above 0.1 %: fitted, not settled.
    assert estimate([66.0, 66.03, 66.0 * 1.0011], H3, p_formal=2.0).status != "settled"


# ---------------------------------------------------------------------------------------
# Four or more meshes: least squares
# ---------------------------------------------------------------------------------------

def test_least_squares_of_an_exact_power_law_is_its_limit_with_fs_1_25():
    """f = 100 + 2 h^1.5 on five meshes: p = 1.5, f0 = 100, no scatter, f_fit(h1) = f1:
    U = 1.25·|f1 − f0| = 1.25·2."""
    f = [100.0 + 2.0 * h ** 1.5 for h in H5]
    est = least_squares_estimate(f, H5, p_formal=2.0)
    assert est.status == "converged"
    assert est.order_observed == pytest.approx(1.5, abs=1e-5)
    assert est.extrapolated == pytest.approx(100.0, abs=1e-6)
    assert est.band == pytest.approx(1.25 * 2.0, abs=1e-5)
    assert est.error_fine == pytest.approx(2.0 / 100.0, abs=1e-7)


def _scattered(h, f0, C, p, bumps):
    return np.array([f0 + C * x ** p + e for x, e in zip(h, bumps)])


def test_least_squares_band_adds_the_scatter_and_the_fit_s_miss_at_the_finest_mesh():
    """A power law with p = 1.5 and bumps of ±0.02 MPa: the band is Eça & Hoekstra's
    1.25·|f1 − f0| + σ + |f1 − f_fit(h1)|, each term worked out from the fit written
    out here at the order the estimate found (which minimises the fit's residual)."""
    h = np.array(H5)
    f = _scattered(h, 100.0, 2.0, 1.5, [0.02, -0.02, 0.02, -0.01, 0.0])
    est = least_squares_estimate(list(f), list(h), p_formal=2.0)
    p = est.order_used
    assert est.order_observed == p and 0.5 <= p <= 2.0  # confirmed: in [P_SINGULAR, p_formal]
    f0, (C,), res = weighted_fit(h, [f], p)
    for q in (p - 0.01, p + 0.01):  # p is the residual's minimum
        assert weighted_fit(h, [f], q)[2] >= res
    n = len(f)
    sigma = math.sqrt(res * n / (n - 3))  # four fitted: f0, C, p (and the weights fixed)
    step = np.ptp(f) / (n - 1)
    assert 0 < sigma < step  # smooth: Fs = 1.25
    miss = abs(f[0] - (f0 + C))
    assert sigma > 1e-3 and miss > 1e-3  # both terms count here
    assert est.extrapolated == pytest.approx(f0, abs=1e-7)
    assert est.band == pytest.approx(1.25 * abs(f[0] - f0) + sigma + miss, rel=1e-6)
    assert est.status == "converged"


def test_least_squares_with_an_order_the_data_do_not_confirm_takes_fs_3():
    """Data of order 3.5 with p_formal = 2: the order is not confirmed, the fit uses p = 1 or
    2, whichever leaves the smaller residual, σ over n − 2 and Fs = 3 ("scattered")."""
    h = np.array(H5)
    f = _scattered(h, 100.0, 0.5, 3.5, [0.0, 0.01, 0.0, -0.01, 0.0])
    est = least_squares_estimate(list(f), list(h), p_formal=2.0)
    assert est.order_observed > 2.0
    fits = {q: weighted_fit(h, [f], q) for q in (1.0, 2.0)}
    p = min(fits, key=lambda q: fits[q][2])
    f0, (C,), res = fits[p]
    n = len(f)
    sigma = math.sqrt(res * n / (n - 2))
    assert est.order_used == p and est.status == "scattered"
    assert est.band == pytest.approx(3.0 * abs(f[0] - f0) + sigma + abs(f[0] - (f0 + C)), rel=1e-9)


def test_four_meshes_or_more_are_fitted_by_least_squares_three_by_richardson():
    f = [100.0 + 2.0 * h ** 1.5 for h in H5]
    assert estimate(f, H5, p_formal=2.0).band == pytest.approx(least_squares_estimate(f, H5, 2.0).band)
    assert estimate(f[:3], H5[:3], p_formal=2.0).band == pytest.approx(three_mesh_estimate(f[:3], H5[:3], 2.0).band)


# ---------------------------------------------------------------------------------------
# Two readings of a midpoint
# ---------------------------------------------------------------------------------------

def test_two_reading_band_is_fs_times_the_gap_plus_scatter_plus_the_fit_s_miss():
    """Upper and lower readings of order 2 about 113.8 MPa with p_formal = 1 (the order is
    then not confirmed: p = 1 is used, three parameters): σ = √(n·res/(2n − 3)) with res the
    two readings' weighted sum of squares, Fs = 3, and the band's last term |mid1 − (f0 +
    (Cu + Cl)/2)|, the fit's miss at the finest mesh (non-zero: p = 1 does not fit order-2 data)."""
    h = np.array([1.0, 1.2, 1.42, 1.67])
    upper = 113.8 + 0.9 * h ** 2
    lower = 113.8 - 0.5 * h ** 2
    est = two_reading_estimate(list(upper), list(lower), list(h), p_formal=1.0)
    assert est.order_observed > 1.0 and est.order_used == 1.0
    f0, (cu, cl), res = weighted_fit(h / h[0], [upper, lower], 1.0)
    n = len(h)
    sigma = math.sqrt(res * n / (2 * n - 3))
    mid = (upper + lower) / 2
    miss = abs(mid[0] - (f0 + (cu + cl) / 2))
    assert miss > 1e-3 and sigma > 1e-3
    assert est.extrapolated == pytest.approx(f0, rel=1e-12)
    assert est.band == pytest.approx(3.0 * abs(mid[0] - f0) + sigma + miss, rel=1e-9)
    assert est.status == "scattered"


def test_two_readings_of_a_confirmed_order_count_four_parameters():
    """Order 1.5 in both readings, bumps of ±0.03 MPa: p confirmed in [0.5, 2], σ over
    2n − 4, the band as above with Fs = 1.25 when σ is below the mean change per mesh."""
    h = np.array(H5)
    upper = _scattered(h, 113.8, 1.2, 1.5, [0.03, -0.03, 0.0, 0.03, 0.0])
    lower = _scattered(h, 113.8, -0.6, 1.5, [-0.03, 0.0, 0.03, 0.0, -0.03])
    est = two_reading_estimate(list(upper), list(lower), list(h), p_formal=2.0)
    p = est.order_used
    assert est.order_observed == p and 0.5 <= p <= 2.0
    f0, (cu, cl), res = weighted_fit(h, [upper, lower], p)
    n = len(h)
    sigma = math.sqrt(res * n / (2 * n - 4))
    mid = (upper + lower) / 2
    smooth = sigma < np.ptp(mid) / (n - 1)
    fs = 1.25 if smooth else 3.0
    assert est.status == ("converged" if smooth else "scattered")
    assert est.band == pytest.approx(fs * abs(mid[0] - f0) + sigma + abs(mid[0] - (f0 + (cu + cl) / 2)), rel=1e-6)


# ---------------------------------------------------------------------------------------
# The midpoint's bracket and the verdict
# ---------------------------------------------------------------------------------------

def test_the_bracket_widens_a_narrower_trend_band_and_keeps_a_wider_one():
    est = three_mesh_estimate([80.0 + 3.0 * h ** 1.6 for h in H3], H3, p_formal=2.0)
    wide = with_bracket(est, est.band + 0.5)
    assert wide.band == est.band + 0.5 and wide.gci_fine == pytest.approx(wide.band / est.values[0], rel=1e-12)
    assert wide.band_trend == est.band and wide.bracket == est.band + 0.5
    narrow = with_bracket(est, est.band / 2)
    assert narrow.band == est.band and narrow.bracket == est.band / 2


@pytest.mark.parametrize("value, band, verdict", [
    (79.0, 1.0, "pass"),        # 80 at the band's top: at the allowable passes
    (79.0, 1.0 + 1e-9, "undecided"),
    (81.0, 1.0 - 1e-9, "fail"),  # its bottom above the allowable
    (81.0, 1.0, "undecided"),    # its bottom at the allowable: not above it
    (79.0, None, "pass"),
    (80.5, None, "fail"),
])
def test_verdict_against_the_allowable_at_its_edges(value, band, verdict):
    """docs/design.md §5: pass when value + band ≤ allowable, fail when value − band > allowable."""
    assert verdict_against(value, band, 80.0) == verdict


def test_a_mesh_s_size_is_its_dof_count_to_the_minus_one_third():
    """A 3-D mesh of size h has N ∝ h^-3 degrees of freedom: h = N^(-1/3); 8× the DOFs,
    half the size (the ratio the error bar's extrapolation uses)."""
    assert representative_size(1_000_000) == pytest.approx(0.01, rel=1e-12)
    assert representative_size(8 * 12_345) / representative_size(12_345) == pytest.approx(0.5, rel=1e-12)
