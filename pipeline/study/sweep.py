"""Running a design study: one analysis per variant of a grid of dimensions and loads
(planned by pipeline.study.plan), spread over MPI ranks, resumable; its table, crossings of the
allowable, plots and report come from pipeline.study.table (mm, N, MPa).

Scheduling is dynamic without a master: every rank walks the same task list and claims the
next task that is neither finished nor claimed by creating ``.claims/<key>`` exclusively
(atomic on a local or shared file system), so a slow variant holds only its own rank. A
task is one geometry and material; the loads of the grid are solved once for it and
scaled (linear elasticity, traction loads only). A task's key hashes every resolved input
and the analysing code (codekey.code_key), so a re-run skips finished tasks and re-runs
any whose inputs or code changed. Invalid variants
(rules of docs/design.md §2) are reported and skipped; a failed variant is reported, not
fatal. Results: ``sweep.csv``, ``sweep.json``, one plot per peak and swept parameter,
``report.md``; each variant's own results in ``variants/<key>/``, with the checksums of
its files (pipeline.study.manifest): a variant whose files no longer match them (edited,
cut short) is named and analysed again, on resuming and before the study is summarised.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator

from mpi4py import MPI

from geometry.part import GeometryError
from pipeline.analysis.context import RunContext
from pipeline.analysis.words import coarse_mesh_note
from pipeline.output import flat
from pipeline.study.screening import (FILE, FULL, NEXT_STEPS, STEPS, screen_case, screened_rows, screening_of,
                                      undecided)
from pipeline.errors import InputError, NumericalError
from pipeline.inputs.case import Case
from pipeline.inputs.options import RunOptions
from pipeline.output.folder import write_run
from pipeline.runtime.interrupts import on_stop, stop_outcome
# pipeline.fe.meshing loads DOLFINx, whose import starts PETSc collectively over COMM_WORLD:
# importing it here, on every rank as the command starts, keeps rank 0's later memory probe
# from being the only rank to do so (it met the others' broadcast and aborted them).
from pipeline.fe.meshing import heartbeat
from pipeline.runtime.atomicfile import write_text
from pipeline.runtime.idle import wait_for_ranks
from pipeline.study.manifest import MANIFEST, failure_fault, folder_fault, write_failure, write_manifest
from pipeline.study.plan import Study, Task, earlier_variants, failure_file, plan, variant_folder, variant_options
from pipeline.study.table import inputs_text, write_outputs

Progress = Callable[[str], None]

# How many times a study analyses again the variants whose files fail their checksums
# after its work: once is enough unless something keeps changing them; then the table
# leaves them out, saying why.
REPAIR_ROUNDS = 1


def _claim(out: Path, key: str) -> bool:
    """Claim task ``key`` for this rank: True if no rank had (an exclusive create)."""
    try:
        os.close(os.open(out / ".claims" / key, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        return True
    except FileExistsError:
        return False


def _done(out: Path, key: str, need: str | None = FULL) -> bool:
    """Has task ``key`` ended as far as ``need`` asks, with results or with its failure
    written, each matching its checksums? (Results without them are a run that stopped,
    or files changed since.) ``need``: FULL, the full error bar; NEXT_STEPS, a screened
    study's step past the cheap level; None, any results (pipeline.study.screening)."""
    failed = failure_file(out, key)
    if failed.is_file() and failure_fault(failed) is None:
        return True
    folder = variant_folder(out, key)
    if folder_fault(folder) is not None:
        return False
    s = screening(folder)
    if need is None or s is None or s["full_error_bar"]:
        return True
    return need == NEXT_STEPS and s.get("step", STEPS[0].name) != STEPS[0].name


def screening(folder: Path) -> dict | None:
    """The cheap level's reading kept in a variant's folder (screening.json), or None: a
    variant of a study that was not screened. Read only from a folder whose files match
    their checksums."""
    from pipeline.study.screening import FILE
    f = folder / FILE
    return json.loads(f.read_text(encoding="utf-8")) if f.is_file() else None


def _ended(out: Path, key: str) -> bool:
    """Has task ``key`` written its checksums or its failure? For the progress line: the
    files are checked against them (:func:`_done`) before a task is skipped or read."""
    return (variant_folder(out, key) / MANIFEST).is_file() or failure_file(out, key).is_file()


