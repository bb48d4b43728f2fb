"""Sensitivity variants by moving the nominal mesh's nodes (pipeline.fe.morph) against
meshing each variant anew: the peaks' variant / nominal ratios, the time per variant, where
one variant's time goes, and where a whole `make run`'s goes.

    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.morph --accuracy --factors 1.9,2.0,2.1,2.2,2.3,2.4,2.5 \
        --noise --reference 0.8,1,1.3 --out /tmp/morph-accuracy.json
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.morph --timing --repeats 5 --out /tmp/morph-timing.json
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.morph --stages --repeats 3
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.morph --runs --repeats 3 --out /tmp/morph-runs
    .venv/bin/python -m bench.morph --table /tmp/morph-accuracy.json

The variants are the sensitivity section's (pipeline.analysis.sensitivity): the nominal
case and both ends of each assumed dimension's default range, each on one mesh at the
run's mesh factor × MESH_RATIO (× ``--factors``/2.2 to see other sizes), refined at the
places its dimensions name, on one process.

``--accuracy``: per factor, each variant meshed anew (sensitivity.analyse_variant, today's
way) and the nominal mesh moved onto it (the same solve, level.solve_level; every variant,
also those pipeline.fe.morph.remesh_reason sends to a fresh mesh); per variant the global
and critical peaks (MPa), variant / nominal of each way and their difference (%), beside
the section's own noise (the nominal case on the run's pilot places instead, as the run
states it; with ``--noise``) and, with ``--reference``, beside variant / nominal of meshes
made anew at finer factors (their mean: the reference each way is held to).

``--timing``: the nine jobs of the section on one process, each way in a process of its
own and the ways interleaved (rotated each repeat): meshed anew ("fresh"), moved and
solved by solve_level ("moved"), moved and solved on the first job's forms, matrices and
DOFs from the last solution (pipeline.fe.resolve, a new preconditioner set-up each:
"resolved"), the same on the first job's preconditioner with the second end of a range
started from the line through the nominal and the first end ("reused"), and that stopped
at a relative residual of LOOSE_RTOL instead of the case's ("reused-loose"); a variant
that morph.remesh_reason refuses is meshed anew in every way. Per way the median wall and
CPU time (s) of the nine jobs and per moved variant, and how far the readings are from
the moved way's.

``--stages``: one fresh, one resolved and one reused job taken apart (geometry, gmsh,
import, loads, assembly, the preconditioner's set-up, the iterations, reactions, peaks,
sections). ``--runs``: `make run`'s command (2 ranks, cache off) whole, with
--no-sensitivity and with --no-fields, interleaved: wall and CPU time (every process),
results.json's timings_s; then each drawing process (pipeline.output.picture, plots,
closeup) alone on the last full run's folder: its wall and CPU time.

Lengths in mm, stresses in MPa, times in s. Results go to stdout, progress to stderr.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from pipeline.runtime.environment import configure

configure()  # before numpy, PETSc or DOLFINx load: the pipeline's form cache, threads, PETSc options

from mpi4py import MPI  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WAYS = ("fresh", "moved", "resolved", "reused", "reused-loose")
LOOSE_RTOL = 1e-5  # --timing's "reused-loose": the relative residual it stops at


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def variant_cases(size: str) -> list[tuple[str, object]]:
    """(label, case) of the section's dimension jobs: the nominal case first, then both ends
    of each assumed dimension's range (sensitivity.ranges_of)."""
    from pipeline.analysis.sensitivity import DIMENSION, ranges_of
    from pipeline.inputs.case import resolve
    case = resolve(size=size)
    out = [("nominal", case)]
    for r in ranges_of(case)[0]:
        if r.kind == DIMENSION:
            out += [(f"{r.input}={v:g}", r.variant(case, v)) for v in (r.low, r.high)]
    return out


def _values(rd) -> dict:
    return {"peak_MPa": rd.peak_MPa, "critical_MPa": rd.critical_MPa, "section_MPa": rd.section_MPa}


