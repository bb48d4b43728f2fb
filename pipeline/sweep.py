"""Design studies: one analysis per variant of a grid of dimensions and loads, spread over
MPI ranks, resumable, with the crossing of each peak through the allowable (mm, N, MPa).

Scheduling is dynamic without a master: every rank walks the same task list and claims the
next task that is neither finished nor claimed by creating ``.claims/<key>`` exclusively
(atomic on a local or shared file system), so a slow variant holds only its own rank. A
task is one geometry and material; the loads of the grid are solved once for it and
scaled (linear elasticity, traction loads only). A task's key hashes every resolved input,
so a re-run skips finished tasks and re-runs any whose inputs changed. Invalid variants
(rules of docs/design.md §2) are reported and skipped; a failed variant is reported, not
fatal. Results: ``sweep.csv``, ``sweep.json``, one plot per peak and swept parameter,
``report.md``; each variant's own results in ``variants/<key>/``.
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import itertools
import json
import math
import os
import shutil
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

from mpi4py import MPI

from .atomicfile import replacing, write_text
from .case import Case, check_error_bar_meshes, resolve
from .errors import InputError, NumericalError, given_twice
from .interrupts import on_stop, stop_outcome

Progress = Callable[[str], None]
# A study file's [sweep] keys and their TOML types.
TOML_NAMES = {str: "a string", int: "an integer", float: "a number", dict: "a table"}
STUDY_KEYS = {"size": (str,), "case": (str,), "dims": (dict,), "load": (str, int, float), "levels": (int,),
              "ratio": (int, float), "mesh_factor": (int, float), "out": (str,)}
PEAKS = (("peak_MPa", "peak_band_MPa", "global peak"), ("critical_peak_MPa", "critical_band_MPa", "critical peak"))
COLUMNS = ("variant", "status", "size", "load_N", "parameters", "peak_MPa", "peak_band_MPa", "critical_peak_MPa",
           "critical_band_MPa", "critical_section_nominal_MPa", "safety_factor", "critical_safety_factor",
           "time_s", "note")


def parse_values(text: str, name: str) -> list[float]:
    """A sweep axis: ``START:STOP:COUNT`` (COUNT values, both ends included) or ``a,b,c``."""
    parts = text.split(":")
    if len(parts) == 1 and any(not v.strip() for v in text.split(",")):
        raise InputError(f"{name}: {text!r} has an empty item")
    try:
        if len(parts) == 3:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
            if not 2 <= n <= 200:
                raise InputError(f"{name}: a range needs 2..200 values, got {n}")
            values = [a + (b - a) * k / (n - 1) for k in range(n)]
        elif len(parts) == 1:
            values = [float(v) for v in text.split(",")]
        else:
            raise ValueError
    except ValueError:
        raise InputError(f"{name}: {text!r}: give START:STOP:COUNT or a list v1,v2,...") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise InputError(f"{name}: {text!r}: every value must be a finite number")
    twice = given_twice(values)
    if twice:
        raise InputError(f"{name}: {text!r}: {', '.join(f'{v:g}' for v in twice)} given twice")
    return values


@dataclass(frozen=True)
class Task:
    """One geometry and material of the grid, with every load it is asked at."""

    key: str
    params: dict  # the swept non-load parameters, name -> value
    case: Case | None  # None: invalid (see note)
    loads: tuple[float, ...]
    note: str = ""


def plan(size: str | None, case_file: Path | None, base: dict, axes: dict[str, list[float]],
         loads: list[float], levels: int, ratio: float, sizes: list[str] | None = None) -> list[Task]:
    """The grid's tasks: the product of ``axes`` (``dims.<name>`` or case fields, values),
    each at every load of ``loads`` (or the case's own load); with ``sizes``, that grid for
    every hook number (each at its own rated load unless loads are given)."""
    names = list(axes)
    tasks = []
    for hook, combo in itertools.product(sizes or [size], itertools.product(*(axes[n] for n in names))):
        params = dict(zip(names, combo), **({"size": hook} if sizes else {}))
        over = dict(base, **{k: v for k, v in params.items() if k != "size"})
        try:
            case = resolve(hook, case_file, over)
            qs = tuple(loads) or (case.load_N,)
            for q in qs:
                resolve(hook, case_file, dict(over, load_N=q))
            note = ""
        except InputError as exc:
            case, qs, note = None, tuple(loads), " ".join(str(exc).split())
        ident = {"case": None if case is None else case.as_dict(), "loads": qs, "levels": levels,
                 "ratio": ratio, "params": params}
        key = hashlib.sha1(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()[:12]
        tasks.append(Task(key=key, params=params, case=case, loads=qs, note=note))
    valid = [t.case for t in tasks if t.case is not None]
    if not valid:  # refused before the output folder is touched: nothing to analyse
        raise InputError(f"sweep: every variant is invalid; the first: {tasks[0].note}")
    check_error_bar_meshes(valid[0], levels, ratio)
    return tasks


def _claim(out: Path, key: str) -> bool:
    try:
        os.close(os.open(out / ".claims" / key, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return True
    except FileExistsError:
        return False


def _done(out: Path, key: str) -> bool:
    return (out / "variants" / key / "results.json").is_file() or (out / "variants" / f"{key}.failed.json").is_file()


def run_task(task: Task, out: Path, levels: int, ratio: float) -> None:
    """Analyse one task on this rank alone; a failure is written beside, never raised."""
    from geometry.part import GeometryError

    from .commands import execute_run
    case = replace(task.case, load_N=task.loads[0])
    try:
        execute_run(case, out / "variants" / task.key, levels=levels, ratio=ratio, write_fields=False,
                    loads=list(task.loads) if len(task.loads) > 1 else None, comm=MPI.COMM_SELF)
    except (NumericalError, GeometryError, InputError) as exc:
        write_text(out / "variants" / f"{task.key}.failed.json",
                   json.dumps({"error": " ".join(str(exc).split())}) + "\n")


def work(tasks: list[Task], out: Path, levels: int, ratio: float, say: Progress, comm=MPI.COMM_WORLD) -> None:
    """Every rank takes the next unclaimed, unfinished task until none is left."""
    todo = [t for t in tasks if t.case is not None]
    t0 = time.perf_counter()
    mine = 0
    for task in todo:
        if _done(out, task.key) or not _claim(out, task.key):
            continue
        run_task(task, out, levels, ratio)
        mine += 1
        finished = sum(_done(out, t.key) for t in todo)
        rate = (time.perf_counter() - t0) / mine / comm.size
        say(f"sweep: {finished}/{len(todo)} variants done (rank {comm.rank}); "
            f"about {rate * (len(todo) - finished):.0f} s left")


def rows_of(tasks: list[Task], out: Path) -> list[dict]:
    """One row per variant and load: inputs, peaks with bands, safety factors, status."""
    rows = []
    for t in tasks:
        base = {"variant": t.key, "parameters": json.dumps(t.params, sort_keys=True),
                **{k: v for k, v in t.params.items()},
                "size": t.params.get("size") or (None if t.case is None else t.case.size)}
        if t.case is None:
            rows += [dict(base, status="invalid", load_N=q, note=t.note) for q in (t.loads or (None,))]
            continue
        failed = out / "variants" / f"{t.key}.failed.json"
        res_path = out / "variants" / t.key / "results.json"
        if failed.is_file():
            note = json.loads(failed.read_text())["error"]
            rows += [dict(base, status="failed", load_N=q, note=note) for q in t.loads]
            continue
        if not res_path.is_file():
            rows += [dict(base, status="not run", load_N=q) for q in t.loads]
            continue
        res = json.loads(res_path.read_text())
        fe = res["fe"]
        nominal = ((fe.get("sections") or {}).get("critical_section") or {}).get("nominal_MPa")
        per_load = res.get("load_sweep") or [{
            "load_N": res["case"]["load_N"], "peak_MPa": fe["peak_MPa"], "critical_peak_MPa": fe["critical_peak_MPa"],
            "peak_band_MPa": (fe["peak"].get("error_estimate") or {}).get("band"),
            "critical_band_MPa": (fe["critical"].get("error_estimate") or {}).get("band"),
            "safety_factor": fe["safety_factor"], "critical_safety_factor": fe["critical_safety_factor"]}]
        q0 = res["case"]["load_N"]
        for r in per_load:
            rows.append(dict(base, status="done", time_s=res["timings_s"]["total"],
                             critical_section_nominal_MPa=None if nominal is None else nominal * r["load_N"] / q0,
                             **{k: r.get(k) for k in ("load_N", "peak_MPa", "peak_band_MPa", "critical_peak_MPa",
                                                      "critical_band_MPa", "safety_factor", "critical_safety_factor")}))
    return rows


def crossings(rows: list[dict], axis: str, allowable: float) -> list[dict]:
    """Where each peak crosses the allowable along ``axis`` (the other parameters fixed):
    linear interpolation between neighbouring variants; the range from the peaks' bands
    (value ± band crossing the allowable) when both neighbours have one."""
    found = []
    others = [k for k in rows[0] if k not in COLUMNS and k != axis] if rows else []
    done = [r for r in rows if r["status"] == "done"]
    groups: dict = {}
    for r in done:
        groups.setdefault(tuple((k, r.get(k)) for k in others + (["load_N"] if axis != "load_N" else [])), []).append(r)
    for fixed, group in groups.items():
        group = sorted(group, key=lambda r: r[axis])
        for key, band_key, label in PEAKS:
            for a, b in zip(group, group[1:]):
                ya, yb = a[key] - allowable, b[key] - allowable
                if ya == 0 or ya * yb < 0:
                    def at(da: float, db: float) -> float | None:
                        y1, y2 = a[key] + da - allowable, b[key] + db - allowable
                        return None if y1 == y2 else a[axis] + (0 - y1) * (b[axis] - a[axis]) / (y2 - y1)
                    x = at(0, 0)
                    lo_hi = None
                    if a.get(band_key) is not None and b.get(band_key) is not None:
                        ends = [v for v in (at(a[band_key], b[band_key]), at(-a[band_key], -b[band_key])) if v is not None]
                        lo_hi = [min(ends), max(ends)] if len(ends) == 2 else None
                    found.append({"peak": label, "axis": axis, "at": x, "range": lo_hi,
                                  "falls_below": yb < ya, "fixed": dict(fixed)})
    return found


def write_outputs(tasks: list[Task], out: Path, axes: dict[str, list[float]], allowable: float) -> dict:
    """sweep.csv, sweep.json, plots and report.md from the variants' results (rank 0)."""
    rows = rows_of(tasks, out)
    names = [n for n in axes]
    cols = list(COLUMNS) + [n for n in names if n not in COLUMNS]
    with replacing(out / "sweep.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    swept = [n for n in names if len(axes[n]) > 1 and n != "size"]  # numeric axes only
    cross = [c for n in swept for c in crossings(rows, n, allowable)]
    summary = {"units": {"length": "mm", "force": "N", "stress": "MPa"}, "allowable_MPa": allowable,
               "axes": axes, "rows": rows, "crossings": cross,
               "counts": {s: sum(r["status"] == s for r in rows) for s in ("done", "invalid", "failed", "not run")}}
    write_text(out / "sweep.json", json.dumps(summary, indent=2, default=str) + "\n")
    plots = [p for n in swept for p in _plots(rows, n, allowable, out)]
    write_text(out / "report.md", _report(summary, swept, plots))
    return summary


def _plots(rows: list[dict], axis: str, allowable: float, out: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    done = [r for r in rows if r["status"] == "done"]
    if not done:
        return []
    names = []
    for key, band_key, label in PEAKS:
        fig, ax = plt.subplots(figsize=(6.5, 4))
        groups: dict = {}
        for r in done:
            groups.setdefault(r["parameters"] if axis == "load_N" else (r["parameters"], r["load_N"]), []).append(r)
        for g in groups.values():
            g = sorted(g, key=lambda r: r[axis])
            ax.errorbar([r[axis] for r in g], [r[key] for r in g], yerr=[r.get(band_key) or 0 for r in g],
                        marker="o", capsize=3, lw=1)
        ax.axhline(allowable, color="red", ls="--", label=f"allowable {allowable:g} MPa")
        ax.set_xlabel(axis.replace("dims.", "") + (" (N)" if axis == "load_N" else " (mm)"))
        ax.set_ylabel(f"{label} von Mises (MPa)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        name = f"{key.replace('_MPa', '')}_vs_{axis.replace('dims.', '')}.png"
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        names.append(name)
    return names


def _report(summary: dict, swept: list[str], plots: list[str]) -> str:
    c = summary["counts"]
    L = ["# Design study\n", "Units: mm, N, MPa.\n",
         f"{c['done']} variants analysed, {c['invalid']} invalid (skipped), {c['failed']} failed, "
         f"{c['not run']} not run. Allowable {summary['allowable_MPa']:g} MPa.\n", "## Crossing the allowable\n"]
    if not summary["crossings"]:
        L.append("No peak crosses the allowable inside the swept ranges.\n")
    for x in summary["crossings"]:
        fixed = ", ".join(f"{k.replace('dims.', '')} = {v:g}" for k, v in x["fixed"].items() if v is not None)
        rng = f" (between {x['range'][0]:.4g} and {x['range'][1]:.4g} within the error bars)" if x["range"] else ""
        word = "falls below" if x["falls_below"] else "rises above"
        L.append(f"- The {x['peak']} {word} {summary['allowable_MPa']:g} MPa at {x['axis'].replace('dims.', '')} "
                 f"≈ {x['at']:.4g}{rng}" + (f" ({fixed})" if fixed else "") + ".")
    L.append("")
    L.append("## Variants\n")
    L.append("| variant | status | parameters | load (N) | global peak (MPa) | critical peak (MPa) | note |")
    L.append("|---|---|---|---|---|---|---|")
    for r in summary["rows"]:
        def f(v, band=None):
            return "" if v is None else f"{v:.2f}" + (f" ± {band:.2f}" if band else "")
        L.append(f"| {r['variant']} | {r['status']} | {r['parameters']} | {r.get('load_N') or ''} | "
                 f"{f(r.get('peak_MPa'), r.get('peak_band_MPa'))} | {f(r.get('critical_peak_MPa'), r.get('critical_band_MPa'))} | "
                 f"{r.get('note') or ''} |")
    L.append("")
    for p in plots:
        L.append(f"![{p}]({p})\n")
    return "\n".join(L) + "\n"


def read_study(path: Path) -> dict:
    """A study file (TOML, e.g. cases/sweep-rf.toml): its [sweep] table with ``size`` or
    ``case``, ``dims`` (NAME = "START:STOP:COUNT" or "a,b,c"), ``load``, ``levels``,
    ``ratio``, ``mesh_factor``, ``out``."""
    import tomllib

    from geometry.table import Dimensions
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8").removeprefix("\ufeff"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"study: cannot read {path}: {exc}") from None
    s = data.get("sweep")
    if not isinstance(s, dict) or set(data) != {"sweep"}:
        extra = ", ".join(sorted(set(data) - {"sweep"}))
        raise InputError(f"study: {path} holds one [sweep] table and nothing else"
                         + (f" (found {extra}; material and mesh options go in a case file, case = ...)"
                            if extra else ""))
    for key, value in s.items():
        types = STUDY_KEYS.get(key)
        if types is None:
            raise InputError(f"sweep.{key}: unknown key in {path}; known: {', '.join(STUDY_KEYS)}")
        if isinstance(value, bool) or not isinstance(value, types):
            raise InputError(f"sweep.{key}: expected {' or '.join(TOML_NAMES[t] for t in types)} in {path}, "
                             f"got {value!r}")
    names = list(Dimensions.__dataclass_fields__)
    dims = {}
    for name, values in s.get("dims", {}).items():
        if name not in names:
            raise InputError(f"sweep.dims.{name}: unknown dimension in {path}; known: {', '.join(names)}")
        if isinstance(values, list) and values and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            values = ",".join(repr(v) for v in values)  # a TOML array of numbers is a list
        if isinstance(values, bool) or not isinstance(values, (str, int, float)):
            raise InputError(f"sweep.dims.{name}: expected \"START:STOP:COUNT\", \"v1,v2,...\", an array of "
                             f"numbers or a number in {path}, got {values!r}")
        dims[name] = values
    return dict(s, **({"dims": dims} if "dims" in s else {}))


def execute_sweep(size: str | None, case_file: Path | None, base: dict, axes: dict[str, list[float]],
                  loads: list[float], out: Path, levels: int, ratio: float, say: Progress,
                  comm=MPI.COMM_WORLD, sizes: list[str] | None = None) -> dict | None:
    """Plan, check the output folder, work on every rank, summarise on rank 0."""
    from .outdir import MARKER, acquire_lock, check_out
    tasks = plan(size, case_file, base, axes, loads, levels, ratio, sizes)
    lock = None
    error = None
    if comm.rank == 0:
        try:
            out = check_out(out)
            out.mkdir(parents=True, exist_ok=True)
            lock = acquire_lock(out)
            shutil.rmtree(out / ".claims", ignore_errors=True)  # the lock: no other sweep is running
            (out / ".claims").mkdir()
            (out / "variants").mkdir(exist_ok=True)
            (out / MARKER).write_text(json.dumps({"tool": "crosshead", "sweep": True}) + "\n")
            stop_outcome(f"the study in {out} keeps the variants finished so far; the same command resumes it")
        except (InputError, OSError) as exc:
            if lock is not None:
                lock.release()
                lock = None
            error = exc if isinstance(exc, InputError) else InputError(f"out: cannot write {out}: {exc}")
    error = comm.bcast(error, root=0)
    if error is not None:
        raise error
    out = Path(out).expanduser().resolve()
    valid = sum(t.case is not None for t in tasks)
    say(f"sweep: {len(tasks)} variants ({valid} valid, {len(tasks) - valid} invalid), "
        f"{sum(_done(out, t.key) for t in tasks if t.case is not None)} already done, {comm.size} rank(s)")
    with contextlib.ExitStack() as stack:
        if lock is not None:  # a stop ends the process with os._exit: the finally below never runs
            stack.enter_context(on_stop(lock.release))
        try:
            work(tasks, out, levels, ratio, say if comm.rank == 0 else (lambda s: None), comm)
            request = comm.Ibarrier()
            while not request.Test():
                time.sleep(0.05)
            if comm.rank == 0:
                allowable = next((t.case.allowable_MPa for t in tasks if t.case is not None), 80.0)
                axes_out = dict(axes, **({"load_N": loads} if len(loads) > 1 else {}))
                return write_outputs(tasks, out, axes_out, allowable)
            return None
        finally:
            if lock is not None:
                shutil.rmtree(out / ".claims", ignore_errors=True)
                lock.release()
