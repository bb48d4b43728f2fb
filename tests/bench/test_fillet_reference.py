"""The fillet reference study's geometry and fit (bench/fillet_reference.py) against closed
forms: its surface points lie on the torus, the torus is where the part's fillet is, and
Richardson's limit of an exact power law is the power law's limit."""
import math

import numpy as np
import pytest

from bench.fillet_reference import (BALL_RADIUS_MM, H_BALLS_MM, Torus, _parse_centres, _scale, _scaled,
                                    fillet_torus, near, reference_value, richardson)
from pipeline.inputs.case import resolve


def test_surface_points_are_on_the_torus_and_tangent_to_the_neighbours():
    d = resolve(size="05").dims
    t = fillet_torus(d)
    th, ph = np.meshgrid(np.linspace(0, math.pi / 2, 7), np.linspace(0, math.pi, 9))
    p = t.point(th.ravel(), ph.ravel())
    assert np.allclose(t.gap(p), 0.0, atol=1e-12)
    # theta = 0 lies on the body face x = b1/2 at radius dj/2 + rf; theta = 90° on the journal.
    start = t.point(np.array([0.0]), np.array([0.3]))[0]
    end = t.point(np.array([math.pi / 2]), np.array([0.3]))[0]
    assert start[0] == pytest.approx(d.b1 / 2)
    assert math.hypot(start[1], start[2] - d.h3 / 2) == pytest.approx(d.dj / 2 + d.rf)
    assert end[0] == pytest.approx(d.b1 / 2 + d.rf)
    assert math.hypot(end[1], end[2] - d.h3 / 2) == pytest.approx(d.dj / 2)


def test_gap_is_negative_inside_the_tube():
    t = Torus(xc=10.0, zc=0.0, R=5.0, r=1.0)
    assert t.gap(np.array([[10.0, 5.0, 0.0]]))[0] == pytest.approx(-1.0)   # on the centre circle
    assert t.gap(np.array([[10.0, 7.0, 0.0]]))[0] == pytest.approx(1.0)


@pytest.mark.parametrize("p", [1.0, 2.0, 3.0])
def test_richardson_recovers_a_power_law(p):
    h = [0.4, 0.3, 0.225]
    fit = richardson(h, [113.0 + 5.0 * x ** p for x in h])
    assert fit["order"] == pytest.approx(p, rel=1e-9)
    assert fit["limit_MPa"] == pytest.approx(113.0, rel=1e-12)


def test_richardson_refuses_an_oscillating_sequence():
    assert math.isnan(richardson([0.4, 0.3, 0.225], [1.0, 2.0, 1.5])["limit_MPa"])


def test_reference_band_covers_every_p3_value_p4_and_the_far_field():
    p3 = {"surface_peak_MPa": [99.0, 100.5, 100.0, 99.5, 100.5], "finest_three_mean_MPa": 100.0,
          "richardson": {"limit_MPa": float("nan")}}
    assert reference_value({3: p3})["value_MPa"] == pytest.approx(100.0)
    assert reference_value({3: p3})["band_MPa"] == pytest.approx(1.0)          # the 99.0 level
    assert reference_value({3: p3, 4: {"finest_three_mean_MPa": 101.5}})["band_MPa"] == pytest.approx(1.5)
    ref = reference_value({3: p3}, [102.0])                                     # mean of 100.5, 100, 99.5, 102
    assert ref["value_MPa"] == pytest.approx(100.5)
    assert ref["band_MPa"] == pytest.approx(1.5)
    assert reference_value({2: p3}) is None


def test_the_balls_follow_rf_and_no_05_keeps_its_lengths():
    """At rf = 0.06·h3 (No. 05's table row) the study's ball sizes and radius are the
    published ones to the digit, so points.jsonl of `make reference` still matches; at
    rf = 0.5 mm they are a third of them (rf / 1.5 mm)."""
    assert _scale("05", {}) == 1.0
    assert [_scaled(h, _scale("05", {})) for h in H_BALLS_MM] == list(H_BALLS_MM)
    assert _scaled(BALL_RADIUS_MM, _scale("05", {})) == BALL_RADIUS_MM
    assert _scale("05", {"rf": 0.5, "dj": 16.0}) == pytest.approx(1 / 3)
    assert _scaled(0.4, 1 / 3) == 0.133333


def test_centres_and_the_region_inside_the_balls():
    assert _parse_centres("1,2,3") == ((1.0, 2.0, 3.0),)
    assert _parse_centres("1,2,3;4.5,5,6") == ((1.0, 2.0, 3.0), (4.5, 5.0, 6.0))
    centres = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    pts = np.array([[0.9, 0.0, 0.0], [1.0, 0.0, 0.0], [2.5, 0.5, 0.0], [1.0, 1.0, 0.0]])
    assert near(pts, centres, 1.0).tolist() == [True, False, True, False]


def test_richardson_gives_no_limit_without_convergence():
    """Equal steps (p = 0; No. 05's P3 levels 113.762, 113.795, 113.829 MPa came close,
    p = -0.015, and put a 'limit' at 105.9 MPa into the reference's band) and steps that
    shrink by less than p = 0.5 give no limit; p = 0.6 still does."""
    h = [0.3, 0.225, 0.16875]
    assert math.isnan(richardson(h, [113.762, 113.795, 113.828])["limit_MPa"])
    assert math.isnan(richardson(h, [113.762, 113.795, 113.829])["limit_MPa"])
    fit = richardson(h, [113.0 + 5.0 * x ** 0.6 for x in h])
    assert fit["order"] == pytest.approx(0.6) and fit["limit_MPa"] == pytest.approx(113.0)
