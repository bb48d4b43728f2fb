"""Richardson/GCI on closed-form sequences, and singularity detection on the real part."""

import numpy as np
import pytest

from pipeline.inputs.case import resolve
from pipeline.post.errorbar import TWO_READINGS, estimate, observed_order, two_reading_estimate
from pipeline.api import RunOptions, run
from pipeline.post.features import singular_feature

H = [1.0, 1.3, 1.69]


@pytest.mark.parametrize("p", [1.0, 1.5, 2.0])
def test_recovers_order_and_limit_of_power_law(p):
    f = [50.0 + 7.0 * h ** p for h in H]
    est = estimate(f, H, p_formal=2.0)
    assert est.status == "converged"
    assert est.order_observed == pytest.approx(p, abs=1e-8)
    assert est.extrapolated == pytest.approx(50.0, rel=1e-10)
    # Roache: GCI = Fs |e21/f1| / (r^p - 1), Fs = 1.25.
    r = 1.3
    gci = 1.25 * abs((f[1] - f[0]) / f[0]) / (r ** p - 1)
    assert est.gci_fine == pytest.approx(gci, rel=1e-10)


def test_unequal_ratios_use_celik_iteration():
    h = [1.0, 1.25, 1.9]
    f = [3.0 + 2.0 * x ** 2 for x in h]
    assert observed_order(f, h) == pytest.approx(2.0, abs=1e-6)


def test_order_above_formal_is_capped_for_the_band():
    f = [10.0 + h ** 4 for h in H]
    est = estimate(f, H, p_formal=2.0)
    assert est.order_observed == pytest.approx(4.0, abs=1e-8) and est.order_used == 2.0
    assert est.band > abs(f[0] - 10.0)          # capped order gives a wider, safe band


def test_growing_values_are_singular_and_not_extrapolated():
    f = [10.0 * h ** -0.3 for h in H]           # grows without bound as h -> 0
    est = estimate(f, H, p_formal=2.0)
    assert est.status == "singular" and est.extrapolated is None and not est.trustworthy


def test_values_growing_by_mesh_noise_are_not_singular():
    """Growth of 0.07 % per mesh (a nodal peak's mesh-to-mesh noise, above the 0.1 % spread
    that counts as settled) is not a singularity: the band is the largest change."""
    f = [65.0 * (1 + 7e-4) ** -k for k in range(3)]    # finest first: 65.0, 64.95, 64.91
    est = estimate(f, H, p_formal=2.0)
    assert est.status == "unsettled" and est.band == pytest.approx(f[0] - f[1])
    assert est.trustworthy
    f4 = [65.0 * (1 + 7e-4) ** -k for k in range(4)]
    assert estimate(f4, H4, p_formal=2.0).status != "singular"
    assert two_reading_estimate([v + 0.1 for v in f4], [v - 0.1 for v in f4], H4, p_formal=2.0).status != "singular"


def test_oscillating_values_get_a_band_not_an_order():
    est = estimate([10.0, 10.2, 9.9], H, p_formal=2.0)
    assert est.status == "oscillatory" and est.band == pytest.approx(0.3)


H4 = [1.0, 1.2, 1.42, 1.67]   # make converge's sizes relative to the finest (ratio 1.3 in factor)


@pytest.mark.parametrize("p", [1.0, 2.0])
def test_two_readings_recover_their_common_limit(p):
    upper = [113.8 + 0.9 * h ** p for h in H4]
    lower = [113.8 - 0.5 * h ** p for h in H4]
    est = two_reading_estimate(upper, lower, H4, p_formal=2.0)
    assert est.method == TWO_READINGS and est.status == "converged"
    assert est.order_observed == pytest.approx(p, abs=1e-6)
    assert est.extrapolated == pytest.approx(113.8, rel=1e-9)
    assert est.values[0] == pytest.approx(113.8 + 0.2, rel=1e-12)   # the finest midpoint
    assert est.band >= abs(est.values[0] - 113.8)


