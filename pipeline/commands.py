"""The two commands' work: a run (one case, with error bar) and a convergence study.

Both write into a staging folder that replaces the output folder only when complete.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from pipeline.inputs.case import Case
from pipeline.fe.meshing import Mesher
from pipeline.runtime.interrupts import on_stop
from pipeline.runtime.outdir import staged_dir
from pipeline.output.flat import own_row
from pipeline.output.jsonio import write_json
from pipeline.output.provenance import complete
from pipeline.fe.elasticity import Material
from pipeline.output.fields import write_fields as write_field_files
from pipeline.output.report import write_report
from pipeline.analysis.level import Level, Progress
from pipeline.analysis.analyse import analyse
from pipeline.analysis.tolerance import Accuracy, analyse_to_tolerance
from pipeline.output.results import add_accuracy, add_sensitivity, build_results, load_sweep, sum_timings
from pipeline.analysis.sensitivity import LOAD_MESH_RATIO, analyse_sensitivity, load_variant_cases
from pipeline.output.drawing import Picture, finish_picture, start_picture
from pipeline.post.features import describe_location
from pipeline.analysis.pilot import Pilot, refinement_places


def execute_run(case: Case, out_dir: Path, levels: int = 3, ratio: float = 1.3,
                progress: Progress | None = None, write_fields: bool = True,
                loads: list[float] | None = None, comm: MPI.Comm = MPI.COMM_WORLD, quarter_fields: bool = False,
                write_mesh: bool = True, sensitivity: bool = False, to_tolerance: bool = False,
                formula_loads: bool = True) -> dict:
    """Analyse ``case`` and write results.json, report.md, mesh.msh, VTK fields and a PNG
    (without ``write_fields`` only results.json and mesh.msh; without ``write_mesh`` no
    mesh.msh: a design study's variant, whose question is its peaks).

    ``loads`` (N): a load sweep. The case is solved once at case.load_N; since the model is
    linear elastic with traction loads only, every stress scales with Q/case.load_N.
    The picture is drawn (in its own process) while the error-bar meshes are solved: it
    shows the requested mesh's field and peaks, which those solves do not change.
    ``sensitivity``: vary the assumed inputs (pipeline/analysis/sensitivity.py) after the
    error bar, when both peaks are wanted (a scene, ``want``, skips it).
    ``to_tolerance``: add meshes until each wanted peak's band is at most
    case.tolerance_pct (pipeline/analysis/tolerance.py); the results then carry what was
    asked and reached, and describe the finest mesh solved. Without it the run solves the
    ``levels`` meshes it is given (a design study's variant). ``formula_loads``: solve the
    journal load at each hand formula's position too (the report's like-with-like sections;
    two more right-hand sides); a design study's variant, whose table does not read them,
    goes without.
    """
    say = progress or (lambda s: None)
    t_all = time.perf_counter()
    with staged_dir(out_dir, comm, say) as stage, Mesher(case.dims, case.model, say) as mesher, \
            contextlib.ExitStack() as stack:
        pl = refinement_places(case, comm=comm, progress=say, mesher=mesher)
        files = {"results": "results.json", **({"mesh": "mesh.msh"} if write_mesh else {})}
        requested = _RequestedOutput(case=case, stage=stage, comm=comm, write_fields=write_fields,
                                     quarter_fields=quarter_fields, stack=stack, files=files)
        vary = sensitivity and case.want == "both"
        try:
            # The load model's variants change only the right-hand side: solved on the
            # operator of the coarsest default error-bar mesh, on its own rank beside the
            # others (or of the requested mesh when the run has no such mesh).
            how = dict(levels=levels, ratio=ratio, msh_path=stage / files["mesh"] if write_mesh else None,
                       progress=say, comm=comm, pl=pl, on_requested=requested.write,
                       mesher=mesher, load_variants=load_variant_cases(case) if vary else (),
                       load_variants_at=case.mesh_factor * LOAD_MESH_RATIO, formula_loads=formula_loads)
            accuracy: Accuracy | None = None
            if to_tolerance:
                lv, pl, case, accuracy, every = analyse_to_tolerance(case, **how)
            else:
                lv, pl = analyse(case, **how)
                every = lv
            # every mesh solved: the load model's variants stay on the mesh that solved them
            sens = analyse_sensitivity(case, comm=comm, progress=say, levels=every, places=pl) if vary else None
        except BaseException:
            requested.abandon()  # the run failed: no picture either
            raise
        res = _run_results(case, lv, pl, comm, loads, write_fields, requested.files, requested.t_output)
        if accuracy is not None:
            add_accuracy(res, accuracy)
        if sens is not None:
            add_sensitivity(res, sens, case)
        requested.finish(res)
        res["timings_s"]["total"] = time.perf_counter() - t_all
        complete(res, own_row(res))
        write_json(stage / "results.json", res, comm.rank)
        if write_fields and comm.rank == 0:
            write_report(stage)
        say(f"output: {', '.join(requested.files.values())} ({res['timings_s']['output']:.2f} s"
            + (f"; picture {res['timings_s']['picture']:.2f} s, beside the error-bar solves)" if requested.picture else ")"))
    return res


@dataclass
class _RequestedOutput:
    """What a run writes from the requested mesh as soon as it is solved, while the
    error-bar meshes are still being solved: the field files, a first results.json and
    the drawing processes (rank 0). ``files`` maps results.json's file keys to names;
    ``t_output`` is the time the files took (s)."""

    case: Case
    stage: Path
    comm: MPI.Comm
    write_fields: bool
    quarter_fields: bool
    stack: contextlib.ExitStack  # the run's: a stop signal kills the drawing while it is open
    files: dict[str, str]  # results.json's file keys → names, the field files and plots added as written
    picture: Picture | None = None
    t_output: float = 0.0

    def write(self, fine: Level, pl: Pilot) -> None:
        """analyse's ``on_requested``: write the fields of the requested mesh's level and
        the results.json the drawing reads (with ``pl``, the places the meshes were refined
        at), then start the drawing (rank 0)."""
        if not self.write_fields:
            return
        if self.picture is not None:  # a finer mesh replaces the one drawn (analysis/tolerance.py)
            self.abandon()
            self.picture = None
        t0 = time.perf_counter()
        self.files.update(write_field_files(self.stage, *fine.fields, Material(E=self.case.E_MPa, nu=self.case.nu),
                                            whole_part=self.case.model == "quarter" and not self.quarter_fields))
        # The picture process reads results.json: the requested mesh's peaks for now,
        # the full results (same peaks) replace it below.
        write_json(self.stage / "results.json", build_results(self.case, [fine], {}, self.comm, pl), self.comm.rank)
        self.t_output += time.perf_counter() - t0
        if self.comm.rank == 0:
            self.picture = start_picture(self.stage)
            self.stack.enter_context(on_stop(self.picture.kill))  # a stopped run draws nothing

    def abandon(self) -> None:
        """Kill the drawing processes, if started, and wait for them to end."""
        if self.picture is not None:
            self.picture.kill(wait_s=None)

    def finish(self, res: dict) -> None:
        """If the drawing was started: write the full results (every mesh's peaks, for
        peaks.png), wait for the drawing, and add its time (s) and the plots it made to
        ``res``."""
        if self.picture is None:
            return
        write_json(self.stage / "results.json", res, self.comm.rank)
        res["timings_s"]["picture"] = finish_picture(self.picture, self.stage)
        for key, name in (("sections_plot", "sections.png"), ("peaks_plot", "peaks.png"),
                          ("sensitivity_plot", "sensitivity.png"), ("mesh_closeup", "mesh_closeup.png")):
            if (self.stage / name).exists():  # drawn by the plots or the close-up process
                self.files[key] = name


def _run_results(case: Case, lv: list[Level], pl: Pilot, comm: MPI.Comm, loads: list[float] | None,
                 write_fields: bool, files: dict[str, str], t_output: float) -> dict:
    """The run's results from its levels and pilot, with the load sweep (loads in N) if
    asked for, the output files (``files``, completed with the picture and reports when
    fields are written) and the output time (s); the picture's and total time come later."""
    timings = sum_timings(lv, pl)
    res = build_results(case, lv, timings, comm, pl)
    if loads:
        res["load_sweep"] = load_sweep(res, case, loads)
    if write_fields:
        files["picture"] = "von_mises.png"
        files["report"] = "report.md"
        files["report_html"] = "report.html"
    res["files"] = files
    res["timings_s"]["output"] = t_output
    return res


def execute_converge(case: Case, out_dir: Path, levels: int = 5, ratio: float = 1.3,
                     progress: Progress | None = None, comm: MPI.Comm = MPI.COMM_WORLD) -> dict:
    """Solve on ``levels`` meshes refined by ``ratio`` from the case's mesh, finest first.

    Writes results.json (with a ``convergence`` block), report.md and convergence.png.
    The finest mesh is the case's own mesh factor divided by ratio^(levels−3), so the
    default mesh sits inside the study and its error can be read off directly.
    """
    say = progress or (lambda s: None)
    t_all = time.perf_counter()
    finest = case.mesh_factor / ratio ** max(levels - 3, 0)
    from dataclasses import replace
    fine_case = replace(case, mesh_factor=finest)
    with staged_dir(out_dir, comm, say) as stage, Mesher(case.dims, case.model, say) as mesher:
        # The refinement places of the case itself, so the case's own mesh is one of the study's levels.
        lv, pl = analyse(fine_case, levels=levels, ratio=ratio, msh_path=stage / "mesh.msh",
                         progress=say, comm=comm, pl=refinement_places(case, comm=comm, progress=say, mesher=mesher),
                         mesher=mesher)
        timings = sum_timings(lv, pl)
        res = build_results(fine_case, lv, timings, comm, pl)
        conv = {"ratio": ratio, "levels": res["fe"]["levels"],
                "peak": res["fe"]["peak"]["error_estimate"],
                "critical": res["fe"]["critical"]["error_estimate"],
                "peak_features": [describe_location(case, l.peak.location_mm) for l in lv],
                "critical_features": [describe_location(case, l.critical.location_mm) for l in lv],
                "not_wanted": {k: res["fe"][k]["not_wanted"] for k in ("peak", "critical")
                               if res["fe"][k].get("not_wanted")}}
        # Error of each level against the extrapolated value (only if converged, and only for
        # a peak the meshes were refined for).
        for key in ("peak", "critical"):
            ext = None if key in conv["not_wanted"] else conv[key].get("extrapolated")
            for row in conv["levels"]:
                v = row["peak_MPa" if key == "peak" else "critical_peak_MPa"]
                row[f"{key}_error_pct"] = None if ext is None else 100 * (v - ext) / ext
        if comm.rank == 0:
            from pipeline.output.plots import convergence_plot
            if convergence_plot(stage / "convergence.png", conv, case):
                conv["plot"] = "convergence.png"
        res["convergence"] = conv
        res["files"] = {"results": "results.json", "report": "report.md", "report_html": "report.html",
                        "mesh": "mesh.msh", **({"convergence_plot": conv["plot"]} if "plot" in conv else {})}
        res["timings_s"]["total"] = time.perf_counter() - t_all
        complete(res, own_row(res))
        write_json(stage / "results.json", res, comm.rank)
        if comm.rank == 0:
            write_report(stage)
    return res
