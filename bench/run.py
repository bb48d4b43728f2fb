"""Run time against error for No. 05, side by side with CalculiX (mm, N, MPa, s).

    python -m bench --out results/bench            the full matrix (make bench)
    python -m bench --quick --out /tmp/b           2 coarse levels, 1 repeat, P2 pmg/mumps + ccx
    python -m bench --ranks 1,2                    also 2 MPI ranks on the finest P2 mesh
    python -m bench --ranks 1,2 --ranks-at targets also P2 pmg and CalculiX on every level on 2 cores
    python -m bench --ranks 1,2 --ranks-at all     every point also on 2 cores (2 ranks; ccx 2 threads)

The matrix: element order (P1, P2 on every mesh level, P3 on the coarse ones), mesh
factor, solver (pmg, gamg, hypre, mumps; pmg is gamg for P1, so P1 skips it); plus CalculiX (ccx 2.20, C3D10, bench.calculix)
on the same P2 meshes. Every repeat of every point runs in a fresh process
(``python -m bench --point JSON``, under ``mpirun -n 2`` for 2 ranks), so the
peak memory (ru_maxrss) belongs to that point alone and each repeat is what a user's
``python -m pipeline run`` sees: a new interpreter with a warm form-compiler cache. One
warm-up run per kind and order fills that cache before timing starts. Interpreter start
and imports are reported separately and excluded from the stage times.

Times per point are medians over ``--repeats`` runs: geometry, mesh, import (gmsh model
→ DOLFINx), assemble, solve, post (von Mises and peaks), and for CalculiX loads (nodal
loads and node sets from DOLFINx), write (.inp), ccx (wall time of the ccx process) and
read (.dat → DOLFINx function). ``total`` is the wall time from geometry to both peaks.
For CalculiX ``core`` = write + ccx + read (what CalculiX itself costs given the mesh).

Errors are relative to the Richardson-extrapolated peaks of the convergence study
(results/05-converge/results.json, made by ``python -m pipeline converge --size 05
--levels 4`` if it is missing and the default path is used). No output files are written
by the points (no VTK, pictures or report): bench writes bench.csv, bench.json, bench.png.

Threads: every point runs with OMP_NUM_THREADS = OPENBLAS_NUM_THREADS = ``--threads``
(default 1), and ccx with that many threads, so one rank of the pipeline and one ccx
process each use one core; the 2-rank points are compared with ccx on 2 threads.
"""
from __future__ import annotations

import time

T_START = time.perf_counter()

from pipeline.environment import configure  # noqa: E402

configure()  # the pipeline's form cache and PETSc options in every bench process

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from pipeline.choices import SOLVERS  # noqa: E402
from pipeline.jsonio import json_safe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_REFERENCE = Path("results/05-converge/results.json")
FULL_FACTORS = (2.0, 1.5, 1.15, 0.9, 0.7)
P3_FACTORS = (2.0, 1.5)
QUICK_FACTORS = (2.0, 1.5)
STAGES = ("pilot", "geometry", "mesh", "import", "loads", "assemble", "solve", "write", "ccx", "read",
          "post", "other")
MARK = "BENCH_POINT "


# ---------------------------------------------------------------- one point, in its own process

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
        from pipeline.elasticity import Material
        from pipeline.level import peaks_of
        from pipeline.loads import crosshead_loads
        from pipeline.meshing import make_mesh
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
        m = make_mesh(case.dims, case.model, case.mesh_spec(spec["factor"], hotspots), comm=comm, mesher=mesher)
        mesher.close()
        mat = Material(E=case.E_MPa, nu=case.nu)
        t1 = time.perf_counter()
        lc = crosshead_loads(m, case.dims, case.load_N, case.support)
        t_lc = time.perf_counter() - t1
        cx = solve_ccx(m.mesh, m.facet_tags, lc, mat, threads=int(spec.get("threads", 1)),
                       solver=spec.get("ccx_solver", "spooles"))
        t1 = time.perf_counter()
        _, pk, cr = peaks_of(case, cx.u, mat)
        t_post = time.perf_counter() - t1
        total = time.perf_counter() - t0
        stages = dict(m.timings, **cx.timings, post=t_post)
        stages["loads"] += t_lc
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