def fault_of(out: Path, key: str) -> str | None:
    """Why the files task ``key`` left in the study ``out`` cannot be taken as its run
    wrote them ("results.json does not match its checksum"), or None: when they match,
    or when it left none."""
    folder, failed = variant_folder(out, key), failure_file(out, key)
    if failed.is_file() or failed.is_symlink():
        why = failure_fault(failed)
        if why is not None:
            return why
    if folder.is_dir() or folder.is_symlink():
        return folder_fault(folder)
    return None


def discard_damaged(out: Path, tasks: list[Task], say: Progress) -> list[str]:
    """Remove what each task of ``tasks`` left in ``out`` that does not match its
    checksums, saying so in one line per task, so that the study analyses it again; its
    keys. Its claim goes too: a study that has run it once takes it again. A user's file in
    a variant's folder stays, named in the line (the new run carries it over)."""
    keys = []
    for t in tasks:
        why = None if t.case is None else fault_of(out, t.key)
        if why is None:
            continue
        kept = []
        for p in (variant_folder(out, t.key), failure_file(out, t.key), out / ".claims" / t.key,
                  out / ".claims" / f"{t.key}.full"):
            kept += _remove(p)
        said = f"; kept {', '.join(kept)} (not the study's)" if kept else ""
        say(f"sweep: variant {t.key} ({inputs_text(t.params)}): {why}; analysed again{said}")
        keys.append(t.key)
    return keys


def study_files(folder: Path) -> set[str]:
    """The entries of a variant's folder that its run and its study wrote: those the run's
    results marker lists (pipeline.runtime.folders.tool_names; a run's files when it lists
    none), the marker, the checksums and a screened study's reading. Anything else is the
    user's."""
    from pipeline.runtime.folders import MARKER, tool_names
    names = {p.name for p in folder.iterdir()}
    return tool_names(folder, names) | (names & {MARKER, MANIFEST, FILE})


def _remove(path: Path, keep_marked: bool = True) -> list[str]:
    """Remove what a task left at ``path``: a file, a link (not what it points to), an
    empty folder, or of a variant's folder (it holds the results marker or the checksums)
    the files its run and its study wrote (:func:`study_files`). Returns the user's entries
    of that folder, which stay: the folder stays too, marked as the tool's with no files of
    its own so that the task's next run replaces it and carries them over (with
    ``keep_marked`` False, unmarked: only the user's entries are left). A folder the tool
    did not write stays whole: the run into it is then refused and written as the task's
    failure."""
    from pipeline.runtime.folders import MARKER
    if path.is_dir() and not path.is_symlink():
        if (path / MARKER).is_file() or (path / MANIFEST).is_file():
            own = study_files(path)
            user = sorted({p.name for p in path.iterdir()} - own)
            if not user:
                # Renamed first (one step), so a stop during the removal leaves no half a
                # variant under its key; the study removes the renamed rest when it ends
                # (earlier_variants: a marked folder of no key of the study).
                gone = path.with_name(f".removing-{path.name}-{os.getpid()}")
                os.replace(path, gone)
                shutil.rmtree(gone)
                return []
            for name in sorted(own - {MARKER}, key=lambda n: n != "results.json"):  # results first: never read again
                entry = path / name
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink(missing_ok=True)
            if keep_marked:  # the marker last: a stop half-way leaves a folder still the tool's
                write_text(path / MARKER, json.dumps({"tool": "crosshead", "files": []}) + "\n")
            else:
                (path / MARKER).unlink(missing_ok=True)
            return [f"{path.name}/{n}" for n in user]
        if not any(path.iterdir()):
            path.rmdir()
        return []
    path.unlink(missing_ok=True)
    return []