@pytest.mark.slow
def test_two_readings_cover_the_limit_where_the_midpoint_alone_scatters():
    """Readings with mesh-to-mesh noise of 0.25 MPa on either side of 113.8 MPa (the size of
    the fillet's scatter on No. 05): the fit of both readings covers the limit in >= 95 % of
    draws with a narrower band than the least squares of the midpoints alone."""
    rng = np.random.default_rng(7)
    h = np.array(H4)
    hits, bands, mid_bands = 0, [], []
    for _ in range(200):
        upper = 113.8 + 0.9 * h ** 2 + rng.normal(0.0, 0.25, h.size)
        lower = 113.8 - 0.5 * h ** 2 + rng.normal(0.0, 0.25, h.size)
        est = two_reading_estimate(upper, lower, h, p_formal=2.0)
        hits += abs(est.extrapolated - 113.8) <= est.band and abs(est.values[0] - 113.8) <= est.band
        bands.append(est.band)
        mid_bands.append(estimate((upper + lower) / 2, h, p_formal=2.0).band or np.inf)
    assert hits / 200 >= 0.95
    assert np.median(bands) < np.median(mid_bands)


def test_two_readings_growing_without_limit_are_singular():
    upper = [30.0 * h ** -0.3 for h in H4]
    lower = [20.0 * h ** -0.3 for h in H4]
    est = two_reading_estimate(upper, lower, H4, p_formal=2.0)
    assert est.status == "singular" and est.extrapolated is None and est.band is None


def _levels(uppers, lowers, dofs, rule):
    from types import SimpleNamespace
    from pipeline.post.peaks import NodalPeak, Peak
    at = (0.0, 0.0, 0.0)
    return [SimpleNamespace(dofs=n, peak=NodalPeak(Peak(u, at), Peak(lo, at), rule))
            for u, lo, n in zip(uppers, lowers, dofs)]


def test_studies_of_four_meshes_fit_a_midpoint_by_both_readings():
    """estimate_levels: a midpoint over four meshes gets the two-reading fit (and at least
    its bracket); over three meshes, or read unaveraged, the values' own fit."""
    from pipeline.post.errorbar import estimate_levels
    from pipeline.post.peaks import MIDPOINT, UNAVERAGED
    case = resolve("05")
    dofs = [int(round((1.0 / h) ** 3 * 1e5)) for h in H4]
    upper, lower = [113.8 + 0.9 * h ** 2 for h in H4], [113.8 - 0.5 * h ** 2 for h in H4]
    four = estimate_levels(_levels(upper, lower, dofs, MIDPOINT), case.order, "peak")
    assert four.method == TWO_READINGS and four.extrapolated == pytest.approx(113.8, abs=0.01)
    assert four.band >= (upper[0] - lower[0]) / 2 == four.bracket
    assert estimate_levels(_levels(upper[:3], lower[:3], dofs[:3], MIDPOINT), case.order, "peak").method != TWO_READINGS
    assert estimate_levels(_levels(upper, lower, dofs, UNAVERAGED), case.order, "peak").method != TWO_READINGS


def test_two_readings_need_four_meshes():
    with pytest.raises(ValueError):
        two_reading_estimate([2.0, 2.1, 2.2], [1.0, 1.1, 1.2], H, p_formal=2.0)


def _study(overrides, factor):
    case = resolve("05", overrides=dict(overrides, mesh_factor=factor))
    result = run(case, RunOptions(levels=3, ratio=1.4, to_tolerance=False, sensitivity=False))
    return case, result.levels, result


@pytest.mark.slow
def test_rigid_support_peak_is_reported_singular():
    """u_z = 0 on the journal halves: the patch edge is a singularity, the peak grows."""
    case, levels, res = _study({"support": "rigid"}, 1.6)
    values = [lv.peak.value_MPa for lv in levels]
    assert values[0] > values[1] > values[2], values           # grows under refinement
    # Three coarse meshes alone can look "converged" (pre-asymptotic); the report still
    # names the singularity because the peak sits on the patch edge.
    peak = res.peaks["peak"]
    assert peak.estimate.status == "singular"
    assert "rigid support patch" in peak.singular  # and it is named
    assert peak.estimate.extrapolated is None


@pytest.mark.slow
def test_zero_fillet_peak_is_reported_singular():
    """rf = 0: a re-entrant 90° corner at the journal root, the peak grows without bound."""
    case, levels, res = _study({"dims.rf": 0.0, "size_fillet_mm": 0.5}, 1.2)
    values = [lv.peak.value_MPa for lv in levels]
    assert values[0] > values[1] > values[2], values           # grows under refinement
    peak = res.peaks["peak"]
    assert "re-entrant edge" in peak.singular, peak
    assert peak.estimate.status == "singular"
    assert peak.estimate.extrapolated is None


