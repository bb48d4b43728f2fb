"""The cost of `make run`'s sensitivity section: today's `make run`, the same with
`--no-sensitivity`, and the `make run` of an earlier commit, timed as whole processes (s).

    python -m bench.run_cost --out results/bench-run [--repeats 3] [--base 83d9271]

Each run is No. 05 on 2 MPI ranks with the run cache off (CROSSHEAD_NO_CACHE=1) into a
fresh folder. The three commands take turns after one warm-up each (interleaved: a drift
of the machine's speed touches all alike); the figures are medians over ``--repeats`` and
the medians of the pairwise ratios. The earlier commit is exported with `git archive`
into ``--out``/base-<commit> (kept for the next bench) and run from there with the same
interpreter, its own launcher (pipeline.launch before the runtime package existed).
Target (docs/performance.md): with the section ≤ 2× the earlier `make run`.
Writes run_cost.json and prints a table.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pipeline.api import refusal

ROOT = Path(__file__).resolve().parents[1]
BASE = "83d9271"  # the round before the sensitivity section (docs/performance.md, `make run`)
TARGET = 2.0  # with the section / the earlier run, at most
OWN_FILES = frozenset({"run_cost.json", "work"})
CONFIGS = ("with", "without", "base")


def base_tree(out: Path, commit: str) -> Path:
    """The files of ``commit`` exported under ``out`` (no worktree, no .git), made once."""
    tree = out / f"base-{commit}"
    if not (tree / "pipeline").is_dir():
        tmp = Path(tempfile.mkdtemp(dir=out, prefix=".export-"))
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", commit],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
        tmp.rename(tree)
    return tree


def launcher(tree: Path) -> str:
    """The module that starts an MPI run in ``tree``: pipeline.runtime.launch, or the older
    pipeline.launch."""
    return "pipeline.runtime.launch" if (tree / "pipeline" / "runtime" / "launch.py").is_file() else "pipeline.launch"


def command(config: str, tree: Path, out: Path) -> list[str]:
    """The run of one configuration: `make run`'s command on 2 ranks into ``out``."""
    head = [sys.executable, "-m", launcher(tree), "2", "run", "--size", "05", "--out", str(out), "--quiet"]
    return head + (["--no-sensitivity"] if config == "without" else [])


def _children_cpu_s() -> float:
    """User + system CPU time (s) of this process's finished children and theirs."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def time_run(config: str, tree: Path, work: Path) -> tuple[float, float]:
    """One whole run's wall and CPU time (s; CPU of every process it started, the MPI ranks
    included), into a fresh folder under ``work`` that is removed after."""
    scratch = Path(tempfile.mkdtemp(dir=work, prefix=f"{config}-"))
    env = dict(os.environ, CROSSHEAD_NO_CACHE="1")
    try:
        t0, c0 = time.perf_counter(), _children_cpu_s()
        p = subprocess.run(command(config, tree, scratch / "run"), cwd=tree, env=env, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _children_cpu_s() - c0
    finally:
        shutil.rmtree(scratch)  # made here, holds only this run's folder
    if p.returncode != 0:
        raise SystemExit(f"{config}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")
    return wall, cpu


def summarise(walls: dict[str, list[float]], cpus: dict[str, list[float]] | None = None) -> dict:
    """Medians (s) per configuration and the medians of the pairwise ratios (repeat k of one
    configuration against repeat k of another: they ran minutes apart); the same of the CPU
    times when given (on a machine shared with other work, the steadier figure)."""
    def ratio(t: dict[str, list[float]], a: str, b: str) -> dict:
        rs = [x / y for x, y in zip(t[a], t[b])]
        return {"median": statistics.median(rs), "min": min(rs), "max": max(rs), "pairs": len(rs)}

    out = {c: {"median_s": statistics.median(w), "min_s": min(w), "max_s": max(w), "runs": len(w)}
           for c, w in walls.items()}
    out["with_over_base"] = ratio(walls, "with", "base")
    out["without_over_base"] = ratio(walls, "without", "base")
    out["with_over_without"] = ratio(walls, "with", "without")
    if cpus:
        for c, t in cpus.items():
            out[c]["cpu_median_s"] = statistics.median(t)
        out["cpu_with_over_base"] = ratio(cpus, "with", "base")
        out["cpu_without_over_base"] = ratio(cpus, "without", "base")
    out["target"] = TARGET
    out["met"] = out["with_over_base"]["median"] <= TARGET
    return out


def table(s: dict, base: str) -> str:
    """The summary as text."""
    rows = [f"{'run':40s} wall median (min-max) s", "-" * 66]
    names = {"with": "make run (with the sensitivity section)", "without": "make run --no-sensitivity",
             "base": f"make run of {base}"}
    rows += [f"{names[c]:40s} {s[c]['median_s']:6.2f} ({s[c]['min_s']:.2f}-{s[c]['max_s']:.2f})" for c in CONFIGS]
    w = s["with_over_base"]
    rows.append(f"with / {base}: {w['median']:.2f} ({w['min']:.2f}-{w['max']:.2f}, {w['pairs']} pairs); "
                f"without / {base}: {s['without_over_base']['median']:.2f}; with / without: "
                f"{s['with_over_without']['median']:.2f}; target <= {TARGET:g}: {'yes' if s['met'] else 'NO'}")
    if "cpu_with_over_base" in s:
        rows.append(f"CPU: with / {base} {s['cpu_with_over_base']['median']:.2f}, without / {base} "
                    f"{s['cpu_without_over_base']['median']:.2f} (medians of the pairs)")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.run_cost", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench-run")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each configuration (default 3)")
    ap.add_argument("--base", default=BASE, help=f"the earlier commit (default {BASE})")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        print("bench.run_cost: --repeats must be >= 1", file=sys.stderr)
        return 2
    why = refusal(args.out, OWN_FILES | {f"base-{args.base}"})
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    work = args.out / "work"
    work.mkdir(parents=True, exist_ok=True)
    trees = {"with": ROOT, "without": ROOT, "base": base_tree(args.out, args.base)}
    t_all = time.perf_counter()
    for c in CONFIGS:  # warm-up: file caches, compiled forms
        wall, _ = time_run(c, trees[c], work)
        print(f"[{time.perf_counter() - t_all:7.1f} s] warm-up {c}: {wall:.2f} s", flush=True)
    walls: dict[str, list[float]] = {c: [] for c in CONFIGS}
    cpus: dict[str, list[float]] = {c: [] for c in CONFIGS}
    for k in range(args.repeats):
        for c in CONFIGS:
            wall, cpu = time_run(c, trees[c], work)
            walls[c].append(wall)
            cpus[c].append(cpu)
            print(f"[{time.perf_counter() - t_all:7.1f} s] repeat {k + 1}/{args.repeats} {c}: {wall:.2f} s, "
                  f"CPU {cpu:.2f} s", flush=True)
    with contextlib.suppress(OSError):
        work.rmdir()  # empty now: each run removed its own folder
    summary = summarise(walls, cpus)
    (args.out / "run_cost.json").write_text(json.dumps({"base": args.base, "walls_s": walls, "cpu_s": cpus,
                                                        "summary": summary},
                                                       indent=2) + "\n", encoding="utf-8")
    print(table(summary, args.base))
    return 0


if __name__ == "__main__":
    sys.exit(main())
