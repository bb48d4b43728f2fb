"""Reference study of the bearing load model: the journal in a side-plate bore, solved with
CalculiX's contact, beside the pipeline's p0·cos θ model on the same mesh (mm, N, MPa).

For each clearance (diametral, mm) and mesh factor the study solves the contact model of
bench/contact.py and reads

- equilibrium: the plate's held face carries Q/4 (the quarter model), and so do the
  nodal forces the contact puts on the journal (the crosshead's out-of-balance forces
  under CalculiX's displacement);
- the contact's centre along the journal (exact, from those nodal forces) and its lever
  from the shoulder, beside the cos θ model's (the middle of the bearing length);
- the pressure −n·σ·n of the journal's own stress at its surface, per band of angle θ
  (from straight down) and per band along the journal, beside p0·cos θ; its extent in θ;
- the global (fillet) and critical peaks, read as the pipeline reads its own, beside the
  pipeline's cos θ model solved on the very same crosshead mesh (no pilot refinement).

Run: ``python -m bench.load_reference --out results/load-reference`` (make load-reference);
docs/load-reference.md has the results and what follows for the load model's inputs.
A point already in ``points.jsonl`` is not solved again.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

from pipeline.api import configure  # noqa: E402

configure()  # before numpy, PETSc or DOLFINx load (pipeline/runtime/environment.py)

from pipeline.api import refusal  # noqa: E402

OWN_FILES = frozenset({"points.jsonl", "table.md"})
# Diametral clearances (mm) on the No. 05 journal, dj = 20 mm (ISO 286, 18-30 mm range):
# 0, a close running fit H7/g6 (7..41 µm, its mean) and a loose fit H9/d9 (65..169 µm, its
# mean), usual for a pivot that only turns when the hook swings.
CLEARANCES = {"zero": 0.0, "H7/g6": 0.024, "H9/d9": 0.117}
PLATE_SIZE_PER_FACTOR = 0.75  # the plate's element size on the bore, mm per unit mesh factor


def hertz_line_contact(dj_mm: float, clearance_mm: float, force_per_mm_N: float, E_MPa: float,
                       nu: float) -> dict:
    """Hertz's line contact of a journal (diameter dj) in a bore of dj + clearance, equal
    materials: half-width b = √(4·w·R/(π·E*)) with 1/R = 1/r1 − 1/r2, E* = E/(2(1 − ν²)),
    peak pressure 2w/(π·b); as the half-angle b/r1 (degrees) and the angle within which
    99 % of the elliptical pressure's force acts (0.9587·b). A closed form beside the
    contact model (valid while b is small against the radius), none for zero clearance."""
    if clearance_mm <= 0:
        return {}
    r1, r2 = dj_mm / 2, dj_mm / 2 + clearance_mm / 2
    R = r1 * r2 / (r2 - r1)
    e_star = E_MPa / (2 * (1 - nu ** 2))
    b = math.sqrt(4 * force_per_mm_N * R / (math.pi * e_star))
    return {"half_width_mm": b, "half_angle_deg": math.degrees(b / r1),
            "extent99_deg": math.degrees(0.9587 * b / r1), "p_max_MPa": 2 * force_per_mm_N / (math.pi * b)}


def fillet_core_peak(case, u, mat):
    """The fillet's peak von Mises (MPa, the pipeline's midpoint reading) over the fillet's
    half next to the body, |x| ≤ b1/2 + rf/2: at least rf/2 from the fillet's run-out, where
    a flush plate's bore edge presses on the journal (an edge of contact, whose local stress
    grows under refinement and depends on the edge's shape, not on the load model)."""
    import numpy as np

    from geometry.places import at_journal_root
    from pipeline.api import fillet_region, node_peak, node_readings

    d = case.dims
    return node_peak(node_readings(u, mat, fillet_region(case)),
                     lambda xyz: at_journal_root(d, xyz) & (np.abs(xyz[:, 0]) <= d.b1 / 2 + d.rf / 2))


