"""One bench point in its own process: solve a spec once and print its result, and the
driver's side of that (the environment, mpirun, reading the result back). Units: mm, MPa, s.

    python -m bench.point '{"kind": "dolfinx", "factor": 1.0, "pilot": true}'

The point process times its own stages; its interpreter start is the driver's wall time
minus ``process_s`` (bench.run).
"""
from __future__ import annotations

import time

T_START = time.perf_counter()

from pipeline.api import configure  # noqa: E402

configure()  # the pipeline's form cache and PETSc options in every point process

import importlib  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import TYPE_CHECKING  # noqa: E402

if TYPE_CHECKING:  # for annotations only: a point imports its modules when it runs (timed)
    from pipeline.api import Case
    from pipeline.api import Mesher

ROOT = Path(__file__).resolve().parents[1]


STAGES = ("pilot", "geometry", "mesh", "import", "loads", "assemble", "solve", "write", "ccx", "read",
          "post", "other")


MARK = "BENCH_POINT "


def run_point(spec: dict) -> dict | None:
    """Solve one point once in this process; the result dict on rank 0, None elsewhere."""
    imports = _import_modules(spec["kind"])
    from mpi4py import MPI

    from pipeline.api import resolve_case as resolve
    from pipeline.api import Mesher
    comm = MPI.COMM_WORLD
    if comm.rank == 0:  # a bench stopped while compiling left a claim that would fail every point
        from pipeline.api import jit_cache_dir, remove_interrupted
        remove_interrupted(jit_cache_dir())
    order = int(spec.get("order", 2))
    case = resolve(spec.get("size", "05"),
                   overrides={"mesh_factor": spec["factor"], "order": order,
                              "solver": spec.get("solver") or "pmg", "want": spec.get("want", "both"),
                              **({"size_fillet_mm": spec["size_fillet_mm"]} if spec.get("size_fillet_mm") else {})})
    out: dict = {"spec": spec, "ranks": comm.size, "imports_s": imports}
    comm.barrier()
    t0 = time.perf_counter()
    # The pipeline's default mesh is refined where a pilot solve finds the peaks; both
    # kinds get that mesh and pay the pilot's time.
    mesher = Mesher(case.dims, case.model)  # the pilot's geometry serves the point's mesh too
    hotspots, t_pilot = _pilot_hotspots(spec, case, comm, mesher)
    solve = _solve_dolfinx if spec["kind"] == "dolfinx" else _solve_calculix
    total, stages, fields = solve(spec, case, comm, hotspots, mesher, t0)
    out.update(fields)
    out.update(_totals(stages, total, t_pilot, comm))
    return out if comm.rank == 0 else None


def _import_modules(kind: str) -> float:
    """Import the modules a point of ``kind`` runs on (MPI, the case, the mesher, the pilot,
    the solver's); the time this takes (s), which the point reports apart from its stages
    as ``imports_s``."""
    t_imp = time.perf_counter()
    for name in ("mpi4py.MPI", *(("bench.calculix",) if kind != "dolfinx" else ()),
                 *(("bench.peer",) if kind == "peer" else ())):
        importlib.import_module(name)
    import pipeline.api as api
    for name in ("resolve_case", "Mesher", "refinement_places", "solve_level"):
        getattr(api, name)
    return time.perf_counter() - t_imp


def _pilot_hotspots(spec: dict, case: Case, comm, mesher: Mesher) -> tuple[tuple, float | None]:
    """The places (mm) a run of the case refines the mesh at, and the time finding them
    took (s), when the spec asks for the pilot: the pilot's, or for the critical peak alone
    the known bore edges (pipeline.analysis.pilot.refinement_places); else no places and None."""
    if not spec.get("pilot"):
        return (), None
    from pipeline.api import RunContext, refinement_places
    pl = refinement_places(case, RunContext(comm=comm, mesher=mesher))
    return pl.hotspots, pl.time_s


def _solve_dolfinx(spec: dict, case: Case, comm, hotspots: tuple, mesher: Mesher,
                   t0: float) -> tuple[float, dict[str, float], dict]:
    """Solve the point with the pipeline: its wall time since t0 (s), its stage times (s)
    and its result fields (size, iterations, both peaks in MPa and where they are, mm)."""
    from pipeline.api import LevelTask, RunContext, solve_level
    lv = solve_level(case, LevelTask(spec["factor"], hotspots=hotspots), RunContext(comm=comm, mesher=mesher))
    mesher.close()
    total = time.perf_counter() - t0
    stages = dict(lv.timings)
    fields = {"dofs": lv.dofs, "cells": lv.cells, "iterations": lv.iterations,
              "peak_MPa": lv.peak.value_MPa, "critical_MPa": lv.critical.value_MPa,
              "peak_location_mm": list(lv.peak.location_mm),
              "critical_location_mm": list(lv.critical.location_mm)}
    return total, stages, fields


