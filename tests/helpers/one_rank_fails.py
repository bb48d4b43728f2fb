"""The command line with one MPI rank failing alone (a test helper, started under mpirun).

usage: mpirun -n 2 python tests/helpers/one_rank_fails.py RANK[:busy] ARGS...

Rank RANK raises RuntimeError("injected ...") just before its first solve on the whole
communicator, while the other ranks enter that solve's collectives: the failure the
product must end cleanly on every rank (pipeline.runtime.rankfailure) instead of hanging. With
":busy" rank 0 (healthy) instead spends minutes in one C call that holds Python's lock, so
that its failure listener cannot run (the fallback of pipeline.runtime.rankfailure).
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from mpi4py import MPI

import pipeline.analysis.reuse
from pipeline.cli import main

FAILING_RANK = int(sys.argv[1].split(":")[0])
BUSY = sys.argv[1].endswith(":busy")
_solve_or_scale = pipeline.analysis.reuse.solve_or_scale


def failing_solve_or_scale(case, prob, reuse=True, more=()):
    if MPI.COMM_WORLD.rank == FAILING_RANK and prob.mesh.mesh.comm.size > 1:
        raise RuntimeError(f"injected on rank {FAILING_RANK} alone")
    if BUSY and MPI.COMM_WORLD.rank == 0 and prob.mesh.mesh.comm.size > 1:
        sum(range(10**12))  # builtin sum in C: Python's lock is not released for minutes
    return _solve_or_scale(case, prob, reuse, more)


pipeline.analysis.reuse.solve_or_scale = failing_solve_or_scale

if __name__ == "__main__":
    sys.exit(main(sys.argv[2:], handle_signals=True))
