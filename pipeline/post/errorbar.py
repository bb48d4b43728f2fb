"""The error bar of a peak, in one place: its estimate from three or more meshes (observed
order, Richardson extrapolation, grid convergence index, and the statuses when values do not
converge), the band a midpoint reading adds, a singular peak's override, and the verdict of a
value with its band against an allowable. Its definition: docs/design.md §5; results.json
and the report only format what this module decides.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Callable, Sequence

import numpy as np

FS = 1.25          # Roache's safety factor for three or more meshes
P_SINGULAR = 0.5   # observed order below this: the peak is not converging


TWO_READINGS = "two readings, one limit"   # Estimate.method of two_reading_estimate
SETTLED = 1e-3     # all meshes within this relative spread: "settled", no order fitted
# A settled peak's band (relative): what a nodal reading can still be off by when its
# meshes agree to within SETTLED, measured against an independent reference
# (docs/decisions/0033-settled-band.md).
SETTLED_BAND = 1.5e-3
# Growth per refinement step (relative) below which growing values are mesh noise, not a
# singularity: a stress singularity of this part grows by percents at every step of 1.3
# (a re-entrant 90° edge, σ ∝ r^-0.46, by 13 %; even r^-0.1 by 2.7 %), while nodal peaks
# move by hundredths of a percent at the bore edge and up to ~1 % at the fillet between
# meshes; so every step must grow by this much, not only the finest.
SINGULAR_MIN_STEP = 5e-3


def grows_like_a_singularity(values: Sequence[float]) -> bool:
    """True when ``values`` (finest mesh first) grow by at least SINGULAR_MIN_STEP of the
    finest value at every refinement step: the growth of a singularity, not mesh noise."""
    f = np.asarray(values, dtype=float)
    return bool(np.all(-np.diff(f) >= SINGULAR_MIN_STEP * max(abs(f[0]), 1e-300)))


@dataclass(frozen=True)
class Estimate:
    """Discretisation error estimate of one quantity (MPa) on the finest mesh; its statuses
    and bands are those of docs/design.md §5. p_used is min(p, p_formal): the order used for
    extrapolation and GCI, never above the element's formal order for stress."""

    values: tuple[float, ...]       # finest first
    h: tuple[float, ...]            # representative sizes, finest first
    status: str
    order_observed: float | None
    order_used: float | None
    extrapolated: float | None
    gci_fine: float | None          # relative
    band: float | None              # absolute, MPa: |f1 - extrapolated| bound
    error_fine: float | None        # relative error of the finest value vs extrapolated
    bracket: float | None = None    # MPa: half the gap of the finest mesh's two nodal values
    band_trend: float | None = None  # MPa: the band from the meshes' trend alone
    method: str = ""                # TWO_READINGS when both readings were fitted, else the values'

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def trustworthy(self) -> bool:
        return self.status in ("converged", "exact", "settled", "oscillatory", "scattered", "unsettled")


def with_bracket(est: Estimate, half_width_MPa: float) -> Estimate:
    """The estimate with its band at least half_width_MPa: the finest mesh's own bracket
    (peaks.NodalPeak, rule MIDPOINT) is an error bound of its midpoint that the meshes' trend may
    not show. A singular peak keeps no band."""
    if est.band is None:
        return replace(est, bracket=half_width_MPa)
    band = max(est.band, half_width_MPa)
    scale = max(abs(est.values[0]), 1e-300)
    return replace(est, band=band, gci_fine=band / scale, bracket=half_width_MPa, band_trend=est.band)


# The error bar's method in one sentence per reading rule (pipeline.post.peaks: MIDPOINT,
# UNAVERAGED), for results.json and the report; the definition itself: docs/design.md §5.
# Kept free of DOLFINx (no import of pipeline.post.peaks) for the processes that only judge.
METHOD_TEXT = {
    "midpoint": "the larger of the trend of the values over the requested mesh and the coarser ones "
              "and half the gap between the unaveraged and averaged readings on the requested mesh",
    "unaveraged": "the trend of the values over the requested mesh and the coarser ones",
}