def _solve_calculix(spec: dict, case: Case, comm, hotspots: tuple, mesher: Mesher,
                    t0: float) -> tuple[float, dict[str, float], dict]:
    """Solve the point with CalculiX on the pipeline's mesh, loads and supports, the peaks
    from its displacement as in the pipeline: wall time since t0 (s), stage times (s) and
    result fields (as :func:`_solve_dolfinx`'s, plus ccx's own peak memory, MiB). A "peer"
    point (a user's mesh, bench.peer) reads its peaks from ccx's .frd nodal stresses
    instead and keeps the pipeline's reading as ``pipeline_peak_MPa``, ``pipeline_critical_MPa``."""
    from bench.calculix import solve_ccx
    from pipeline.api import LevelTask, RunContext, peaks_of, set_up
    if comm.size != 1:
        raise SystemExit("CalculiX points run on one rank (use threads)")
    prob = set_up(case, LevelTask(spec["factor"], hotspots=hotspots), RunContext(comm=comm, mesher=mesher))
    mesher.close()
    m, mat = prob.mesh, prob.material
    cx = solve_ccx(m.mesh, m.facet_tags, prob.loads, mat, threads=int(spec.get("threads", 1)),
                   solver=spec.get("ccx_solver", "spooles"), nodal_stress=spec["kind"] == "peer")
    t1 = time.perf_counter()
    _, pk, cr = peaks_of(case, cx.u, mat)
    read = {"peak_MPa": pk.value_MPa, "peak_location_mm": list(pk.location_mm),
            "critical_MPa": cr.value_MPa, "critical_location_mm": list(cr.location_mm)}
    if spec["kind"] == "peer":
        from bench.calculix import frd_peaks
        read = dict(frd_peaks(case, cx.model.nodes, cx.nodal_stress),
                    pipeline_peak_MPa=pk.value_MPa, pipeline_critical_MPa=cr.value_MPa)
    t_post = time.perf_counter() - t1
    total = time.perf_counter() - t0
    stages = dict(m.timings, **cx.timings, post=t_post)
    stages["loads"] += prob.loads_s
    n_nodes = cx.model.nodes.shape[0]
    fields = {"dofs": 3 * n_nodes, "cells": cx.model.elements.shape[0], "iterations": None, **read,
              "ccx_maxrss_MiB": cx.ccx_maxrss_kib / 1024}
    return total, stages, fields


def _totals(stages: dict[str, float], total: float, t_pilot: float | None, comm) -> dict:
    """The point's times and memory over the ranks: stage times (s, the slowest rank's,
    with the pilot's, and "other" for what no stage accounts for), the total (s), the peak
    memory (MiB, largest and summed) and the process's time since it started (s)."""
    import resource

    from mpi4py import MPI
    if t_pilot is not None:
        stages["pilot"] = t_pilot
    stages = {k: comm.allreduce(float(v), op=MPI.MAX) for k, v in stages.items()}
    total = comm.allreduce(total, op=MPI.MAX)
    stages["other"] = max(total - sum(stages.values()), 0.0)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB → MiB (Linux)
    return {"stages_s": stages, "total_s": total,
            "maxrss_MiB": comm.allreduce(rss, op=MPI.MAX),
            "maxrss_sum_MiB": comm.allreduce(rss, op=MPI.SUM),
            "process_s": time.perf_counter() - T_START}


def point_env(threads: int) -> dict:
    """The environment of a point process: ``threads`` BLAS/OpenMP threads, unbuffered
    output, the repository on the module path, and the run cache off: a point times the
    meshing, the pilot and the solve, not the reuse of an earlier repeat's."""
    env = dict(os.environ)
    env.update(OMP_NUM_THREADS=str(threads), OPENBLAS_NUM_THREADS=str(threads),
               PYTHONUNBUFFERED="1", CROSSHEAD_NO_CACHE="1")
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def mpirun_prefix(ranks: int) -> list[str]:
    """The command prefix that starts ``ranks`` MPI processes (empty for one)."""
    if ranks == 1:
        return []
    exe = shutil.which("mpirun") or shutil.which("mpiexec")
    if exe is None:
        raise FileNotFoundError("mpirun not found (Debian package mpi-default-bin)")
    cmd = [exe]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-run-as-root")
    return cmd + ["--oversubscribe", "-n", str(ranks)]


def spawn_point(spec: dict, ranks: int, threads: int, timeout: float) -> dict:
    """Run one repeat of a point in a fresh process; its result, or {"error": ...}."""
    cmd = mpirun_prefix(ranks) + [sys.executable, "-m", "bench.point", json.dumps(spec)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=point_env(threads), capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:g} s"}
    wall = time.perf_counter() - t0
    lines = [s for s in proc.stdout.splitlines() if s.startswith(MARK)]
    if proc.returncode != 0 or not lines:
        tail = (proc.stderr.strip().splitlines() or proc.stdout.strip().splitlines() or ["no output"])[-1]
        return {"error": f"exit {proc.returncode}: {tail}"}
    res = json.loads(lines[-1][len(MARK):])
    res["wall_s"] = wall
    return res


if __name__ == "__main__":
    result = run_point(json.loads(sys.argv[1]))
    if result is not None:
        print(MARK + json.dumps(result), flush=True)