class Moved:
    """The nominal case's sensitivity mesh at ``factor`` on this process, moved onto each
    variant in turn and solved by level.solve_level (``options`` None) or by one
    resolve.Resolver set up on the first solve with these options; with ``extrapolate``
    the second end of a range starts CG from resolve.extrapolated."""

    def __init__(self, case, factor: float, options=None, extrapolate: bool = False, strict: bool = True) -> None:
        from pipeline.analysis.level import set_up
        from pipeline.analysis.pilot import known_places
        from pipeline.fe import morph
        self.nominal = replace(case, mesh_factor=factor)
        self.factor = factor
        self.problem = set_up(self.nominal, factor, comm=MPI.COMM_SELF,
                              hotspots=known_places(self.nominal).hotspots)
        self.mover = morph.Mover.of(self.problem.mesh.mesh, case.dims)
        self.options, self.extrapolate, self.strict = options, extrapolate, strict
        self.resolver = None
        self.solved: dict[tuple[str, float], object] = {}  # (input, value) -> this rank's DOF values

    def close(self) -> None:
        if self.resolver is not None:
            self.resolver.close()
        self.mover.reset()

    def reading(self, v) -> tuple[dict, dict]:
        """The readings of case ``v`` (the nominal case with other dimensions) on the moved
        mesh, and how the move left the tets and the solver's iterations."""
        from pipeline.analysis.level import Problem, solve_level
        from pipeline.analysis.sensitivity import read_level
        from pipeline.fe import morph
        from pipeline.fe.elasticity import Material
        from pipeline.fe.loads import crosshead_loads
        v = replace(v, mesh_factor=self.factor)
        why = morph.remesh_reason(self.nominal.dims, v.dims) if self.strict else None
        if why is not None:  # meshed anew, as today
            from pipeline.analysis.sensitivity import analyse_variant
            return _values(analyse_variant(v, self.factor)), {"fresh": why, "iterations": None}
        t0, c0 = time.perf_counter(), time.process_time()
        q = self.mover.move_to(v.dims, strict=self.strict)
        m = morph.as_variant(self.problem.mesh, v.dims, q, time.perf_counter() - t0)
        cpu_move = time.process_time() - c0
        mat = Material(E=v.E_MPa, nu=v.nu)
        t0, c0 = time.perf_counter(), time.process_time()
        lc = crosshead_loads(m, v.dims, v.load_N, v.support, shape=v.bearing_shape, band=v.bearing_band(),
                             order=v.order)
        info = {"jacobian_ratio": q.jacobian_ratio, "squeeze": q.squeeze, "stretch": q.stretch,
                "stages_s": {"move nodes, check tets": [m.timings["morph"], cpu_move],
                             "loads": [time.perf_counter() - t0, time.process_time() - c0]}}
        if self.options is None:
            lv = solve_level(v, self.factor, problem=Problem(m, mat, lc, 0.0), with_sections=True,
                             formula_loads=False, reuse=False)
            return _values(read_level(v, lv)), dict(info, iterations=lv.iterations)
        rd, its = self._resolved(v, m, mat, lc, info["stages_s"])
        return rd, dict(info, iterations=its)

    def _resolved(self, v, m, mat, lc, stages_s: dict) -> tuple[dict, int]:
        """Solve on the Resolver and read as solve_level does (equilibrium checked)."""
        from pipeline.analysis.level import peaks_of
        from pipeline.errors import NumericalError
        from pipeline.fe.loads import equilibrium
        from pipeline.fe.resolve import Resolver
        from pipeline.post.sections import section_results
        from pipeline.fe.morph import MOVABLE
        from pipeline.fe.resolve import extrapolated
        if self.resolver is None:
            self.resolver = Resolver(m.mesh, m.facet_tags, v.order, mat, lc.constraints, v.rtol, self.options)
        changed = [k for k in MOVABLE if getattr(v.dims, k) != getattr(self.nominal.dims, k)]
        key = (changed[0], getattr(v.dims, changed[0])) if len(changed) == 1 else ("nominal", 0.0)
        guess = None
        ends = [(val, u) for (k, val), u in self.solved.items() if k == key[0] and val != key[1]]
        if self.extrapolate and ends and ("nominal", 0.0) in self.solved:
            nominal = getattr(self.nominal.dims, key[0])
            guess = extrapolated(self.solved[("nominal", 0.0)], ends[0][1], nominal, ends[0][0], key[1])
        sol = self.resolver.solve(lc.tractions, guess)
        self.solved[key] = sol.u.x.array.copy()
        stages_s.update({k: [w, self.resolver.last_cpu_timings[k]] for k, w in self.resolver.last_timings.items()})
        _, eq_err, point_r = equilibrium(lc, sol.reactions)
        if not max(eq_err, point_r) <= 1e-6 * v.load_N:
            raise NumericalError(f"loads out of balance: {eq_err:.3g} N, {point_r:.3g} N")
        t0, c0 = time.perf_counter(), time.process_time()
        _, pk, crit = peaks_of(v, sol.u, mat)
        stages_s["peaks"] = [time.perf_counter() - t0, time.process_time() - c0]
        t0, c0 = time.perf_counter(), time.process_time()
        sym_x = m.facet_ids.get("symmetry_x")
        sym_idx = next((i for i, c in enumerate(lc.constraints) if c.component == 0 and c.marker == sym_x
                        and sym_x is not None), None)
        sec = section_results(sol, mat, v.dims, v.load_N, 0.25 if v.model == "quarter" else 1.0, sym_idx,
                              pk.value_MPa, bearing_centre_mm=v.bearing_band().centre_mm)
        stages_s["sections"] = [time.perf_counter() - t0, time.process_time() - c0]
        return {"peak_MPa": pk.value_MPa, "critical_MPa": crit.value_MPa,
                "section_MPa": sec["critical_section"]["nominal_MPa"]}, sol.iterations


