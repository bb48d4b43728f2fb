"""The cheap level of a screened design study (mm, N, MPa): one coarse mesh per variant,
read with a conservative band, which decides a variant against the allowable when the
band stays clear of it; only the others get the full error bar (pipeline.study.sweep).

The cheap level is one mesh at SCREEN_RATIO × the case's mesh factor, refined at the
pilot's places like every run, with no error-bar meshes. Its band per peak is the larger
of a fixed fraction of the value (MARGIN) and half the gap between the unaveraged and
averaged readings (the midpoint's own bracket, docs/design.md §5). The fractions are
chosen by measurement: the band of every variant of the 19 sizes and of No. 05's
rf × dj grid holds the full study's value with its error bar (docs/accuracy.md, *The
screening level*); coarse meshes misread the fillet by up to +7.8 % at factors 2–4.
"""
from __future__ import annotations

from dataclasses import replace

from pipeline.inputs.case import Case
from pipeline.output import flat
from pipeline.post.errorbar import verdict_against

SCREEN_RATIO = 2.2  # the cheap level's mesh factor: the case's × this
# Per peak (results.json's fe block): the band's smallest fraction of the value.
MARGIN = {"peak": 0.10, "critical": 0.03}
SCREENED = "screened"  # a peak's status on the cheap level (its band is the screening band)
FILE = "screening.json"  # beside a screened variant's results.json


def screen_case(case: Case) -> Case:
    """The case the cheap level analyses: the same part and load on a mesh SCREEN_RATIO
    times coarser (one mesh, no error bar)."""
    return replace(case, mesh_factor=case.mesh_factor * SCREEN_RATIO)


def screening_of(res: dict) -> dict:
    """The cheap level's reading of a one-mesh run's results.json content ``res``: per peak
    its value (MPa), band (MPa, ±), the band's fraction of the value, and the evidence in
    words; ``full_error_bar`` False (the variant is decided here until the study says
    otherwise)."""
    fe = res["fe"]
    peaks = {}
    for block in flat.PEAKS:
        b = fe[block]
        key = "peak_MPa" if block == "peak" else "critical_peak_MPa"
        # A peak not asked for (want) has no answer (null): its reading, for orientation.
        value = fe[key] if fe.get(key) is not None else fe.get(key.replace("_MPa", "_unresolved_MPa"))
        un, av = b.get("unaveraged_MPa"), b.get("averaged_MPa")
        gap = 0.0 if un is None or av is None else 0.5 * abs(un - av)
        band = max(MARGIN[block] * abs(value), gap)
        peaks[block] = {"value_MPa": value, "band_MPa": band, "fraction": band / abs(value) if value else 0.0,
                        "bracket_MPa": gap}
    return {"mesh_factor": res["case"]["mesh_factor"], "ratio": SCREEN_RATIO, "margin": dict(MARGIN),
            "peaks": peaks, "full_error_bar": False, "why_full": None}


def evidence(s: dict) -> str:
    """How a variant was decided, in words: the cheap level's mesh and bands, or why it got
    the full error bar."""
    if s["full_error_bar"]:
        return f"full error bar ({s['why_full']})"
    return (f"screened: one mesh at factor {s['mesh_factor']:.3g}, band ±"
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
