"""The command line stopped by Ctrl-C while PETSc's Krylov solver runs (a test helper, one process).

usage: python tests/helpers/stop_while_solving.py REPORT ARGS...

The process sends itself SIGINT as its first Krylov solve starts. A clean-up registered
with the stop (pipeline.runtime.interrupts.on_stop) writes to REPORT where that solve stood when
the stop ran: ``reason R at iteration N`` with PETSc's converged reason (0 while it still
iterates, > 0 once converged), or why it could not be read (the solver was already
destroyed). The stop must act during the solve, not after it.
"""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from petsc4py import PETSc

import pipeline.fe.solve
from pipeline.cli import main
from pipeline.runtime.interrupts import on_stop

REPORT = Path(sys.argv[1])
first: list[PETSc.KSP] = []


class _SignalledKSP(PETSc.KSP):
    """A KSP whose first solve sends this process SIGINT as it starts."""

    def solve(self, b, x):
        if not first:
            first.append(self)
            os.kill(os.getpid(), signal.SIGINT)
        return super().solve(b, x)


class _PETSc:
    """petsc4py's PETSc as pipeline.fe.solve sees it, with the KSP above."""

    KSP = _SignalledKSP

    def __getattr__(self, name: str):
        return getattr(PETSc, name)


def report() -> None:
    if not first:
        text = "no solve had started"
    elif not first[0].handle:  # destroyed after its solve (reading it then would crash)
        text = "the solver is gone: its solve had ended"
    else:
        text = f"reason {first[0].getConvergedReason()} at iteration {first[0].getIterationNumber()}"
    REPORT.write_text(text + "\n")


pipeline.fe.solve.PETSc = _PETSc()

if __name__ == "__main__":
    with on_stop(report):
        sys.exit(main(sys.argv[2:], handle_signals=True))
