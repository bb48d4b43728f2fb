"""Stand-in peak answers for tests of the decisions taken on them (verdicts, safety
factors, the sensitivity section): a value (MPa), its error bar and where it sits."""
from __future__ import annotations

from pipeline.analysis.result import PeakAnswer
from pipeline.analysis.words import peak_status
from pipeline.post.errorbar import Estimate
from pipeline.post.peaks import UNAVERAGED, NodalPeak, Peak


def answer(value: float, band: float | None = None, singular: str | None = None) -> PeakAnswer:
    """A peak answer of ``value`` MPa with error bar ± ``band`` MPa (None: one mesh, no
    band), at the singular feature ``singular`` (None: a finite value)."""
    at = (0.0, 0.0, 0.0)
    est = None if band is None else Estimate((value,), (1.0,), "converged", None, None, value, None, band, None)
    status = peak_status(1.0, value, band, singular, True)
    return PeakAnswer(NodalPeak(Peak(value, at), Peak(value, at), UNAVERAGED), "somewhere", est, singular, None, status)


def run_verdicts(case, peak: float = 100.0, band: float = 1.0, critical: float = 60.0,
                 critical_band: float = 0.06, nominal: tuple[float, float] | None = (40.0, 44.56)) -> dict:
    """The verdicts of a run whose peaks are these values (MPa) with these bands, and the
    critical-section and journal-root nominal stresses ``nominal`` (MPa, no band)."""
    from pipeline.analysis.verdicts import verdicts
    checks = {"global_peak": (peak, answer(peak, band)), "critical_peak": (critical, answer(critical, critical_band))}
    if nominal is not None:
        checks.update(critical_section_nominal=(nominal[0], None), journal_root_nominal=(nominal[1], None))
    return verdicts(case.allowable_MPa, case.load_N, checks)
