"""crosshead's public entry points: what a user's script, the examples and the bench use
(mm, N, MPa). Everything else in the package is internal and may move.

    from pipeline.api import RunOptions, resolve_case, run
    case = resolve_case("05")                       # hook No. 05 under its rated load
    result = run(case, RunOptions(sensitivity=False))
    print(result.peaks["peak"].value_MPa, result.peaks["peak"].band_MPa)

``run`` computes and decides and writes nothing; ``write_run`` runs into an output
folder and writes results.json, the report, the field file and the pictures, as
`crosshead run` does. Below them, the building blocks of one mesh (set up, solve, read
the peaks) for peers and references that solve the same problem another way, and the
process and folder helpers every entry point uses.

Importing this module sets the process up (pipeline/runtime/environment.py: threads,
form cache, PETSc options) and loads nothing else: each name loads its module when it is
first used, so a tool that only checks a folder does not start MPI or DOLFINx.
"""
from __future__ import annotations

import importlib

from pipeline.runtime.environment import configure

configure()  # before numpy, PETSc or DOLFINx load

# Each public name and the module that defines it (under the same name unless given).
WHERE = {
    # The run.
    "RunContext": "pipeline.analysis.context", "RunResult": "pipeline.analysis.result",
    "PeakAnswer": "pipeline.analysis.result", "Verdict": "pipeline.analysis.result",
    "run": "pipeline.analysis.run", "write_run": "pipeline.output.folder",
    "Case": "pipeline.inputs.case", "resolve_case": ("pipeline.inputs.case", "resolve"),
    "RunOptions": "pipeline.inputs.options", "Outputs": "pipeline.inputs.options",
    "converge_options": "pipeline.inputs.options", "SOLVERS": "pipeline.inputs.choices",
    "InputError": "pipeline.errors", "NumericalError": "pipeline.errors",
    # One mesh: its places, its problem, its solve and its peaks.
    "Level": "pipeline.analysis.level", "LevelTask": "pipeline.analysis.level", "Problem": "pipeline.analysis.level",
    "peaks_of": "pipeline.analysis.level", "set_up": "pipeline.analysis.level", "solve_level": "pipeline.analysis.level",
    "MeshPlan": "pipeline.analysis.meshes", "solve_meshes": "pipeline.analysis.meshes",
    "analyse_sensitivity": "pipeline.analysis.sensitivity", "analyse_variant": "pipeline.analysis.sensitivity",
    "Pilot": "pipeline.analysis.pilot", "known_places": "pipeline.analysis.pilot", "pilot": "pipeline.analysis.pilot",
    "refinement_places": "pipeline.analysis.pilot",
    "dirichlet_bc": "pipeline.fe.assembly", "Material": "pipeline.fe.elasticity", "strain": "pipeline.fe.elasticity",
    "stress": "pipeline.fe.elasticity", "LoadCase": "pipeline.fe.loads",
    "Mesher": "pipeline.fe.meshing", "make_mesh": "pipeline.fe.meshing", "meshing_scale": "pipeline.fe.meshing",
    "normalised": "pipeline.fe.meshing", "owners": "pipeline.fe.meshing",
    "estimate_levels": "pipeline.post.errorbar", "critical_region": "pipeline.post.features",
    "fillet_region": "pipeline.post.features",
    "MIDPOINT": "pipeline.post.peaks", "UNAVERAGED": "pipeline.post.peaks", "NodalPeak": "pipeline.post.peaks",
    "Peak": "pipeline.post.peaks", "NodeReadings": "pipeline.post.peaks", "node_readings": "pipeline.post.peaks",
    "node_peak": "pipeline.post.peaks",
    "peak": "pipeline.post.peaks", "von_mises": "pipeline.post.peaks", "von_mises_of": "pipeline.post.peaks",
    # Design studies: the screening steps and their bands.
    "STEPS": "pipeline.study.screening", "TWO_MESH_FACTOR": "pipeline.study.screening",
    # Files and the process.
    "write_fields": "pipeline.output.fields", "json_safe": "pipeline.output.jsonio",
    "code_key": "pipeline.cache.codekey", "source_files": "pipeline.cache.codekey",
    "jit_cache_dir": "pipeline.cache.forms", "remove_interrupted": "pipeline.cache.forms",
    "write_text": "pipeline.runtime.atomicfile", "marked_kind": "pipeline.runtime.folders",
    "refusal": "pipeline.runtime.folders",
}
__all__ = ["configure", *WHERE]


def __getattr__(name: str):
    """Load a public name's module on first use (PEP 562)."""
    where = WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'pipeline.api' has no attribute {name!r}")
    module, attr = (where, name) if isinstance(where, str) else where
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value
