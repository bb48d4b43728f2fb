"""The process settings every entry point makes before DOLFINx, PETSc or numpy load.

- One BLAS thread: the parallelism is MPI ranks, and OpenBLAS's idle threads spin on the
  cores the other ranks and the picture process need.
- PETSc without its signal handlers (pipeline.interrupts does the clean stops).
- The compiled-form cache in the repository's .venv, whatever the working folder: DOLFINx
  0.5.2 puts it under $XDG_CACHE_HOME/fenics (read when dolfinx.jit is imported), and a
  cache shared with every other FEniCS project on the machine is slow to search.
- The form compiler's C build logs (about 50 INFO lines on a fresh machine) are not shown;
  warnings and errors still are.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
CACHE_HOME = REPOSITORY / ".venv" / "cache"  # the form cache is CACHE_HOME/fenics


def configure() -> None:
    """Apply the settings above to this process and the processes it starts."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    opts = os.environ.get("PETSC_OPTIONS", "")
    if "-no_signal_handler" not in opts.split():
        os.environ["PETSC_OPTIONS"] = f"{opts} -no_signal_handler".strip()
    os.environ["XDG_CACHE_HOME"] = str(CACHE_HOME)
    # Our handler first (basicConfig elsewhere then adds none); its own level stays at
    # WARNING even when setuptools lowers the root logger's level during a compile.
    logging.basicConfig(format="%(levelname)s: %(name)s: %(message)s")
    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)