def run_task(task: Task, out: Path, study: Study, screen: bool = False,
             escalation: tuple[str, str] | None = None) -> None:
    """Analyse one task on this rank alone, then write the checksums of its files; a
    failure is written beside (with its own checksum), never raised. What the task left
    before (files that failed their checksums) is removed first, so that only this run's
    files are found. ``screen``: the cheap level only (pipeline.study.screening), whose
    reading goes into screening.json; when it fails, the full analysis runs at once.
    ``escalation``: (why, how far) a screened study's variant goes past the cheap level:
    the next steps until one decides it, or the full error bar. No variant solves the
    journal load at the hand formulas' positions: the study's table does not read those
    sections (results.json's ``fe.sections.formula_load`` is null)."""
    case = replace(task.case, load_N=task.loads[0])
    folder, failed = variant_folder(out, task.key), failure_file(out, task.key)
    cheap = screening(folder) if escalation is not None and folder_fault(folder) is None else None
    _remove(folder)
    _remove(failed)
    options = variant_options(study, tuple(task.loads))
    alone = RunContext(comm=MPI.COMM_SELF, memo={})  # a variant's steps solve each mesh once
    tried = list((cheap or {}).get("steps", []))  # every step's reading so far, for the bench's coverage check
    try:
        if screen:
            try:
                res = write_run(screen_case(case), replace(options, levels=1, sensitivity=False), folder, alone)
                first = screening_of(res)
                _finish(folder, dict(first, steps=[_brief(first)]))
                return
            except (NumericalError, GeometryError, InputError) as exc:
                _remove(folder)
                escalation = (f"the cheap level failed: {' '.join(str(exc).split())}", FULL)
        why, how_far = escalation or (None, FULL)
        if how_far == NEXT_STEPS and _stepwise(study, case):
            for s in _next_steps(case, options, folder, alone):
                tried.append(_brief(s))
                if s["decided"]:
                    _finish(folder, dict(s, steps=tried))
                    return
        write_run(case, options, folder, alone)
    except (NumericalError, GeometryError, InputError) as exc:
        _remove(folder)
        write_failure(failed, {"error": " ".join(str(exc).split()), "size": case.size, "parameters": task.params})
        return
    _finish(folder, None if why is None else dict(cheap or {"peaks": None}, full_error_bar=True, why_full=why,
                                                  steps=tried))


def _stepwise(study: Study, case: Case) -> bool:
    """Whether a screened variant may stop short of the full error bar on the steps
    between: their bands were measured for the default three meshes at ratio 1.3, on the
    default mesh (a coarser case mesh misreads more)."""
    return (study.screen and study.levels == 3 and math.isclose(study.ratio, 1.3) and not study.sensitivity
            and case.mesh_factor <= 1.0)


def _next_steps(case: Case, options: RunOptions, folder: Path, ctx: RunContext) -> Iterator[dict]:
    """The readings of the steps between the cheap level and the full error bar
    (screening.STEPS), cheapest first, each on the full error bar's own meshes and places
    (ctx's memo solves each mesh once) with its results in ``folder``; each says whether
    its bands decide every peak against the allowable (``decided``). The caller stops at
    the first that does; after the last, the full error bar reuses what they solved."""
    for step in STEPS[1:-1]:
        coarser = options.levels - step.levels  # ratio steps from the case's mesh to the step's finest
        res = write_run(case, replace(options, levels=step.levels, finer=-coarser), folder, ctx)
        s = screening_of(res, step)
        s["decided"] = not any(undecided(r, case.allowable_MPa) for r in screened_rows(flat.rows(res), s))
        yield s


def _brief(s: dict) -> dict:
    """A step's reading as screening.json's ``steps`` lists it: the step, its meshes and
    each peak's value and band (MPa)."""
    return {"step": s["step"], "meshes": s["meshes"],
            "peaks": {b: {k: s["peaks"][b][k] for k in ("value_MPa", "band_MPa")} for b in s["peaks"]}}


def _finish(folder: Path, kept: dict | None) -> None:
    """Write a variant's screening.json (``kept``, when it has one) and its checksums."""
    if kept is not None:
        write_text(folder / FILE, json.dumps(kept, indent=1) + "\n")
    write_manifest(folder)


