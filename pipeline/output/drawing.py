"""The drawing processes of a run: the picture (pipeline.output.picture, VTK), the plots
(pipeline.output.plots, matplotlib) and the mesh close-ups at the peaks
(pipeline.output.closeup, VTK), each in a process of its own started beside the error-bar
solves; they read only the files the run wrote."""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Picture:
    """The drawing processes started by :func:`start_picture` (the picture, the plots, the
    close-ups), and
    when (perf_counter, s)."""

    procs: list[subprocess.Popen]
    started: float

    def kill(self, wait_s: float | None = 1.0) -> None:
        """Stop every drawing process (a failed or stopped run draws nothing) and reap it, so
        that none lingers as a zombie while the run ends; each is waited for ``wait_s``
        seconds at most (None: until it has ended; after SIGKILL it takes milliseconds)."""
        for proc in self.procs:
            proc.kill()
        for proc in self.procs:
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=wait_s)


def start_picture(folder: Path) -> Picture:
    """Start pipeline.output.picture and pipeline.output.closeup (VTK: it cannot share a
    process with DOLFINx) and pipeline.output.plots (matplotlib) in processes of their own:
    side by side they finish sooner than one after the other once the ranks' solves leave
    the cores free."""
    procs = [subprocess.Popen([sys.executable, "-m", module, str(folder)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              cwd=Path(__file__).resolve().parents[2])
             for module in ("pipeline.output.picture", "pipeline.output.plots", "pipeline.output.closeup")]
    # mpirun binds each rank to one core, and a child inherits its parent's binding: the
    # drawing then shared rank 0's core while rank 1's core idled once its mesh was
    # solved. Let them run on any core.
    for proc in procs:
        with contextlib.suppress(AttributeError, OSError):  # no affinity outside Linux
            os.sched_setaffinity(proc.pid, range(os.cpu_count() or 1))
    return Picture(procs=procs, started=time.perf_counter())


def finish_picture(pic: Picture, folder: Path) -> float:
    """Wait for the drawing processes; their wall time (s) from start. Raises if one failed
    or no picture was made."""
    for proc in pic.procs:
        _, err = proc.communicate()
        if proc.returncode != 0:
            tail = (err.strip().splitlines() or ["no message"])[-1]
            raise RuntimeError(f"drawing failed ({proc.args[2]}): {tail}")
    if not (folder / "von_mises.png").exists():
        raise RuntimeError("picture rendering failed: no von_mises.png")
    return time.perf_counter() - pic.started
