"""The speed targets of a run against version 0.6 (the code before the sensitivity
section), timed as whole processes (s), and one table of every speed target with its
measured ratio and the command that reproduces it.

    python -m bench.run_cost --out results/bench-run [--repeats 3] [--base 83d9271]
        [--peer results/bench-peer/peer.json] [--sweeps results/bench-sweeps/sweeps.json]

The configurations, each a whole process into a fresh folder:

- ``with``: `make run` (No. 05 on 2 MPI ranks, everything included), run cache off;
- ``without``: the same with `--no-sensitivity`;
- ``base``: version 0.6's `make run` (the earlier commit, exported with `git archive` into
  ``--out``/base-<commit>, kept for the next bench, run with the same interpreter and its
  own launcher), run cache off;
- ``reload``: a changed-load re-run: `make run`'s command at 12 000 N after the same part
  at 10 000 N (untimed, a new rf per repeat so that the first is cold), cache on;
- ``scene``: the critical-peak scene, cold: `run --want critical --levels 1
  --mesh-factor 4 --no-fields` on one process, run cache off.

They take turns after one warm-up each (interleaved: a drift of the machine's speed
touches all alike); the figures are medians over ``--repeats`` and the medians of the
pairwise ratios; CPU is user + system of every process a run starts. The targets (issue
49): `make run` wall <= 1.2x and CPU <= 1.5x version 0.6's; the changed-load re-run <=
0.30 of version 0.6's cold `make run`; the scene >= 3x faster than CalculiX as its users
run it, at the same accuracy (the fair peer's whole-process time for the critical peak,
read from ``--peer``: `make bench-peer` of the same session); a screened study >= 3x
faster than version 0.6's full study (read from ``--sweeps``: `make bench-sweeps
SWEEP_BENCH_BASE=<version 0.6>`). Writes run_cost.json and prints the table.
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
OWN_FILES = frozenset({"run_cost.json", "work"})
CONFIGS = ("with", "without", "base", "reload", "scene")
# The speed targets: `make run` wall and CPU against version 0.6's (at most), the
# changed-load re-run against version 0.6's cold `make run` (at most), the scene and a
# screened study against their peers (at least).
TARGETS = {"wall": 1.2, "cpu": 1.5, "reload": 0.30, "scene": 3.0, "screen": 3.0}
SCENE = ["--want", "critical", "--levels", "1", "--mesh-factor", "4", "--no-fields"]


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


def command(config: str, tree: Path, out: Path, rf: float | None = None, load: float = 12000.0) -> list[str]:
    """The run of one configuration into ``out``: `make run`'s command on 2 ranks (the
    scene: one process); ``rf`` (mm) and ``load`` (N) for the changed-load re-run."""
    if config == "scene":
        return [sys.executable, "-m", "pipeline", "run", "--size", "05", *SCENE, "--out", str(out), "--quiet"]
    head = [sys.executable, "-m", launcher(tree), "2", "run", "--size", "05", "--out", str(out), "--quiet"]
    if config == "reload":
        return head + ["--dim", f"rf={rf:g}", "--load", f"{load:g}"]
    return head + (["--no-sensitivity"] if config == "without" else [])


def _children_cpu_s() -> float:
    """User + system CPU time (s) of this process's finished children and theirs."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def reload_rf(k: int) -> float:
    """The fillet radius (mm) of the changed-load re-run's repeat ``k``: a part of its own,
    near No. 05's 1.2 mm, so that its first run is cold."""
    return round(1.2 + 0.002 * (k + 1) + 0.0001 * (os.getpid() % 10), 4)


def time_run(config: str, tree: Path, work: Path, k: int = 0) -> tuple[float, float]:
    """One whole run's wall and CPU time (s; CPU of every process it started, the MPI ranks
    included), into a fresh folder under ``work`` that is removed after. The changed-load
    re-run first runs its part at 10 000 N, untimed, with the run cache on."""
    scratch = Path(tempfile.mkdtemp(dir=work, prefix=f"{config}-"))
    env = dict(os.environ, CROSSHEAD_NO_CACHE="0" if config == "reload" else "1")
    rf = reload_rf(k)
    try:
        if config == "reload":
            _run(config, command(config, tree, scratch / "first", rf, 10000.0), tree, env)
        t0, c0 = time.perf_counter(), _children_cpu_s()
        _run(config, command(config, tree, scratch / "run", rf), tree, env)
        wall, cpu = time.perf_counter() - t0, _children_cpu_s() - c0
    finally:
        shutil.rmtree(scratch)  # made here, holds only this run's folders
    return wall, cpu


def _run(config: str, cmd: list[str], tree: Path, env: dict) -> None:
    """Run ``cmd`` in ``tree``; SystemExit with its last line if it fails."""
    p = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{config}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")


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
    if "reload" in walls:
        out["reload_over_base"] = ratio(walls, "reload", "base")
    if cpus:
        for c, t in cpus.items():
            out[c]["cpu_median_s"] = statistics.median(t)
        out["cpu_with_over_base"] = ratio(cpus, "with", "base")
        out["cpu_without_over_base"] = ratio(cpus, "without", "base")
    out["met"] = out["with_over_base"]["median"] <= TARGETS["wall"]
    return out