# The same method for a person (the report's appendix), in two paragraphs; self-contained
# (the report is read without the repository's docs).
TREND_TEXT = ("The trend over the meshes (the same case on coarser meshes, every size × the ratio in the "
              "table): with three meshes Richardson extrapolation and Roache's GCI (Fs = 1.25, Celik et "
              "al. 2008); with four or more a weighted least-squares fit f = f0 + C·h^p (Eça & Hoekstra "
              "2014) whose band adds the data's scatter about the fit and uses Fs = 3 when they scatter; "
              "for a midpoint the fit takes both readings with one common limit f0.")
STATUS_TEXT = ("*converged* (monotone, observed order ≥ 0.5: GCI band), "
               f"*settled* (every mesh within {100 * SETTLED:g} %: band {100 * SETTLED_BAND:g} %, what such "
               "readings are still off by), "
               "*oscillatory* (the changes alternate in sign: band = "
               "largest change), *unsettled* (not yet in the asymptotic range: band = largest change, no "
               "extrapolation), *scattered* (four or more meshes about a fit: band with Fs = 3), *singular* "
               "(grows under refinement: no finite value).")


def estimate_levels(levels: Sequence, order: int, attr: str) -> Estimate:
    """The error estimate of one peak ("peak" or "critical") over the solved ``levels``
    (finest first; each with ``dofs`` and a NodalPeak under ``attr``) of an element
    ``order``: the trend of its values over the meshes; a
    midpoint's band is at least its own half-width. With four or more meshes a midpoint's
    two readings are fitted to one limit (:func:`two_reading_estimate`): the midpoint alone
    scatters more than it changes."""
    from pipeline.post.peaks import MIDPOINT
    peaks = [getattr(lv, attr) for lv in levels]
    h = [representative_size(lv.dofs) for lv in levels]
    fine = peaks[0]
    if fine.rule == MIDPOINT and len(levels) >= 4:
        est = two_reading_estimate([p.unaveraged.value_MPa for p in peaks], [p.averaged.value_MPa for p in peaks],
                                   h, p_formal=float(order))
    else:
        est = estimate([p.value_MPa for p in peaks], h, p_formal=float(order))
    return with_bracket(est, fine.half_width_MPa) if fine.rule == MIDPOINT else est


def singular_override(est: Estimate | None, place: str | None, feature: str, refined: bool
                      ) -> tuple[Estimate | None, str | None]:
    """(the estimate as reported, the singular feature or None). A peak is singular at a
    ``place`` known to be singular (a rigid support's edge, named by the caller), or when
    its values grow like a singularity on meshes refined for it (``refined``; an unrefined
    peak's growth is the mesh's). A singular peak keeps no converged number, whatever a
    fit of a few meshes says: no extrapolation, band, GCI or error."""
    if est is not None and est.status == "singular" and place is None and refined:
        place = f"{feature} (values do not converge under refinement)"
    if place is None or est is None:
        return est, place
    return replace(est, status="singular", extrapolated=None, band=None, gci_fine=None, error_fine=None), place


def observed_order(f: Sequence[float], h: Sequence[float]) -> float | None:
    """Observed order p from three values f (finest first) on sizes h (finest first).

    None if the differences change sign (oscillatory) or one of them is zero.
    """
    f1, f2, f3 = f[:3]
    r21, r32 = h[1] / h[0], h[2] / h[1]
    e21, e32 = f2 - f1, f3 - f2
    if e21 == 0 or e32 == 0 or (e32 / e21) < 0:
        return None
    lr = math.log(abs(e32 / e21))
    if abs(r21 - r32) < 1e-12 * r21:
        return lr / math.log(r21)
    # Celik's equation p·ln r21 = ln|e32/e21| + ln((r21^p − s)/(r32^p − s)), s = +1 here;
    # solved by bracketing (the fixed-point iteration diverges for unequal ratios).
    from scipy.optimize import brentq

    def g(p: float) -> float:
        return p * math.log(r21) - lr - math.log((r21 ** p - 1.0) / (r32 ** p - 1.0))

    # Negative p (differences growing under refinement) marks a singularity: search there too.
    for lo, hi in ((1e-6, 30.0), (-30.0, -1e-6)):
        if g(lo) * g(hi) <= 0:
            return brentq(g, lo, hi, xtol=1e-12)
    return None


