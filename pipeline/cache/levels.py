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

Besides the entry's sha256, a reused result is checked for consistency of its stored
numbers: every one finite, the mesh factor the spec's, the seat force equal to the
model's share of the stored load (−Q/4 or −Q, N, to 1e-9), the equilibrium error and the
constraint reaction within the 1e-6·Q (N) a solve must meet, the residual within the
solver's limit, DOFs a multiple of three, no peak below zero.

A checksum proves that a file is whole, not that it is true: a result whose peaks were
scaled and whose checksum was written again passed those checks (its error bars grew from
16.8 / 0.72 to 41.8 / 13.0 MPa). So a result is stored only with what it derives from, the
names and sha256 of the mesh entry and the solution entry (pipeline/cache/meshes.py,
pipeline/cache/solutions.py) of the same mesh and problem, and before reuse both must still
be there (a result whose entries were evicted is dropped without a line: stale, not
damaged), unchanged, of one mesh (the solution's nodes at the mesh's node positions to 1e-6
mm, its DOFs and iterations the result's), and both peaks' readings are read again from
them at the places the result names (pipeline/post/reread.py: the cells around each place,
about 0.1 s) and must equal the stored ones, scaled to the stored load, to DERIVED_REL.
Forging a result that passes means computing the stress field's readings at another
place of the mesh: the work the cache saves, not an edit. A P3 solution is not kept, so a
P3 result is not either.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, replace

from geometry.table import model_share
from pipeline.cache import runs as runcache
from pipeline.fe.linearity import stress_factor
from pipeline.inputs.case import Case
from pipeline.post.peaks import MIDPOINT, UNAVERAGED, NodalPeak, Peak

REDO = "solved again"
# Why a result cannot be checked because the mesh or solution entry it derives from is no
# longer kept (the cache drops the least recently used): it is dropped without a line, as
# a result never kept would be; one whose entries changed is refused with one.
GONE = "the mesh or solution it derives from is no longer kept"
# A stored reading and the one read again from its solution agree to this (relative):
# far above the round-off of two ways of reading one field (~1e-13) and the solver's
# tolerance between a solve and a later one of the same problem (rtol 1e-8 on the
# residual), far below a change of an error bar worth the name.
DERIVED_REL = 1e-6
NUMBERS = ("factor", "dofs", "cells", "iterations", "residual_rel", "seat_force_N", "support_force_N",
           "equilibrium_error_N", "constraint_reaction_N", "jacobian_ratio")
FORCES = ("seat_force_N", "support_force_N", "equilibrium_error_N", "constraint_reaction_N")  # scale with Q


@dataclass(frozen=True)
class StoredLevel:
    """An error-bar mesh's numbers (NUMBERS: sizes, solver figures, forces in N), its two
    peaks (MPa, mm), its timings (s) and the load and E it was solved at."""

    numbers: dict
    peak: NodalPeak
    critical: NodalPeak
    timings: dict
    scaled_from: dict | None = None


def key(case: Case, spec) -> str:
    """The run-cache key of the case's results on the mesh of ``spec`` (a MeshSpec)."""
    return runcache.key("level", spec=spec, dims=case.dims, model=case.model, support=case.support,
                        bearing=case.load_model(),
                        nu=case.nu, order=case.order, solver=case.solver, rtol=case.rtol)


def derives_from(mesh: str, solution: str | None) -> dict | None:
    """What a result of the mesh entry ``mesh`` solved as the solution entry ``solution``
    derives from: both names and the sha256 their files hold now; None when one of them is
    not kept (the cache is off, the solution is P3's, an entry above the bound)."""
    if solution is None:
        return None
    sums = {k: runcache.digest(n) for k, n in (("mesh", mesh), ("solution", solution))}
    if None in sums.values():
        return None
    return {"mesh": mesh, "mesh_sha256": sums["mesh"], "solution": solution, "solution_sha256": sums["solution"]}


def store(name: str, level: StoredLevel, case: Case, derived: dict | None) -> None:
    """Keep ``level``, solved at the case's load and E, with what it ``derived`` from
    (:func:`derives_from`); a result that names no such entries is not kept: it could not be
    checked against them."""
    meta = {k: level.numbers[k] for k in NUMBERS}
    if derived is None or not runcache.finite(*meta.values()):
        return  # not a result to reuse (the checks below would refuse it)
    meta.update(load_N=case.load_N, E_MPa=case.E_MPa, peak=_plain(level.peak), critical=_plain(level.critical),
                timings=dict(level.timings), scaled_from=level.scaled_from, derives_from=derived)
    runcache.store(name, runcache.Entry(meta))


def earlier(name: str, case: Case, factor: float) -> StoredLevel | None:
    """The stored results ``name`` of the mesh at ``factor`` scaled to the case's load, or
    None (a failed entry is dropped, with one line). The timings are the lookup's (s);
    ``scaled_from`` names the stored load and E."""
    t0 = time.perf_counter()
    entry = runcache.load(name, REDO)
    if entry is None:
        return None
    why = problem(entry.meta, case, factor) or derivation_problem(entry.meta, case)
    if why == GONE:  # what it derives from was evicted (least recently used): stale, not damaged
        with contextlib.suppress(OSError):
            runcache.path_of(name).unlink()
        return None
    if why is not None:
        runcache.reject(name, why, REDO)
        return None
    m = entry.meta
    if not case.load_N > 0.0:
        return None  # von Mises scales with |Q|: a sign change would need the tensor
    k = stress_factor(case.load_N, m["load_N"])
    numbers = {n: (k * m[n] if n in FORCES else m[n]) for n in NUMBERS}
    return StoredLevel(numbers, _scaled(_peak(m["peak"]), k), _scaled(_peak(m["critical"]), k),
                       {"post": time.perf_counter() - t0}, {"load_N": m["load_N"], "E_MPa": m["E_MPa"]})


def problem(m: dict, case: Case, factor: float) -> str | None:
    """What is inconsistent in a stored result (a few words), or None."""
    try:
        peaks = [_peak(m["peak"]), _peak(m["critical"])]
        numbers = [m[k] for k in NUMBERS] + [m["load_N"], m["E_MPa"]]
    except (KeyError, TypeError, ValueError, IndexError):
        return "a number missing or of the wrong type"
    if not (runcache.finite(*numbers) and all(runcache.finite(p.unaveraged.value_MPa, p.averaged.value_MPa,
                                                               *p.unaveraged.location_mm, *p.averaged.location_mm)
                                              for p in peaks)):
        return "a number missing or not finite"
    load, share = m["load_N"], model_share(case.model)
    if m["factor"] != factor:
        return f"mesh factor {m['factor']:g}, not {factor:g}"
    if not (load > 0 and m["E_MPa"] > 0):
        return "a stored load or E not above zero"
    if abs(m["seat_force_N"] + share * load) > 1e-9 * share * load:
        return f"seat force {m['seat_force_N']:.9g} N for a load of {load:.9g} N"
    if max(m["equilibrium_error_N"], m["constraint_reaction_N"]) > 1e-6 * load:
        return "out of balance"
    if not (0 <= m["residual_rel"] <= max(1e3 * case.rtol, 1e-6)):
        return f"residual {m['residual_rel']:.3g}"
    if any(int(m[k]) != m[k] or m[k] < 0 for k in ("dofs", "cells", "iterations")) or m["dofs"] % 3 or not m["cells"]:
        return "sizes not whole"
    if not m["jacobian_ratio"] > 0 or any(min(p.unaveraged.value_MPa, p.averaged.value_MPa) < 0 for p in peaks):
        return "a peak below zero or an inverted element"
    return None


def _plain(p: NodalPeak) -> dict:
    """A peak as JSON: its two readings (MPa, mm) and its rule."""
    return {"unaveraged": [p.unaveraged.value_MPa, list(p.unaveraged.location_mm)],
            "averaged": [p.averaged.value_MPa, list(p.averaged.location_mm)], "rule": p.rule}


def _peak(d: dict) -> NodalPeak:
    """The peak that :func:`_plain` wrote; ValueError if it is not one."""
    if d["rule"] not in (MIDPOINT, UNAVERAGED) or any(len(d[k][1]) != 3 for k in ("unaveraged", "averaged")):
        raise ValueError("not a peak")
    return NodalPeak(unaveraged=Peak(d["unaveraged"][0], tuple(d["unaveraged"][1])),
                     averaged=Peak(d["averaged"][0], tuple(d["averaged"][1])), rule=d["rule"])


def _scaled(p: NodalPeak, k: float) -> NodalPeak:
    """A peak read two ways, both readings × k (MPa), in the same places."""
    return replace(p, unaveraged=Peak(k * p.unaveraged.value_MPa, p.unaveraged.location_mm),
                   averaged=Peak(k * p.averaged.value_MPa, p.averaged.location_mm))


def derivation_problem(m: dict, case: Case) -> str | None:
    """What of a stored result (its meta ``m``, checked by :func:`problem`) its mesh and
    solution entries do not bear out, in a few words, or None (see the module: both there
    and unchanged, of one mesh, and both peaks' readings read again from them)."""
    import numpy as np

    from pipeline.cache import meshes as meshcache
    from pipeline.cache import solutions as solvecache
    from pipeline.post.reread import MeshArrays, readings_at
    d = m.get("derives_from")
    if not isinstance(d, dict) or not all(isinstance(d.get(k), str) for k in
                                          ("mesh", "mesh_sha256", "solution", "solution_sha256")):
        return "it names no mesh and solution it derives from"
    mesh_sum = runcache.digest(d["mesh"])
    if mesh_sum is None:
        return GONE
    if mesh_sum != d["mesh_sha256"]:
        return "the mesh it derives from has changed since"
    loaded = runcache.load(d["solution"], REDO)
    if loaded is None:
        return GONE
    if loaded.sha256 != d["solution_sha256"]:
        return "the solution it derives from has changed since"
    sol = solvecache.as_stored(loaded)
    mesh = meshcache.earlier(d["mesh"])
    if sol is None or mesh is None:
        return "the mesh or solution it derives from is not one"
    x = np.asarray(mesh.fields["x"], dtype=np.float64)
    cells = np.asarray(mesh.fields["cells"])
    if cells.ndim != 2 or cells.shape[1] not in (4, 10) or len(x) == 0 or sol.node_ids.max(initial=-1) >= len(x):
        return "its mesh is not one of tetrahedra of degree 1 or 2"
    if np.abs(x[sol.node_ids] - sol.nodes_mm).max(initial=0.0) > 1e-6:
        return "its solution is not of its mesh"
    if (sol.dofs, sol.iterations) != (m["dofs"], m["iterations"]):
        return f"its DOFs and iterations ({m['dofs']}, {m['iterations']}) are not its solution's"
    u = np.full((len(x), 3), np.nan)
    u[sol.node_ids] = sol.u_mm
    arrays = MeshArrays(x, cells[:, _gmsh_to_dolfinx(cells.shape[1])])
    k = stress_factor(m["load_N"], sol.load_N)  # stresses scale with the load; E does not change them
    for which in ("peak", "critical"):
        p = _peak(m[which])
        read = readings_at(arrays, u, sol.E_MPa, case.nu, p.unaveraged.location_mm, p.averaged.location_mm,
                           1e-6 * max(1.0, float(np.abs(x).max())))
        stored = (p.unaveraged.value_MPa, p.averaged.value_MPa)
        if read is None or not all(np.isfinite(read)):
            return f"its {which} peak's places are not nodes of its mesh"
        if any(abs(k * r - v) > DERIVED_REL * max(abs(v), 1e-300) for r, v in zip(read, stored)):
            return (f"its {which} peak's readings {stored[0]:.6g} / {stored[1]:.6g} MPa are not what its solution "
                    f"gives there, {k * read[0]:.6g} / {k * read[1]:.6g} MPa")
    return None


def _gmsh_to_dolfinx(nodes: int):
    """The column order that turns a gmsh tetrahedron of ``nodes`` nodes into DOLFINx's."""
    from dolfinx.io import gmshio
    from dolfinx.mesh import CellType
    return gmshio.cell_perm_array(CellType.tetrahedron, nodes)
