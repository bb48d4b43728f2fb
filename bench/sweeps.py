"""Design-study throughput: whole `pipeline sweep` processes timed on this machine (s).

    python -m bench.sweeps --out results/bench-sweeps [--repeats 3] [--base DIR]   (make bench-sweeps)

Each study is a fresh process into a fresh folder with the run cache off:

- ``sizes-2``: every row of geometry/sizes.csv on 2 MPI ranks, every variant with its
  error bar (what `make sizes` runs); ``sizes-1`` the same on one rank, for the
  throughput ratio of 2 ranks to 1;
- ``grid-2``: No. 05 at the default mesh, rf × dj = 6 × 4 = 24 variants, on 2 ranks;
- ``grid-full`` / ``grid-screen``: that grid against an allowable of 140 MPa (the global
  peak crosses it along rf), every variant with its error bar, and screened (``--screen``:
  one coarse mesh first, the full error bar only where the decision needs it;
  docs/sweeps.md, *Screened studies*);
- ``sizes-full`` / ``sizes-screen``: the 19 sizes the same way, at 80 MPa;
- ``near-full`` / ``near-screen``: a 24-variant grid of No. 05 (rf 1.8-2.5 mm × dj
  17.5-19 mm) against 120 MPa, about half of whose variants lie within 5 % of it: the
  screened study's steps between the cheap level and the full error bar at work.

A ``*-full`` study runs the code of the checkout ``--base`` names (the same .venv; its
own launcher), else this code without ``--screen``. The configurations take turns (each repeat
runs every one) so that a drift of the machine's speed touches all alike; the figures are
medians over ``--repeats``. A screened study is compared with its full study of the same
repeat: its decisions (each row's verdict per peak, the crossings of the allowable) must
be identical, and each variant's cheap band must hold the full study's value with its
band, at every step it took; and from the full study's three readings of each variant, the
smallest band each step short of the full error bar would need (needed_margins). The
targets: 19 sizes <= 60 s, 24 variants <= 90 s, 2 ranks >= 1.8x the throughput of 1, a
screened study >= 3x faster than its full one (medians). Writes sweeps.json and prints a
table.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.run_cost import launcher
from pipeline.api import marked_kind, refusal

ROOT = Path(__file__).resolve().parents[1]
GRID = ["--size", "05", "--dim", "rf=0.5:2.5:6", "--dim", "dj=16,17,18,19"]
GRID_ALLOWABLE = ["--allowable", "140"]  # MPa: the grid's global peak crosses it along rf
SIZES_ALLOWABLE = ["--allowable", "80"]  # MPa: St 50's lower value (paper: 80-120 MPa)
# A grid whose global peak lies within 5 % of its allowable at about half of its variants.
NEAR = ["--size", "05", "--dim", "rf=1.8:2.5:6", "--dim", "dj=17.5,18,18.5,19", "--allowable", "120"]
NEAR_PCT = 5.0  # a variant is near the allowable when a peak lies within this % of it
# name -> (MPI ranks, sweep arguments, run by today's code when --base is given)
STUDIES = {
    "sizes-2": (2, ["--sizes", "all"], False),
    "sizes-1": (1, ["--sizes", "all"], False),
    "grid-2": (2, GRID, False),
    "grid-full": (2, GRID + GRID_ALLOWABLE, True),
    "grid-screen": (2, GRID + GRID_ALLOWABLE + ["--screen"], False),
    "sizes-full": (2, ["--sizes", "all"] + SIZES_ALLOWABLE, True),
    "sizes-screen": (2, ["--sizes", "all"] + SIZES_ALLOWABLE + ["--screen"], False),
    "near-full": (2, NEAR, True),
    "near-screen": (2, NEAR + ["--screen"], False),
}
SCREENED = {"grid-screen": "grid-full", "sizes-screen": "sizes-full", "near-screen": "near-full"}
DEFAULT_STUDIES = ("grid-full", "grid-screen", "sizes-full", "sizes-screen", "near-full", "near-screen")
# --quick: the grid's line at dj = 17 mm (6 variants) and 6 sizes spread over the table,
# for a machine too busy for the whole studies in one sitting.
QUICK = {"dj=16,17,18,19": "dj=17", "all": "025,05,1.6,5,16,50", "dj=17.5,18,18.5,19": "dj=18"}
TARGETS_S = {"sizes-2": 60.0, "grid-2": 90.0}
TARGET_SPEEDUP = 1.8
TARGET_SCREEN_SPEEDUP = 3.0
OWN_FILES = frozenset({"sweeps.json", "work"})  # what it writes into --out
VERDICTS = ("verdict", "critical_verdict")
CROSSING_KEYS = ("peak", "axis", "fixed", "falls_below", "only_crossing", "last", "range_reaches")


def command(ranks: int, args: list[str], out: Path, tree: Path = ROOT) -> list[str]:
    """The sweep's command line on ``ranks`` MPI ranks (the launcher of the code in
    ``tree`` for more than one), run in ``tree``."""
    head = [sys.executable, "-m", "pipeline"] if ranks == 1 else [sys.executable, "-m", launcher(tree), str(ranks)]
    return head + ["sweep", *args, "--out", str(out), "--quiet"]


def remove_study(out: Path) -> None:
    """Delete a sweep folder this bench made (it carries the sweep's marker); refuse to
    touch anything else found at that path."""
    if not out.exists():
        return
    if marked_kind(out) != "sweep":  # only the tool's own study marker, not any file of that name
        raise SystemExit(f"bench.sweeps: {out} exists and is not a sweep folder; choose another --out")
    shutil.rmtree(out)


def time_study(name: str, work: Path, base: Path | None = None, quick: bool = False) -> dict:
    """Run one study into a fresh folder under ``work`` (today's code from ``base`` for a
    study that asks for it; with ``quick`` its smaller form, QUICK); its wall time (s), row
    counts, decisions and, per variant, its peaks (MPa) and what decided it."""
    ranks, args, old = STUDIES[name]
    if quick:
        args = [QUICK.get(a, a) for a in args]
    out = (work / name).resolve()
    remove_study(out)  # the previous repeat's
    env = dict(os.environ, CROSSHEAD_NO_CACHE="1")
    t0 = time.perf_counter()
    tree = base if (old and base) else ROOT
    p = subprocess.run(command(ranks, args, out, tree), cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{name}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")
    res = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    statuses = [r.get("status") for r in res["rows"]]
    found = {"wall_s": wall, "variants": len(res["rows"]), "ok": statuses.count("done"),
             "code": str(base) if (old and base) else "this", **outcome(res, out)}
    remove_study(out)
    return found


def row_name(row: dict) -> str:
    """A row's inputs as one text that is the same in every code's study (its key is not:
    it hashes the code)."""
    return json.dumps([json.loads(row["parameters"]), row.get("load_N")], sort_keys=True)


def outcome(res: dict, out: Path) -> dict:
    """What a study decided (sweep.json's content ``res``; its folder ``out``): per row its
    status and verdicts, its peaks (value, band; MPa), how it was decided and the reading
    of each screening step it took (value, band per peak; MPa), and the crossings of the
    allowable."""
    rows = {}
    for r in res["rows"]:
        screening = out / "variants" / r["variant"] / "screening.json"
        s = json.loads(screening.read_text(encoding="utf-8")) if screening.is_file() else None
        rows[row_name(r)] = {"status": r["status"], **{v: r.get(v) for v in VERDICTS},
                             "peak": [r.get("peak_MPa"), r.get("peak_band_MPa")],
                             "critical": [r.get("critical_peak_MPa"), r.get("critical_band_MPa")],
                             "decided_by": r.get("decided_by") or "", "time_s": r.get("time_s"),
                             "steps": [] if s is None else [_step(t) for t in s.get("steps") or
                                                            ([s] if s.get("peaks") else [])],
                             "meshes": readings(out / "variants" / r["variant"])}
    return {"rows": rows, "crossings": res["crossings"], "allowable_MPa": res["allowable_MPa"]}


LEVEL_KEYS = {"peak": ("peak_MPa", "peak_unaveraged_MPa", "peak_averaged_MPa"),
              "critical": ("critical_peak_MPa", "critical_unaveraged_MPa", "critical_averaged_MPa")}


def readings(folder: Path) -> dict | None:
    """A variant's reading per peak on each of its meshes, finest first: [value, half the
    gap between its unaveraged and averaged readings] (MPa); None unless it has the three
    meshes of the full error bar."""
    f = folder / "results.json"
    if not f.is_file():
        return None
    levels = json.loads(f.read_text(encoding="utf-8"))["fe"].get("levels") or []
    if len(levels) != 3 or any(lv.get(k) is None for lv in levels for keys in LEVEL_KEYS.values() for k in keys):
        return None
    return {peak: [[lv[v], 0.5 * abs(lv[u] - lv[a])] for lv in levels] for peak, (v, u, a) in LEVEL_KEYS.items()}


def needed_margins(full: dict) -> dict:
    """Per screening step short of the full error bar and per peak, the smallest fraction
    of the value its band needs so that, on every variant of the full study ``full``, it
    holds the full value with its error bar: one mesh (the x1.69 reading, band the larger
    of the fraction and its half bracket) and two meshes (the x1.3 reading, band the larger
    of the fraction and its half bracket plus TWO_MESH_FACTOR x the two readings'
    difference; pipeline/study/screening.py)."""
    from pipeline.api import TWO_MESH_FACTOR
    need = {"one mesh": {"peak": 0.0, "critical": 0.0}, "two meshes": {"peak": 0.0, "critical": 0.0}}
    for r in full["rows"].values():
        if r["status"] != "done" or not r.get("meshes"):
            continue
        for peak in ("peak", "critical"):
            (v, b), ((r1, g1), (r2, g2)) = r[peak], r["meshes"][peak][1:]
            if v is None:
                continue
            for step, (x, own) in (("one mesh", (r2, g2)), ("two meshes", (r1, g1 + TWO_MESH_FACTOR * abs(r1 - r2)))):
                want = abs(x - v) + (b or 0.0)
                if own < want:
                    need[step][peak] = max(need[step][peak], want / abs(x))
    return need


def _step(s: dict) -> dict:
    """A screening step's name and reading (value, band per peak; MPa)."""
    return {"step": s.get("step", "cheap level"),
            **{b: [s["peaks"][b]["value_MPa"], s["peaks"][b]["band_MPa"]] for b in ("peak", "critical")}}


def differences(full: dict, screened: dict) -> list[str]:
    """Where a screened study's decisions differ from its full study's: a row's status or
    verdict per peak, or a crossing of the allowable (place and range equal to 1e-9)."""
    diffs = []
    for name in sorted(set(full["rows"]) | set(screened["rows"])):
        a, b = full["rows"].get(name), screened["rows"].get(name)
        if a is None or b is None:
            diffs.append(f"{name}: in one study only")
            continue
        for k in ("status", *VERDICTS):
            if a[k] != b[k]:
                diffs.append(f"{name}: {k} {a[k]} (full) against {b[k]} (screened)")
    if len(full["crossings"]) != len(screened["crossings"]):
        diffs.append(f"{len(full['crossings'])} crossings (full) against {len(screened['crossings'])} (screened)")
    for x, y in zip(full["crossings"], screened["crossings"]):
        same = all(x[k] == y[k] for k in CROSSING_KEYS) and math.isclose(x["at"], y["at"], rel_tol=1e-9)
        same = same and ((x["range"] is None) == (y["range"] is None)) and (
            x["range"] is None or all(math.isclose(u, v, rel_tol=1e-9, abs_tol=1e-12)
                                      for u, v in zip(x["range"], y["range"])))
        if not same:
            diffs.append(f"crossing of the {x['peak']} along {x['axis']} at {x['fixed']}: {x['at']:.6g} "
                         f"{x['range']} (full) against {y['at']:.6g} {y['range']} (screened)")
    return diffs


def coverage(full: dict, screened: dict) -> list[dict]:
    """Per variant of a screened study, per screening step it took, per peak: the step's
    value and band (MPa), the full study's value and band, and whether the step's band
    holds the full value and the full value with its band."""
    out = []
    for name, b in screened["rows"].items():
        a = full["rows"].get(name)
        if a is None or a["status"] != "done":
            continue
        for step in b["steps"]:
            for peak in ("peak", "critical"):
                (c, cb), (v, vb) = step[peak], a[peak]
                if c is None or v is None:
                    continue
                out.append({"row": name, "step": step["step"], "peak": peak, "cheap_MPa": c, "cheap_band_MPa": cb,
                            "full_MPa": v, "full_band_MPa": vb, "covers_value": abs(v - c) <= cb,
                            "covers_band": abs(v - c) + (vb or 0.0) <= cb, "decided_by": b["decided_by"]})
    return out


def near(full: dict, pct: float = NEAR_PCT) -> int:
    """How many rows of a full study have a peak within ``pct`` % of its allowable."""
    a = full["allowable_MPa"]
    return sum(any(r[p][0] is not None and abs(r[p][0] - a) <= pct / 100 * a for p in ("peak", "critical"))
               for r in full["rows"].values())


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
    for screen, full in SCREENED.items():
        if screen in runs and full in runs:
            ratio = out[full]["median_s"] / out[screen]["median_s"]
            diffs = [d for a, b in zip(runs[full], runs[screen]) for d in differences(a, b)]
            cover = [c for a, b in zip(runs[full], runs[screen]) for c in coverage(a, b)]
            cheap = [r for r in runs[screen][0]["rows"].values() if r["decided_by"].startswith("screened")]
            by_step: dict[str, int] = {}
            for r in runs[screen][0]["rows"].values():
                last = r["steps"][-1]["step"] if r["decided_by"].startswith("screened") and r["steps"] else "full"
                by_step[last] = by_step.get(last, 0) + 1
            out[f"{screen}_against_full"] = {
                "median_ratio": ratio, "target": TARGET_SCREEN_SPEEDUP, "met": ratio >= TARGET_SCREEN_SPEEDUP,
                "paired_ratios": [a["wall_s"] / b["wall_s"] for a, b in zip(runs[full], runs[screen])],
                "decided_cheaply": len(cheap), "rows": len(runs[screen][0]["rows"]), "decided_at": by_step,
                "near_allowable": near(runs[full][0]), "needed_margins": needed_margins(runs[full][0]),
                "identical_decisions": not diffs, "differences": diffs,
                "cheap_bands": len(cover), "cover_values": sum(c["covers_value"] for c in cover),
                "cover_bands": sum(c["covers_band"] for c in cover), "coverage": cover}
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
        lines.append(f"{name:12s} {s['variants']:4d} ({s['ok']:2d})    {s['median_s']:7.1f} "
                     f"({s['min_s']:.1f}-{s['max_s']:.1f})        {target:9s} {met}")
    for screen, full in SCREENED.items():
        c = summary.get(f"{screen}_against_full")
        if c:
            lines.append(f"{screen} against {full}: {c['median_ratio']:.2f}x faster (medians; target >= "
                         f"{c['target']:g}x: {'yes' if c['met'] else 'NO'}); {c['decided_cheaply']} of {c['rows']} "
                         f"rows decided short of the full error bar "
                         f"({', '.join(f'{k} {n}' for k, n in c['decided_at'].items())}); "
                         f"{c['near_allowable']} within {NEAR_PCT:g} % of the allowable; decisions identical: "
                         f"{'yes' if c['identical_decisions'] else 'NO'}; step bands holding the full value "
                         f"{c['cover_values']}/{c['cheap_bands']}, with its band {c['cover_bands']}/{c['cheap_bands']}")
            lines += [f"  differs: {d}" for d in c["differences"][:10]]
            lines.append("  margins the full study needs: " + "; ".join(
                f"{step} {100 * m['peak']:.2f} % / {100 * m['critical']:.2f} %" for step, m in c["needed_margins"].items()))
    sp = summary.get("speedup_2_over_1")
    if sp:
        lines.append(f"2 ranks / 1 rank throughput: {sp['median']:.2f}x (median of {sp['pairs']} pairs; "
                     f"target >= {sp['target']}x: {'yes' if sp['met'] else 'NO'})")
    return "\n".join(lines)


def write_json(out: Path, runs: dict[str, list[dict]]) -> dict:
    """sweeps.json in ``out``: the runs and their summary (:func:`summarise`), which it returns."""
    summary = summarise(runs)
    (out / "sweeps.json").write_text(json.dumps({"runs": runs, "summary": summary}, indent=2) + "\n",
                                     encoding="utf-8")
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.sweeps", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "bench-sweeps")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each study (default 1)")
    ap.add_argument("--studies", default=",".join(DEFAULT_STUDIES), help=f"comma list of {', '.join(STUDIES)} "
                    f"(default {','.join(DEFAULT_STUDIES)})")
    ap.add_argument("--quick", action="store_true", help="smaller studies: the grid's line at dj = 17 mm and "
                    f"the sizes {QUICK['all']} (for a busy machine)")
    ap.add_argument("--base", type=Path, help="a checkout (same .venv) whose code runs the *-full studies, "
                    "e.g. a git worktree of version 0.6; default: this code without --screen")
    args = ap.parse_args(argv)
    names = [n for n in args.studies.split(",") if n]
    unknown = [n for n in names if n not in STUDIES]
    if unknown or args.repeats < 1:
        print(f"bench.sweeps: unknown study {unknown}" if unknown else "bench.sweeps: --repeats must be >= 1",
              file=sys.stderr)
        return 2
    if args.base is not None and not (args.base / "pipeline" / "__main__.py").is_file():
        print(f"bench.sweeps: --base {args.base} is not a checkout of crosshead (no pipeline/__main__.py)",
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
            r = time_study(name, work, args.base and args.base.resolve(), args.quick)
            runs[name].append(r)
            print(f"[{time.perf_counter() - t_all:7.1f} s] repeat {k + 1}/{args.repeats} {name}: "
                  f"{r['wall_s']:.1f} s, {r['ok']}/{r['variants']} variants ok", file=sys.stderr, flush=True)
            write_json(args.out, {n: rs for n, rs in runs.items() if rs})  # what is measured so far
    with contextlib.suppress(OSError):
        work.rmdir()  # empty now: each study removed its own folder
    print(table(write_json(args.out, runs)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