def accuracy(size: str, factors: list[float], noise: bool, reference: list[float] = ()) -> list[dict]:
    """Per factor and job: the fresh and the moved readings; with ``reference`` (mesh
    factors / the run's) each job also meshed anew at those finer factors (rows with
    "reference" set)."""
    from pipeline.analysis.sensitivity import MESH_RATIO, analyse_variant
    cases = variant_cases(size)
    rows = []
    for fac in reference:
        f = cases[0][1].mesh_factor * fac
        for label, c in cases:
            rows.append({"factor": fac, "job": label, "reference": _values(analyse_variant(c, f))})
            _say(f"reference ×{fac:g} {label}: {rows[-1]['reference']['peak_MPa']:.3f} / "
                 f"{rows[-1]['reference']['critical_MPa']:.3f} MPa")
    for fac in factors:
        f = cases[0][1].mesh_factor * fac
        moved = Moved(cases[0][1], f, strict=False)
        try:
            for label, c in cases:
                fresh = _values(analyse_variant(c, f))
                mv, info = moved.reading(c) if label != "nominal" else (fresh, {})
                rows.append({"factor": fac, "job": label, "fresh": fresh, "moved": mv, **info})
                _say(f"×{fac:g} {label}: fresh {fresh['peak_MPa']:.3f} / {fresh['critical_MPa']:.3f}, moved "
                     f"{mv['peak_MPa']:.3f} / {mv['critical_MPa']:.3f} MPa")
        finally:
            moved.close()
        if noise and abs(fac - MESH_RATIO) < 1e-9:
            rows.append({"factor": fac, "job": "noise", **_noise(cases[0][1], f)})
    return rows


def _noise(case, f: float) -> dict:
    """The section's noise as a run states it: the nominal case on the run's pilot places
    against the dimensions' places, same factor (MPa and %)."""
    from pipeline.analysis.pilot import pilot
    from pipeline.analysis.sensitivity import analyse_variant
    places = pilot(case, comm=MPI.COMM_SELF).hotspots
    a, b = analyse_variant(case, f), analyse_variant(case, f, places)
    return {"known_places": _values(a), "pilot_places": _values(b),
            "global_pct": 100 * abs(a.peak_MPa - b.peak_MPa) / a.peak_MPa,
            "critical_MPa": abs(a.critical_MPa - b.critical_MPa)}


def ratios(rows: list[dict]) -> list[dict]:
    """Per factor and variant: variant / nominal of the fresh and of the moved readings, and
    moved − fresh (% points), for the global and the critical peak."""
    base = {r["factor"]: r for r in rows if r["job"] == "nominal" and "fresh" in r}
    out = []
    for r in rows:
        if r["job"] in ("nominal", "noise") or "fresh" not in r:
            continue
        b = base[r["factor"]]
        row = {"factor": r["factor"], "job": r["job"], "jacobian_ratio": r.get("jacobian_ratio")}
        for k in ("peak_MPa", "critical_MPa"):
            fr, mr = r["fresh"][k] / b["fresh"][k], r["moved"][k] / b["moved"][k]
            row[k] = {"fresh": fr, "moved": mr, "diff_pct": 100 * (mr - fr)}
        out.append(row)
    return out


