"""A run's folder: the analysis (pipeline.analysis.run) run into a staging folder that
replaces the output folder only when complete, each file written once (mm, N, MPa).

What a run writes: results.json (always), mesh.msh (``outputs.mesh``) and, with
``outputs.fields``, fields.vtu, peaks.vtp, the pictures and plots, report.md, report.html,
report.pdf (where a headless Chromium is installed: pipeline/output/pdf.py) and the tables
meshes.csv and sensitivity.csv. The field file is written as soon as the requested mesh is
solved, so that the drawing processes start beside the error-bar solves; peaks.vtp (the
reported places with their bands) and results.json are written when the result is complete
and the drawings have ended, and the report and the tables read only results.json; the PDF
is printed beside the tables, the run's last work.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

from mpi4py import MPI

from pipeline.analysis.context import RunContext
from pipeline.analysis.level import Level
from pipeline.analysis.pilot import Pilot
from pipeline.analysis.result import RunResult
from pipeline.analysis.run import run
from pipeline.fe.elasticity import Material
from pipeline.inputs.case import Case
from pipeline.inputs.options import RunOptions
from pipeline.output import drawing, flat, pdf
from pipeline.output.fields import write_fields, write_peaks
from pipeline.output.jsonio import write_json
from pipeline.output.plots import convergence_plot
from pipeline.output.report import write_report
from pipeline.output.results import results_json
from pipeline.post.features import describe_location
from pipeline.runtime.interrupts import on_stop
from pipeline.runtime.outdir import staged_dir

# The plots the drawing processes may make, by results.json's file key.
PLOTS = {"sections_plot": "sections.png", "peaks_plot": "peaks.png", "sensitivity_plot": "sensitivity.png",
         "mesh_closeup": "mesh_closeup.png"}


def write_run(case: Case, options: RunOptions, out_dir: Path, ctx: RunContext = RunContext()) -> dict:
    """Analyse ``case`` as ``options`` ask and write its folder ``out_dir`` whole (or leave
    an earlier one as it was); returns results.json's content."""
    t_all = time.perf_counter()
    with staged_dir(out_dir, ctx.comm, ctx.say) as stage, contextlib.ExitStack() as stack:
        early = EarlyOutput(case, options, stage, ctx.comm, stack, say=ctx.say)
        try:
            result = run(case, options, replace(ctx, on_requested=early.requested))
        except BaseException:
            early.abandon()  # the run failed: no picture either
            raise
        res = _write_files(result, stage, early, t_all)
        ctx.say(f"output: {', '.join(res['files'].values())} ({res['timings_s']['output']:.2f} s"
                + (f"; picture {res['timings_s']['picture']:.2f} s, beside the error-bar solves" if early.drawing else "")
                + (f"; report.pdf {early.t_pdf:.2f} s" if early.t_pdf is not None else "") + ")")
    return res


def _write_files(result: RunResult, stage: Path, early: "EarlyOutput", t_all: float) -> dict:
    """The files of a complete result: mesh.msh, the plots (the drawing ends), peaks.vtp,
    results.json once, then the report and the tables (meshes.csv, sensitivity.csv) from it,
    and report.html printed to report.pdf by a browser started at the outset (rank 0, with
    fields, where one is installed); returns results.json's content."""
    comm, outputs = early.comm, result.options.outputs
    exe = pdf.browser() if outputs.fields and comm.rank == 0 else None
    # Started now, so that it is up when report.html is written: its start-up overlaps the plots.
    browser = pdf.Browser(exe) if exe else None
    with on_stop(browser.kill) if browser else contextlib.nullcontext():
        try:
            return _write_result(result, stage, early, t_all, browser)
        finally:
            if browser is not None:
                browser.kill()


