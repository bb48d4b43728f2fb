"""The error-bar meshes' results of an earlier run, scaled to a new hook load Q (N)
instead of meshed, solved and read again.

An error-bar mesh contributes only numbers to a run (its peaks and where they sit, its
forces, sizes and solver figures), no fields. With traction loads in linear elasticity
every stress (MPa) and force (N) of a mesh scales with Q/Q0 and none depends on E, and
where the peaks sit does not move (pipeline/cache/solutions.py says the same of the
displacements). So a run that changes only the load, E or the allowable takes each
error-bar mesh's results from the run cache, scaled, and neither imports that mesh nor
solves it: those meshes cost the ranks about 0.7 s each in such a run (No. 05), beside the
picture and the plots on the same cores.

The key is everything that makes those numbers apart from Q and E: the mesh spec (sizes,
factor, refined places), the part, model, support, ν, element order, solver and
tolerance, and the source of the code that meshes, solves and reads the peaks. Entries
live in the run cache (pipeline/cache/runs.py) and follow its switch and size bound.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

from pipeline.cache import runs as runcache
from pipeline.inputs.case import Case
from pipeline.analysis.level import Level
from pipeline.post.peaks import NodalPeak, Peak


@dataclass
class Stored:
    """An error-bar mesh's Level (no fields) at load ``load_N`` (N) and modulus ``E_MPa`` (MPa)."""

    load_N: float
    E_MPa: float
    level: Level


def key(case: Case, spec) -> str:
    """The run-cache key of the case's results on the mesh of ``spec`` (a MeshSpec)."""
    return runcache.key("level", spec=spec, dims=case.dims, model=case.model, support=case.support,
                        nu=case.nu, order=case.order, solver=case.solver, rtol=case.rtol)


def store(name: str, lv: Level, case: Case) -> None:
    """Keep ``lv``, solved at the case's load and E (its fields, if any, are not kept)."""
    runcache.store(name, Stored(case.load_N, case.E_MPa, replace(lv, fields=None, sections=None)))


def earlier(name: str, case: Case) -> Level | None:
    """The stored results ``name`` scaled to the case's load, or None. The Level's timings
    are the lookup's (s); its ``scaled_from`` names the stored load and E."""
    t0 = time.perf_counter()
    entry = runcache.load(name)
    if not (isinstance(entry, Stored) and entry.load_N > 0.0 and case.load_N > 0.0):
        return None  # von Mises scales with |Q|: a sign change would need the tensor
    k = case.load_N / entry.load_N
    lv = entry.level
    return replace(lv, peak=_scaled(lv.peak, k), critical=_scaled(lv.critical, k),
                   seat_force_N=k * lv.seat_force_N, support_force_N=k * lv.support_force_N,
                   equilibrium_error_N=k * lv.equilibrium_error_N,
                   constraint_reaction_N=k * lv.constraint_reaction_N,
                   timings={"post": time.perf_counter() - t0},
                   scaled_from={"load_N": entry.load_N, "E_MPa": entry.E_MPa})


def _scaled(p: NodalPeak, k: float) -> NodalPeak:
    """A peak read two ways, both readings × k (MPa), in the same places."""
    return replace(p, unaveraged=Peak(k * p.unaveraged.value_MPa, p.unaveraged.location_mm),
                   averaged=Peak(k * p.averaged.value_MPa, p.averaged.location_mm))
