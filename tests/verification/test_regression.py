"""Regression values for No. 05 with the defaults of docs/design.md §2 (mm, N, MPa).

Formula baselines: the paper (Imrak et al. 2007 §5) and docs/design.md §6.

FE baselines: an independent solution of the same model with P3 elements and MUMPS
(another element order and solver than the P2 + p-multigrid default), on its own
pilot-refined mesh (388 650 DOFs), made with

    python -m pipeline run --size 05 --order 3 --mesh-factor 1.3 --levels 1 --solver mumps --no-fields

on the 2-core development machine (Debian 12, gmsh 4.8.0, DOLFINx 0.5.2): global peak
113.72 MPa (journal shoulder fillet), critical peak 66.27 MPa (66.265, bore edge). The
same command at --mesh-factor 1.69 gives 113.83 and 66.26 MPa (66.263).

The global peak's baseline is the fillet reference of `make reference`
(bench/fillet_reference.py, docs/fillet-reference.md): 113.82 ± 0.10 MPa, from P3 and P4
on meshes refined only at the fillet, the peak sampled on the exact torus.

Tolerances come from measured errors and the project's target, no tighter:
- global: 1 % of the reference (the project's accuracy target, docs/design.md §6). The
  default mesh reads 113.64 MPa (−0.16 %, `make run`); at mesh factors 0.8 … 1.3 `make
  run` reads within −0.47 … +0.23 % (docs/accuracy.md). The run's error bar must cover
  the reference.
- critical: 0.2 MPa (0.3 %). The levels of `make converge` lie within 66.22 … 66.25 MPa
  and both P3 solutions at 66.27; the tolerance is ten times that spread so that gmsh's
  run-to-run mesh changes pass while a change to loads, supports, solver or stress
  evaluation of more than 0.3 % fails.
Regenerate with the command above (and `make run`, `make converge`) and update these
numbers and docs/accuracy.md together.
"""
import pytest

from pipeline.post import formulas
from pipeline.api import RunOptions, run
from pipeline.post.errorbar import estimate_levels
from pipeline.inputs.case import resolve
from pipeline.analysis.pilot import pilot
from pipeline.analysis.level import LevelTask, solve_level


ERROR_BAR = RunOptions(levels=3, to_tolerance=False, sensitivity=False)  # make run's three meshes, no more
GLOBAL_LIMIT = 113.82                    # make reference (docs/fillet-reference.md)
GLOBAL_BAND = 0.01 * GLOBAL_LIMIT
CRITICAL_LIMIT, CRITICAL_BAND = 66.27, 0.2


def test_formulas_against_paper():
    h = formulas.hand_results(resolve("05").dims, 10_000.0)
    assert h.approximate.sigma_MPa == pytest.approx(37.8, abs=0.05)      # paper 37.8
    assert h.exact.sigma_MPa == pytest.approx(43.75, abs=0.07)           # paper 43.75 (43.81)


@pytest.fixture(scope="module")
def default_level():
    """The mesh `make run` answers on: the case's mesh, refined where the pilot found the peaks."""
    case = resolve("05")
    return solve_level(case, LevelTask(case.mesh_factor, hotspots=pilot(case).hotspots))


@pytest.mark.slow
def test_default_mesh_global_peak(default_level):
    lv = default_level
    assert abs(lv.peak.value_MPa - GLOBAL_LIMIT) <= GLOBAL_BAND, lv.peak
    assert 22.5 <= lv.peak.location_mm[0] <= 24.0                       # on the shoulder fillet


@pytest.mark.slow
def test_default_mesh_critical_peak(default_level):
    lv = default_level
    assert abs(lv.critical.value_MPa - CRITICAL_LIMIT) <= CRITICAL_BAND, lv.critical
    x, y, z = lv.critical.location_mm
    assert abs(x) < 1e-6 and abs(y - 10.5) < 1e-6 and z in (pytest.approx(0.0, abs=1e-6), pytest.approx(25.0, abs=1e-6))


@pytest.mark.slow
def test_default_run_error_bar_covers_the_reference():
    """`make run`'s three meshes (×1, ×1.3, ×1.69): the global peak's band covers the
    independent reference, and the value lies within 1 % of it; the critical peak's band
    covers the P3 solutions' 66.27 MPa."""
    case = resolve("05")
    levels = run(case, ERROR_BAR).levels
    est = estimate_levels(levels, case.order, "peak")
    value = levels[0].peak.value_MPa
    print(f"global peak {value:.3f} ± {est.band:.3f} MPa ({est.status}); reference {GLOBAL_LIMIT} MPa")
    assert abs(value - GLOBAL_LIMIT) <= est.band, (value, est)
    assert abs(value - GLOBAL_LIMIT) <= GLOBAL_BAND
    crit = estimate_levels(levels, case.order, "critical")
    assert abs(levels[0].critical.value_MPa - CRITICAL_LIMIT) <= crit.band, (levels[0].critical.value_MPa, crit)


# Independent references of other parts (bench/fillet_reference.py, docs/fillet-reference.md):
# P3 on balls refined along the fillet's crest, the peak sampled on the exact
# torus. Each is (size, dimension overrides in mm, reference MPa).
OTHER_PARTS = [
    ("1.6", {}, 114.30),                                   # --size 1.6 --orders 3
    ("05", {"dims.rf": 0.5, "dims.dj": 16.0}, 275.86),     # --crest 0,42,8 --ball-sizes 4
    ("05", {"dims.rf": 0.3}, 228.12),                      # --crest 20,66,12 --ball-sizes 4
]


@pytest.mark.slow
@pytest.mark.parametrize("size,dims,reference", OTHER_PARTS, ids=["1.6", "05-rf0.5-dj16", "05-rf0.3"])
def test_default_run_error_bar_covers_other_parts_references(size, dims, reference):
    """The default path's three meshes on parts other than No. 05's row: the global peak's
    band covers the part's own independent reference and the value lies within 1 % of it
    (measured: +0.14 %, −0.28 %, −0.14 %; before the pilot's threshold followed the midpoint
    No. 1.6 read +3.1 % and rf = 0.3 mm +4.0 %)."""
    case = resolve(size, overrides=dims)
    levels = run(case, ERROR_BAR).levels
    est = estimate_levels(levels, case.order, "peak")
    value = levels[0].peak.value_MPa
    print(f"{size} {dims}: global peak {value:.3f} ± {est.band:.3f} MPa ({est.status}); reference {reference} MPa")
    assert abs(value - reference) <= est.band, (value, est)
    assert abs(value - reference) <= 0.01 * reference

