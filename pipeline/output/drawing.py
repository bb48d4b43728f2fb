"""The drawing process of a run: the picture (pipeline.output.picture, VTK), the mesh
close-ups at the peaks (pipeline.output.closeup, VTK) and the plots
(pipeline.output.plots, matplotlib), in one process of its own (VTK cannot share a
process with DOLFINx). It starts as soon as the requested mesh's fields are written, so
that its imports and the picture overlap the error-bar solves, and reads what it draws
from its standard input, one JSON document a line: the requested mesh's case and peaks
(the picture and the close-ups, drawn at once), then the complete results (the plots).
It reads the field file the run wrote and no other state.

    python -m pipeline.output.drawing FOLDER    # the run's; reads its standard input
"""
from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from pipeline.output.closeup import render_closeup
from pipeline.output.jsonio import json_safe
from pipeline.output.picture import render_folder
from pipeline.output.plots import draw_plots, load_matplotlib
from pipeline.runtime.cores import unbind

@dataclass
class Drawing:
    """The drawing process started by :func:`start`, and when (perf_counter, s)."""

    proc: subprocess.Popen
    started: float

    def kill(self, wait_s: float | None = 1.0) -> None:
        """Stop the drawing (a failed or stopped run draws nothing) and reap it, so that it
        does not linger as a zombie while the run ends; waited for ``wait_s`` seconds at most
        (None: until it has ended; after SIGKILL it takes milliseconds)."""
        self.proc.kill()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=wait_s)
        with contextlib.suppress(OSError, ValueError):
            self.proc.stdin.close()

    def finish(self, results: dict, folder: Path) -> float:
        """Hand the drawing the complete ``results`` (for the plots), wait for it, and return
        its wall time (s) from start. Raises if it failed or made no picture."""
        _send(self.proc, results, last=True)
        err = self.proc.stderr.read()  # to its end: the process's only pipe left open
        self.proc.wait()
        if self.proc.returncode != 0:
            raise failure(err, self.proc.returncode)
        if not (folder / "von_mises.png").exists():
            raise RuntimeError("picture rendering failed: no von_mises.png")
        return time.perf_counter() - self.started


def failure(err: str, status: int) -> Exception:
    """Why the drawing process failed, from its stderr ``err`` and exit ``status``, as one
    line: the last line that names an error (VTK's warnings and colour escapes left out),
    else the last line; OutOfMemory when it ran out of memory (the drawing process has the
    run's address-space limit to itself)."""
    import re
    from pipeline.errors import OutOfMemory, out_of_memory
    lines = [" ".join(re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", ln).split()) for ln in err.splitlines()]
    lines = [ln for ln in lines if ln]
    errors = [ln for ln in lines if re.search(r"\b\w*(Error|Exception)\b|bad_alloc|[Ss]egmentation|Killed", ln)]
    tail = (errors or lines or [f"exit status {status}"])[-1]
    if out_of_memory(RuntimeError(err)) or status in (-9, 137):
        return OutOfMemory(f"drawing: {tail}")
    return RuntimeError(f"drawing failed: {tail}")


def start(folder: Path, scene: dict) -> Drawing:
    """Start the drawing process of the run writing into ``folder`` and hand it ``scene``
    (the requested mesh's case and peaks, results.json's keys): it draws the picture and
    the close-ups at once."""
    proc = subprocess.Popen([sys.executable, "-m", "pipeline.output.drawing", str(folder)],
                            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, cwd=Path(__file__).resolve().parents[2])
    unbind(proc.pid)  # not on rank 0's core alone, while rank 1's idles once its mesh is solved
    _send(proc, scene)
    return Drawing(proc=proc, started=time.perf_counter())


def _send(proc: subprocess.Popen, doc: dict, last: bool = False) -> None:
    """Write ``doc`` as one line of JSON to the process's standard input, and close it when
    ``last`` (a process that has already ended is left to report its own failure)."""
    with contextlib.suppress(BrokenPipeError, OSError, ValueError):
        proc.stdin.write(json.dumps(json_safe(doc)) + "\n")
        proc.stdin.flush()
        if last:
            proc.stdin.close()


def draw(folder: Path) -> None:
    """The drawing process: the picture and the close-ups from the first line of standard
    input, then the plots from the second (the complete results)."""
    scene = json.loads(sys.stdin.readline())
    render_folder(folder, scene)
    render_closeup(folder, scene)
    load_matplotlib()  # while the run goes on: the plots are the last thing it waits for
    line = sys.stdin.readline()
    if line.strip():  # none: the run ended without results (it was stopped)
        draw_plots(folder, json.loads(line))


if __name__ == "__main__":
    draw(Path(sys.argv[1]))
