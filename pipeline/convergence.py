"""Richardson extrapolation, observed order and Roache's grid convergence index (GCI).

Follows Celik et al. (2008), "Procedure for estimation and reporting of uncertainty due
to discretization in CFD applications", J. Fluids Eng. 130: the representative mesh size
of an unstructured 3-D mesh is h = N^(-1/3) (N = DOFs), the observed order p comes from
the finest three meshes by fixed-point iteration (refinement ratios may differ), and
GCI_fine = Fs·|e21/f1| / (r21^p − 1) with Fs = 1.25.

A peak at a singular feature (re-entrant corner, edge of a rigid constraint) has no
finite limit: its values keep growing under refinement with p → 0. Such a study gets
status "singular" and no extrapolated value.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

FS = 1.25          # Roache's safety factor for three or more meshes
P_SINGULAR = 0.5   # observed order below this: the peak is not converging


@dataclass(frozen=True)
class Estimate:
    """Discretisation error estimate of one quantity (MPa) on the finest mesh.

    status: "converged" (monotone, p >= 0.5), "oscillatory" (differences change sign;
    band = largest difference), "singular" (growing with refinement, p < 0.5: no finite
    limit), "diverging" (decreasing with p < 0.5), "exact" (no change between meshes).
    p_used is min(p, p_formal): the order used for extrapolation and GCI, never above
    the element's formal order for stress so the band is not optimistic.
    """

    values: tuple[float, ...]       # finest first
    h: tuple[float, ...]            # representative sizes, finest first
    status: str
    order_observed: float | None
    order_used: float | None
    extrapolated: float | None
    gci_fine: float | None          # relative
    band: float | None              # absolute, MPa: |f1 - extrapolated| bound
    error_fine: float | None        # relative error of the finest value vs extrapolated

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def trustworthy(self) -> bool:
        return self.status in ("converged", "exact", "oscillatory")


def observed_order(f: Sequence[float], h: Sequence[float], max_iter: int = 100) -> float | None:
    """Observed order p from three values f (finest first) on sizes h (finest first).

    None if the differences change sign (oscillatory) or one of them is zero.
    """
    f1, f2, f3 = f[:3]
    r21, r32 = h[1] / h[0], h[2] / h[1]
    e21, e32 = f2 - f1, f3 - f2
    if e21 == 0 or e32 == 0 or (e32 / e21) < 0:
        return None
    s = 1.0
    p = math.log(abs(e32 / e21)) / math.log(r21)
    for _ in range(max_iter):
        try:
            q = math.log((r21 ** p - s) / (r32 ** p - s)) if p > 0 else 0.0
        except (ValueError, ZeroDivisionError):
            q = 0.0
        p_new = (math.log(abs(e32 / e21)) + q) / math.log(r21)
        if abs(p_new - p) < 1e-10:
            p = p_new
            break
        p = p_new
    return p


def estimate(values: Sequence[float], h: Sequence[float], p_formal: float) -> Estimate:
    """Error estimate from >= 3 values (finest first) on sizes h (finest first)."""
    if len(values) < 3 or len(values) != len(h):
        raise ValueError("need at least three meshes, finest first, with one size each")
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
        status = "singular" if f1 > f2 > f3 else "diverging"
        return Estimate(vals, hs, status, p, None, None, None, None, None)
    p_used = min(p, p_formal)
    r21 = h[1] / h[0]
    ext = f1 + (f1 - f2) / (r21 ** p_used - 1)
    gci = FS * abs(e21 / f1) / (r21 ** p_used - 1)
    return Estimate(vals, hs, "converged", p, p_used, ext, gci, gci * abs(f1),
                    abs(f1 - ext) / abs(ext))


def representative_size(dofs: int) -> float:
    """h = N^(-1/3) for N degrees of freedom of a 3-D mesh (dimensionless)."""
    return dofs ** (-1.0 / 3.0)
