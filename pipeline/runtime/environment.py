"""The process settings every entry point makes before DOLFINx, PETSc or numpy load.

- One BLAS thread: the parallelism is MPI ranks, and OpenBLAS's idle threads spin on the
  cores the other ranks and the picture process need.
- PETSc without its signal handlers (pipeline.runtime.interrupts does the clean stops).
- The compiled-form cache in the repository's .venv, whatever the working folder: DOLFINx
  0.5.2 puts it under $XDG_CACHE_HOME/fenics (read when dolfinx.jit is imported), and a
  cache shared with every other FEniCS project on the machine is slow to search.
- The form compiler's C build logs (about 50 INFO lines on a fresh machine) are not shown;
  warnings and errors still are.
- UFL and FFCx ask ``pkg_resources`` for their own version as they load, and importing it
  costs about 0.1 s of every process's start: a stand-in answers that from
  ``importlib.metadata`` and loads the real module the first time anything else is asked
  of it (docs/stack.md).
- Open MPI does not try its ``cm`` message layer, unless the user chose a layer
  (OMPI_MCA_pml or OMPI_MCA_mtl set): trying it starts libfabric and PSM, which costs
  every process about 0.2 s at MPI start-up on a machine without such a network, where
  Open MPI then falls back to ``ob1`` anyway (docs/stack.md, which also says how to
  choose ``cm`` on a cluster whose network needs it).
"""
from __future__ import annotations

import importlib
import importlib.metadata
import logging
import os
import sys
import types
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[2]
CACHE_HOME = REPOSITORY / ".venv" / "cache"  # the form cache is CACHE_HOME/fenics


def configure() -> None:
    """Apply the settings above to this process and the processes it starts."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    opts = os.environ.get("PETSC_OPTIONS", "")
    if "-no_signal_handler" not in opts.split():
        os.environ["PETSC_OPTIONS"] = f"{opts} -no_signal_handler".strip()
    os.environ["XDG_CACHE_HOME"] = str(CACHE_HOME)
    if "OMPI_MCA_pml" not in os.environ and "OMPI_MCA_mtl" not in os.environ:
        os.environ["OMPI_MCA_pml"] = "^cm"
    # Our handler first (basicConfig elsewhere then adds none); its own level stays at
    # WARNING even when setuptools lowers the root logger's level during a compile.
    logging.basicConfig(format="%(levelname)s: %(name)s: %(message)s")
    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)
    if "pkg_resources" not in sys.modules:
        sys.modules["pkg_resources"] = VersionsOnly("pkg_resources")


class _Distribution:
    """What UFL and FFCx read of ``pkg_resources.get_distribution(name)``: its version."""

    def __init__(self, version: str) -> None:
        self.version = version


class VersionsOnly(types.ModuleType):
    """A stand-in for ``pkg_resources`` that answers ``get_distribution(name).version``
    from importlib.metadata and hands every other question to the real module, which it
    then loads (in its place in sys.modules)."""

    def get_distribution(self, name: str) -> _Distribution:
        return _Distribution(importlib.metadata.version(name))

    def __getattr__(self, name: str):
        if sys.modules.get("pkg_resources") is self:
            del sys.modules["pkg_resources"]
        return getattr(importlib.import_module("pkg_resources"), name)