def estimate(values: Sequence[float], h: Sequence[float], p_formal: float) -> Estimate:
    """Error estimate from >= 3 values (finest first) on sizes h (finest first).

    Three meshes: Richardson/GCI of Celik et al. Four or more: least squares with scatter.
    """
    if len(values) < 3 or len(values) != len(h):
        raise ValueError("need at least three meshes, finest first, with one size each")
    spread = max(values) - min(values)
    if 0 < spread <= SETTLED * abs(values[0]):
        # Changes of a few hundredths of a percent are below the mesh-to-mesh noise of a nodal
        # peak: an order fitted to them is meaningless (No. 05's critical peak, 66.22/66.23/
        # 66.26 MPa, fitted p = -17 and was called singular). Real singularities grow by
        # percents per refinement.
        # The band is what such readings are off by, not the smaller spread: three meshes
        # that agree to 0.04 % still read the bore edge up to 0.11 % low (SETTLED_BAND).
        vals, hs = tuple(float(v) for v in values), tuple(float(x) for x in h)
        band = SETTLED_BAND * abs(vals[0])
        return Estimate(vals, hs, "settled", None, None, vals[0], SETTLED_BAND, band, SETTLED_BAND)
    if len(values) >= 4:
        return least_squares_estimate(values, h, p_formal)
    return three_mesh_estimate(values, h, p_formal)


def _fit(values: np.ndarray, h: np.ndarray, p: float) -> tuple[float, float, float]:
    """Weighted least-squares f0, C of f = f0 + C h^p (weights ∝ 1/h: fine meshes count
    more, as Eça & Hoekstra do); returns (f0, C, weighted sum of squared residuals)."""
    w = np.sqrt((1.0 / h) / np.sum(1.0 / h))
    A = np.column_stack([np.ones_like(h), h ** p])
    (f0, C), *_ = np.linalg.lstsq(A * w[:, None], values * w, rcond=None)
    r = (values - A @ np.array([f0, C])) * w
    return float(f0), float(C), float(r @ r)


def _best_order(ssr: Callable[[float], float], lo: float, hi: float) -> float:
    """Order p in [lo, hi] minimising a fit's residual ssr(p) (grid, then bounded search)."""
    from scipy.optimize import minimize_scalar
    grid = np.linspace(lo, hi, 200)
    k = int(np.argmin([ssr(p) for p in grid]))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    res = minimize_scalar(ssr, bounds=(a, b), method="bounded", options={"xatol": 1e-10})
    return float(res.x)


def _order_used(p_obs: float, p_formal: float, ssr: Callable[[float], float]) -> tuple[float, bool]:
    """The order to extrapolate with, and whether the data confirm it: the observed order if
    it lies in [P_SINGULAR, p_formal]; else the data do not fix it, and p = 1 or the formal
    order is used, whichever fits better (smaller ssr(p))."""
    if P_SINGULAR <= p_obs <= p_formal:
        return p_obs, True
    return min((ssr(q), q) for q in (1.0, p_formal))[1], False