def _write_result(result: RunResult, stage: Path, early: "EarlyOutput", t_all: float,
                  browser: "pdf.Browser | None") -> dict:
    """:func:`_write_files` with the browser that prints report.pdf (None: no PDF)."""
    comm, outputs = early.comm, result.options.outputs
    files = {"results": "results.json", **({"mesh": "mesh.msh"} if outputs.mesh else {}), **early.files}
    if outputs.fields:
        files.update(peaks="peaks.vtp", picture="von_mises.png", report="report.md", report_html="report.html",
                     **({"report_pdf": "report.pdf"} if browser else {}), meshes_table="meshes.csv",
                     **({"sensitivity_table": "sensitivity.csv"} if result.sensitivity is not None else {}))
    if outputs.mesh and comm.rank == 0 and result.requested.msh is not None:
        (stage / "mesh.msh").write_bytes(result.requested.msh)
    timings = {"output": early.t_output}
    res = results_json(result, files, timings)
    if outputs.fields and comm.rank == 0:   # the places reported, beside the field file
        write_peaks(stage, res["fe"], early.whole_part)
    if early.drawing is not None:
        timings["picture"] = early.drawing.finish(res, stage)
        res["files"].update({k: name for k, name in PLOTS.items() if (stage / name).exists()})
    if result.convergence is not None and comm.rank == 0 and convergence_plot(stage / "convergence.png",
                                                                               res["convergence"], result.case):
        res["convergence"]["plot"] = "convergence.png"
        res["files"]["convergence_plot"] = "convergence.png"
    res["timings_s"].update(timings, total=time.perf_counter() - t_all)
    write_json(stage / "results.json", res, comm.rank)
    if (outputs.fields or result.convergence is not None) and comm.rank == 0:
        write_report(stage)
    if outputs.fields and comm.rank == 0:
        write_tables(stage, res)
    if browser is not None:
        early.t_pdf, why = browser.print_pdf(stage / "report.html", stage / "report.pdf")
        if why is not None:  # the run stands without its PDF: results.json says so
            early.say(f"report.pdf: not printed, {why}")
            del res["files"]["report_pdf"]
            write_json(stage / "results.json", res, comm.rank)
    return res


def write_tables(folder: Path, res: dict) -> None:
    """A run's tables from its results.json content ``res`` (pipeline/output/flat.py):
    meshes.csv, and sensitivity.csv when the run has a sensitivity section."""
    (folder / "meshes.csv").write_text(flat.csv_text(flat.MESH_COLUMNS, flat.mesh_rows(res)), encoding="utf-8")
    if res.get("sensitivity"):
        (folder / "sensitivity.csv").write_text(flat.csv_text(flat.SENSITIVITY_COLUMNS, flat.sensitivity_rows(res)),
                                                encoding="utf-8")


@dataclass
class EarlyOutput:
    """What a run writes from the requested mesh as soon as it is solved, while the
    error-bar meshes are still being solved: the field file, and the drawing processes
    started (rank 0). ``files`` maps results.json's file keys to names; ``t_output`` is the
    time the files took (s)."""

    case: Case
    options: RunOptions
    stage: Path
    comm: MPI.Comm
    stack: contextlib.ExitStack  # the run's: a stop signal kills the drawing while it is open
    files: dict[str, str] = field(default_factory=dict)
    drawing: drawing.Drawing | None = None
    t_output: float = 0.0
    whole_part: bool = False   # the field file holds a quarter model mirrored to the whole part
    t_pdf: float | None = None  # the print of report.pdf (s), when the run made one
    say: Callable[[str], None] = print

    def requested(self, fine: Level, places: Pilot) -> None:
        """The run's ``on_requested``: write the field file of the requested mesh's level and
        start the drawing (rank 0). Collective."""
        if not self.options.outputs.fields:
            return
        if self.drawing is not None:  # a finer mesh replaces the one drawn (analysis/tolerance.py)
            self.abandon()
            self.drawing = None
        t0 = time.perf_counter()
        case = replace(self.case, mesh_factor=fine.factor)
        self.whole_part = case.model == "quarter" and not self.options.outputs.quarter_fields
        self.files.update(write_fields(self.stage, fine.fields[0], fine.readings, Material(E=case.E_MPa, nu=case.nu),
                                       whole_part=self.whole_part))
        self.t_output += time.perf_counter() - t0
        if self.comm.rank == 0:
            self.drawing = drawing.start(self.stage, scene(case, fine))
            self.stack.enter_context(on_stop(self.drawing.kill))  # a stopped run draws nothing

    def abandon(self) -> None:
        """Kill the drawing processes, if started, and wait for them to end."""
        if self.drawing is not None:
            self.drawing.kill(wait_s=None)


def scene(case: Case, fine: Level) -> dict:
    """What the picture and the close-ups draw besides the field file: the case and the
    requested mesh's two peaks, in results.json's keys (MPa, mm)."""
    def block(p) -> dict:
        return {"value_MPa": p.value_MPa, "location_mm": list(p.location_mm),
                "feature": describe_location(case, p.location_mm)}
    return {"case": case.as_dict(),
            "fe": {"peak_MPa": fine.peak.value_MPa, "peak_location_mm": list(fine.peak.location_mm),
                   "critical_peak_MPa": fine.critical.value_MPa,
                   "critical_location_mm": list(fine.critical.location_mm),
                   "peak": block(fine.peak), "critical": block(fine.critical)}}