def test_singular_feature_names_only_true_singularities():
    case = resolve("05")
    assert singular_feature(case, (22.9, 6.9, 4.8)) is None            # filleted shoulder
    assert singular_feature(case, (0.0, 10.5, 0.0)) is None             # bore edge
    rigid = resolve("05", overrides={"support": "rigid"})
    assert "fillet run-out" in singular_feature(rigid, (24.0, 0.0, 2.5))
    sharp = resolve("05", overrides={"dims.rf": 0.0})
    assert "re-entrant" in singular_feature(sharp, (22.5, 0.0, 2.5))


def test_changes_below_noise_are_settled_not_singular():
    """No. 05's critical peak on three pilot-refined meshes (66.22, 66.23, 66.26 MPa, finest
    last) fitted an order of -17 and was called singular; 0.06 % is below the noise of a nodal peak."""
    est = estimate([66.26, 66.23, 66.22], H, p_formal=2.0)
    assert est.status == "settled" and est.trustworthy
    # The band is not the smaller spread of 0.04 MPa, and it holds P3's 66.27 MPa.
    assert est.band > 0.04 and abs(66.27 - est.extrapolated) <= est.band
    # The bore edge read on --mesh-factor 1.3's error-bar meshes (x1.3, x1.48, x1.69; 66.195,
    # 66.212, 66.245 MPa) sits 0.11 % below P3's 66.27 MPa (docs/accuracy.md): the band
    # of a settled peak holds it.
    low = estimate([66.195, 66.212, 66.245], H, p_formal=2.0)
    assert low.status == "settled" and abs(66.27 - low.values[0]) <= low.band
    # A real singularity grows by percents: still singular.
    assert estimate([130.0, 120.0, 111.0], H, p_formal=2.0).status == "singular"


def test_one_noisy_step_is_not_a_singularity():
    """No. 05's global peak at mesh factor 1.2 (meshes ×1.2, ×1.56, ×2.03): 114.51, 113.78,
    113.73 MPa, finest first. The finest step grows by 0.64 % (a fillet nodal peak's
    mesh-to-mesh noise), the coarser by 0.05 %; a singularity grows by percents at every
    step. Not singular: the band (largest change) covers the reference 113.82 MPa
    (docs/fillet-reference.md)."""
    est = estimate([114.51, 113.78, 113.73], [1.2, 1.56, 2.028], p_formal=2.0)
    assert est.status != "singular" and est.trustworthy
    assert abs(114.51 - 113.82) <= est.band


def test_order_far_above_formal_gets_safety_factor_3():
    """No. 05's global peak on the make-run meshes: p = 16 is a coarse-mesh outlier, not
    fast convergence; the band uses Fs = 3 instead of 1.25."""
    f, h = [114.89, 115.06, 117.38], [1.0, 1.184, 1.41]
    est = estimate(f, h, p_formal=2.0)
    assert est.status == "converged" and est.order_observed > 4.0
    r = h[1] / h[0]
    assert est.gci_fine == pytest.approx(3.0 * (0.17 / 114.89) / (r ** 2 - 1), rel=1e-9)
    assert est.band > 1.1          # covers the P3 solution 113.79 MPa


def test_pilot_is_never_coarser_than_the_fillet():
    """run.pilot_factor: 2.2 × the case's mesh factor, capped where the pilot's fillet
    elements (0.25·rf × factor by default) would exceed rf, i.e. at 4, and never finer than
    the case's own mesh. No. 05: rf = 1.5 mm, fillet size 0.375 mm."""
    from pipeline.inputs.case import resolve
    from pipeline.analysis.pilot import pilot_factor
    assert pilot_factor(resolve("05")) == pytest.approx(2.2)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 1.69})) == pytest.approx(1.69 * 2.2)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 2.5})) == pytest.approx(1.5 / 0.375)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 5.0})) == pytest.approx(5.0)
    # A finer fillet size moves the cap: rf / 0.25 mm = 6.
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 4.0, "size_fillet_mm": 0.25})) == pytest.approx(6.0)
