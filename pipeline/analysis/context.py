"""Where a run's analysis happens: its MPI communicator, its progress lines, its gmsh
session and who is told when the requested mesh is solved. Passed down as one object,
never kept in module state."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

from mpi4py import MPI

from pipeline.fe.meshing import Mesher

Progress = Callable[[str], None]


def quiet(line: str) -> None:
    """A progress sink that drops every line."""


@dataclass(frozen=True)
class RunContext:
    """``comm``: the ranks that share the analysis; ``say``: one progress line (rank 0's
    matter); ``mesher``: this process's gmsh session of the case's part, if it has one;
    ``on_requested``: called with the requested mesh's level (fields kept) and the refined
    places as soon as it is solved, so that a caller may write its fields and draw them
    while the error-bar meshes are solved (the analysis itself writes nothing); ``memo``:
    where the runs of one process keep the places and meshes they solved for each other
    (a screened study's steps on one variant; None: nothing kept,
    pipeline/analysis/reuse.py)."""

    comm: MPI.Comm = field(default_factory=lambda: MPI.COMM_WORLD)
    say: Progress = quiet
    mesher: Mesher | None = None
    on_requested: Callable[..., None] | None = None  # (Level, Pilot) -> None
    memo: dict | None = None

    def alone(self) -> "RunContext":
        """This context on this rank alone (MPI.COMM_SELF), saying nothing unless it is rank 0,
        telling no one of its meshes."""
        return replace(self, comm=MPI.COMM_SELF, say=self.say if self.comm.rank == 0 else quiet,
                       on_requested=None)
