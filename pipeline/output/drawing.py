"""The drawing processes of a run: the picture (pipeline.output.picture, VTK), the mesh
close-ups at the peaks (pipeline.output.closeup, VTK) and the plots
(pipeline.output.plots, matplotlib), each in a process of its own. They start as soon as
the requested mesh's fields are written, so that their imports overlap the error-bar
solves, and each reads what it draws from its standard input: the picture and the
close-ups the requested mesh's peaks at once, the plots the complete results when the run
has them. They read the field file the run wrote and no other state."""
from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from pipeline.output.jsonio import json_safe

EARLY = ("pipeline.output.picture", "pipeline.output.closeup")   # drawn from the requested mesh
LATE = ("pipeline.output.plots",)                                 # drawn from the complete results


@dataclass
class Drawing:
    """The drawing processes started by :func:`start`, by module, and when (perf_counter, s)."""

    procs: dict[str, subprocess.Popen]
    started: float

    def kill(self, wait_s: float | None = 1.0) -> None:
        """Stop every drawing process (a failed or stopped run draws nothing) and reap it, so
        that none lingers as a zombie while the run ends; each is waited for ``wait_s``
        seconds at most (None: until it has ended; after SIGKILL it takes milliseconds)."""
        for proc in self.procs.values():
            proc.kill()
        for proc in self.procs.values():
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=wait_s)
            with contextlib.suppress(OSError, ValueError):
                proc.stdin.close()

    def finish(self, results: dict, folder: Path) -> float:
        """Hand the plots the complete ``results``, wait for every drawing process, and
        return their wall time (s) from start. Raises if one failed or no picture was made."""
        for module in LATE:
            _send(self.procs[module], results)
        for module, proc in self.procs.items():
            err = proc.stderr.read()  # to its end: the process's only pipe left open
            proc.wait()
            if proc.returncode != 0:
                raise failure(module, err, proc.returncode)
        if not (folder / "von_mises.png").exists():
            raise RuntimeError("picture rendering failed: no von_mises.png")
        return time.perf_counter() - self.started


def failure(module: str, err: str, status: int) -> Exception:
    """Why drawing process ``module`` failed, from its stderr ``err`` and exit ``status``, as
    one line: the last line that names an error (VTK's warnings and colour escapes left
    out), else the last line; OutOfMemory when it ran out of memory (a drawing process
    has the run's address-space limit to itself)."""
    import re
    from pipeline.errors import OutOfMemory, out_of_memory
    lines = [" ".join(re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", ln).split()) for ln in err.splitlines()]
    lines = [ln for ln in lines if ln]
    errors = [ln for ln in lines if re.search(r"\b\w*(Error|Exception)\b|bad_alloc|[Ss]egmentation|Killed", ln)]
    tail = (errors or lines or [f"exit status {status}"])[-1]
    if out_of_memory(RuntimeError(err)) or status in (-9, 137):
        return OutOfMemory(f"drawing ({module}): {tail}")
    return RuntimeError(f"drawing failed ({module}): {tail}")


def start(folder: Path, scene: dict) -> Drawing:
    """Start the drawing processes of the run writing into ``folder``, the picture and the
    close-ups with ``scene`` (the requested mesh's case and peaks, results.json's keys).
    VTK cannot share a process with DOLFINx; side by side they finish sooner than one
    after the other once the ranks' solves leave the cores free."""
    procs = {module: subprocess.Popen([sys.executable, "-m", module, str(folder), "--stdin"],
                                      stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                      text=True, cwd=Path(__file__).resolve().parents[2])
             for module in (*EARLY, *LATE)}
    # mpirun binds each rank to one core, and a child inherits its parent's binding: the
    # drawing then shared rank 0's core while rank 1's core idled once its mesh was
    # solved. Let them run on any core.
    for proc in procs.values():
        with contextlib.suppress(AttributeError, OSError):  # no affinity outside Linux
            os.sched_setaffinity(proc.pid, range(os.cpu_count() or 1))
    for module in EARLY:
        _send(procs[module], scene)
    return Drawing(procs=procs, started=time.perf_counter())


def _send(proc: subprocess.Popen, doc: dict) -> None:
    """Write ``doc`` as JSON to the process's standard input and close it (a process that
    has already ended is left to report its own failure)."""
    with contextlib.suppress(BrokenPipeError, OSError, ValueError):
        proc.stdin.write(json.dumps(json_safe(doc)))
        proc.stdin.close()


def read_input(argv: list[str], folder: Path) -> dict:
    """What a drawing process draws: the document on its standard input when the run
    started it (``--stdin``), else folder/results.json (a person drawing a finished run)."""
    if "--stdin" in argv:
        return json.load(sys.stdin)
    return json.loads((folder / "results.json").read_text(encoding="utf-8"))