def solve_point(size: str, factor: float, fit: str, clearance_mm: float, friction: float = 0.0,
                penalty_scale: float = 1.0, offset_mm: float = 0.0, size_body_mm: float | None = None,
                held: str = "top") -> dict:
    """One contact solve and the cos θ model on the same mesh: the study's row (JSON-ready).

    ``size_body_mm``: the crosshead's far-field element size before the factor (the case's
    size_body_mm). The journal's elements grow from the fillet's size with slope 0.5 up to
    that size, so it is what makes the journal's surface fine enough for a narrow contact."""
    from mpi4py import MPI

    from bench.contact import (PlateSpec, contact_model, force_summary, nodal_contact_forces, penalty,
                               pressure_summary, solve_contact, stress_samples)
    from pipeline.api import LevelTask, RunContext, peaks_of, resolve_case, set_up, solve_level

    case = resolve_case(size, overrides={"mesh_factor": factor, "solver": "mumps", "size_body_mm": size_body_mm})
    case = replace(case, rtol=1e-10)
    t0 = time.perf_counter()
    alone = RunContext(comm=MPI.COMM_SELF)
    prob = set_up(case, LevelTask(factor), alone)
    lv = solve_level(case, LevelTask(factor, keep_fields=True), alone, problem=prob)
    core_cos = fillet_core_peak(case, lv.fields[0], prob.material)
    t_cos = time.perf_counter() - t0
    plate_size = PLATE_SIZE_PER_FACTOR * factor
    if size_body_mm is not None:  # the journal as fine as the far field: the plate's bore too
        plate_size = min(PLATE_SIZE_PER_FACTOR, size_body_mm) * factor
    spec = PlateSpec(clearance_mm=clearance_mm, size_mm=plate_size, friction=friction,
                     offset_mm=offset_mm, held=held)
    spec = replace(spec, penalty_MPa_per_mm=penalty(spec, case.E_MPa) * penalty_scale)
    t0 = time.perf_counter()
    cm = contact_model(prob.mesh.mesh, prob.mesh.facet_tags, prob.loads, case.dims, spec)
    sol = solve_contact(cm, prob.material, increments=1)
    _, pk, cr = peaks_of(case, sol.u, prob.material)
    core = fillet_core_peak(case, sol.u, prob.material)
    xyz, F = nodal_contact_forces(cm, sol.u, prob.loads, prob.material)
    forces = force_summary(xyz, F, case.dims, case.load_N)
    pressure = pressure_summary(stress_samples(cm, sol.u, prob.material, case.dims), case.dims, spec, case.load_N)
    t_contact = time.perf_counter() - t0
    return {
        "size": size, "mesh_factor": factor, "size_body_mm": size_body_mm, "fit": fit, "clearance_mm": clearance_mm,
        "friction": friction, "offset_mm": offset_mm, "plate_held": held, "penalty_MPa_per_mm": spec.penalty_MPa_per_mm,
        "plate_size_mm": spec.size_mm, "plate_x_mm": list(spec.x_range(case.dims)),
        "crosshead_cells": lv.cells, "crosshead_dofs": lv.dofs,
        "contact_nodes": int(cm.model.nodes.shape[0]), "plate_cells": int(cm.plate.elements.shape[0]),
        "slave_faces": int(len(cm.slave_faces)), "master_faces": int(len(cm.master_faces)),
        "ccx_s": sol.timings["ccx"], "contact_total_s": t_contact, "cos_model_s": t_cos,
        "ccx_iterations": sol.iterations, "ccx_attempts": sol.attempts,
        "plate_reaction_N": sol.plate_reaction_N.tolist(), "spring_force_N": sol.spring_force_N,
        "quarter_load_N": case.load_N / 4,
        "forces": forces, "pressure": pressure,
        "peak_contact_MPa": pk.value_MPa, "peak_contact_location_mm": list(pk.location_mm),
        "peak_cos_MPa": lv.peak.value_MPa, "peak_cos_location_mm": list(lv.peak.location_mm),
        "peak_diff_pct": 100 * (pk.value_MPa / lv.peak.value_MPa - 1),
        "fillet_core_contact_MPa": core.value_MPa, "fillet_core_contact_location_mm": list(core.location_mm),
        "fillet_core_cos_MPa": core_cos.value_MPa, "fillet_core_cos_location_mm": list(core_cos.location_mm),
        "fillet_core_diff_pct": 100 * (core.value_MPa / core_cos.value_MPa - 1),
        "critical_contact_MPa": cr.value_MPa, "critical_cos_MPa": lv.critical.value_MPa,
        "critical_diff_pct": 100 * (cr.value_MPa / lv.critical.value_MPa - 1),
        "hertz": hertz_of(case, clearance_mm),
    }


def hertz_of(case, clearance_mm: float) -> dict:
    """:func:`hertz_line_contact` for the case's journal under Q/2 spread over its bearing
    length b6/2 − b1/2 − rf (mm, N/mm, MPa)."""
    d = case.dims
    return hertz_line_contact(d.dj, clearance_mm, case.load_N / 2 / (d.b6 / 2 - d.b1 / 2 - d.rf),
                              case.E_MPa, case.nu)


def table(rows: list[dict]) -> str:
    """The study's results as a Markdown table (mm, N, MPa, s)."""
    head = ("| fit | clearance mm | factor | crosshead DOFs | plate reaction / (Q/4) | contact force / (Q/4) "
            "| centre x mm | lever mm (cos θ: 7.00) | extent ° (99 %) | p max MPa (p0 28.9) "
            "| global peak MPa: contact | cos θ | diff % | fillet core MPa: contact | cos θ | diff % "
            "| critical diff % | ccx s |")
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        f, p = r["forces"], r["pressure"]
        out.append(
            f"| {r['fit']}{' μ=' + format(r['friction'], 'g') if r['friction'] else ''}"
            f"{' K×' + format(r.get('penalty_scale', 1), 'g') if r.get('penalty_scale', 1) != 1 else ''}"
            f"{' offset ' + format(r['offset_mm'], 'g') + ' mm' if r.get('offset_mm') else ''}"
            f"{' plate held at its bottom' if r.get('plate_held') == 'bottom' else ''} "
            f"| {r['clearance_mm']:.3f} | {r['mesh_factor']:g}{_body(r)} | {r['crosshead_dofs']} "
            f"| {r['plate_reaction_N'][2] / r['quarter_load_N']:.5f} | {f['force_z_over_quarter_load']:.5f} "
            f"| {f['centre_x_mm']:.2f} | {f['lever_mm']:.2f} | {p['extent_deg']:.0f}{_hertz(r, 'extent99_deg')} "
            f"| {p['p_max_MPa']:.1f}{_hertz(r, 'p_max_MPa')} "
            f"| {r['peak_contact_MPa']:.2f} | {r['peak_cos_MPa']:.2f} | {r['peak_diff_pct']:+.2f} "
            f"| {r['fillet_core_contact_MPa']:.2f} | {r['fillet_core_cos_MPa']:.2f} | {r['fillet_core_diff_pct']:+.2f} "
            f"| {r['critical_diff_pct']:+.2f} | {r['ccx_s']:.0f} |")
    return "\n".join(out) + "\n"


