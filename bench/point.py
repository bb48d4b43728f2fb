"""One bench point in its own process: solve a spec once and print its result, and the
driver's side of that (the environment, mpirun, reading the result back). Units: mm, MPa, s.

    python -m bench.point '{"kind": "dolfinx", "factor": 1.0, "pilot": true}'

The point process times its own stages; its interpreter start is the driver's wall time
minus ``process_s`` (bench.run).
"""
from __future__ import annotations

import time

T_START = time.perf_counter()

from pipeline.environment import configure  # noqa: E402

configure()  # the pipeline's form cache and PETSc options in every point process

import json  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


STAGES = ("pilot", "geometry", "mesh", "import", "loads", "assemble", "solve", "write", "ccx", "read",
          "post", "other")


MARK = "BENCH_POINT "


def run_point(spec: dict) -> dict | None:
    """Solve one point once in this process; the result dict on rank 0, None elsewhere."""
    import resource
    t_imp = time.perf_counter()
    from mpi4py import MPI

    from pipeline.case import resolve
    comm = MPI.COMM_WORLD
    from pipeline.meshing import Mesher
    from pipeline.pilot import pilot
    if spec["kind"] == "dolfinx":
        from pipeline.level import solve_level
    else:
        from bench.calculix import solve_ccx
        from pipeline.level import peaks_of, set_up
    imports = time.perf_counter() - t_imp
    if comm.rank == 0:  # a bench stopped while compiling left a claim that would fail every point
        from pipeline.formcache import jit_cache_dir, remove_interrupted
        remove_interrupted(jit_cache_dir())
    order = int(spec.get("order", 2))
    case = resolve(spec.get("size", "05"),
                   overrides={"mesh_factor": spec["factor"], "order": order,
                              "solver": spec.get("solver") or "pmg"})
    out: dict = {"spec": spec, "ranks": comm.size, "imports_s": imports}
    comm.barrier()
    t0 = time.perf_counter()
    # The pipeline's default mesh is refined where a pilot solve finds the peaks; both
    # kinds get that mesh and pay the pilot's time.
    hotspots, t_pilot = (), None
    mesher = Mesher(case.dims, case.model)  # the pilot's geometry serves the point's mesh too
    if spec.get("pilot"):
        pl = pilot(case, comm=comm, mesher=mesher)
        hotspots, t_pilot = pl.hotspots, pl.time_s
    if spec["kind"] == "dolfinx":
        lv = solve_level(case, spec["factor"], comm=comm, hotspots=hotspots, mesher=mesher)
        mesher.close()
        total = time.perf_counter() - t0
        stages = dict(lv.timings)
        out.update(dofs=lv.dofs, cells=lv.cells, iterations=lv.iterations,
                   peak_MPa=lv.peak.value_MPa, critical_MPa=lv.critical.value_MPa,
                   peak_location_mm=list(lv.peak.location_mm),
                   critical_location_mm=list(lv.critical.location_mm))
    else:
        if comm.size != 1:
            raise SystemExit("CalculiX points run on one rank (use threads)")
        prob = set_up(case, spec["factor"], comm=comm, hotspots=hotspots, mesher=mesher)
        mesher.close()
        m, mat = prob.mesh, prob.material
        cx = solve_ccx(m.mesh, m.facet_tags, prob.loads, mat, threads=int(spec.get("threads", 1)),
                       solver=spec.get("ccx_solver", "spooles"))
        t1 = time.perf_counter()
        _, pk, cr = peaks_of(case, cx.u, mat)
        t_post = time.perf_counter() - t1
        total = time.perf_counter() - t0
        stages = dict(m.timings, **cx.timings, post=t_post)
        stages["loads"] += prob.loads_s
        n_nodes = cx.model.nodes.shape[0]
        out.update(dofs=3 * n_nodes, cells=cx.model.elements.shape[0], iterations=None,
                   peak_MPa=pk.value_MPa, critical_MPa=cr.value_MPa,
                   peak_location_mm=list(pk.location_mm),
                   critical_location_mm=list(cr.location_mm),
                   ccx_maxrss_MiB=cx.ccx_maxrss_kib / 1024)
    if t_pilot is not None:
        stages["pilot"] = t_pilot
    # Stage times: the slowest rank's; "other" is what no stage accounts for.
    stages = {k: comm.allreduce(float(v), op=MPI.MAX) for k, v in stages.items()}
    total = comm.allreduce(total, op=MPI.MAX)
    stages["other"] = max(total - sum(stages.values()), 0.0)
    out["stages_s"] = stages
    out["total_s"] = total
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB → MiB (Linux)
    out["maxrss_MiB"] = comm.allreduce(rss, op=MPI.MAX)
    out["maxrss_sum_MiB"] = comm.allreduce(rss, op=MPI.SUM)
    out["process_s"] = time.perf_counter() - T_START
    return out if comm.rank == 0 else None


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
