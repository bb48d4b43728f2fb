"""Design-study throughput: whole `pipeline sweep` processes timed on this machine (s).

    python -m bench.sweeps --out results/bench-sweeps [--repeats 3]     (make bench-sweeps)

Three studies, each a fresh process into a fresh folder with the run cache off, every
variant with its error bar (three meshes):

- ``sizes-2``: every row of geometry/sizes.csv on 2 MPI ranks (what `make sizes` runs);
- ``sizes-1``: the same on one rank, for the throughput ratio of 2 ranks to 1;
- ``grid-2``: No. 05 at the default mesh, rf × dj = 6 × 4 = 24 variants, on 2 ranks.

The configurations take turns (sizes-2, sizes-1, grid-2, sizes-2, ...) so that a drift of
the machine's speed touches all alike; the figures are medians over ``--repeats``. The
targets (docs/performance.md, *Where things stand*): 19 sizes ≤ 60 s, 24 variants ≤ 90 s,
2 ranks ≥ 1.8× the throughput of 1. Writes sweeps.json and prints a table.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from pipeline.runtime.folders import marked_kind, refusal

ROOT = Path(__file__).resolve().parents[1]
GRID = ["--size", "05", "--dim", "rf=0.5:2.5:6", "--dim", "dj=16,17,18,19"]
STUDIES = {
    "sizes-2": (2, ["--sizes", "all"]),
    "sizes-1": (1, ["--sizes", "all"]),
    "grid-2": (2, GRID),
}
TARGETS_S = {"sizes-2": 60.0, "grid-2": 90.0}
TARGET_SPEEDUP = 1.8
OWN_FILES = frozenset({"sweeps.json", "work"})  # what it writes into --out


def command(ranks: int, args: list[str], out: Path) -> list[str]:
    """The sweep's command line on ``ranks`` MPI ranks (pipeline.runtime.launch for more than one)."""
    head = [sys.executable, "-m", "pipeline"] if ranks == 1 else [sys.executable, "-m", "pipeline.runtime.launch", str(ranks)]
    return head + ["sweep", *args, "--out", str(out), "--quiet"]


def remove_study(out: Path) -> None:
    """Delete a sweep folder this bench made (it carries the sweep's marker); refuse to
    touch anything else found at that path."""
    if not out.exists():
        return
    if marked_kind(out) != "sweep":  # only the tool's own study marker, not any file of that name
        raise SystemExit(f"bench.sweeps: {out} exists and is not a sweep folder; choose another --out")
    shutil.rmtree(out)


def time_study(name: str, work: Path) -> dict:
    """Run one study into a fresh folder under ``work``; its wall time (s) and row counts."""
    ranks, args = STUDIES[name]
    out = work / name
    remove_study(out)  # the previous repeat's
    env = dict(os.environ, CROSSHEAD_NO_CACHE="1")
    t0 = time.perf_counter()
    p = subprocess.run(command(ranks, args, out), cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{name}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")
    rows = json.loads((out / "sweep.json").read_text(encoding="utf-8"))["rows"]
    statuses = [r.get("status") for r in rows]
    remove_study(out)
    return {"wall_s": wall, "variants": len(rows), "ok": statuses.count("done")}


def summarise(runs: dict[str, list[dict]]) -> dict:
    """Medians (s), spreads and the targets' verdicts from every study's runs."""
    out: dict = {}
    for name, rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        out[name] = {"median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
                     "runs": len(rs), "variants": rs[0]["variants"], "ok": rs[0]["ok"],
                     "target_s": TARGETS_S.get(name)}
        if name in TARGETS_S:
            out[name]["met"] = out[name]["median_s"] <= TARGETS_S[name]
    if "sizes-1" in runs and "sizes-2" in runs:
        # Pair by repeat: the two ran next to each other.
        ratios = [a["wall_s"] / b["wall_s"] for a, b in zip(runs["sizes-1"], runs["sizes-2"])]
        out["speedup_2_over_1"] = {"median": statistics.median(ratios), "pairs": len(ratios),
                                   "target": TARGET_SPEEDUP,
                                   "met": statistics.median(ratios) >= TARGET_SPEEDUP}
    return out


def table(summary: dict) -> str:
    lines = ["study      variants (done)   wall median (min-max) s   target    met",
             "-" * 68]
    for name in STUDIES:
        s = summary.get(name)
        if s is None:
            continue
        target = f"<= {s['target_s']:.0f} s" if s["target_s"] else "-"
        met = ("yes" if s["met"] else "NO") if "met" in s else "-"
        lines.append(f"{name:10s} {s['variants']:4d} ({s['ok']:2d})      {s['median_s']:7.1f} "
                     f"({s['min_s']:.1f}-{s['max_s']:.1f})        {target:9s} {met}")
    sp = summary.get("speedup_2_over_1")
    if sp:
        lines.append(f"2 ranks / 1 rank throughput: {sp['median']:.2f}x (median of {sp['pairs']} pairs; "
                     f"target >= {sp['target']}x: {'yes' if sp['met'] else 'NO'})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.sweeps", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench-sweeps")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each study (default 1)")
    ap.add_argument("--studies", default=",".join(STUDIES), help=f"comma list of {', '.join(STUDIES)}")
    args = ap.parse_args(argv)
    names = [n for n in args.studies.split(",") if n]
    unknown = [n for n in names if n not in STUDIES]
    if unknown or args.repeats < 1:
        print(f"bench.sweeps: unknown study {unknown}" if unknown else "bench.sweeps: --repeats must be >= 1",
              file=sys.stderr)
        return 2
    why = refusal(args.out, OWN_FILES)
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    work = args.out / "work"
    runs: dict[str, list[dict]] = {n: [] for n in names}
    t_all = time.perf_counter()
    for k in range(args.repeats):
        for name in names:
            r = time_study(name, work)
            runs[name].append(r)
            print(f"[{time.perf_counter() - t_all:7.1f} s] repeat {k + 1}/{args.repeats} {name}: "
                  f"{r['wall_s']:.1f} s, {r['ok']}/{r['variants']} variants ok", flush=True)
    with contextlib.suppress(OSError):
        work.rmdir()  # empty now: each study removed its own folder
    summary = summarise(runs)
    (args.out / "sweeps.json").write_text(json.dumps({"runs": runs, "summary": summary}, indent=2) + "\n",
                                          encoding="utf-8")
    print(table(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