def _body(row: dict) -> str:
    """', body N mm' for a table cell when the far-field size was set, else nothing."""
    return f", body {row['size_body_mm']:g} mm" if row.get("size_body_mm") else ""


def _hertz(row: dict, key: str) -> str:
    """' (Hertz: v)' for a table cell, or nothing (zero clearance)."""
    h = row.get("hertz") or {}
    return f" (Hertz {h[key]:.0f})" if key in h else ""


def main(argv: list[str] | None = None) -> int:
    """The study: every clearance at every mesh factor, one row each in points.jsonl, then
    table.md. Exit 2 on a bad --out or option."""
    p = argparse.ArgumentParser(prog="python -m bench.load_reference", description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True, type=Path, help="results folder (points.jsonl, table.md)")
    p.add_argument("--size", default="05")
    p.add_argument("--factors", default="2.0", help="mesh factors, comma-separated (default 2.0)")
    p.add_argument("--fits", default=",".join(CLEARANCES), help=f"of {', '.join(CLEARANCES)} (default all)")
    p.add_argument("--friction", type=float, default=0.0, help="Coulomb μ (default 0: frictionless)")
    p.add_argument("--size-body-mm", type=float, default=None,
                   help="the crosshead's far-field element size before the factor (default: the case's)")
    p.add_argument("--plate-held", choices=("top", "bottom"), default="top",
                   help="the plate's face held fixed: top (it hangs, default) or bottom (it stands)")
    p.add_argument("--offset-mm", type=float, default=0.0,
                   help="the plate's inner face this far off the fillet's run-out (default 0: flush)")
    p.add_argument("--penalty-scale", type=float, default=1.0,
                   help="the penalty slope × this (a sensitivity check; default 1)")
    a = p.parse_args(argv)
    try:
        factors = [float(s) for s in a.factors.split(",")]
        fits = [s.strip() for s in a.fits.split(",")]
    except ValueError:
        sys.stderr.write(f"--factors: not a list of numbers: {a.factors!r}\n")
        return 2
    bad = [f for f in fits if f not in CLEARANCES]
    if bad or not all(f > 0 for f in factors) or a.friction < 0 or a.penalty_scale <= 0 \
            or not 0 <= a.offset_mm < 5 or (a.size_body_mm is not None and a.size_body_mm <= 0):
        sys.stderr.write(f"bad option: fits {bad or 'ok'}; need factors > 0, friction >= 0, "
                         "penalty scale > 0, 0 <= offset < 5 mm, size body > 0\n")
        return 2
    why = refusal(a.out, OWN_FILES)
    if why is not None:
        sys.stderr.write(why + "\n")
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    points = a.out / "points.jsonl"
    rows = [json.loads(s) for s in points.read_text().splitlines() if s.strip()] if points.exists() else []
    done = {(r["size"], r["mesh_factor"], r["fit"], r["friction"], r.get("penalty_scale", 1.0), r.get("offset_mm", 0.0),
             r.get("size_body_mm"), r.get("plate_held", "top")) for r in rows}
    for factor in factors:
        for fit in fits:
            key = (a.size, factor, fit, a.friction, a.penalty_scale, a.offset_mm, a.size_body_mm, a.plate_held)
            if key in done:
                continue
            print(f"load-reference: No. {a.size}, mesh factor {factor:g}, {fit} ({CLEARANCES[fit]:g} mm) ...",
                  flush=True)
            row = solve_point(a.size, factor, fit, CLEARANCES[fit], a.friction, a.penalty_scale, a.offset_mm,
                              a.size_body_mm, a.plate_held)
            row["penalty_scale"] = a.penalty_scale
            with points.open("a") as fh:  # one complete line per point: a stop loses at most one
                fh.write(json.dumps(row) + "\n")
            rows.append(row)
            print(f"  fillet peak {row['peak_contact_MPa']:.2f} MPa (cos θ {row['peak_cos_MPa']:.2f}, "
                  f"{row['peak_diff_pct']:+.2f} %), lever {row['forces']['lever_mm']:.2f} mm, "
                  f"ccx {row['ccx_s']:.0f} s", flush=True)
    from pipeline.api import write_text
    write_text(a.out / "table.md", table(rows))
    print(table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