# ---------------------------------------------------------------- the driver

def _env(threads: int) -> dict:
    env = dict(os.environ)
    env.update(OMP_NUM_THREADS=str(threads), OPENBLAS_NUM_THREADS=str(threads),
               PYTHONUNBUFFERED="1")
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
    cmd = mpirun_prefix(ranks) + [sys.executable, "-m", "bench.run", "--point", json.dumps(spec)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=_env(threads), capture_output=True, text=True,
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


def aggregate(spec: dict, ranks: int, threads: int, runs: list[dict], ref: dict) -> dict:
    """One row: medians of the stage times over the runs, errors against the reference."""
    row = {"kind": spec["kind"], "order": spec.get("order", 2),
           "solver": spec.get("solver") or f"ccx-{spec.get('ccx_solver', 'spooles')}",
           "factor": spec["factor"], "pilot": bool(spec.get("pilot")), "ranks": ranks, "threads": threads,
           "cores": ranks * threads}
    ok = [r for r in runs if "error" not in r]
    if not ok:
        row["error"] = runs[-1].get("error", "no run") if runs else "no run"
        return row
    first = ok[0]
    med = statistics.median
    for k in ("dofs", "cells", "iterations", "peak_MPa", "critical_MPa"):
        row[k] = first.get(k)
    row["peak_location_mm"] = first["peak_location_mm"]
    row["critical_location_mm"] = first["critical_location_mm"]
    for st in STAGES:
        vals = [r["stages_s"].get(st) for r in ok if r["stages_s"].get(st) is not None]
        row[f"t_{st}"] = med(vals) if vals else None
    row["t_total"] = med([r["total_s"] for r in ok])
    row["t_core"] = (med([r["stages_s"]["write"] + r["stages_s"]["ccx"] + r["stages_s"]["read"] for r in ok])
                     if spec["kind"] == "calculix" else row["t_total"])
    row["t_total_min"] = min(r["total_s"] for r in ok)
    row["t_total_max"] = max(r["total_s"] for r in ok)
    row["t_imports"] = med([r["imports_s"] for r in ok])
    row["t_interpreter"] = med([max(r["wall_s"] - r["process_s"], 0.0) for r in ok])
    row["mem_MiB"] = max(r["maxrss_MiB"] for r in ok)
    row["mem_sum_MiB"] = max(r["maxrss_sum_MiB"] for r in ok)
    if spec["kind"] == "calculix":
        row["ccx_mem_MiB"] = max(r.get("ccx_maxrss_MiB", 0.0) for r in ok)
    row["repeats"] = len(ok)
    row["peak_err"] = (row["peak_MPa"] - ref["peak"]) / ref["peak"]
    row["critical_err"] = (row["critical_MPa"] - ref["critical"]) / ref["critical"]
    spread = [abs(r["peak_MPa"] - first["peak_MPa"]) for r in ok]
    row["peak_repeat_spread_MPa"] = max(spread)
    return row


def load_reference(path: Path, make: bool, say, remake: bool = False) -> dict:
    """Extrapolated peaks (MPa) of the convergence study; runs the study if allowed and missing."""
    path = Path(path)
    if not path.is_absolute():
        path = ROOT / path
    if remake or not path.exists():
        if not make:
            raise SystemExit(f"bench: reference {path} not found; run `python -m pipeline converge "
                             f"--size 05 --levels 4 --out {path.parent}` (make converge) first")
        say(f"reference {path} {'to be remade' if remake else 'missing'}: running the convergence study (python -m pipeline converge --size 05 --levels 4)")
        proc = subprocess.run([sys.executable, "-m", "pipeline", "converge", "--size", "05",
                               "--levels", "4", "--out", str(path.parent)], cwd=ROOT, env=_env(1))
        if proc.returncode != 0 or not path.exists():
            raise SystemExit(f"bench: the convergence study failed (exit {proc.returncode}); no reference")
    res = json.loads(path.read_text())
    conv = res.get("convergence") or {}
    ref = {}
    for key in ("peak", "critical"):
        est = conv.get(key) or {}
        if est.get("extrapolated") is None:
            raise SystemExit(f"bench: {path} has no convergence.{key}.extrapolated "
                             f"(status {est.get('status')!r}); cannot measure errors")
        ref[key] = float(est["extrapolated"])
        ref[f"{key}_gci"] = est.get("gci_fine")
        ref[f"{key}_status"] = est.get("status")
    c = res.get("case", {})
    if str(c.get("size")) != "05" or c.get("model") != "quarter" or c.get("support") != "bearing":
        raise SystemExit(f"bench: {path} is not the No. 05 quarter/bearing study")
    ref["path"] = str(path)
    ref["levels"] = conv.get("levels")
    # A reference made before the geometry or mesher last changed belongs to other meshes.
    newer = [str(f.relative_to(ROOT)) for f in (ROOT / "geometry" / "builder.py", ROOT / "pipeline" / "mesh_io.py",
                                                 ROOT / "pipeline" / "solve.py", ROOT / "pipeline" / "crosshead.py")
             if f.exists() and f.stat().st_mtime > path.stat().st_mtime]
    if newer:
        ref["stale_warning"] = (f"{', '.join(newer)} changed after the reference was made; "
                                f"re-run with --remake-reference (or make converge)")
        say(f"WARNING: {ref['stale_warning']}")
    return ref


def time_to_error(rows: list[dict], kinds: set[str], keys: tuple[str, ...], tol: float = 0.01,
                  time_key: str = "t_total", cores: int = 1) -> dict | None:
    """Fastest row of the given kinds on ``cores`` cores whose |errors| (keys) are all <= tol."""
    ok = [r for r in rows if r["kind"] in kinds and r.get("cores") == cores and "error" not in r
          and all(abs(r[k]) <= tol for k in keys)]
    if not ok:
        return None
    best = min(ok, key=lambda r: r[time_key])
    return {"time_s": best[time_key], "config": label(best), "factor": best["factor"],
            "dofs": best["dofs"], "peak_err": best["peak_err"], "critical_err": best["critical_err"]}


def label(r: dict) -> str:
    if r["kind"] == "calculix":
        s = f"CalculiX C3D10 {r['solver'][4:]}" + (" +pilot" if r.get("pilot") else "")
        return s + (f" {r['threads']}thr" if r.get("threads", 1) != 1 else "")
    s = f"P{r['order']} {r['solver']}" + (" +pilot" if r.get("pilot") else "")
    return s + (f" x{r['ranks']}ranks" if r.get("ranks", 1) != 1 else "")


def summary(rows: list[dict], cores: int = 1) -> dict:
    """Times to 1 % error (s) of the pipeline and of CalculiX on ``cores`` cores, their
    ratios, and the 1- against multi-rank times on the finest mesh."""
    out: dict = {"tolerance": 0.01, "cores": cores}
    for name, keys in (("both", ("peak_err", "critical_err")), ("critical", ("critical_err",))):
        pipe = time_to_error(rows, {"dolfinx"}, keys, cores=cores)
        ccx_total = time_to_error(rows, {"calculix"}, keys, cores=cores)
        ccx_core = time_to_error(rows, {"calculix"}, keys, time_key="t_core", cores=cores)
        block = {"pipeline": pipe, "calculix_total": ccx_total, "calculix_core": ccx_core}
        if pipe and ccx_total:
            block["ratio_total"] = ccx_total["time_s"] / pipe["time_s"]
        if pipe and ccx_core:
            block["ratio_core"] = ccx_core["time_s"] / pipe["time_s"]
        out[name] = block
    # Scaling: the same finest-mesh point on more ranks (pipeline) or threads (CalculiX).
    good = [r for r in rows if "error" not in r]
    scaling = []
    for r in good:
        if r["cores"] == cores:
            continue
        base = next((b for b in good if b["cores"] == cores and b["kind"] == r["kind"]
                     and b["order"] == r["order"] and b["solver"] == r["solver"]
                     and b["factor"] == r["factor"] and b.get("pilot") == r.get("pilot")), None)
        if base is None:
            continue
        scaling.append({"config": label(r), "factor": r["factor"], "dofs": r["dofs"],
                        "same_mesh": r["dofs"] == base["dofs"],
                        "cores": r["cores"], "time_s": r["t_total"], "base_time_s": base["t_total"],
                        "speedup": base["t_total"] / r["t_total"],
                        "solve_speedup": (base["t_ccx"] / r["t_ccx"] if r["kind"] == "calculix"
                                          else base["t_solve"] / r["t_solve"]),
                        "peak_rel_diff": (r["peak_MPa"] - base["peak_MPa"]) / base["peak_MPa"],
                        "critical_rel_diff": (r["critical_MPa"] - base["critical_MPa"]) / base["critical_MPa"]})
    out["scaling"] = scaling
    return out


COLUMNS = [("config", 22), ("factor", 6), ("DOFs", 8), ("its", 4), ("geom", 6), ("mesh", 6),
           ("import", 6), ("asm|wr", 6), ("solve|ccx", 9), ("post", 6), ("total", 7),
           ("MiB", 6), ("peak", 7), ("err%", 7), ("crit", 7), ("err%", 7)]


def table(rows: list[dict]) -> str:
    def f(v, w, fmt="{:.2f}"):
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return "-".rjust(w)
        return (fmt.format(v) if not isinstance(v, str) else v).rjust(w)

    head = " ".join(n.rjust(w) for n, w in COLUMNS)
    lines = [head, "-" * len(head)]
    for r in rows:
        if "error" in r:
            lines.append(f"{label(r):>22} {r['factor']:6.2f}  FAILED: {r['error']}")
            continue
        ccx = r["kind"] == "calculix"
        asm = (r["t_loads"] or 0) + (r["t_write"] or 0) if ccx else r["t_assemble"]
        sol = r["t_ccx"] if ccx else r["t_solve"]
        mem = max(r["mem_MiB"], r.get("ccx_mem_MiB") or 0.0)
        cells = [label(r), f"{r['factor']:.2f}", str(r["dofs"]), f(r["iterations"], 4, "{:d}"),
                 f(r["t_geometry"], 6), f(r["t_mesh"], 6), f(r["t_import"], 6), f(asm, 6),
                 f(sol, 9), f(r["t_post"], 6), f(r["t_total"], 7), f(mem, 6, "{:.0f}"),
                 f(r["peak_MPa"], 7), f(100 * r["peak_err"], 7, "{:+.2f}"),
                 f(r["critical_MPa"], 7), f(100 * r["critical_err"], 7, "{:+.2f}")]
        lines.append(" ".join(c.rjust(w) for c, (_, w) in zip(cells, COLUMNS)))
    return "\n".join(lines)


CSV_KEYS = ["kind", "order", "solver", "factor", "ranks", "threads", "dofs", "cells", "iterations",
            "repeats"] + [f"t_{s}" for s in STAGES] + [
            "t_total", "t_core", "t_total_min", "t_total_max", "t_imports", "t_interpreter",
            "mem_MiB", "mem_sum_MiB", "ccx_mem_MiB", "peak_MPa", "peak_err", "critical_MPa",
            "critical_err", "error"]


def write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_KEYS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in CSV_KEYS})


