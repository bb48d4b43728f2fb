"""The paper's two hand formulas (docs/design.md §4), every intermediate term kept (mm, N, MPa).

The span l is an explicit input to both, because the paper uses l = b1 + b2 = 57.5 mm
(journal centres) in the approximate method and l = b6 = 70 mm in the exact one.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from geometry.table import Dimensions, paper_spans


@dataclass(frozen=True)
class Approximate:
    """Beam on two supports: Me = Q/2·(l/2 − Dm/π), σ = 6·Me / ((b − di)·h²)."""

    span_mm: float
    lever_mm: float  # l/2 − Dm/π
    Me_Nmm: float
    sigma_MPa: float


@dataclass(frozen=True)
class Exact:
    """Rudenko's curved-bar model of the ring around the bore, R = (b + di)/4."""

    span_mm: float
    R_mm: float
    N1_N: float
    M1_Nmm: float
    N2_N: float
    M2_Nmm: float
    F_mm2: float
    W_mm3: float
    sigma_MPa: float


def approximate(Q_N: float, span_mm: float, b: float, di: float, h: float, Dm: float) -> Approximate:
    """Approximate method, eqs. (1) and (4): point loads Q/2 at Dm/π, reactions at l/2."""
    lever = span_mm / 2 - Dm / math.pi
    Me = Q_N / 2 * lever
    return Approximate(span_mm=span_mm, lever_mm=lever, Me_Nmm=Me,
                       sigma_MPa=6 * Me / ((b - di) * h ** 2))


def exact(Q_N: float, span_mm: float, b: float, di: float, h: float) -> Exact:
    """Exact method, eqs. (9), (10), (7), (11), step by step; σ = M2/W + N2/F.

    F and W are those of the ring ligament, (b − di)/2 wide and h high.
    """
    l = span_mm
    R = (b + di) / 4
    N1 = (1 + 2 * l / R) * Q_N / (4 * math.pi)
    M1 = (-0.12 + 0.034 * l / R) * Q_N * R
    N2 = N1 - Q_N / math.pi
    M2 = 2 * N1 * R - (l / (4 * R) + 1 / math.pi) * Q_N * R - M1
    width = (b - di) / 2
    F = h * width
    W = h * width ** 2 / 6
    return Exact(span_mm=l, R_mm=R, N1_N=N1, M1_Nmm=M1, N2_N=N2, M2_Nmm=M2, F_mm2=F,
                 W_mm3=W, sigma_MPa=M2 / W + N2 / F)


@dataclass(frozen=True)
class HandResults:
    """Both methods with the paper's spans and with one consistent span each way."""

    approximate: Approximate          # paper: l = b1 + b2
    exact: Exact                      # paper: l = b6
    approximate_at_exact_span: Approximate
    exact_at_approximate_span: Exact

    def as_dict(self) -> dict:
        return {k: asdict(v) for k, v in self.__dict__.items()}


def hand_results(d: Dimensions, Q_N: float, approximate_span_mm: float | None = None,
                 exact_span_mm: float | None = None) -> HandResults:
    """Both formulas for dimensions d under Q_N, spans defaulting to the paper's choice."""
    la, le = paper_spans(d)
    la = la if approximate_span_mm is None else approximate_span_mm
    le = le if exact_span_mm is None else exact_span_mm
    geo = dict(b=d.b1, di=d.d2, h=d.h3)
    return HandResults(
        approximate=approximate(Q_N, la, Dm=d.d14, **geo),
        exact=exact(Q_N, le, **geo),
        approximate_at_exact_span=approximate(Q_N, le, Dm=d.d14, **geo),
        exact_at_approximate_span=exact(Q_N, la, **geo),
    )


def sigma_at_span(d: Dimensions, Q_N: float, which: str, span_mm: float) -> float:
    """The stress (MPa) of formula ``which`` ("approximate" or "exact") for dimensions d
    under Q_N with span ``span_mm`` (mm)."""
    geo = dict(b=d.b1, di=d.d2, h=d.h3)
    if which == "approximate":
        return approximate(Q_N, span_mm, Dm=d.d14, **geo).sigma_MPa
    return exact(Q_N, span_mm, **geo).sigma_MPa
