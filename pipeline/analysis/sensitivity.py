"""What a run's answer rests on: the inputs the case assumed, each varied over a stated
plausible range, and how far that moves the peaks, the critical-section nominal stress and
the capacity (mm, N, MPa; docs/design.md §10).

Why: the error bar says how far the answer is from the exact solution of *this* model
(±0.64 % on No. 05); the assumed journal diameter, fillet radius and seat move the global
peak by −7 % to +31 % over plausible values. A reader must see both.

Each end of a range is one variant: the case with that one input changed, analysed on a
single mesh coarser than the run's (its own pilot, no error bar) over the MPI ranks, one
variant per rank. The nominal case is analysed the same way, and its values are the
baseline the variants are compared with, so the mesh's bias cancels: an end's value is
the run's value × variant / baseline. The nominal case on a second mesh (the run's own
error-bar mesh of the same size, refined at the run's places, or one slightly coarser)
measures the noise of such single meshes, stated beside the differences.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Sequence

from mpi4py import MPI

from geometry.table import Dimensions, InputError, validate

from pipeline.inputs.case import Case, check, journal_bearing_surface
from pipeline.inputs.choices import BEARING_SHAPES
from pipeline.analysis.level import Level, Progress
from pipeline.analysis.pilot import pilot_factor
from pipeline.fe.meshing import owners
from pipeline.post.sections import journal_nominal
from pipeline.runtime.idle import wait_for_ranks

# The variants' mesh: the run's mesh factor × this, the coarsest mesh of a default error
# bar (ratio 1.3, three meshes). On No. 05 its peaks lie within 0.2 % of the run's mesh
# (113.96 against 113.77 MPa, 66.24 against 66.22 MPa) at a third of its DOFs.
MESH_RATIO = 1.69
NOISE_RATIO = 1.1  # the second nominal mesh, × the variants' factor: measures their noise
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


def load_model_ranges(case: Case) -> dict[str, Range]:
    """The plausible range of each load-model choice of support "bearing", from the geometry
    (until a contact study bounds them): the pressure's shape, both; its centre from the
    quarter-point of the journal's bearing surface nearest the shoulder to its middle; the
    loaded length from half the bearing surface to all of it (mm)."""
    start, end = journal_bearing_surface(case.dims)
    length = end - start
    band = case.bearing_band()
    return {
        "bearing_shape": Range("bearing_shape", LOAD_MODEL, "", case.bearing_shape, BEARING_SHAPES[0],
                               BEARING_SHAPES[-1], "both shapes of the bearing pressure: how the side plate's "
                               "bore bears on the journal is not known"),
        "bearing_centre_mm": Range("bearing_centre_mm", LOAD_MODEL, "mm", band.centre_mm,
                                   round(start + length / 4, 9), round(start + length / 2, 9),
                                   "the centre of pressure from the bearing surface's quarter-point nearest the "
                                   "shoulder (a plate that bears on its inner edge as the journal bends) to its "
                                   "middle (pressure spread over the whole plate); from the geometry, no contact "
                                   "study yet"),
        "bearing_length_mm": Range("bearing_length_mm", LOAD_MODEL, "mm", band.length_mm,
                                   round(length / 2, 9), round(length, 9),
                                   "the loaded length from half the journal's bearing surface (a thinner side "
                                   "plate, centred) to all of it; from the geometry, no contact study yet"),
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


def analyse_variant(case: Case, factor: float) -> Reading:
    """One variant on this rank alone: its own pilot and a single mesh at ``factor``; a
    variant that breaks a geometry rule, or whose mesh or solve fails, says so."""
    from geometry.part import GeometryError

    from pipeline.analysis.analyse import analyse
    from pipeline.errors import NumericalError
    try:
        validate(case.dims)
    except InputError as exc:
        return Reading(invalid=" ".join(str(exc).split()))
    variant = replace(case, mesh_factor=factor)
    try:
        lv, _ = analyse(variant, levels=1, comm=MPI.COMM_SELF, formula_loads=False)
    except (NumericalError, GeometryError) as exc:
        return Reading(failed=" ".join(str(exc).split()))
    return read_level(variant, lv[0])


def analyse_sensitivity(case: Case, comm: MPI.Comm = MPI.COMM_WORLD, progress: Progress | None = None,
                        analyse_one: Callable[[Case, float], Reading] = analyse_variant,
                        levels: Sequence[Level] = ()) -> Sensitivity:
    """Every range's two ends and the nominal case, spread over the ranks (one variant per
    rank at a time, each on MPI.COMM_SELF), gathered on every rank.

    The noise is the nominal case's value on a second mesh at the same factor: the run's
    own error-bar mesh there, if ``levels`` (the run's) has one and the run's pilot ran at
    another factor than the variants' (other refined places: another mesh of the same part,
    no solve needed), else a mesh NOISE_RATIO coarser, solved here."""
    say = progress or (lambda s: None)
    t0 = time.perf_counter()
    ranges, skipped = ranges_of(case)
    if not levels:  # no requested mesh whose operator the load model's variants are solved on
        skipped.update({r.input: "no requested mesh to solve it on" for r in ranges if r.kind == LOAD_MODEL})
        ranges = [r for r in ranges if r.kind == DIMENSION]
    factor = case.mesh_factor * MESH_RATIO
    same = next((lv for lv in levels if math.isclose(lv.factor, factor, rel_tol=1e-9)), None)
    if math.isclose(pilot_factor(case), pilot_factor(replace(case, mesh_factor=factor)), rel_tol=1e-9):
        same = None  # the same pilot, the same places: the very mesh of the baseline
    jobs: list[tuple[Case, float, str]] = [(case, factor, "nominal")]
    if same is None:
        jobs.append((case, factor * NOISE_RATIO, "nominal, 2nd mesh"))
    for r in (r for r in ranges if r.kind == DIMENSION):
        jobs += [(r.variant(case, r.low), factor, f"{r.input} = {r.low:.4g} {r.unit}"),
                 (r.variant(case, r.high), factor, f"{r.input} = {r.high:.4g} {r.unit}")]
    who = owners([1.0] * len(jobs), comm.size)
    mine: dict[int, Reading] = {}
    error = None
    for k, (c, f, label) in enumerate(jobs):
        if who[k] != comm.rank or error is not None:
            continue
        try:
            mine[k] = analyse_one(c, f)
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
    for k, (_, _, label) in enumerate(jobs):
        if who[k] != 0:  # rank 0 said its own
            say(_line(label, who[k], readings[k]))
    second = read_level(case, same) if same is not None else readings[1]
    k = 1 if same is not None else 2  # the first dimension variant's job
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
    how = (f"the run's error-bar mesh ×{factor:.3g}, refined at the run's places" if same is not None
           else f"a mesh ×{factor * NOISE_RATIO:.3g}, refined at its own pilot's places")
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
