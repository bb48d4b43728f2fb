"""The words a run's decisions are said in, in one place: the terminal, the report, the
plots, a study's table and results.json take them from here (or from results.json, which
holds what these made), so that one status is named alike everywhere."""
from __future__ import annotations

# The stresses a verdict is given for, by results.json's verdict names.
STRESS_NAMES = {"global_peak": "global peak", "critical_peak": "critical peak",
                "critical_section_nominal": "critical-section nominal stress",
                "journal_root_nominal": "journal-root nominal stress"}


def value_text(value: float | str, unit: str) -> str:
    """An input's value with its unit: '1.2 mm', or a choice as it is ('uniform')."""
    return value if isinstance(value, str) else f"{value:.4g} {unit}".rstrip()


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
