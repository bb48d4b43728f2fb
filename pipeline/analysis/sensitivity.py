"""What a run's answer rests on: the inputs the case assumed, each varied over a stated
plausible range, and how far that moves the peaks, the critical-section nominal stress and
the capacity (mm, N, MPa; docs/design.md §10).

Why: the error bar says how far the answer is from the exact solution of *this* model
(±0.64 % on No. 05); the assumed journal diameter, fillet radius and seat move the global
peak by −7 % to +31 % over plausible values. A reader must see both.

Each end of a dimension's range is one variant: the case with that one input changed,
analysed on a single mesh coarser than the run's, refined at the places its dimensions
name (features.known_raisers: no pilot solve), over the MPI ranks, one variant per rank.
The nominal case is analysed the same way, and its values are the baseline the variants
are compared with, so the mesh's bias cancels: an end's value is the run's value ×
variant / baseline. The nominal case on a second mesh of the same size, refined at the
run's own pilot places instead, measures the noise of such single meshes (how far another
choice of places moves one reading), stated beside the differences. A load-model choice
changes only the right-hand side: its ends are solved on the operator of one of the run's
own meshes (analysis.analyse's ``load_variants``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

from mpi4py import MPI

from geometry.table import Dimensions, InputError, validate

from geometry.part import GeometryError
from pipeline.analysis.context import RunContext
from pipeline.analysis.level import Level
from pipeline.analysis.meshes import MeshPlan, solve_meshes
from pipeline.analysis.pilot import KNOWN, Pilot, known_places
from pipeline.errors import NumericalError
from pipeline.fe.meshing import owners
from pipeline.inputs.case import Case, check, journal_bearing_surface
from pipeline.inputs.choices import BEARING_SHAPES
from pipeline.post.sections import journal_nominal
from pipeline.runtime.idle import wait_for_ranks

# The dimension variants' mesh: the run's mesh factor × this, refined at the places the
# dimensions name (docs/design.md §10 gives its noise against the changes it reports).
MESH_RATIO = 2.2
# The load-model variants' mesh: the run's coarsest error-bar mesh of the default three at
# ratio 1.3, whose operator they are solved on beside the other error-bar mesh.
LOAD_MESH_RATIO = 1.69
NOISE_RATIO = 1.1  # without the run's pilot places, the second nominal mesh is this much coarser
# Default ranges stop this far (× h3, mm) inside a geometry rule of geometry/table.py: a
# fillet that runs out exactly at a face is degenerate geometry (docs/design.md §2).
RULE_MARGIN = 0.02
DJ_SPREAD = 0.10  # dj: ± this fraction of the assumed 0.8·h
RF_SPREAD = 0.20  # rf: ± this fraction of the assumed fillet (r/dj 0.06–0.09 at No. 05)
SEAT_SPREAD = 0.06  # seat_inner, seat_outer: ± this fraction of Dm
# The stresses a verdict is given for, and their results.json names (pipeline/output/results.py).
CHECKED = ("global_peak", "critical_peak", "critical_section_nominal", "journal_root_nominal")


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


@dataclass(frozen=True)
class Reading:
    """One variant analysed on the sensitivity mesh (MPa): both peaks, the critical
    section's nominal stress (None without the quarter model's section) and the journal
    root's; or why it has none (``invalid``: the variant breaks a geometry rule;
    ``failed``: its mesh or solve failed)."""

    peak_MPa: float | None = None
    critical_MPa: float | None = None
    section_MPa: float | None = None
    journal_MPa: float | None = None
    invalid: str | None = None
    failed: str | None = None

    @property
    def ok(self) -> bool:
        return self.invalid is None and self.failed is None


@dataclass
class Sensitivity:
    """The sensitivity analysis of a run: each range with the readings at its two ends and
    the reading they are compared with (a dimension's: the nominal case on the variants'
    mesh; a load-model choice's: the run's requested mesh, which its ends were solved on),
    the nominal case's reading on the variants' mesh and on a second mesh (the noise), the
    variants' mesh factor, which assumed inputs were not varied and why, and its wall time
    (s)."""

    ranges: list[Range]
    ends: list[tuple[Reading, Reading]]
    baselines: list[Reading]  # per range, what its ends are compared with
    baseline: Reading
    second: Reading
    mesh_factor: float
    not_varied: dict[str, str] = field(default_factory=dict)
    time_s: float = 0.0
    second_mesh: str = ""  # which mesh the noise was measured on, in words


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
            out += [c for c in ends if not _invalid_load(c) and not same_load(case, c)]
    return out


def same_load(a: Case, b: Case) -> bool:
    """Whether two cases load the journals alike (shape and band)."""
    return a.bearing_shape == b.bearing_shape and a.bearing_band() == b.bearing_band()


def read_level(case: Case, lv: Level) -> Reading:
    """The values of one analysed variant (MPa)."""
    sec = lv.sections or {}
    return Reading(peak_MPa=lv.peak.value_MPa, critical_MPa=lv.critical.value_MPa,
                   section_MPa=(sec.get("critical_section") or {}).get("nominal_MPa"),
                   journal_MPa=journal_root(case))


def journal_root(case: Case) -> float:
    """The journal root's nominal bending stress 32·M/(π·dj³) of a case (MPa), M from Q/2 at
    the middle of its bearing band (statics, docs/design.md §5)."""
    return journal_nominal(case.dims, case.load_N, case.bearing_band().centre_mm)[1]


def analyse_variant(case: Case, factor: float, places: Sequence[tuple[float, float, float]] | None = None
                    ) -> Reading:
    """One variant on this rank alone: a single mesh at ``factor`` refined at ``places``
    (mm; None: the places its own dimensions name, features.known_raisers, with the pilot
    as solve_meshes' fallback when the critical peak falls outside them); a variant that
    breaks a geometry rule, or whose mesh or solve fails, says so."""
    try:
        validate(case.dims)
    except InputError as exc:
        return Reading(invalid=" ".join(str(exc).split()))
    variant = replace(case, mesh_factor=factor)
    pl = known_places(variant) if places is None else Pilot(factor=None, hotspots=tuple(places), time_s=0.0)
    try:
        lv, _ = solve_meshes(variant, MeshPlan(factors=(factor,)), pl, RunContext(comm=MPI.COMM_SELF))
    except (NumericalError, GeometryError) as exc:
        return Reading(failed=" ".join(str(exc).split()))
    return read_level(variant, lv[0])


Places = Sequence[tuple[float, float, float]]


def analyse_sensitivity(case: Case, ctx: RunContext, levels: Sequence[Level] = (), places: Pilot | None = None,
                        analyse_one: Callable[[Case, float, Places | None], Reading] = analyse_variant) -> Sensitivity:
    """Every range's two ends and the nominal case, spread over the ranks (one variant per
    rank at a time, each on MPI.COMM_SELF), gathered on every rank.

    The noise is the nominal case's value on a second mesh at the same factor refined at
    the run's pilot places (``places``, the run's), or, when the run has none or they are
    the dimensions' own, at the dimensions' places on a mesh NOISE_RATIO coarser. The load
    model's ends come from ``levels`` (the run's: the one that solved them)."""
    say, comm = ctx.say, ctx.comm
    t0 = time.perf_counter()
    ranges, skipped = ranges_of(case)
    if not levels:  # no requested mesh whose operator the load model's variants are solved on
        skipped.update({r.input: "no requested mesh to solve it on" for r in ranges if r.kind == LOAD_MODEL})
        ranges = [r for r in ranges if r.kind == DIMENSION]
    factor = case.mesh_factor * MESH_RATIO
    known = known_places(replace(case, mesh_factor=factor)).hotspots
    own = places is not None and places.source != KNOWN and tuple(places.hotspots) != tuple(known)
    jobs: list[tuple[Case, float, Places | None, str]] = [
        (case, factor, None, "nominal"),
        (case, factor, places.hotspots, "nominal, the run's places") if own
        else (case, factor * NOISE_RATIO, None, "nominal, 2nd mesh")]
    for r in (r for r in ranges if r.kind == DIMENSION):
        jobs += [(r.variant(case, r.low), factor, None, f"{r.input} = {r.low:.4g} {r.unit}"),
                 (r.variant(case, r.high), factor, None, f"{r.input} = {r.high:.4g} {r.unit}")]
    who = owners([1.0] * len(jobs), comm.size)
    mine: dict[int, Reading] = {}
    error = None
    for k, (c, f, at, label) in enumerate(jobs):
        if who[k] != comm.rank or error is not None:
            continue
        try:
            mine[k] = analyse_one(c, f, at)
        except Exception as exc:  # re-raised on every rank below
            error = exc
            continue
        if comm.rank == 0:
            say(_line(label, 0, mine[k]))
    wait_for_ranks(comm)
    gathered = comm.allgather((mine, error))
    errors = [e for _, e in gathered if e is not None]
    if errors:
        raise errors[0]
    readings = {k: rd for m, _ in gathered for k, rd in m.items()}
    for k, (_, _, _, label) in enumerate(jobs):
        if who[k] != 0:  # rank 0 said its own
            say(_line(label, who[k], readings[k]))
    second = readings[1]
    k = 2  # the first dimension variant's job
    # The load model's ends were solved on one of the run's meshes (analyse's
    # load_variants_at): its nominal reading is their baseline, its variants their ends.
    host = next((lv for lv in levels if lv.load_variants), levels[0] if levels else None)
    run = read_level(case, host) if host is not None else None
    solved = iter(host.load_variants if any(r.kind == LOAD_MODEL for r in ranges) else [])
    ends, baselines = [], []
    for r in ranges:
        if r.kind == DIMENSION:
            ends.append((readings[k], readings[k + 1]))
            baselines.append(readings[0])
            k += 2
            continue
        pair = []
        for v in (r.low, r.high):
            c = r.variant(case, v)
            why = _invalid_load(c)
            pair.append(Reading(invalid=why) if why else run if same_load(case, c)
                        else _reading(c, *next(solved)))
            if pair[-1].ok:
                say(f"sensitivity {r.input} = {v if isinstance(v, str) else f'{v:.4g} {r.unit}'} (the run's mesh "
                    f"×{host.factor:.3g}, its operator): peak {pair[-1].peak_MPa:.2f} MPa, "
                    f"critical {pair[-1].critical_MPa:.2f} MPa")
        ends.append((pair[0], pair[1]))
        baselines.append(run)
    how = (f"a mesh ×{factor:.3g} refined at the run's pilot places instead of the dimensions' places" if own
           else f"a mesh ×{factor * NOISE_RATIO:.3g}, refined at the dimensions' places")
    return Sensitivity(ranges=ranges, ends=ends, baselines=baselines, baseline=readings[0], second=second,
                       mesh_factor=factor,
                       not_varied=skipped, time_s=time.perf_counter() - t0, second_mesh=how)


def _invalid_load(case: Case) -> str | None:
    """Why a load-model variant cannot be solved (a band off the journal), or None."""
    try:
        check(case)
    except InputError as exc:
        return " ".join(str(exc).split())
    return None


def _reading(case: Case, peak, critical, sections: dict | None) -> Reading:
    """The values (MPa) of a load-model variant solved on the run's mesh (level.Level's
    load_variants)."""
    sec = sections or {}
    return Reading(peak_MPa=peak.value_MPa, critical_MPa=critical.value_MPa,
                   section_MPa=(sec.get("critical_section") or {}).get("nominal_MPa"),
                   journal_MPa=(sec.get("journal_root") or {}).get("nominal_MPa"))


def _line(label: str, rank: int, rd: Reading) -> str:
    """The progress line of one variant."""
    return f"sensitivity {label} (rank {rank}): " + (
        f"peak {rd.peak_MPa:.2f} MPa, critical {rd.critical_MPa:.2f} MPa" if rd.ok
        else f"invalid: {rd.invalid}" if rd.invalid else f"failed: {rd.failed}")