def work(tasks: list[Task], out: Path, study: Study, say: Progress, before: int,
         more: dict[str, tuple[str, str]] | None = None) -> None:
    """Every rank takes the next unclaimed, unfinished task until none is left; ``before``
    tasks had finished when the study started (the pace counts only this run's). A
    screened study's tasks on the cheap level only; ``more``: these tasks of a screened
    study further (key -> why the cheap level was not enough, and how far: the next
    steps or the full error bar)."""
    screen = study.screen and more is None
    todo = [t for t in tasks if t.case is not None and (more is None or t.key in more)]
    t0 = time.perf_counter()
    what = "screened" if screen else "done" if more is None else "analysed further"

    def need(key: str) -> str | None:
        return None if screen else FULL if more is None else more[key][1]
    for task in todo:
        claim = task.key + ("" if more is None else f".{more[task.key][1].replace(' ', '-')}")
        if _done(out, task.key, need(task.key)) or not _claim(out, claim):
            continue
        # A variant says nothing until it ends: a large one (a fine mesh, a small fillet)
        # is heard from every HEARTBEAT_S while it runs.
        with heartbeat(say, f"sweep: variant {inputs_text(task.params)}"):
            run_task(task, out, study, screen=screen, escalation=None if more is None else more[task.key])
        finished = sum(_done(out, t.key, need(t.key)) if more is not None else _ended(out, t.key) for t in todo)
        say(f"sweep: {finished}/{len(todo)} variants {what}; "
            f"about {time_left_s(time.perf_counter() - t0, finished - before, len(todo) - finished):.0f} s left")


def escalate(tasks: list[Task], out: Path, study: Study, allowable: float, say: Progress, comm: MPI.Comm) -> None:
    """The second step of a screened study: the variants whose cheap band holds the
    allowable (MPa), or that border a crossing of it, get the full error bar; repeated,
    since a variant analysed in full can move a crossing next to one decided cheaply,
    until no variant needs it (pipeline.study.table.escalations)."""
    from pipeline.study.table import escalations, rows_of, swept_axes, with_verdicts
    while True:
        wait_for_ranks(comm)  # every rank's variants of the last pass have ended
        todo = None
        if comm.rank == 0:
            rows = with_verdicts(rows_of(tasks, out), allowable)
            todo = {k: w for k, w in escalations(rows, swept_axes(axes_of(study)), allowable).items()
                    if not _done(out, k, w[1])}
            if todo:
                full = sum(w[1] == FULL for w in todo.values())
                say(f"sweep: {_count(len(todo), 'variant')} {'needs' if len(todo) == 1 else 'need'} more than the cheap level "
                    f"({full} the full error bar, {len(todo) - full} the next steps)")
        todo = comm.bcast(todo, root=0)
        if not todo:
            return
        work(tasks, out, study, say, 0, more=todo)


def _count(n: int, noun: str) -> str:
    """'1 variant', '3 variants'."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def time_left_s(elapsed_s: float, finished_here: int, left: int) -> float:
    """The study's remaining wall time (s): the tasks left at the pace of this run so far,
    ``finished_here`` tasks (by every rank, read from the output folder) in ``elapsed_s``.
    Counting every rank's finished tasks, not one rank's, keeps the estimate right when the
    ranks move at different paces (a slow variant, a busier node)."""
    return elapsed_s / max(finished_here, 1) * left


def check_variants_fit(tasks: list[Task], limit_gb: float | None, copies: int, say: Progress) -> None:
    """Refuse (InputError, exit 2) a study a variant of which would not fit in memory
    (pipeline.analysis.memory) when ``copies`` variants run at once on this machine (one per
    rank that shares its memory). A variant's meshes are solved one after another on its
    own rank, so its requested (finest) mesh sets what it needs. Only variants that could
    be large are probed (a finer mesh factor, sizes by hand, a small fillet), and under an
    address-space limit (``ulimit -v``) every variant."""
    from pipeline.analysis.memory import check_fits, needs_probe
    from pipeline.runtime.environment import address_space_limit
    limited = address_space_limit() is not None  # ulimit -v: every variant is held to it
    large = [t for t in tasks if t.case is not None and (limited or needs_probe(t.case, [t.case.mesh_factor]))]
    if large:
        say(f"sweep: estimating the memory of {_count(len(large), 'variant')} that could be large (a mesh each)")
    for t in large:
        check_fits(t.case, [t.case.mesh_factor], limit_gb, copies, what=f"variant {inputs_text(t.params)}: ")


def remove_earlier_variants(out: Path, tasks: list[Task], say: Progress) -> None:
    """Remove the results of variants that this study does not have, once it has finished:
    left by a run of it with other inputs or older code, they would be read beside its own
    (a summary of ``variants/`` would list a size twice) and only take room. Until the
    study finishes they stay, so an interrupted re-run loses nothing. A user's file in such
    a folder stays, named, in a folder that is no longer marked as a variant's."""
    gone = earlier_variants(out, {t.key for t in tasks})
    kept = [k for p in gone for k in _remove(p, keep_marked=False)]
    if gone:
        said = f"; kept {', '.join(kept)} (not the study's)" if kept else ""
        say(f"sweep: removed the results of {_count(len(gone), 'variant')} that this study does not have "
            f"(earlier inputs or code){said}")