def reference_ratios(rows: list[dict]) -> dict:
    """Per variant and peak: variant / nominal meshed anew at each reference factor, and
    their mean (empty without reference rows)."""
    ref = [r for r in rows if "reference" in r]
    if not ref:
        return {}
    factors = sorted({r["factor"] for r in ref})
    nominal = {r["factor"]: r["reference"] for r in ref if r["job"] == "nominal"}
    out: dict = {"factors": factors}
    for r in ref:
        if r["job"] == "nominal":
            continue
        for k in ("peak_MPa", "critical_MPa"):
            out.setdefault(r["job"], {}).setdefault(k, {"all": []})["all"].append(
                r["reference"][k] / nominal[r["factor"]][k])
    for j, ks in out.items():
        if j != "factors":
            for k in ks.values():
                k["mean"] = statistics.mean(k["all"])
    return out


def accuracy_table(rows: list[dict]) -> str:
    """The ratios as text, with the noise when measured and each variant's mean and largest
    difference over the factors."""
    lines = [f"{'factor':>6s} {'variant':18s} {'global fresh':>12s} {'moved':>7s} {'diff %':>7s}   "
             f"{'critical fresh':>14s} {'moved':>7s} {'diff %':>7s} {'MPa':>6s}  det J ratio", "-" * 104]
    crit_nom = {r["factor"]: r["fresh"]["critical_MPa"] for r in rows if r["job"] == "nominal" and "fresh" in r}
    rs = ratios(rows)
    for r in rs:
        g, c = r["peak_MPa"], r["critical_MPa"]
        lines.append(f"{r['factor']:6.3g} {r['job']:18s} {g['fresh']:12.4f} {g['moved']:7.4f} {g['diff_pct']:+7.3f}   "
                     f"{c['fresh']:14.4f} {c['moved']:7.4f} {c['diff_pct']:+7.3f} "
                     f"{c['diff_pct'] / 100 * crit_nom[r['factor']]:+6.3f}  {r['jacobian_ratio']:.3f}")
    for r in rows:
        if r["job"] == "noise":
            lines.append(f"noise at ×{r['factor']:g} (the run's places against the dimensions'): global "
                         f"{r['global_pct']:.2f} %, critical {r['critical_MPa']:.3f} MPa")
    jobs = sorted({r["job"] for r in rs}, key=[r["job"] for r in rs].index)
    if len({r["factor"] for r in rs}) > 1:
        lines.append("over the factors (variant / nominal, medians; SD of each way's ratio, % points):")
        lines.append(f"  {'variant':18s} {'global fresh':>12s} {'moved':>7s} {'diff %':>7s} {'SD':>11s}   "
                     f"{'critical fresh':>14s} {'moved':>7s} {'diff %':>7s} {'SD':>11s}")
        for j in jobs:
            sel = [r for r in rs if r["job"] == j]
            parts = []
            for k in ("peak_MPa", "critical_MPa"):
                fr, mv = (statistics.median(r[k][w] for r in sel) for w in ("fresh", "moved"))
                sd = [statistics.stdev([100 * r[k][w] for r in sel]) for w in ("fresh", "moved")]
                parts.append(f"{fr:{12 if k == 'peak_MPa' else 14}.4f} {mv:7.4f} {100 * (mv - fr):+7.3f} "
                             f"{sd[0]:5.2f} {sd[1]:5.2f}")
            lines.append(f"  {j:18s} " + "   ".join(parts))
    refs = reference_ratios(rows)
    if refs:
        at = sorted({r["factor"] for r in rs})
        lines.append(f"against the reference (variant / nominal meshed anew at ×{', ×'.join(f'{f:g}' for f in refs['factors'])}"
                     "; its mean and range), each way's deviation (% points) at every factor:")
        for j in jobs:
            parts = []
            for k in ("peak_MPa", "critical_MPa"):
                ref = refs[j][k]
                dev = {w: [100 * (r[k][w] - ref["mean"]) for f in at for r in rs if r["job"] == j and r["factor"] == f]
                       for w in ("fresh", "moved")}
                parts.append(f"{k[:-4]} {ref['mean']:.4f} ({min(ref['all']):.4f}-{max(ref['all']):.4f}) fresh "
                             + " ".join(f"{x:+.2f}" for x in dev["fresh"]) + " moved "
                             + " ".join(f"{x:+.2f}" for x in dev["moved"]))
            lines.append(f"  {j:18s} " + " | ".join(parts))
    return "\n".join(lines)