def least_squares_estimate(values: Sequence[float], h: Sequence[float], p_formal: float) -> Estimate:
    """Eça–Hoekstra style estimate from >= 4 meshes (finest first)."""
    f = np.asarray(values, dtype=float)
    hh = np.asarray(h, dtype=float) / float(h[0])   # sizes relative to the finest
    vals, hs = tuple(float(v) for v in values), tuple(float(x) for x in h)
    scale = max(abs(f[0]), 1e-300)
    n = len(f)
    if np.ptp(f) <= 1e-12 * scale:
        return Estimate(vals, hs, "exact", None, None, float(f[0]), 0.0, 0.0, 0.0)
    def ssr(p: float) -> float:
        return _fit(f, hh, p)[2]
    p_obs = _best_order(ssr, 0.05, 2.0 * p_formal + 1.0)
    if p_obs < P_SINGULAR and grows_like_a_singularity(f):
        return Estimate(vals, hs, "singular", p_obs, None, None, None, None, None)
    delta_step = float(np.ptp(f)) / (n - 1)
    p_used, confirmed = _order_used(p_obs, p_formal, ssr)
    f0, C, res = _fit(f, hh, p_used)
    if confirmed:
        sigma = math.sqrt(res * n / (n - 3)) if n > 3 else 0.0
        smooth = sigma < delta_step
    else:   # an unconfirmed order: the safety factor of scattered data
        sigma = math.sqrt(res * n / (n - 2))
        smooth = False
    fs = FS if smooth else 3.0
    band = fs * abs(f[0] - f0) + sigma + abs(f[0] - (f0 + C))
    status = "converged" if smooth else "scattered"
    return Estimate(vals, hs, status, p_obs, p_used, f0, band / scale, band,
                    abs(f[0] - f0) / abs(f0))


def three_mesh_estimate(values: Sequence[float], h: Sequence[float], p_formal: float) -> Estimate:
    """Celik et al. (2008) Richardson/GCI from exactly the finest three meshes."""
    f1, f2, f3 = values[:3]
    vals, hs = tuple(float(v) for v in values), tuple(float(x) for x in h)
    scale = max(abs(f1), 1e-300)
    e21, e32 = f1 - f2, f2 - f3
    if abs(e21) <= 1e-12 * scale and abs(e32) <= 1e-12 * scale:
        return Estimate(vals, hs, "exact", None, None, f1, 0.0, 0.0, 0.0)
    p = observed_order(values, h)
    if p is None:
        band = max(abs(e21), abs(e32))
        return Estimate(vals, hs, "oscillatory", None, None, f1, band / scale, band, band / scale)
    if p < P_SINGULAR:
        if grows_like_a_singularity(values[:3]):  # no finite limit
            return Estimate(vals, hs, "singular", p, None, None, None, None, None)
        # Falling, or growing by less than a singularity would, but not yet at a steady
        # rate: not in the asymptotic range. No extrapolation; the band is the largest
        # change between meshes.
        band = max(abs(e21), abs(e32))
        return Estimate(vals, hs, "unsettled", p, None, f1, band / scale, band, band / scale)
    p_used = min(p, p_formal)
    r21 = h[1] / h[0]
    ext = f1 + (f1 - f2) / (r21 ** p_used - 1)
    # An observed order far above the formal one means the coarsest mesh is off the trend,
    # not that convergence is fast: Roache's Fs = 3 (as for unconfirmed order). No. 05's
    # global peak, 117.38 / 115.06 / 114.89 MPa (p = 16), got ±0.53 MPa with Fs = 1.25 but
    # sits 1.1 MPa above an independent P3 solution; Fs = 3 gives ±1.3 MPa.
    fs = FS if p <= 2.0 * p_formal else 3.0
    gci = fs * abs(e21 / f1) / (r21 ** p_used - 1)
    return Estimate(vals, hs, "converged", p, p_used, ext, gci, gci * abs(f1),
                    abs(f1 - ext) / abs(ext))


