"""Richardson/GCI on closed-form sequences, and singularity detection on the real part."""

import pytest

from pipeline.case import resolve
from pipeline.errorbar import estimate, observed_order
from pipeline.analysis import analyse
from pipeline.results import build_results
from pipeline.features import singular_feature

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


def test_oscillating_values_get_a_band_not_an_order():
    est = estimate([10.0, 10.2, 9.9], H, p_formal=2.0)
    assert est.status == "oscillatory" and est.band == pytest.approx(0.3)


def _study(overrides, factor):
    case = resolve("05", overrides=dict(overrides, mesh_factor=factor))
    levels, pl = analyse(case, levels=3, ratio=1.4)
    return case, levels, build_results(case, levels, {}, pl=pl)


def test_rigid_support_peak_is_reported_singular():
    """u_z = 0 on the journal halves: the patch edge is a singularity, the peak grows."""
    case, levels, res = _study({"support": "rigid"}, 1.6)
    values = [lv.peak.value_MPa for lv in levels]
    assert values[0] > values[1] > values[2], values           # grows under refinement
    # Three coarse meshes alone can look "converged" (pre-asymptotic); the report still
    # names the singularity because the peak sits on the patch edge.
    block = res["fe"]["peak"]
    assert block["error_estimate"]["status"] == "singular"
    assert "rigid support patch" in block["singular_feature"]  # and it is named
    assert block["error_estimate"]["extrapolated"] is None


def test_zero_fillet_peak_is_reported_singular():
    """rf = 0: a re-entrant 90° corner at the journal root, the peak grows without bound."""
    case, levels, res = _study({"dims.rf": 0.0, "size_fillet_mm": 0.5}, 1.2)
    values = [lv.peak.value_MPa for lv in levels]
    assert values[0] > values[1] > values[2], values           # grows under refinement
    block = res["fe"]["peak"]
    assert "re-entrant edge" in block["singular_feature"], block
    assert block["error_estimate"]["status"] == "singular"
    assert block["error_estimate"]["extrapolated"] is None


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
    assert est.band == pytest.approx(0.04) and est.extrapolated == 66.26
    # A real singularity grows by percents: still singular.
    assert estimate([130.0, 120.0, 111.0], H, p_formal=2.0).status == "singular"


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
    from pipeline.case import resolve
    from pipeline.pilot import pilot_factor
    assert pilot_factor(resolve("05")) == pytest.approx(2.2)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 1.69})) == pytest.approx(1.69 * 2.2)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 2.5})) == pytest.approx(1.5 / 0.375)
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 5.0})) == pytest.approx(5.0)
    # A finer fillet size moves the cap: rf / 0.25 mm = 6.
    assert pilot_factor(resolve("05", overrides={"mesh_factor": 4.0, "size_fillet_mm": 0.25})) == pytest.approx(6.0)
