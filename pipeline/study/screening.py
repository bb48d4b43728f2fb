"""The steps of a screened design study (mm, N, MPa): each variant is read first with the
least work and a conservative band, and takes the next, dearer step only while its band
holds the allowable (pipeline.study.sweep):

1. the cheap level: one mesh at SCREEN_RATIO × the case's mesh factor, refined at its own
   pilot's places, band MARGIN of the value;
2. one mesh at the full error bar's coarsest factor (×1.69), band ONE_MESH_MARGIN;
3. two meshes, the error bar's two coarser ones (×1.3 and ×1.69), band the finer one's
   bracket plus TWO_MESH_FACTOR × their difference, at least TWO_MESH_MARGIN;
4. the full error bar (×1, ×1.3, ×1.69): the study's own analysis.

Steps 2–4 solve the full error bar's own meshes at its places, each once (a memo shared
by the steps of one variant), so a variant that needs them all costs the cheap level more
than its full analysis. Steps 2 and 3 are taken only where their bands were measured: the
default three meshes at ratio 1.3 on the default mesh factor or a finer one, without the
sensitivity section; elsewhere an undecided variant goes from the cheap level to the full
error bar. Every band is also at least half the gap between the unaveraged
and averaged readings (the midpoint's own bracket, docs/design.md §5). The fractions are
chosen by measurement: every step's band of every variant of the 19 sizes and of No. 05's
rf × dj grid holds the full study's value with its error bar (docs/accuracy.md, *The
screening level*); coarse meshes misread the fillet by up to +7.8 % at factors 2–4.
A variant next to a crossing of the allowable goes to the full error bar at once: the
crossing's place is read from its neighbours' values and bands.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from pipeline.inputs.case import Case
from pipeline.output import flat
from pipeline.post.errorbar import verdict_against

SCREEN_RATIO = 2.2  # the cheap level's mesh factor: the case's × this
# Per peak (results.json's fe block): the band's smallest fraction of the value, on the
# cheap level, on the error bar's coarsest mesh alone, and on its two coarser meshes.
MARGIN = {"peak": 0.10, "critical": 0.03}
ONE_MESH_MARGIN = {"peak": 0.05, "critical": 0.005}
TWO_MESH_MARGIN = {"peak": 0.035, "critical": 0.005}
TWO_MESH_FACTOR = 3.0  # × the two meshes' difference: Roache's Fs for unconfirmed order over r^p − 1 ≈ 1
SCREENED = "screened"  # a peak's status on a step short of the full error bar (its band is the step's)
NEXT_STEPS, FULL = "next steps", "full error bar"  # how far a screened variant goes next
FILE = "screening.json"  # beside a screened variant's results.json
# The coarsest case mesh factor a screened study accepts: the bands above were measured on
# the default mesh (factor 1); at factor 2 the cheap level (×4.4) misreads No. 05's global
# peak by more than its band (docs/accuracy.md, *The screening level*).
SCREEN_MAX_MESH_FACTOR = 1.0


@dataclass(frozen=True)
class Step:
    """A step of a screened variant: its name, its finest mesh (× the case's mesh factor),
    how many meshes it solves (at the study's ratio, coarser), and its band's smallest
    fraction of each peak's value (None: the full error bar's own band)."""

    name: str
    factor: float
    levels: int
    margin: dict[str, float] | None


STEPS = (Step("cheap level", SCREEN_RATIO, 1, MARGIN),
         Step("one mesh", 1.69, 1, ONE_MESH_MARGIN),
         Step("two meshes", 1.3, 2, TWO_MESH_MARGIN),
         Step("full error bar", 1.0, 3, None))


def screen_case(case: Case) -> Case:
    """The case the cheap level analyses: the same part and load on a mesh SCREEN_RATIO
    times coarser (one mesh, no error bar)."""
    return replace(case, mesh_factor=case.mesh_factor * SCREEN_RATIO)


def screening_of(res: dict, step: Step = STEPS[0]) -> dict:
    """A step's reading of its run's results.json content ``res`` (one mesh, or two for
    the two-mesh step): per peak its value (MPa), band (MPa, ±), the band's fraction of
    the value and the readings' half gap; ``full_error_bar`` False (the variant is decided
    here until the study says otherwise)."""
    fe = res["fe"]
    peaks = {}
    for block in flat.PEAKS:
        b = fe[block]
        key = "peak_MPa" if block == "peak" else "critical_peak_MPa"
        # A peak not asked for (want) has no answer (null): its reading, for orientation.
        value = fe[key] if fe.get(key) is not None else fe.get(key.replace("_MPa", "_unresolved_MPa"))
        un, av = b.get("unaveraged_MPa"), b.get("averaged_MPa")
        gap = 0.0 if un is None or av is None else 0.5 * abs(un - av)
        band = max(step.margin[block] * abs(value), gap)
        if step.levels == 2:  # the finer mesh's bracket and the trend between the two, with a safety factor
            col = "peak_MPa" if block == "peak" else "critical_peak_MPa"
            f1, f2 = (row[col] for row in fe["levels"][:2])
            band = max(band, gap + TWO_MESH_FACTOR * abs(f1 - f2))
        peaks[block] = {"value_MPa": value, "band_MPa": band, "fraction": band / abs(value) if value else 0.0,
                        "bracket_MPa": gap}
    return {"step": step.name, "mesh_factor": res["case"]["mesh_factor"],
            "meshes": [row["mesh_factor"] for row in fe["levels"]], "ratio": step.factor,
            "margin": dict(step.margin), "peaks": peaks, "full_error_bar": False, "why_full": None}


def evidence(s: dict) -> str:
    """How a variant was decided, in words: the step's meshes and bands, or why it got the
    full error bar."""
    if s["full_error_bar"]:
        return f"full error bar ({s['why_full']})"
    meshes = s.get("meshes") or [s["mesh_factor"]]
    what = "one mesh at factor" if len(meshes) == 1 else "meshes at factors"
    return (f"screened: {what} {', '.join(f'{m:.3g}' for m in meshes)}, band ±"
            + " / ±".join(f"{100 * s['peaks'][b]['fraction']:.3g} %" for b in flat.PEAKS))


def screened_rows(rows: list[dict], s: dict) -> list[dict]:
    """``rows`` (pipeline.output.flat, one per load) of a variant decided on the cheap level
    with its screening ``s``: each peak with a value gets the screening band (the same
    fraction of the value at every load) and the status SCREENED."""
    for r in rows:
        for block, p in flat.PEAKS.items():
            if r[p.value] is not None and r[p.status] != flat.SINGULAR:
                r[p.band] = s["peaks"][block]["fraction"] * abs(r[p.value])
                r[p.status] = SCREENED
    return rows


def undecided(row: dict, allowable: float) -> bool:
    """Whether a finished row is not decided by its bands against the allowable (MPa):
    some peak with a value is undecided, or a peak is singular (no value: only the full
    analysis says so for certain)."""
    for p in flat.PEAKS.values():
        if row[p.status] == flat.SINGULAR:
            return True
        if row[p.value] is not None and verdict_against(row[p.value], row[p.band], allowable) == "undecided":
            return True
    return False