def _way_options() -> dict:
    from pipeline.fe.resolve import ResolveOptions
    return {"moved": (None, False), "resolved": (ResolveOptions(warm_start=True), False),
            "reused": (ResolveOptions(warm_start=True, reuse_preconditioner=True), True),
            "reused-loose": (ResolveOptions(warm_start=True, reuse_preconditioner=True, rtol=LOOSE_RTOL), True)}


def job(way: str, size: str, factor_ratio: float) -> dict:
    """The section's nine dimension jobs on this process, one way: per job its wall and CPU
    time (s) and readings; the set-up of the nominal mesh counts in the nominal job."""
    from pipeline.analysis.sensitivity import analyse_variant
    cases = variant_cases(size)
    f = cases[0][1].mesh_factor * factor_ratio
    out = []
    moved = None
    WAY_OPTIONS = _way_options()
    for label, c in cases:
        t0, c0 = time.perf_counter(), time.process_time()
        if way == "fresh":
            rd, its = _values(analyse_variant(c, f)), None
        else:
            if moved is None:
                moved = Moved(c, f, *WAY_OPTIONS[way])
            rd, info = moved.reading(c)
            its = info["iterations"]
        out.append({"job": label, "wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                    "iterations": its, **rd})
    if moved is not None:
        moved.close()
    return {"way": way, "jobs": out}


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timing(size: str, repeats: int, ways: list[str], factor_ratio: float) -> dict:
    """Each way's nine jobs in a process of its own, the ways interleaved (the order rotated
    by one each repeat, after one warm-up round); per way and job the runs' times."""
    runs: dict[str, list[dict]] = {w: [] for w in ways}
    for k in range(repeats + 1):
        order = ways[k % len(ways):] + ways[:k % len(ways)]
        for w in order:
            t0, c0 = time.perf_counter(), _children_cpu_s()
            p = subprocess.run([sys.executable, "-m", "bench.morph", "--job", w, "--size", size,
                                "--factor-ratio", repr(factor_ratio)], cwd=ROOT, capture_output=True, text=True,
                               env=dict(os.environ, CROSSHEAD_NO_CACHE="1"))
            if p.returncode != 0:
                raise SystemExit(f"{w}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")
            res = json.loads(p.stdout.strip().splitlines()[-1])
            res["process_wall_s"], res["process_cpu_s"] = time.perf_counter() - t0, _children_cpu_s() - c0
            if k > 0:  # round 0 warms the file caches and compiled forms
                runs[w].append(res)
            _say(f"{'warm-up' if k == 0 else f'repeat {k}/{repeats}'} {w}: jobs "
                 f"{sum(j['wall_s'] for j in res['jobs']):.2f} s wall, {sum(j['cpu_s'] for j in res['jobs']):.2f} s CPU; "
                 f"process {res['process_wall_s']:.2f} s")
    return runs


def timing_table(runs: dict[str, list[dict]]) -> str:
    """Per way: the medians of the nine jobs' wall and CPU time, of the mean per moved
    variant (a variant meshed anew in a moving way counted apart), of the nominal job, the
    median of the pairwise CPU ratios to the fresh way's nine jobs, the iterations; and how
    far each way's readings are from the moved way's (the same mesh, solve_level)."""
    def med(xs) -> float:
        return statistics.median(list(xs))

    def moved_jobs(r: dict, w: str) -> list[dict]:
        return [j for j in r["jobs"][1:] if w == "fresh" or j["iterations"] is not None]

    lines = [f"{'way':14s} {'9 jobs wall':>11s} {'CPU':>6s} {'per moved variant wall':>22s} {'CPU':>6s} "
             f"{'nominal job CPU':>15s} {'9 jobs CPU / fresh':>18s}  iterations", "-" * 118]
    for w, rs in runs.items():
        rel = ""
        if "fresh" in runs and w != "fresh":
            pairs = zip(rs, runs["fresh"])
            rel = f"{med(sum(j['cpu_s'] for j in a['jobs']) / sum(j['cpu_s'] for j in b['jobs']) for a, b in pairs):.2f}"
        its = " ".join("-" if j["iterations"] is None else str(j["iterations"]) for j in rs[0]["jobs"])
        lines.append(f"{w:14s} {med(sum(j['wall_s'] for j in r['jobs']) for r in rs):11.2f} "
                     f"{med(sum(j['cpu_s'] for j in r['jobs']) for r in rs):6.2f} "
                     f"{med(statistics.mean(j['wall_s'] for j in moved_jobs(r, w)) for r in rs):22.3f} "
                     f"{med(statistics.mean(j['cpu_s'] for j in moved_jobs(r, w)) for r in rs):6.3f} "
                     f"{med(r['jobs'][0]['cpu_s'] for r in rs):15.3f} {rel:>18s}  {its}")
    fresh_in = [j["cpu_s"] for w, rs in runs.items() if w != "fresh" for r in rs for j in r["jobs"][1:]
                if j["iterations"] is None]
    if fresh_in:
        lines.append(f"a variant meshed anew in a moving way (morph.remesh_reason): {med(fresh_in):.3f} s CPU")
    if "moved" in runs:
        ref = runs["moved"][0]["jobs"]
        for w, rs in runs.items():
            if w in ("fresh", "moved"):
                continue
            worst = max(abs(a[k] - b[k]) for a, b in zip(rs[0]["jobs"], ref) for k in ("peak_MPa", "critical_MPa"))
            lines.append(f"{w}: readings within {worst:.4f} MPa of the moved way's (solve_level on the moved mesh)")
    return "\n".join(lines)


def stages(size: str, repeats: int = 1) -> dict:
    """One fresh job (dj at its low end), one resolved and one reused job taken apart, each
    after a warm-up job, ``repeats`` times: per stage the median [wall, CPU] time (s)."""
    runs = [_stages_once(size) for _ in range(repeats)]
    out: dict[str, dict] = {}
    for way in runs[0]:
        out[way] = {}
        for k, v in runs[0][way].items():
            vals = [r[way][k] for r in runs]
            out[way][k] = (statistics.median(vals) if k == "iterations" else
                           [round(statistics.median(x[i] for x in vals), 4) for i in (0, 1)])
    return out


def _stages_once(size: str) -> dict:
    """:func:`stages` once."""
    import pipeline.analysis.analyse as analyse_mod
    import pipeline.analysis.level as level
    import pipeline.fe.meshing as meshing
    import pipeline.fe.solve as solve
    from pipeline.analysis.sensitivity import MESH_RATIO, analyse_variant
    cases = dict(variant_cases(size))
    nominal = cases["nominal"]
    variant = next(c for k, c in cases.items() if k.startswith("dj="))
    f = nominal.mesh_factor * MESH_RATIO
    spent: dict[str, list[float]] = {}
    marks: dict[str, tuple[float, float]] = {}
    iterations = [0]

    def now() -> tuple[float, float]:
        return time.perf_counter(), time.process_time()

    def timed(name: str, fn):
        def wrapper(*a, **k):
            t0 = now()
            try:
                return fn(*a, **k)
            finally:
                t1 = now()
                w, c = spent.get(name, [0.0, 0.0])
                spent[name] = [w + t1[0] - t0[0], c + t1[1] - t0[1]]
                marks[name] = t1
        return wrapper

    def monitor(ksp, its, rnorm):
        marks.setdefault("first_iteration", now())
        marks["last_iteration"] = now()
        iterations[0] = its

    def between(a: str, b: str) -> list[float]:
        return [marks[b][0] - marks[a][0], marks[b][1] - marks[a][1]]

    patches = [(meshing, "build", "geometry (OCC)"), (meshing, "mesh", "gmsh meshing"),
               (meshing, "distribute", "import to DOLFINx"), (level, "crosshead_loads", "loads"),
               (solve, "_assemble", "forms, sparsity, assembly"),
               (solve, "p_multigrid", "P1 matrix, interpolation"), (solve, "_reactions", "reactions"),
               (level, "peaks_of", "peaks"), (level, "section_results", "sections"),
               (analyse_mod, "solve_level", "solve_level")]
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in patches]
    saved.append((solve, "_let_threads_run", solve._let_threads_run))
    out: dict[str, dict] = {}
    try:
        for mod, name, label in patches:
            setattr(mod, name, timed(label, getattr(mod, name)))
        solve._let_threads_run = monitor
        analyse_variant(nominal, f)  # warm-up
        spent.clear()
        marks.clear()
        t0 = now()
        analyse_variant(variant, f)
        t1 = now()
        parts = {k: v for k, v in spent.items() if k != "solve_level"}
        parts["preconditioner set-up (GAMG, Chebyshev)"] = between("P1 matrix, interpolation", "first_iteration")
        parts["CG iterations"] = between("first_iteration", "last_iteration")
        total = [t1[0] - t0[0], t1[1] - t0[1]]
        parts["rest (places, specs, analyse, checks)"] = [total[i] - sum(v[i] for v in parts.values()) for i in (0, 1)]
        out["fresh"] = {**{k: [round(x, 4) for x in v] for k, v in parts.items()},
                        "iterations": iterations[0], "total": [round(x, 4) for x in total]}
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)
    for way in ("resolved", "reused"):
        moved = Moved(nominal, f, *_way_options()[way])
        try:
            moved.reading(nominal)  # the nominal job: the set-up
            t0, c0 = time.perf_counter(), time.process_time()
            _, info = moved.reading(variant)
            total = [time.perf_counter() - t0, time.process_time() - c0]
            out[way] = {**{k: [round(x, 4) for x in v] for k, v in info["stages_s"].items()},
                        "iterations": info["iterations"], "total": [round(x, 4) for x in total]}
        finally:
            moved.close()
    return out