def axes_of(study: Study) -> dict[str, list[float]]:
    """The study's axes as its table lists them: its grid's, and the loads when several."""
    return dict(study.axes, **({"load_N": study.loads} if len(study.loads) > 1 else {}))


def execute_sweep(study: Study, out: Path, say: Progress, comm: MPI.Comm = MPI.COMM_WORLD) -> dict | None:
    """Plan, check memory and the output folder, work on every rank, summarise on rank 0.
    Only rank 0 calls ``say``. With the study's ``sensitivity`` each variant varies its
    assumed inputs too (pipeline/analysis/sensitivity.py), and the table says whether its
    verdict holds; a screened study analyses every variant on the cheap level first, and
    only those it does not decide get the full error bar (:func:`escalate`)."""
    from pipeline.runtime.outdir import MARKER, acquire_lock, check_out
    if comm.rank != 0:
        say = lambda s: None  # noqa: E731
    tasks = plan(study)
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    copies = node.size  # the ranks that share this machine's memory, each with a variant
    node.Free()
    lock = None
    error = None
    if comm.rank == 0:
        try:
            out = check_out(out, kind="sweep")  # the cheap check first
            check_variants_fit(tasks, study.memory_limit_gb, copies, say)
            out.mkdir(parents=True, exist_ok=True)
            lock = acquire_lock(out)
            shutil.rmtree(out / ".claims", ignore_errors=True)  # the lock: no other sweep is running
            (out / ".claims").mkdir()
            (out / "variants").mkdir(exist_ok=True)
            (out / MARKER).write_text(json.dumps({"tool": "crosshead", "sweep": True}) + "\n")
            discard_damaged(out, tasks, say)  # before anything counts them as done
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
    before = sum(_done(out, t.key) for t in tasks if t.case is not None)
    each = f" at {len(study.loads)} loads each" if len(study.loads) > 1 else ""
    say(f"sweep: {_count(len(tasks), 'variant')}{each} ({valid} valid, {len(tasks) - valid} invalid), "
        f"{before} already done, {comm.size} rank(s)")
    for note in dict.fromkeys(n for t in tasks if t.case is not None and (n := coarse_mesh_note(t.case))):
        say(f"note: {note}")  # as a run says it before its work (pipeline/cli/preflight.py)
    with contextlib.ExitStack() as stack:
        if lock is not None:  # a stop ends the process with os._exit: the finally below never runs
            stack.enter_context(on_stop(lock.release))
        try:
            allowable = next((t.case.allowable_MPa for t in tasks if t.case is not None), 80.0)
            for round_ in range(REPAIR_ROUNDS + 1):
                work(tasks, out, study, say, before)
                if study.screen:
                    escalate(tasks, out, study, allowable, say, comm)
                wait_for_ranks(comm)
                # Before the study is summarised: every variant's files as its run wrote them.
                again = comm.bcast(bool(discard_damaged(out, tasks, say)) if comm.rank == 0
                                   and round_ < REPAIR_ROUNDS else False, root=0)
                if not again:
                    break
            if comm.rank == 0:
                remove_earlier_variants(out, tasks, say)
                return write_outputs(tasks, out, axes_of(study), allowable)
            return None
        finally:
            if lock is not None:
                shutil.rmtree(out / ".claims", ignore_errors=True)
                lock.release()
