"""Each peak's error bar as the run reports it, decided here once: the estimate over the
meshes (pipeline/post/errorbar.py), overridden where the peak sits at a singular feature,
and what that band is as a share of the value (mm, MPa; docs/design.md §5)."""
from __future__ import annotations

from typing import Sequence

from pipeline.analysis.level import Level
from pipeline.inputs.case import Case
from pipeline.post.errorbar import Estimate, estimate_levels, singular_override
from pipeline.post.features import describe_location, singular_feature
from pipeline.post.peaks import MIDPOINT

PEAKS = {"global": "peak", "critical": "critical"}   # a wanted peak → its Level attribute


def wanted_peaks(case: Case) -> tuple[str, ...]:
    """The peaks the case asks for ("global", "critical"), by its ``want``."""
    return tuple(p for p in PEAKS if case.want in ("both", p))


def peak_estimate(case: Case, levels: Sequence[Level], attr: str, refined: bool = True
                  ) -> tuple[Estimate | None, str | None]:
    """The error estimate of one peak (``attr`` "peak" or "critical") over ``levels``
    (finest first) as reported, and the singular feature it sits at (None when it has a
    finite value). No estimate on fewer than three meshes. ``refined``: the meshes were
    refined for this peak; an unrefined peak's growth is its mesh's, not a singularity."""
    fine = getattr(levels[0], attr)
    est = estimate_levels(levels, case.order, attr) if len(levels) >= 3 else None
    return singular_override(est, singular_feature(case, fine.location_mm), describe_location(case, fine.location_mm),
                             refined)


def band_pct(case: Case, levels: Sequence[Level], peak: str) -> float | None:
    """The band (% of the value) of a wanted ``peak`` over ``levels`` (finest first) as
    results.json reports it: None with fewer than three meshes or at a singular feature."""
    attr = PEAKS[peak]
    est, _ = peak_estimate(case, levels, attr)
    if est is None or est.band is None:
        return None
    return 100.0 * est.band / max(abs(getattr(levels[0], attr).value_MPa), 1e-300)


def bands_of(case: Case, levels: Sequence[Level]) -> dict[str, float | None]:
    """Each wanted peak's band (%) over ``levels``."""
    return {p: band_pct(case, levels, p) for p in wanted_peaks(case)}


def half_gap_pct(case: Case, fine: Level) -> float:
    """The largest half gap between the two readings (% of the value) of a wanted peak
    read by their midpoint on the mesh ``fine``: a floor under that peak's band on any
    set of meshes with ``fine`` as the finest (errorbar.with_bracket), so coarser meshes
    cannot bring the band below it."""
    peaks = [getattr(fine, PEAKS[p]) for p in wanted_peaks(case)]
    return max([100.0 * p.half_width_MPa / max(abs(p.value_MPa), 1e-300) for p in peaks if p.rule == MIDPOINT],
               default=0.0)