def pareto_plot(path: Path, rows: list[dict], ref: dict) -> bool:
    """Two log-log panels (global, critical): |error| against time, one series per config."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    good = [r for r in rows if "error" not in r]
    series: dict[str, list[dict]] = {}
    for r in good:
        series.setdefault(label(r), []).append(r)
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.8))
    markers = {1: "v", 2: "o", 3: "s"}
    floor = 1e-5
    for ax, key, title in ((axes[0], "peak_err", "global peak"), (axes[1], "critical_err", "critical-region peak")):
        for k, (name, rs) in enumerate(sorted(series.items())):
            rs = sorted(rs, key=lambda r: r["t_total"])
            err = [max(abs(r[key]), floor) for r in rs]
            if rs[0]["kind"] == "calculix":
                # Black for the iterative solver, grey for spooles; dashed on more threads;
                # CalculiX's own part (write + ccx + read) dotted, on one thread only.
                colour = "k" if rs[0]["solver"] == "ccx-iterative" else "0.55"
                one = rs[0].get("threads", 1) == 1
                ax.plot([r["t_total"] for r in rs], err, "-" if one else "--", marker="*", color=colour,
                        ms=9, label=f"{name} (geometry→peak)")
                if one:
                    ax.plot([r["t_core"] for r in rs], err, ":", marker="*", color=colour, ms=7, mfc="none",
                            label=f"{name} (write+ccx+read only)")
            else:
                ax.plot([r["t_total"] for r in rs], err, "-" if rs[0]["ranks"] == 1 else "--",
                        marker=markers.get(rs[0]["order"], "o"), color=f"C{k % 10}", label=name)
        pipe = sorted((r for r in good if r["kind"] == "dolfinx"), key=lambda r: r["t_total"])
        front, best = [], math.inf
        for r in pipe:
            e = max(abs(r[key]), floor)
            if e < best * (1 - 1e-6):
                front.append((r["t_total"], e))
                best = e
        if front:
            ax.step(*zip(*front), where="post", color="grey", lw=4, alpha=0.25, label="pipeline Pareto front")
        ax.axhline(0.01, color="r", ls="--", lw=1, label="1 %")
        ax.set_xscale("log")
        ax.set_yscale("log")
        errs = [max(abs(r[key]), floor) for r in good] or [0.01]
        ax.set_ylim(min(0.5 * min(errs), 1e-3), max(1.5 * max(errs), 0.02))
        ax.set_xlabel("wall time, geometry → peaks (s; median of repeats)")
        ax.set_ylabel("|relative error| vs the reference")
        ax.set_title(f"No. 05 {title} (reference {ref['peak' if key == 'peak_err' else 'critical']:.2f} MPa)")
        ax.grid(alpha=0.3, which="both")
    # One legend for both panels (the same series), below them: inside, it covered data.
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def build_matrix(args) -> list[tuple[dict, int, int]]:
    """(spec, ranks, threads) for every point, cheapest first within each series."""
    pts: list[tuple[dict, int, int]] = []
    thr = args.threads
    factors = sorted(args.factors, reverse=True)
    pilots = {"on": (True,), "off": (False,), "both": (False, True)}[args.pilot]
    for pl in pilots:
        for order in args.orders:
            fs = factors if order != 3 else sorted(args.p3_factors, reverse=True)
            for f in fs:
                for s in args.solvers:
                    if order == 1 and s == "pmg" and "gamg" in args.solvers:
                        continue  # the same solver for P1 (pipeline.solve)
                    pts.append(({"kind": "dolfinx", "order": order, "factor": f, "solver": s, "pilot": pl}, 1, thr))
        if args.ccx:
            for f in factors:
                for cs in args.ccx_solvers:
                    pts.append(({"kind": "calculix", "order": 2, "factor": f, "ccx_solver": cs,
                                 "threads": thr, "pilot": pl}, 1, thr))
    # On more cores: the finest P2 mesh (the scaling check, every solver), and with
    # --ranks-at targets also the pipeline's default solver (pmg) on P2 and CalculiX at every
    # mesh level (the time to 1 % with every core in use), or with --ranks-at all every point.
    # The pipeline gets n MPI ranks, CalculiX (one process) n threads.
    finest = min(factors)

    def twin(spec: dict) -> bool:
        if args.ranks_at == "all":
            return True
        if spec["order"] != 2 or spec["pilot"] != pilots[-1]:
            return False
        return spec["factor"] == finest or (args.ranks_at == "targets" and
                                            (spec["kind"] == "calculix" or spec["solver"] == "pmg"))

    twins = [spec for spec, _, _ in pts if twin(spec)]
    for n in args.ranks:
        if n == 1:
            continue
        for spec in twins:
            if spec["kind"] == "calculix":
                pts.append((dict(spec, threads=n * thr), 1, n * thr))
            else:
                pts.append((spec, n, thr))
    return pts


def _csv_list(conv):
    return lambda s: [conv(x) for x in s.split(",") if x.strip()]


def make_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("results/bench"), help="output folder (default results/bench)")
    p.add_argument("--quick", action="store_true",
                   help="2 coarse levels, 1 repeat, P2 pmg + mumps + CalculiX (for tests)")
    p.add_argument("--repeats", type=int, help="runs per point, median taken (default 3; --quick 1)")
    p.add_argument("--factors", type=_csv_list(float), help="mesh factors (default 2.0,1.5,1.15,0.9,0.7)")
    p.add_argument("--p3-factors", type=_csv_list(float), help="mesh factors for P3 (default 2.0,1.5)")
    p.add_argument("--orders", type=_csv_list(int), help="element orders (default 1,2,3)")
    p.add_argument("--solvers", type=_csv_list(str), help="pmg,gamg,hypre,mumps (default all)")
    p.add_argument("--ccx-solvers", type=_csv_list(str),
                   help="CalculiX solvers: spooles (direct), iterative (ITERATIVE CHOLESKY); "
                        "default both (--quick: spooles)")
    p.add_argument("--no-ccx", dest="ccx", action="store_false", help="skip CalculiX")
    p.add_argument("--pilot", choices=("on", "off", "both"), default="both",
                   help="meshes refined where a pilot solve finds the peaks (the pipeline's default), "
                        "plain graded meshes, or both (default; --quick: off)")
    p.add_argument("--ranks", type=_csv_list(int), default=[1],
                   help="MPI rank counts for the finest P2 mesh, e.g. 1,2 (default 1)")
    p.add_argument("--ranks-at", choices=("finest", "targets", "all"), default="finest",
                   help="where the --ranks counts above 1 run: the finest P2 mesh only (default); "
                        "targets: also P2 pmg and CalculiX (with as many threads) on every mesh level, "
                        "for the time to 1 %% on every core; all: every point")
    p.add_argument("--threads", type=int, default=1, help="threads per rank and for ccx (default 1)")
    p.add_argument("--reference", type=Path, default=DEFAULT_REFERENCE,
                   help="convergence-study results.json with the extrapolated peaks")
    p.add_argument("--reference-values", type=_csv_list(float),
                   help="GLOBAL,CRITICAL peaks (MPa) of an independent solution to measure errors "
                        "against instead of the study's extrapolation")
    p.add_argument("--remake-reference", action="store_true",
                   help="re-run the convergence study into the --reference folder first")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per run before it is abandoned")
    p.add_argument("--no-warmup", dest="warmup", action="store_false", help="skip the warm-up runs")
    p.add_argument("--point", help=argparse.SUPPRESS)
    return p


def main(argv: list[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    if args.point:
        res = run_point(json.loads(args.point))
        if res is not None:
            print(MARK + json.dumps(res), flush=True)
        return 0
    if args.quick:
        args.factors = args.factors or list(QUICK_FACTORS)
        args.orders = args.orders or [2]
        args.solvers = args.solvers or ["pmg", "mumps"]
        args.repeats = args.repeats or 1
        args.ccx_solvers = args.ccx_solvers or ["spooles"]
        args.pilot = "off" if args.pilot == "both" else args.pilot
    args.ccx_solvers = args.ccx_solvers or ["spooles", "iterative"]
    args.factors = args.factors or list(FULL_FACTORS)
    args.p3_factors = args.p3_factors or list(P3_FACTORS)
    args.orders = args.orders or [1, 2, 3]
    args.solvers = args.solvers or list(SOLVERS)
    args.repeats = args.repeats or 3
    bad = [s for s in args.solvers if s not in SOLVERS] + \
          [s for s in args.ccx_solvers if s not in ("spooles", "iterative")]
    if args.reference_values is not None and (len(args.reference_values) != 2 or
                                              not all(math.isfinite(v) and v > 0 for v in args.reference_values)):
        sys.stderr.write("error: --reference-values needs two positive numbers GLOBAL,CRITICAL (MPa)\n")
        return 2
    if bad or any(o not in (1, 2, 3) for o in args.orders) or args.repeats < 1 or \
            any(n < 1 for n in args.ranks) or args.threads < 1:
        sys.stderr.write("error: bad --solvers/--ccx-solvers/--orders/--repeats/--ranks/--threads\n")
        return 2
    if args.ccx and shutil.which("ccx") is None:
        sys.stderr.write("error: ccx (CalculiX) not found; install calculix-ccx (tools/setup.sh) or use --no-ccx\n")
        return 2

    def say(msg: str) -> None:
        print(f"[bench {time.perf_counter() - T_START:7.1f} s] {msg}", flush=True)

    make_ref = Path(args.reference) == DEFAULT_REFERENCE
    ref = load_reference(args.reference, make_ref or args.remake_reference, say,
                         remake=args.remake_reference)
    if args.reference_values:
        # An independent solution given by hand (e.g. P3 + MUMPS): errors are measured
        # against it; the study's extrapolation stays in bench.json for comparison.
        ref["study_peak"], ref["study_critical"] = ref["peak"], ref["critical"]
        ref["peak"], ref["critical"] = args.reference_values
        ref["path"] = f"--reference-values (study: {ref['path']})"
        ref["peak_gci"] = ref["critical_gci"] = None
    say(f"reference: peak {ref['peak']:.3f} MPa (GCI {100 * (ref['peak_gci'] or 0):.2f} %), "
        f"critical {ref['critical']:.3f} MPa (GCI {100 * (ref['critical_gci'] or 0):.2f} %) from {ref['path']}")
    out = Path(args.out)
    if not out.is_absolute():
        out = ROOT / out
    out.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()
    fingerprint = source_fingerprint()
    points = build_matrix(args)
    if args.warmup:
        seen = set()
        for spec, ranks, thr in points:
            key = (spec["kind"], spec["order"])
            if key in seen or ranks != 1:
                continue
            seen.add(key)
            w = dict(spec, factor=max(args.factors))
            say(f"warm-up (form cache) {key[0]} P{key[1]}")
            r = spawn_point(w, 1, thr, args.timeout)
            if "error" in r:
                say(f"  warm-up failed: {r['error']}")
    rows = []
    t_bench = time.perf_counter()
    for spec, ranks, thr in points:
        runs = [spawn_point(spec, ranks, thr, args.timeout) for _ in range(args.repeats)]
        row = aggregate(spec, ranks, thr, runs, ref)
        rows.append(row)
        if "error" in row:
            say(f"{label(row)} factor {spec['factor']}: FAILED {row['error']}")
        else:
            say(f"{label(row)} factor {spec['factor']}: {row['dofs']} DOFs, total {row['t_total']:.2f} s, "
                f"peak {row['peak_MPa']:.2f} ({100 * row['peak_err']:+.2f} %), critical "
                f"{row['critical_MPa']:.2f} ({100 * row['critical_err']:+.2f} %)")
    changed = source_fingerprint() != fingerprint
    if changed:
        say("WARNING: geometry/ or pipeline/ sources changed while the bench ran; "
            "its points may come from different meshes: run it again on a frozen tree")
    summ = summary(rows, cores=args.threads)
    by_cores = {n * args.threads: summary(rows, cores=n * args.threads)
                for n in args.ranks if n != 1 and args.ranks_at != "finest"}
    text = table(rows)
    print()
    print(text)
    print()
    print(summary_text(summ))
    for n, s_n in by_cores.items():
        print(f"\non {n} cores (pipeline on {n} MPI ranks, CalculiX with {n} threads):")
        print(summary_text(s_n, scaling=False))
    meta = {"date": time.strftime("%Y-%m-%d %H:%M:%S"), "host": platform.node(),
            "cpus": os.cpu_count(), "python": sys.version.split()[0],
            "loadavg_before": load_before, "loadavg_after": os.getloadavg(),
            "bench_wall_s": time.perf_counter() - t_bench, "repeats": args.repeats,
            "threads": args.threads, "quick": args.quick, "source_fingerprint": fingerprint,
            "sources_changed_during_run": changed,
            "versions": _versions(),
            "notes": ["times are medians over fresh processes with a warm FFCx cache; interpreter "
                      "start and imports are excluded (t_interpreter, t_imports)",
                      "CalculiX core = write + ccx + read; total = geometry → peaks, including the "
                      "gmsh mesh and the DOLFINx import used to build its loads and compute its peaks",
                      "errors are relative to the Richardson extrapolation of the convergence study"]}
    data = {"units": {"time": "s", "stress": "MPa", "memory": "MiB"}, "meta": meta,
            "reference": ref, "rows": rows, "summary": summ,
            "summary_by_cores": {str(n): v for n, v in by_cores.items()}, "table": text}
    (out / "bench.json").write_text(json.dumps(json_safe(data), indent=2) + "\n")
    write_csv(out / "bench.csv", rows)
    plotted = pareto_plot(out / "bench.png", rows, ref)
    say(f"wrote {out}/bench.json, bench.csv" + (", bench.png" if plotted else ""))
    return 0 if all("error" not in r for r in rows) else 3


def summary_text(s: dict, scaling: bool = True) -> str:
    lines = []
    for name, title in (("both", "both peaks"), ("critical", "critical peak")):
        b = s[name]
        p, ct, cc = b["pipeline"], b["calculix_total"], b["calculix_core"]

        def one(x):
            return "not reached" if x is None else \
                f"{x['time_s']:.2f} s ({x['config']}, factor {x['factor']}, {x['dofs']} DOFs)"
        lines.append(f"time to 1 % ({title}): pipeline {one(p)}")
        lines.append(f"    CalculiX geometry→peaks {one(ct)}; write+ccx+read only {one(cc)}")
        if "ratio_total" in b or "ratio_core" in b:
            r1 = b.get("ratio_total")
            r2 = b.get("ratio_core")
            lines.append(f"    CalculiX / pipeline: {r1:.2f}× (geometry→peaks), {r2:.2f}× (ccx core only)"
                         if r1 and r2 else f"    CalculiX / pipeline: {r1 or r2}")
    for sc in s.get("scaling", []) if scaling else []:
        lines.append(f"{sc['config']} on {sc['cores']} cores, factor {sc['factor']} ({sc['dofs']} DOFs): "
                     f"{sc['time_s']:.2f} s vs {sc['base_time_s']:.2f} s (speed-up {sc['speedup']:.2f}, "
                     f"solve {sc['solve_speedup']:.2f}); peaks differ by {sc['peak_rel_diff']:.1e} / "
                     f"{sc['critical_rel_diff']:.1e} relative"
                     + ("" if sc["same_mesh"] else " -- NOT THE SAME MESH (DOFs differ)"))
    return "\n".join(lines)


def source_fingerprint() -> str:
    """Hash of the sources that decide the mesh and the solution (a bench needs them frozen)."""
    import hashlib
    h = hashlib.sha1()
    files = sorted((ROOT / "geometry").glob("*.py")) + sorted((ROOT / "pipeline").glob("*.py")) + \
        [ROOT / "geometry" / "sizes.csv"]
    for f in files:
        if f.exists():
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _versions() -> dict:
    out = {}
    try:
        import dolfinx
        import gmsh
        out["dolfinx"], out["gmsh"] = dolfinx.__version__, gmsh.__version__
    except Exception:  # noqa: BLE001 - versions are informative only
        pass
    try:
        first = subprocess.run(["ccx", "-v"], capture_output=True, text=True, timeout=10).stdout
        out["ccx"] = " ".join(first.split())
    except Exception:  # noqa: BLE001
        pass
    return out


if __name__ == "__main__":
    sys.exit(main())
