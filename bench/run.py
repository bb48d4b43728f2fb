"""Run time against error for No. 05, side by side with CalculiX (mm, N, MPa, s).

    python -m bench --out results/bench            the full matrix (make bench)
    python -m bench --quick --out /tmp/b           2 coarse levels, 1 repeat, P2 pmg/mumps + ccx
    python -m bench --ranks 1,2                    also 2 MPI ranks on the finest P2 mesh
    python -m bench --ranks 1,2 --ranks-at targets also P2 pmg and CalculiX on every level on 2 cores
    python -m bench --ranks 1,2 --ranks-at all     every point also on 2 cores (2 ranks; ccx 2 threads)

The matrix: element order (P1, P2 on every mesh level, P3 on the coarse ones), mesh
factor, solver (pmg, gamg, hypre, mumps; pmg is gamg for P1, so P1 skips it); plus CalculiX (ccx 2.20, C3D10, bench.calculix)
on the same P2 meshes. Every repeat of every point runs in a fresh process
(``python -m bench.point JSON``, under ``mpirun -n 2`` for 2 ranks; bench/point.py), so the
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

from pipeline.api import configure  # noqa: E402

configure()  # the pipeline's form cache and PETSc options in every bench process

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from pipeline.api import SOLVERS  # noqa: E402
from pipeline.api import refusal  # noqa: E402
from pipeline.api import code_key, source_files  # noqa: E402
from pipeline.api import json_safe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OWN_FILES = frozenset({"bench.json", "bench.csv", "bench.png", "bench.md"})  # written into --out (bench.md: earlier versions)
# The files that decide a reference study's numbers: the part, its mesh, the loads, the
# solve, how peaks are read and how the study extrapolates.
REFERENCE_INPUTS = tuple(f.relative_to(ROOT).as_posix() for f in source_files(ROOT))
DEFAULT_REFERENCE = Path("results/05-converge/results.json")
FULL_FACTORS = (2.0, 1.5, 1.15, 0.9, 0.7)
P3_FACTORS = (2.0, 1.5)
QUICK_FACTORS = (2.0, 1.5)


from bench.point import point_env, spawn_point  # noqa: E402
from bench.tables import aggregate, csv_list, label, pareto_plot, summary, summary_text, table, write_csv  # noqa: E402



def load_reference(path: Path, make: bool, say, remake: bool = False) -> dict:
    """Extrapolated peaks (MPa) of the convergence study; runs the study if allowed and missing."""
    path = Path(path)
    if not path.is_absolute():
        path = ROOT / path
    if remake or not path.exists():
        if not make:
            raise SystemExit(f"bench: reference {path} not found; run `python -m pipeline converge "
                             f"--size 05 --levels 4 --out {path.parent}` (make converge) first")
        say(f"reference {path} {'to be remade' if remake else 'missing'}: running the convergence study "
            "(python -m pipeline converge --size 05 --levels 4)")
        proc = subprocess.run([sys.executable, "-m", "pipeline", "converge", "--size", "05",
                               "--levels", "4", "--out", str(path.parent)], cwd=ROOT, env=point_env(1))
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
    newer = [str(f.relative_to(ROOT)) for f in (ROOT / name for name in REFERENCE_INPUTS)
             if f.stat().st_mtime > path.stat().st_mtime]
    if newer:
        ref["stale_warning"] = (f"{', '.join(newer)} changed after the reference was made; "
                                f"re-run with --remake-reference (or make converge)")
        say(f"WARNING: {ref['stale_warning']}")
    return ref


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
                        continue  # the same solver for P1 (pipeline.fe.solve)
                    pts.append(({"kind": "dolfinx", "order": order, "factor": f, "solver": s, "pilot": pl,
                                 "want": args.want}, 1, thr))
        if args.ccx:
            for f in factors:
                for cs in args.ccx_solvers:
                    pts.append(({"kind": "calculix", "order": 2, "factor": f, "ccx_solver": cs,
                                 "threads": thr, "pilot": pl, "want": args.want}, 1, thr))
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


def make_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=Path("results/bench"), help="output folder (default results/bench)")
    p.add_argument("--quick", action="store_true",
                   help="2 coarse levels, 1 repeat, P2 pmg + mumps + CalculiX (for tests)")
    p.add_argument("--repeats", type=int, help="runs per point, median taken (default 3; --quick 1)")
    p.add_argument("--factors", type=csv_list(float), help="mesh factors (default 2.0,1.5,1.15,0.9,0.7)")
    p.add_argument("--p3-factors", type=csv_list(float), help="mesh factors for P3 (default 2.0,1.5)")
    p.add_argument("--orders", type=csv_list(int), help="element orders (default 1,2,3)")
    p.add_argument("--solvers", type=csv_list(str), help="pmg,gamg,hypre,mumps (default all)")
    p.add_argument("--ccx-solvers", type=csv_list(str),
                   help="CalculiX solvers: spooles (direct), iterative (ITERATIVE CHOLESKY); "
                        "default both (--quick: spooles)")
    p.add_argument("--no-ccx", dest="ccx", action="store_false", help="skip CalculiX")
    p.add_argument("--pilot", choices=("on", "off", "both"), default="both",
                   help="meshes refined where a pilot solve finds the peaks (the pipeline's default), "
                        "plain graded meshes, or both (default; --quick: off)")
    p.add_argument("--want", choices=("both", "critical"), default="both",
                   help="the peaks every point's mesh is made for (the run's scene): both (default), or "
                        "critical (with --pilot on: the known bore edges refined, no pilot solve)")
    p.add_argument("--ranks", type=csv_list(int), default=[1],
                   help="MPI rank counts for the finest P2 mesh, e.g. 1,2 (default 1)")
    p.add_argument("--ranks-at", choices=("finest", "targets", "all"), default="finest",
                   help="where the --ranks counts above 1 run: the finest P2 mesh only (default); "
                        "targets: also P2 pmg and CalculiX (with as many threads) on every mesh level, "
                        "for the time to 1 %% on every core; all: every point")
    p.add_argument("--threads", type=int, default=1, help="threads per rank and for ccx (default 1)")
    p.add_argument("--reference", type=Path, default=DEFAULT_REFERENCE,
                   help="convergence-study results.json with the extrapolated peaks")
    p.add_argument("--reference-values", type=csv_list(float),
                   help="GLOBAL,CRITICAL peaks (MPa) of an independent solution to measure errors "
                        "against instead of the study's extrapolation")
    p.add_argument("--remake-reference", action="store_true",
                   help="re-run the convergence study into the --reference folder first")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per run before it is abandoned")
    p.add_argument("--no-warmup", dest="warmup", action="store_false", help="skip the warm-up runs")
    return p


def main(argv: list[str] | None = None) -> int:
    args = make_parser().parse_args(argv)
    _fill_defaults(args)
    error = _argument_error(args)
    if error is not None:
        sys.stderr.write(error)
        return 2
    out = Path(args.out)
    if not out.is_absolute():
        out = ROOT / out
    why = refusal(out, OWN_FILES)
    if why is not None:
        sys.stderr.write(why + "\n")
        return 2
    ref = _reference(args)
    out.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()
    fingerprint = source_fingerprint()
    points = build_matrix(args)
    if args.warmup:
        _warm_up(points, max(args.factors), args.timeout)
    t_bench = time.perf_counter()
    rows = _run_points(points, args.repeats, args.timeout, ref)
    changed = source_fingerprint() != fingerprint
    if changed:
        _say("WARNING: geometry/ or pipeline/ sources changed while the bench ran; "
             "its points may come from different meshes: run it again on a frozen tree")
    summ, by_cores, text = _print_tables(rows, args.threads, args.ranks, args.ranks_at)
    meta = _meta(args, load_before, t_bench, fingerprint, changed)
    _write_outputs(out, meta, ref, rows, summ, by_cores, text)
    return 0 if all("error" not in r for r in rows) else 3


def _say(msg: str) -> None:
    """One progress line, stamped with the seconds since this process started."""
    print(f"[bench {time.perf_counter() - T_START:7.1f} s] {msg}", flush=True)


def _fill_defaults(args: argparse.Namespace) -> None:
    """Fill the options left out: --quick's small matrix first, then the full matrix's
    defaults (mesh factors, orders, solvers, 3 repeats) for what is still unset."""
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


def _argument_error(args: argparse.Namespace) -> str | None:
    """The stderr line for options the bench cannot run with (exit 2), or None: reference
    values that are not two positive MPa, unknown solvers or orders, counts below 1, or
    CalculiX asked for but not installed."""
    bad = [s for s in args.solvers if s not in SOLVERS] + \
          [s for s in args.ccx_solvers if s not in ("spooles", "iterative")]
    if args.reference_values is not None and (len(args.reference_values) != 2 or
                                              not all(math.isfinite(v) and v > 0 for v in args.reference_values)):
        return "error: --reference-values needs two positive numbers GLOBAL,CRITICAL (MPa)\n"
    if bad or any(o not in (1, 2, 3) for o in args.orders) or args.repeats < 1 or \
            any(n < 1 for n in args.ranks) or args.threads < 1:
        return "error: bad --solvers/--ccx-solvers/--orders/--repeats/--ranks/--threads\n"
    if args.ccx and shutil.which("ccx") is None:
        return "error: ccx (CalculiX) not found; install calculix-ccx (tools/setup.sh) or use --no-ccx\n"
    return None


def _reference(args: argparse.Namespace) -> dict:
    """The peaks (MPa) errors are measured against: the convergence study's extrapolation
    (made first when the default path is missing or --remake-reference asks), or the
    --reference-values given by hand; says which."""
    make_ref = Path(args.reference) == DEFAULT_REFERENCE
    ref = load_reference(args.reference, make_ref or args.remake_reference, _say,
                         remake=args.remake_reference)
    if args.reference_values:
        # An independent solution given by hand (e.g. P3 + MUMPS): errors are measured
        # against it; the study's extrapolation stays in bench.json for comparison.
        ref["study_peak"], ref["study_critical"] = ref["peak"], ref["critical"]
        ref["peak"], ref["critical"] = args.reference_values
        ref["path"] = f"--reference-values (study: {ref['path']})"
        ref["peak_gci"] = ref["critical_gci"] = None
    _say(f"reference: peak {ref['peak']:.3f} MPa (GCI {100 * (ref['peak_gci'] or 0):.2f} %), "
         f"critical {ref['critical']:.3f} MPa (GCI {100 * (ref['critical_gci'] or 0):.2f} %) from {ref['path']}")
    return ref


def _warm_up(points: list[tuple[dict, int, int]], factor: float, timeout: float) -> None:
    """One untimed run per kind and element order on one rank, at the coarsest mesh
    ``factor``, so the form-compiler cache is full before any point is timed."""
    seen = set()
    for spec, ranks, thr in points:
        key = (spec["kind"], spec["order"])
        if key in seen or ranks != 1:
            continue
        seen.add(key)
        w = dict(spec, factor=factor)
        _say(f"warm-up (form cache) {key[0]} P{key[1]}")
        r = spawn_point(w, 1, thr, timeout)
        if "error" in r:
            _say(f"  warm-up failed: {r['error']}")


def _run_points(points: list[tuple[dict, int, int]], repeats: int, timeout: float, ref: dict) -> list[dict]:
    """Every point ``repeats`` times, each run in a fresh process (at most ``timeout`` s);
    one row per point with the median times (s) and the errors against ``ref``, each said
    as it finishes."""
    rows = []
    for spec, ranks, thr in points:
        runs = [spawn_point(spec, ranks, thr, timeout) for _ in range(repeats)]
        row = aggregate(spec, ranks, thr, runs, ref)
        rows.append(row)
        if "error" in row:
            _say(f"{label(row)} factor {spec['factor']}: FAILED {row['error']}")
        else:
            _say(f"{label(row)} factor {spec['factor']}: {row['dofs']} DOFs, total {row['t_total']:.2f} s, "
                 f"peak {row['peak_MPa']:.2f} ({100 * row['peak_err']:+.2f} %), critical "
                 f"{row['critical_MPa']:.2f} ({100 * row['critical_err']:+.2f} %)")
    return rows


def _print_tables(rows: list[dict], threads: int, ranks: list[int],
                  ranks_at: str) -> tuple[dict, dict[int, dict], str]:
    """Print the table of every point and the time-to-1 % summary on one core per process
    (``threads`` threads), then on each larger core count the --ranks ran every level on;
    returns (summary, summaries by core count, table text) for bench.json."""
    summ = summary(rows, cores=threads)
    by_cores = {n * threads: summary(rows, cores=n * threads)
                for n in ranks if n != 1 and ranks_at != "finest"}
    text = table(rows)
    print()
    print(text)
    print()
    print(summary_text(summ))
    for n, s_n in by_cores.items():
        print(f"\non {n} cores (pipeline on {n} MPI ranks, CalculiX with {n} threads):")
        print(summary_text(s_n, scaling=False))
    return summ, by_cores, text


def _meta(args: argparse.Namespace, load_before: tuple[float, float, float], t_bench: float,
          fingerprint: str, changed: bool) -> dict:
    """How, where and when the bench ran, for bench.json: the machine, its load before
    and now, the wall time since ``t_bench`` (s), the sources' fingerprint, versions."""
    return {"date": time.strftime("%Y-%m-%d %H:%M:%S"), "host": platform.node(),
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


def _write_outputs(out: Path, meta: dict, ref: dict, rows: list[dict], summ: dict,
                   by_cores: dict[int, dict], text: str) -> None:
    """Write bench.json (everything, units s, MPa, MiB), bench.csv (the rows) and
    bench.png (error against time, when matplotlib can draw it) into ``out``."""
    data = {"units": {"time": "s", "stress": "MPa", "memory": "MiB"}, "meta": meta,
            "reference": ref, "rows": rows, "summary": summ,
            "summary_by_cores": {str(n): v for n, v in by_cores.items()}, "table": text}
    (out / "bench.json").write_text(json.dumps(json_safe(data), indent=2) + "\n")
    write_csv(out / "bench.csv", rows)
    plotted = pareto_plot(out / "bench.png", rows, ref)
    _say(f"wrote {out}/bench.json, bench.csv" + (", bench.png" if plotted else ""))


def source_fingerprint() -> str:
    """The code key of the sources that decide the mesh and the solution (a bench needs them frozen)."""
    code_key.cache_clear()
    return code_key(ROOT)[:16]


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
