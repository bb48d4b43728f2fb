"""What a run decided, as typed data (mm, N, MPa): each peak with its error bar and status,
the verdicts against the allowable, the safety factors, the rows at every load asked, the
sensitivity section's ends and sentence, the notes a reader must see. The analysis fills
these once (pipeline.analysis.run); results.json, the report, the terminal, the plots and a
study's table format them and decide nothing."""
from __future__ import annotations

from dataclasses import asdict, dataclass

from pipeline.analysis.level import Level
from pipeline.analysis.pilot import Pilot
from pipeline.analysis.sensitivity import Sensitivity
from pipeline.analysis.tolerance import Accuracy
from pipeline.inputs.case import Case
from pipeline.inputs.options import RunOptions
from pipeline.post.errorbar import Estimate
from pipeline.post.formulas import HandResults
from pipeline.post.peaks import NodalPeak


@dataclass(frozen=True)
class PeakAnswer:
    """One peak as the run reports it: its reading on the requested mesh (MPa, mm), where it
    sits in words, its error estimate as reported (None on one mesh, or no finite value),
    the singular feature it sits at (None: it has a finite value), for a peak the run was
    not asked for (want) why it is shown for orientation only, and its status in the words
    every output uses (pipeline.analysis.words: within tolerance, above tolerance, single
    mesh, singular, not asked)."""

    reading: NodalPeak
    feature: str
    estimate: Estimate | None
    singular: str | None
    not_wanted: str | None
    status: str

    @property
    def value_MPa(self) -> float:
        return self.reading.value_MPa

    @property
    def band_MPa(self) -> float | None:
        return None if self.estimate is None else self.estimate.band

    @property
    def has_verdict(self) -> bool:
        """Whether the peak is a value a verdict can be given on (wanted, finite)."""
        return self.singular is None and self.not_wanted is None


@dataclass(frozen=True)
class SafetyFactor:
    """allowable / peak, or None with the reason (a singular or unwanted peak)."""

    value: float | None
    note: str | None


@dataclass(frozen=True)
class Verdict:
    """One checked stress against the allowable (MPa): its value and band, pass / fail /
    undecided (the band straddles the allowable) / none (no finite or wanted value, ``why``
    says which), the margin (%), the hook load at which it reaches the allowable (N),
    that load's range over the band, and the safety factor allowable / value (None
    without a verdict)."""

    value_MPa: float
    band_MPa: float | None
    verdict: str
    margin_pct: float | None
    capacity_N: float | None
    capacity_range_N: list[float] | None
    why: str | None
    safety_factor: float | None = None

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class LoadRow:
    """A hook load of the run's list (N) with every stress scaled to it (MPa), the safety
    factors there, each checked stress's verdict there (pass, fail, undecided, none) and
    the sensitivity sentence at that load (None without the sensitivity section)."""

    load_N: float
    peak_MPa: float | None
    critical_peak_MPa: float | None
    approximate_MPa: float
    exact_MPa: float
    peak_band_MPa: float | None
    critical_band_MPa: float | None
    safety_factor: float | None
    critical_safety_factor: float | None
    verdicts: dict[str, str]
    sensitivity_sentence: str | None

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Flip:
    """A verdict that changes at one end of a range: the input and its value there (its
    unit), which stress, from which verdict to which."""

    input: str
    value: float | str
    unit: str
    stress: str
    was: str
    becomes: str

    def as_dict(self) -> dict:
        return {"input": self.input, "value": self.value, "unit": self.unit, "stress": self.stress,
                "from": self.was, "to": self.becomes}


@dataclass(frozen=True)
class SensitivityEntry:
    """One input varied: its range and, at its low and high end, each checked stress (MPa,
    the run's value scaled by the variant), the capacity (N), the verdicts and why an end
    has none (invalid or failed)."""

    input: str
    kind: str
    unit: str
    nominal: float | str
    range: list
    reason: str
    note: str
    peak_MPa: list
    critical_peak_MPa: list
    critical_section_nominal_MPa: list
    journal_root_nominal_MPa: list
    capacity_N: list
    verdicts: list
    invalid: list

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SensitivityAnswer:
    """The sensitivity section decided: the analysis (ranges, readings), each input's entry,
    the noise of a single variant mesh (MPa), what flips, the ends not analysed and the one
    sentence; the contact study's measured effect on this run's peaks (None where the run's
    load model is not the one it was measured against)."""

    analysis: Sensitivity
    entries: list[SensitivityEntry]
    noise_MPa: dict[str, float | None]
    flips: list[Flip]
    invalid: list[dict]
    sentence: str
    contact_study: dict | None


@dataclass
class RunResult:
    """Everything a run computed and decided. ``case`` is the case as analysed (at the
    finest mesh's factor when the tolerance refined it); ``levels`` the error bar's meshes,
    finest (the requested one) first; ``solved`` every mesh solved, in order; ``places``
    where they were refined; ``peaks`` by results.json's block ("peak" the global,
    "critical"); ``load_rows`` each load of a multi-load run, ``loads_verdict`` the one
    sentence of the verdicts over them; ``notes``: what a reader must know beside the
    numbers (a coarse mesh, ...). ``timings`` (s) are the analysis stages'."""

    case: Case
    options: RunOptions
    places: Pilot
    levels: list[Level]
    solved: list[Level]
    peaks: dict[str, PeakAnswer]
    hand: HandResults
    safety: dict[str, SafetyFactor]
    verdicts: dict[str, Verdict]
    comparison_pct: dict[str, float | None]
    accuracy: Accuracy | None
    load_rows: list[LoadRow] | None
    sensitivity: SensitivityAnswer | None
    notes: list[str]
    timings: dict[str, float]
    mpi_ranks: int
    convergence: dict | None = None
    loads_verdict: str | None = None

    @property
    def requested(self) -> Level:
        """The requested (finest) mesh's level: its fields, sections and peaks."""
        return self.levels[0]
