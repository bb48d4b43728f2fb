"""The words a run's decisions are said in, in one place: the terminal, the report, the
plots, a study's table and results.json take them from here (or from results.json, which
holds what these made), so that one status is named alike everywhere."""
from __future__ import annotations

import re

# A peak's status: how far its error bar can be trusted, in the words every output uses
# (results.json's fe.peak.status and fe.critical.status, the terminal, the plots' titles,
# the report, the tables' peak_status and critical_status columns), decided once by
# peak_status below when the run builds its answer (pipeline.analysis.run.peak_answer).
WITHIN_TOLERANCE = "within tolerance"  # its band is at most the tolerance asked (% of the value)
ABOVE_TOLERANCE = "above tolerance"    # its band is wider than the tolerance asked
SINGLE_MESH = "single mesh"            # read on one mesh (--levels 1): no error bar
SINGULAR = "singular"                  # at a singular feature: no finite value, no verdict
NOT_ASKED = "not asked"                # the run did not refine for it (--want): no value, no verdict
PEAK_STATUSES = {
    WITHIN_TOLERANCE: "its error bar is at most the tolerance asked (case tolerance_pct, % of the value)",
    ABOVE_TOLERANCE: "its error bar is wider than the tolerance asked: a finer --mesh-factor narrows it",
    SINGLE_MESH: "read on one mesh (--levels 1): no error bar",
    SINGULAR: "it sits at a singular feature and grows under refinement: no finite value, no verdict",
    NOT_ASKED: "the run was asked for the other peak only (--want) and did not refine for this one: "
               "no value, no verdict",
}


def peak_status(tolerance_pct: float, value_MPa: float, band_MPa: float | None, singular: str | None,
                wanted: bool) -> str:
    """A peak's status (the words above), decided once for every output: not asked
    for (not ``wanted``), at a ``singular`` feature, read on a single mesh (no band), else
    whether its band (MPa) is within ``tolerance_pct`` (% of ``value_MPa``), the same test
    as the run's accuracy (tolerance.within)."""
    if not wanted:
        return NOT_ASKED
    if singular is not None:
        return SINGULAR
    if band_MPa is None:
        return SINGLE_MESH
    return WITHIN_TOLERANCE if 100.0 * band_MPa / max(abs(value_MPa), 1e-300) <= tolerance_pct else ABOVE_TOLERANCE


# A verdict (results.json's fe.verdict.*.verdict) as a person reads it, on the terminal,
# in the report and in the plots.
VERDICT_WORDS = {"pass": "PASS", "fail": "FAIL", "undecided": "UNDECIDED", "none": "no verdict"}


def verdict_word(verdict: str) -> str:
    """A verdict for a person: 'PASS', 'FAIL', 'UNDECIDED' (the band holds the allowable) or
    'no verdict'."""
    return VERDICT_WORDS.get(verdict, verdict)


# The stresses a verdict is given for, by results.json's verdict names.
STRESS_NAMES = {"global_peak": "global peak", "critical_peak": "critical peak",
                "critical_section_nominal": "critical-section nominal stress",
                "journal_root_nominal": "journal-root nominal stress"}


# How a sensitivity sentence opens (pipeline.analysis.verdicts.sentence), by what it says:
# the verdict holds at both ends of every range, it flips at an end, or neither can be
# said of every range (an end not analysed, nothing varied, no verdict to hold). The
# study's tables sort the variants by these (:func:`rests_on`).
HOLDS, FLIPS, NOT_CHECKED = "holds", "flips", "not checked"  # what rests_on returns
HOLDS_OPENING, FLIPS_OPENING = "The verdict holds over every range", "The verdict flips on"


def rests_on(sentence: str) -> str:
    """What a sensitivity sentence says of the verdict: HOLDS at both ends of every range,
    FLIPS at an end, or NOT_CHECKED (an end not analysed, nothing varied, no verdict);
    '' for no sentence (no sensitivity section). A multi-load run's sentence, one sentence
    per group of loads ("At 5000 N: The verdict ... At 10000 N: The verdict ..."), is read
    sentence by sentence: it flips if one flips, and holds only if every one holds."""
    if not sentence:
        return ""
    clauses = [c for c in re.split(r"(?:^|(?<=\.) )At [0-9][^:]*: ", sentence) if c]
    kinds = {FLIPS if c.startswith(FLIPS_OPENING) else HOLDS if c.startswith(HOLDS_OPENING) else NOT_CHECKED
             for c in clauses}
    return FLIPS if FLIPS in kinds else NOT_CHECKED if NOT_CHECKED in kinds else HOLDS


def value_text(value: float | str, unit: str) -> str:
    """An input's value with its unit: '1.2 mm', or a choice as it is ('uniform')."""
    return value if isinstance(value, str) else f"{value:.4g} {unit}".rstrip()


def loads_text(loads: list[float]) -> str:
    """Hook loads (N), sorted, as a person reads them: '5000 N', '5000 and 10000 N',
    '5000, 7500 and 10000 N', or for more than four the ends and the count ('5000–20000 N,
    7 loads')."""
    q = sorted(loads)
    if len(q) > 4:
        return f"{q[0]:g}–{q[-1]:g} N, {len(q)} loads"
    return (", ".join(f"{v:g}" for v in q[:-1]) + " and " if len(q) > 1 else "") + f"{q[-1]:g} N"


def range_text(rng: list, unit: str) -> str:
    """A range: '1.2–1.8 mm', or the two choices ('cosine / uniform')."""
    lo, hi = rng
    return f"{lo} / {hi}" if isinstance(lo, str) else f"{lo:.4g}–{hi:.4g} {unit}".rstrip()


COARSE_FILLET_FACTOR = 1.3  # meshes coarser than this do not resolve the shoulder fillet (README, Known limits)


def coarse_mesh_note(case) -> str | None:
    """The note a run on a mesh too coarse for the fillet carries (None otherwise): its
    global peak's value and verdict are rough."""
    if case.mesh_factor > COARSE_FILLET_FACTOR and case.want != "critical":
        return (f"mesh factor {case.mesh_factor:g} > {COARSE_FILLET_FACTOR:g}: the global (fillet) peak is not resolved "
                "on meshes this coarse (README, Known limits); its value and verdict are rough")
    return None