def targets(s: dict, base: str, peer: dict | None = None, sweeps: dict | None = None) -> list[dict]:
    """Every speed target of a run with its measured figures, ratio, verdict and the
    command that reproduces it: from this bench's summary ``s`` and, when given, the fair
    peer's peer.json content and bench.sweeps' sweeps.json content (None: not measured)."""
    me = "python -m bench.run_cost --out results/bench-run --repeats 3"
    rows = [{"target": f"make run wall <= {TARGETS['wall']:g}x version 0.6", "at_most": TARGETS["wall"],
             "figures": f"{s['with']['median_s']:.2f} s against {s['base']['median_s']:.2f} s",
             "ratio": s["with_over_base"]["median"], "command": me}]
    if "cpu_with_over_base" in s:
        rows.append({"target": f"make run CPU <= {TARGETS['cpu']:g}x version 0.6", "at_most": TARGETS["cpu"],
                     "figures": f"{s['with']['cpu_median_s']:.2f} s against {s['base']['cpu_median_s']:.2f} s",
                     "ratio": s["cpu_with_over_base"]["median"], "command": me})
    if "reload_over_base" in s:
        rows.append({"target": f"changed-load re-run <= {TARGETS['reload']:.2f} of version 0.6's cold make run",
                     "at_most": TARGETS["reload"],
                     "figures": f"{s['reload']['median_s']:.2f} s against {s['base']['median_s']:.2f} s",
                     "ratio": s["reload_over_base"]["median"], "command": me})
    if "scene" in s:
        ccx = None
        if peer is not None:
            best = (peer.get("comparison", {}).get("critical_stays") or {}).get("peer")
            ccx = best and best.get("t_wall")
        rows.append({"target": f"critical-peak scene, cold, >= {TARGETS['scene']:g}x CalculiX at the same accuracy",
                     "at_least": TARGETS["scene"],
                     "figures": f"{s['scene']['median_s']:.2f} s" + (f" against {ccx:.2f} s" if ccx else
                                                                     " (CalculiX not measured: no --peer)"),
                     "ratio": ccx / s["scene"]["median_s"] if ccx else None,
                     "command": me + " --peer results/bench-peer/peer.json (after make bench-peer)"})
    near = (sweeps or {}).get("summary", {}).get("near-screen_against_full")
    rows.append({"target": f"screened study near its allowable >= {TARGETS['screen']:g}x version 0.6's full study",
                 "at_least": TARGETS["screen"],
                 "figures": "not measured: no --sweeps" if near is None else
                 f"{near['decided_cheaply']} of {near['rows']} decided short of the full error bar, decisions "
                 f"identical: {'yes' if near['identical_decisions'] else 'NO'}",
                 "ratio": None if near is None else near["median_ratio"],
                 "command": "make bench-sweeps SWEEP_BENCH_BASE=<a checkout of version 0.6> "
                            "SWEEP_BENCH_ARGS='--studies near-full,near-screen'"})
    for r in rows:
        x = r["ratio"]
        r["met"] = None if x is None else (x <= r["at_most"] if "at_most" in r else x >= r["at_least"])
    return rows


def table(s: dict, base: str, rows: list[dict]) -> str:
    """The runs' medians, then the targets (:func:`targets`) as text."""
    names = {"with": "make run", "without": "make run --no-sensitivity", "base": f"make run of {base}",
             "reload": "changed-load re-run (cache on)", "scene": "critical-peak scene (1 process)"}
    out = [f"{'run':34s} wall median (min-max) s   CPU median s", "-" * 72]
    out += [f"{names[c]:34s} {s[c]['median_s']:6.2f} ({s[c]['min_s']:.2f}-{s[c]['max_s']:.2f})"
            f"{s[c].get('cpu_median_s', float('nan')):14.2f}" for c in CONFIGS if c in s]
    out += ["", "target | measured | ratio | met | command", "---|---|---|---|---"]
    for r in rows:
        ratio = "-" if r["ratio"] is None else f"{r['ratio']:.2f}"
        met = "-" if r["met"] is None else ("yes" if r["met"] else "NO")
        out.append(f"{r['target']} | {r['figures']} | {ratio} | {met} | `{r['command']}`")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.run_cost", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench-run")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each configuration (default 3)")
    ap.add_argument("--base", default=BASE, help=f"the earlier commit (default {BASE})")
    ap.add_argument("--peer", type=Path, help="peer.json of make bench-peer (CalculiX's time for the scene's target)")
    ap.add_argument("--sweeps", type=Path, help="sweeps.json of make bench-sweeps (the screened study's target)")
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
    trees = {c: ROOT for c in CONFIGS}
    trees["base"] = base_tree(args.out, args.base)
    t_all = time.perf_counter()
    for c in CONFIGS:  # warm-up: file caches, compiled forms (a part of its own for the re-run)
        wall, _ = time_run(c, trees[c], work, -1)
        print(f"[{time.perf_counter() - t_all:7.1f} s] warm-up {c}: {wall:.2f} s", flush=True)
    walls: dict[str, list[float]] = {c: [] for c in CONFIGS}
    cpus: dict[str, list[float]] = {c: [] for c in CONFIGS}
    for k in range(args.repeats):
        for c in CONFIGS:
            wall, cpu = time_run(c, trees[c], work, k)
            walls[c].append(wall)
            cpus[c].append(cpu)
            print(f"[{time.perf_counter() - t_all:7.1f} s] repeat {k + 1}/{args.repeats} {c}: {wall:.2f} s, "
                  f"CPU {cpu:.2f} s", flush=True)
    with contextlib.suppress(OSError):
        work.rmdir()  # empty now: each run removed its own folder
    summary = summarise(walls, cpus)
    read = {k: json.loads(f.read_text(encoding="utf-8")) if f is not None and f.is_file() else None
            for k, f in (("peer", args.peer), ("sweeps", args.sweeps))}
    rows = targets(summary, args.base, read["peer"], read["sweeps"])
    (args.out / "run_cost.json").write_text(json.dumps({"base": args.base, "walls_s": walls, "cpu_s": cpus,
                                                        "summary": summary, "targets": rows},
                                                       indent=2) + "\n", encoding="utf-8")
    print(table(summary, args.base, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