def stages_table(rows: dict) -> str:
    """The stages of each job as text: wall and CPU (s)."""
    lines = []
    for way, parts in rows.items():
        lines += [f"{way} job, dj at its low end:", f"  {'stage':42s} {'wall':>7s} {'CPU':>7s}"]
        for k, v in parts.items():
            if k == "iterations":
                lines.append(f"  {'CG iterations (count)':42s} {v:7g}")
            else:
                lines.append(f"  {k:42s} {v[0]:7.3f} {v[1]:7.3f}")
    return "\n".join(lines)


RUN_CONFIGS = {"full": [], "no-sensitivity": ["--no-sensitivity"], "no-fields": ["--no-fields"]}
DRAWINGS = ("pipeline.output.picture", "pipeline.output.plots", "pipeline.output.closeup")


def runs(out: Path, repeats: int) -> dict:
    """`make run`'s command whole, with --no-sensitivity and with --no-fields, interleaved
    after a warm-up each: wall and CPU (s) and results.json's timings_s; then each drawing
    process alone on the last full run's folder."""
    out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, CROSSHEAD_NO_CACHE="1")
    res: dict[str, list[dict]] = {c: [] for c in RUN_CONFIGS}
    keep = out / "full-run"
    for k in range(repeats + 1):
        for c, extra in RUN_CONFIGS.items():
            folder = Path(tempfile.mkdtemp(dir=out, prefix=f"{c}-")) / "run"
            cmd = [sys.executable, "-m", "pipeline.runtime.launch", "2", "run", "--size", "05", "--out", str(folder),
                   "--quiet", *extra]
            t0, c0 = time.perf_counter(), _children_cpu_s()
            p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
            wall, cpu = time.perf_counter() - t0, _children_cpu_s() - c0
            if p.returncode != 0:
                raise SystemExit(f"{c}: exit {p.returncode}: {(p.stderr.strip().splitlines() or ['?'])[-1]}")
            timings = json.loads((folder / "results.json").read_text())["timings_s"]
            if k > 0:
                res[c].append({"wall_s": wall, "cpu_s": cpu, "timings_s": timings})
            _say(f"{'warm-up' if k == 0 else f'repeat {k}/{repeats}'} {c}: {wall:.2f} s wall, {cpu:.2f} s CPU")
            if c == "full":
                shutil.rmtree(keep, ignore_errors=True)
                shutil.move(str(folder), keep)
            shutil.rmtree(folder.parent, ignore_errors=True)
    drawings: dict[str, list[dict]] = {m: [] for m in DRAWINGS}
    for k in range(repeats):
        for m in DRAWINGS:
            t0, c0 = time.perf_counter(), _children_cpu_s()
            p = subprocess.run([sys.executable, "-m", m, str(keep)], cwd=ROOT, env=env, capture_output=True,
                               text=True)
            if p.returncode != 0:
                raise SystemExit(f"{m}: exit {p.returncode}")
            drawings[m].append({"wall_s": time.perf_counter() - t0, "cpu_s": _children_cpu_s() - c0})
    shutil.rmtree(keep, ignore_errors=True)
    return {"runs": res, "drawings": drawings}


