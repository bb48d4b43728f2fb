"""Places on the part (pipeline.features): the a-priori stress raisers lie on the surfaces
they name, checked against the fillet's torus and the bore's circle written out here."""
import math

import pytest

from pipeline.case import resolve
from pipeline.features import describe_location, known_raisers


@pytest.mark.parametrize("size", ["025", "05", "16"])
def test_known_fillet_places_lie_on_the_fillet_torus(size):
    case = resolve(size)
    d = case.dims
    fillet = [p for p in known_raisers(case) if p[0] > d.b1 / 2]
    assert len(fillet) >= 10
    for x, y, z in fillet:
        # Torus: centre circle of radius dj/2 + rf in the plane x = b1/2 + rf, tube radius rf.
        rho = math.hypot(y, z - d.h3 / 2)
        assert math.hypot(x - (d.b1 / 2 + d.rf), rho - (d.dj / 2 + d.rf)) == pytest.approx(d.rf, rel=1e-12)
        assert z <= d.h3 / 2 + 1e-12 and y >= 0.0       # the lower journal half of the quarter
        assert describe_location(case, (x, y, z)) == "journal shoulder fillet"


def test_known_bore_places_are_the_bore_edges_of_the_critical_plane():
    case = resolve("05")
    bore = [p for p in known_raisers(case) if p[0] == 0.0]
    assert sorted(bore) == [(0.0, 10.5, 0.0), (0.0, 10.5, 25.0)]   # di/2 = 10.5 mm, h = 25 mm
    assert {describe_location(case, p) for p in bore} == {"bore edge (bottom face)", "bore edge (top face)"}


def test_known_places_follow_the_wanted_peaks_and_the_fillet():
    assert all(p[0] == 0.0 for p in known_raisers(resolve("05", overrides={"want": "critical"})))
    assert all(p[0] > 0.0 for p in known_raisers(resolve("05", overrides={"want": "global"})))
    assert len(known_raisers(resolve("05", overrides={"dims.rf": 0.0}))) == 2
