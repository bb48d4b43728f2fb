"""Known stress raisers against the pilot: does refinement placed from the dimensions alone
(pipeline.post.features.known_raisers) give the peaks and error bars of the pilot's places?

    CROSSHEAD_NO_CACHE=1 mpirun -n 2 .venv/bin/python -m bench.raisers --sizes all

For every size: the default run's analysis (three meshes ×1, ×1.3, ×1.69; both peaks, or
those ``--want`` names) once with the pilot and once with the known places, on the same
ranks, one after the other.
Prints one line per size and the largest differences (MPa, %, s); ``--out FILE`` keeps
the rows as JSON. Run with the run cache off, so neither side reuses the other's meshes.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from mpi4py import MPI


def analyse_both(size: str, comm, want: str = "both") -> dict:
    """Both analyses of one size for the peaks ``want`` asks for (the case's scene): peaks
    and bands (MPa), finest DOFs, places, wall time (s)."""
    from pipeline.api import (MeshPlan, RunContext, RunOptions, estimate_levels, known_places, pilot, resolve_case,
                              solve_meshes)

    case = resolve_case(size, overrides={"want": want})
    ctx = RunContext(comm=comm)
    plan = MeshPlan(factors=tuple(RunOptions().factors(case)), formula_loads=True)
    row: dict = {"size": size, "want": want}
    for name in ("pilot", "known"):
        comm.barrier()
        t0 = time.perf_counter()
        # The known places as a run of the critical scene takes them (KNOWN: analyse falls
        # back to the pilot if the critical peak lands outside them; "source" says if it did).
        given = pilot(case, ctx) if name == "pilot" else known_places(case)
        levels, pl = solve_meshes(case, plan, given, ctx)
        wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        out = {"places": len(pl.hotspots), "source": pl.source, "dofs": levels[0].dofs, "wall_s": wall}
        for key in ("peak", "critical"):
            est = estimate_levels(levels, case.order, key)
            out[key] = {"value_MPa": getattr(levels[0], key).value_MPa, "band_MPa": est.band, "status": est.status}
        row[name] = out
    return row


def summary_line(row: dict) -> str:
    """One line: both routes' peaks with bands, their difference and the wall-time ratio."""
    p, k = row["pilot"], row["known"]

    def pk(side: dict, key: str) -> str:
        b = side[key]["band_MPa"]
        return f"{side[key]['value_MPa']:.2f}" + ("" if b is None else f" ± {b:.2f}")
    diffs = "  ".join(f"{key} {100 * (k[key]['value_MPa'] / p[key]['value_MPa'] - 1):+.2f} %"
                      for key in ("peak", "critical"))
    return (f"{row['size']:>5}: pilot {pk(p, 'peak')} / {pk(p, 'critical')} ({p['places']} places, "
            f"{p['dofs']} DOFs, {p['wall_s']:.1f} s) | known {pk(k, 'peak')} / {pk(k, 'critical')} "
            f"({k['places']} places, {k['dofs']} DOFs, {k['wall_s']:.1f} s) | {diffs}, "
            f"time {k['wall_s'] / p['wall_s']:.2f}x")


def main(argv: list[str] | None = None) -> int:
    from geometry.table import load_table

    ap = argparse.ArgumentParser(prog="python -m bench.raisers", description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="all", help="hook numbers, e.g. 05,1.6, or 'all' rows (default)")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    ap.add_argument("--want", choices=("both", "critical", "global"), default="both",
                    help="the peaks the runs are asked for (default both)")
    args = ap.parse_args(argv)
    comm = MPI.COMM_WORLD
    sizes = list(load_table()) if args.sizes == "all" else [s.strip() for s in args.sizes.split(",") if s.strip()]
    rows = []
    for size in sizes:
        row = analyse_both(size, comm, args.want)
        rows.append(row)
        if comm.rank == 0:
            print(summary_line(row), flush=True)
    if comm.rank == 0:
        for key in ("peak", "critical"):
            worst = max(rows, key=lambda r: abs(r["known"][key]["value_MPa"] / r["pilot"][key]["value_MPa"] - 1))
            dev = 100 * (worst["known"][key]["value_MPa"] / worst["pilot"][key]["value_MPa"] - 1)
            print(f"largest {key} difference: {dev:+.2f} % (No. {worst['size']})")
        if args.out:
            args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
