"""What the sensitivity section varies and over which range: each assumed dimension (dj,
rf, the seat annulus) over a plausible range kept inside the geometry rules, and the journal
load model's choices (shape, centre, loaded length) over the ranges the contact study
measured (mm; docs/design.md §10, docs/decisions/0026-load-model-ranges-from-the-contact-study.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from geometry.table import Dimensions, InputError
from pipeline.inputs.case import Case, check, journal_bearing_surface
from pipeline.inputs.choices import BEARING_SHAPES

# Default ranges stop this far (× h3, mm) inside a geometry rule of geometry/table.py: a
# fillet that runs out exactly at a face is degenerate geometry (docs/design.md §2).
RULE_MARGIN = 0.02
DJ_SPREAD = 0.10  # dj: ± this fraction of the assumed 0.8·h
RF_SPREAD = 0.20  # rf: ± this fraction of the assumed fillet (r/dj 0.06–0.09 at No. 05)
SEAT_SPREAD = 0.06  # seat_inner, seat_outer: ± this fraction of Dm


@dataclass(frozen=True)
class Range:
    """One input varied: its --dim (or load-model option) name, its unit, its value in the
    case, the ends of its range (in that unit), why that range, and what a geometry rule
    changed in it (empty when nothing)."""

    input: str
    kind: str  # DIMENSION or LOAD_MODEL
    unit: str  # "mm", or "" for a choice (the bearing pressure's shape)
    nominal: float | str
    low: float | str
    high: float | str
    reason: str
    note: str = ""

    def variant(self, case: Case, value: float | str) -> Case:
        """The case with this input at ``value`` (unchecked)."""
        if self.kind == DIMENSION:
            return replace(case, dims=replace(case.dims, **{self.input: value}))
        return replace(case, **{self.input: value})


DIMENSION, LOAD_MODEL = "dimension", "load model"  # the kinds of input


STEP_MM = 0.01  # default range ends are rounded to this (mm): a drawing's precision


def _clip_high(value: float, limit: float, rule: str, unit: str) -> tuple[float, str]:
    """``value`` (rounded to STEP_MM) capped at ``limit`` (rounded down) and a note saying
    so (empty when not capped)."""
    value = round(round(value / STEP_MM) * STEP_MM, 9)
    if value <= limit:
        return value, ""
    capped = round(math.floor(limit / STEP_MM + 1e-9) * STEP_MM, 9)
    return capped, f"high end clipped from {value:.4g} to {capped:.4g} {unit} ({rule})"


def _clip_low(value: float, limit: float, rule: str, unit: str) -> tuple[float, str]:
    """``value`` (rounded to STEP_MM) raised to ``limit`` (rounded up) and a note saying
    so (empty when not raised)."""
    value = round(round(value / STEP_MM) * STEP_MM, 9)
    if value >= limit:
        return value, ""
    raised = round(math.ceil(limit / STEP_MM - 1e-9) * STEP_MM, 9)
    return raised, f"low end clipped from {value:.4g} to {raised:.4g} {unit} ({rule})"


def default_range(name: str, d: Dimensions) -> Range:
    """The plausible range (mm) of an assumed dimension of part ``d``, kept
    RULE_MARGIN·h3 inside the geometry rules (the note says where it was clipped).

    dj ± 10 %: journals of standard diameters around 0.8·h that still fit the bearing
    plates; rf ± 20 %: the fillet radii a machinist would turn on this journal (r/dj 0.06 to
    0.09 at No. 05's 20 mm journal); seat diameters ± 0.06·Dm: another thrust washer on the
    same track."""
    m = RULE_MARGIN * d.h3
    room = min(d.h3, d.b1) / 2 - m  # dj/2 + rf must stay below this
    if name == "dj":
        lo, _ = _clip_low(d.dj * (1 - DJ_SPREAD), 0.0, "", "mm")
        hi, note = _clip_high(d.dj * (1 + DJ_SPREAD), 2 * (room - d.rf), f"dj/2 + rf <= min(h3, b1)/2 - {m:.2g} mm", "mm")
        return Range("dj", DIMENSION, "mm", d.dj, lo, hi,
                     f"±{100 * DJ_SPREAD:.0f} % of the assumed journal diameter: the journal diameters that fit "
                     "the bearing plates and the geometry rules", note)
    if name == "rf":
        lo, hi = _clip_low(d.rf * (1 - RF_SPREAD), 0.0, "", "mm")[0], d.rf * (1 + RF_SPREAD)
        hi, note = _clip_high(hi, min(room - d.dj / 2, d.b2 - m),
                              f"dj/2 + rf <= min(h3, b1)/2 - {m:.2g} mm and rf <= b2 - {m:.2g} mm", "mm")
        return Range("rf", DIMENSION, "mm", d.rf, lo, hi,
                     f"±{100 * RF_SPREAD:.0f} % of the assumed fillet radius: the radii a machinist would turn "
                     f"on this journal (r/dj {lo / d.dj:.3f} to {hi / d.dj:.3f})", note)
    if name in ("seat_inner", "seat_outer"):
        v = getattr(d, name)
        lo, hi = v - SEAT_SPREAD * d.d14, v + SEAT_SPREAD * d.d14  # rounded by the clips below
        if name == "seat_inner":
            lo, n1 = _clip_low(lo, d.d2 + m, f"seat_inner >= d2 + {m:.2g} mm", "mm")
            hi, n2 = _clip_high(hi, d.d14 - m, f"seat_inner <= d14 - {m:.2g} mm", "mm")
        else:
            lo, n1 = _clip_low(lo, d.d14 + m, f"seat_outer >= d14 + {m:.2g} mm", "mm")
            hi, n2 = _clip_high(hi, d.b1 - m, f"seat_outer <= b1 - {m:.2g} mm", "mm")
        return Range(name, DIMENSION, "mm", v, lo, hi,
                     f"±{100 * SEAT_SPREAD:.0f} % of Dm: another thrust washer on the same track (a judgement; "
                     "the paper gives no seat)", "; ".join(n for n in (n1, n2) if n))
    raise ValueError(f"no default range for {name!r}")


DIMENSION_INPUTS = ("dj", "rf", "seat_inner", "seat_outer")  # the dimensions with a default range


def ranges_of(case: Case) -> tuple[list[Range], dict[str, str]]:
    """The ranges a run varies, and the inputs it does not vary with the reason: every
    assumed input over its default range (or the case's own range for it), and an input
    the user set only when the case gives a range for it (case file [sensitivity], or
    --vary); the dimensions first, then the load model's choices."""
    given = dict((k, (lo, hi)) for k, lo, hi in case.sensitivity_ranges)
    out: list[Range] = []
    skipped: dict[str, str] = {}
    for name in DIMENSION_INPUTS:
        if name in given:
            lo, hi = given[name]
            out.append(Range(name, DIMENSION, "mm", getattr(case.dims, name), lo, hi,
                             "the range the case gives"))
        elif name in case.assumed:
            out.append(default_range(name, case.dims))
        else:
            skipped[name] = "set by the user, and no range given for it"
    if case.support != "bearing":
        skipped.update({name: f"support {case.support}: no bearing pressure" for name in LOAD_MODEL_INPUTS})
        return out, skipped
    defaults = load_model_ranges(case)
    for name in LOAD_MODEL_INPUTS:
        if name in given:
            lo, hi = given[name]
            out.append(replace(defaults[name], low=lo, high=hi, reason="the range the case gives", note=""))
        elif getattr(case, name) == getattr(Case, name):  # the default model: assumed
            out.append(defaults[name])
        else:
            skipped[name] = "set by the user, and no range given for it"
    return out, skipped


# The load model's choices (docs/design.md §3), varied after the dimensions.
LOAD_MODEL_INPUTS = ("bearing_shape", "bearing_centre_mm", "bearing_length_mm")


@dataclass(frozen=True)
class ContactStudy:
    """The measured figures of the CalculiX contact study of the bearing load model (a
    documented reference study, like the paper's published values: kept here, never
    computed at run time). Lengths as fractions of the journal's bearing length
    Lj = b6/2 − b1/2 − rf, from the fillet's run-out; peaks as the contact model's change
    against this pipeline's cos θ model on the same mesh (%)."""

    source: str
    size: str  # the one size it was measured on
    centre_hanging: tuple[float, float]  # the contact force's centre / Lj, plate hanging from its top
    centre_standing: tuple[float, float]  # the same, plate standing on its bottom
    peak_line_load: float  # the largest line load along the journal / its mean (innermost eighth)
    fillet_peak_pct: dict[str, tuple[float, float]]  # per fit, over plate supports and the finer meshes
    critical_peak_pct: tuple[float, float]  # every fit, support and mesh
    edge_of_contact_pct: tuple[float, float]  # H9/d9: the plate bore's sharp edge as the global peak

    @property
    def fillet_range_pct(self) -> tuple[float, float]:
        """The fillet peak's change over every fit (%)."""
        return min(lo for lo, _ in self.fillet_peak_pct.values()), max(hi for _, hi in self.fillet_peak_pct.values())


# docs/load-reference.md, "Results" and "Ranges for the load model's inputs" (make load-reference).
CONTACT_STUDY = ContactStudy(
    source="CalculiX contact, the journal in a side-plate bore (the load reference study, make load-reference)",
    size="05",
    centre_hanging=(0.387, 0.408),  # x_c 28.25–28.49 mm, lever 5.75–5.99 mm, every fit and mesh
    centre_standing=(0.277, 0.347),  # x_c 27.05–27.82 mm, lever 4.55–5.32 mm
    peak_line_load=2.5,  # standing plate, zero clearance (hanging: 1.55–1.8)
    fillet_peak_pct={"zero clearance": (-7.1, 2.3), "H7/g6": (-10.7, -6.2), "H9/d9": (-3.4, 6.9)},
    critical_peak_pct=(-13.2, -4.3),
    edge_of_contact_pct=(28.0, 49.0),
)


def load_model_ranges(case: Case) -> dict[str, Range]:
    """The plausible range of each load-model choice of support "bearing", set by the
    contact study (CONTACT_STUDY, measured on No. 05 and applied to every size as fractions
    of the journal's bearing length Lj): the pressure's shape, both; its centre from the
    contact's nearest centre of pressure to the middle of the bearing surface (this model's,
    a journal that does not bend against its plate); the loaded length from the band as
    concentrated as the contact's largest line load to all of it (mm)."""
    start, end = journal_bearing_surface(case.dims)
    length = end - start
    band = case.bearing_band()
    cs = CONTACT_STUDY
    where = "" if str(case.size) == cs.size else f"; measured on No. {cs.size}, applied as fractions of Lj"

    def mm(v: float) -> float:
        return round(round(v / STEP_MM) * STEP_MM, 9)

    nearest = min(cs.centre_standing[0], cs.centre_hanging[0])
    return {
        "bearing_shape": Range("bearing_shape", LOAD_MODEL, "", case.bearing_shape, BEARING_SHAPES[0],
                               BEARING_SHAPES[-1], "both shapes of the bearing pressure: the contact study's pressure "
                               "around the journal at zero clearance lies between them (standing plate within 2.5 "
                               "points of cos θ's share per 15° band, hanging plate flat to 63°); with clearance it "
                               "narrows to a Hertz contact of ±17–40°, which neither shape is (see the contact "
                               "study's effect below)"),
        "bearing_centre_mm": Range("bearing_centre_mm", LOAD_MODEL, "mm", band.centre_mm,
                                   mm(start + nearest * length), mm(start + length / 2),
                                   f"the contact study's centre of pressure lies {cs.centre_hanging[0]:.3g}–"
                                   f"{cs.centre_hanging[1]:.3g} of the bearing length Lj from the fillet's run-out "
                                   f"with a hanging side plate, {cs.centre_standing[0]:.3g}–{cs.centre_standing[1]:.3g}"
                                   f" with a standing one (every fit, mesh, μ 0 and 0.1): from its nearest, "
                                   f"{nearest:.3g}·Lj, to the middle, 0.5·Lj (this model's){where}"),
        "bearing_length_mm": Range("bearing_length_mm", LOAD_MODEL, "mm", band.length_mm,
                                   mm(length / cs.peak_line_load), mm(length),
                                   f"the contact study spreads the load over the whole bearing length, its line load "
                                   f"largest next to the fillet, up to {cs.peak_line_load:g}× its mean (standing "
                                   f"plate; hanging 1.55–1.8×): from a band as concentrated, Lj/{cs.peak_line_load:g}, "
                                   f"to all of it{where}"),
    }


def load_variant_cases(case: Case) -> list[Case]:
    """The cases the load-model ranges need solved on the run's mesh: each end of each range
    that differs from the case's own load model and is valid, in the order of the ranges
    (:func:`analyse_sensitivity` reads their results in this order)."""
    out = []
    for r in ranges_of(case)[0]:
        if r.kind == LOAD_MODEL:
            ends = [r.variant(case, v) for v in (r.low, r.high)]
            out += [c for c in ends if not invalid_load(c) and not same_load(case, c)]
    return out


def same_load(a: Case, b: Case) -> bool:
    """Whether two cases load the journals alike (shape and band)."""
    return a.bearing_shape == b.bearing_shape and a.bearing_band() == b.bearing_band()


def invalid_load(case: Case) -> str | None:
    """Why a load-model variant cannot be solved (a band off the journal), or None."""
    try:
        check(case)
    except InputError as exc:
        return " ".join(str(exc).split())
    return None