def _fit_two(upper: np.ndarray, lower: np.ndarray, h: np.ndarray, p: float) -> tuple[np.ndarray, float]:
    """Weighted least squares of upper = f0 + Cu h^p and lower = f0 + Cl h^p with one f0
    (weights ∝ 1/h within each reading, as in _fit); returns ((f0, Cu, Cl), the weighted sum
    of squared residuals of both readings)."""
    n = len(h)
    w = np.tile(np.sqrt((1.0 / h) / np.sum(1.0 / h)), 2)
    hp, zero = h ** p, np.zeros(n)
    A = np.vstack([np.column_stack([np.ones(n), hp, zero]), np.column_stack([np.ones(n), zero, hp])])
    y = np.concatenate([upper, lower])
    x, *_ = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)
    r = (A @ x - y) * w
    return x, float(r @ r)


def two_reading_estimate(upper: Sequence[float], lower: Sequence[float], h: Sequence[float],
                         p_formal: float) -> Estimate:
    """Estimate of a midpoint peak from >= 4 meshes (finest first) and both of its readings.

    The unaveraged (upper) and nodal-averaged (lower) readings of one peak converge to one
    value from either side, so both are fitted with a common limit f0 and a common order p
    (Eça–Hoekstra least squares, as :func:`least_squares_estimate`, on 2n data). The midpoint
    alone changes by less per mesh than it scatters, and a fit to it misses its limit; the
    two readings pin the limit from both sides. ``values`` are the midpoints, the band bounds
    |finest midpoint − f0| as in :func:`least_squares_estimate`.
    """
    if len(h) < 4 or not len(upper) == len(lower) == len(h):
        raise ValueError("need at least four meshes, finest first, with both readings and one size each")
    u, lo = np.asarray(upper, dtype=float), np.asarray(lower, dtype=float)
    hh = np.asarray(h, dtype=float) / float(h[0])
    mid = (u + lo) / 2.0
    vals, hs = tuple(float(v) for v in mid), tuple(float(x) for x in h)
    n, scale = len(mid), max(abs(mid[0]), 1e-300)
    def ssr(p: float) -> float:
        return _fit_two(u, lo, hh, p)[1]
    p_obs = _best_order(ssr, 0.05, 2.0 * p_formal + 1.0)
    if p_obs < P_SINGULAR and grows_like_a_singularity(mid):
        return Estimate(vals, hs, "singular", p_obs, None, None, None, None, None, method=TWO_READINGS)
    delta_step = float(np.ptp(mid)) / (n - 1)
    p_used, confirmed = _order_used(p_obs, p_formal, ssr)
    k = 4 if confirmed else 3   # fitted parameters: f0, Cu, Cl and (if confirmed) p
    (f0, cu, cl), res = _fit_two(u, lo, hh, p_used)
    # res is a weighted mean square per reading; summed over the two, over 2n data.
    sigma = math.sqrt(res / 2.0 * (2 * n) / (2 * n - k))
    smooth = confirmed and sigma < delta_step
    fs = FS if smooth else 3.0
    band = fs * abs(mid[0] - f0) + sigma + abs(mid[0] - (f0 + (cu + cl) / 2.0))
    return Estimate(vals, hs, "converged" if smooth else "scattered", p_obs, p_used, float(f0),
                    band / scale, band, abs(mid[0] - f0) / abs(f0), method=TWO_READINGS)


def representative_size(dofs: int) -> float:
    """h = N^(-1/3) for N degrees of freedom of a 3-D mesh (dimensionless)."""
    return dofs ** (-1.0 / 3.0)


def verdict_against(value_MPa: float, band_MPa: float | None, allowable_MPa: float) -> str:
    """Where a stress with its error bar lies against an allowable (MPa): "pass" when all of
    value ± band is at or below it, "fail" when all of it is above, else "undecided". No
    band (a nominal stress, a single mesh): the value alone decides."""
    lo, hi = value_MPa - (band_MPa or 0.0), value_MPa + (band_MPa or 0.0)
    return "pass" if hi <= allowable_MPa else "fail" if lo > allowable_MPa else "undecided"