def runs_table(r: dict) -> str:
    """Medians of the whole runs, their timings_s and the drawing processes."""
    def med(xs: list[float]) -> float:
        return statistics.median(xs)

    lines = [f"{'make run (2 ranks, cache off)':34s} {'wall':>6s} {'CPU':>6s}  results.json timings_s (median)",
             "-" * 100]
    keys = ("pilot", "error_bar_meshes", "sensitivity", "output", "picture", "total")
    for c, rows in r["runs"].items():
        t = {k: med([x["timings_s"].get(k, 0.0) for x in rows]) for k in keys}
        lines.append(f"{c:34s} {med([x['wall_s'] for x in rows]):6.2f} {med([x['cpu_s'] for x in rows]):6.2f}  "
                     + ", ".join(f"{k} {v:.2f}" for k, v in t.items()))
    full = r["runs"]["full"]
    for c in ("no-sensitivity", "no-fields"):
        pairs_w = [a["wall_s"] - b["wall_s"] for a, b in zip(full, r["runs"][c])]
        pairs_c = [a["cpu_s"] - b["cpu_s"] for a, b in zip(full, r["runs"][c])]
        lines.append(f"full − {c}: wall {med(pairs_w):+.2f} s, CPU {med(pairs_c):+.2f} s (median of the pairs)")
    for m, rows in r["drawings"].items():
        lines.append(f"{m:34s} {med([x['wall_s'] for x in rows]):6.2f} {med([x['cpu_s'] for x in rows]):6.2f}  "
                     "(alone, its process's start included)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.morph", description=__doc__.splitlines()[0])
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--accuracy", action="store_true", help="fresh against moved readings and ratios")
    what.add_argument("--timing", action="store_true", help="time per variant, each way")
    what.add_argument("--stages", action="store_true", help="one fresh and one resolved job taken apart")
    what.add_argument("--runs", action="store_true", help="make run whole, without the section, without fields")
    what.add_argument("--job", choices=WAYS, help=argparse.SUPPRESS)  # --timing's child process
    what.add_argument("--table", type=Path, help="print the table of an earlier --out JSON again")
    ap.add_argument("--size", default="05", help="hook number (default 05)")
    ap.add_argument("--factors", default="2.2", help="--accuracy: mesh factors / the run's (default 2.2, the section's)")
    ap.add_argument("--noise", action="store_true", help="--accuracy: also the section's noise at 2.2 (a pilot solve)")
    ap.add_argument("--reference", help="--accuracy: also every job meshed anew at these finer factors / the run's, "
                                        "e.g. 0.8,1,1.3 (minutes)")
    ap.add_argument("--ways", default=",".join(WAYS), help=f"--timing: which ways (default {','.join(WAYS)})")
    ap.add_argument("--factor-ratio", type=float, default=2.2, help="--timing: the mesh factor / the run's")
    ap.add_argument("--repeats", type=int, default=3,
                    help="--timing, --runs, --stages: rounds after the warm-up (default 3)")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here (--runs: a folder for the runs)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        print("--repeats: at least 1", file=sys.stderr)
        return 2
    if args.job:
        print(json.dumps(job(args.job, args.size, args.factor_ratio)))
        return 0
    if args.accuracy:
        rows = accuracy(args.size, [float(f) for f in args.factors.split(",")], args.noise,
                        [float(f) for f in args.reference.split(",")] if args.reference else [])
        print(accuracy_table(rows))
    elif args.timing:
        ways = [w.strip() for w in args.ways.split(",") if w.strip()]
        if any(w not in WAYS for w in ways):
            print(f"--ways: one of {', '.join(WAYS)}", file=sys.stderr)
            return 2
        rows = timing(args.size, args.repeats, ways, args.factor_ratio)
        print(timing_table(rows))
    elif args.table:
        rows = json.loads(args.table.read_text())
        print(timing_table(rows) if isinstance(rows, dict) and "fresh" in rows else
              runs_table(rows) if isinstance(rows, dict) else accuracy_table(rows))
        return 0
    elif args.stages:
        rows = stages(args.size, args.repeats)
        print(stages_table(rows))
    else:
        if args.out is None:
            print("--runs needs --out (a folder for the runs)", file=sys.stderr)
            return 2
        rows = runs(args.out, args.repeats)
        print(runs_table(rows))
        (args.out / "runs.json").write_text(json.dumps(rows, indent=1))
        return 0
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
