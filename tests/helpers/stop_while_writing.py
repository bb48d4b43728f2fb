"""The command line stopped by Ctrl-C at the end of a run (a test helper, one process).

usage: python tests/helpers/stop_while_writing.py WHEN ARGS...

The process sends itself SIGINT at a chosen moment of the output folder's last steps
(pipeline.runtime.outdir.staged_dir), where a stop races with the main thread's own writing:

- ``writing``: when every file is in the staging folder (with EARLY_FILES more, so that
  removing it takes a while), and the main thread then goes on writing files into it for
  a second, as a run's last writes would;
- ``publishing``: just as the finished staging folder is put in place of ``--out``.

The product must then end with exit 130 and one line that says truthfully what happened
to ``--out`` (as it was; or replaced by the finished result) and leave nothing beside it.
"""
from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import pipeline.runtime.outdir
from pipeline.cli import main

WHEN = sys.argv[1]
OUT = Path(sys.argv[sys.argv.index("--out") + 1]).resolve()
WRITE_FOR_S = 1.0
EARLY_FILES = 3000
_wait_for_ranks = pipeline.runtime.outdir.wait_for_ranks
_publish = pipeline.runtime.outdir._publish


def stop_while_writing(comm) -> None:
    (staging,) = OUT.parent.glob(f".{OUT.name}.*.partial")  # the run writes by this path
    for k in range(EARLY_FILES):  # many files: removing them takes a while
        (staging / f"early-{k}.txt").write_text("written before the stop\n")
    os.kill(os.getpid(), signal.SIGINT)
    end = time.monotonic() + WRITE_FOR_S
    n = 0
    while time.monotonic() < end:
        n += 1
        try:
            (staging / f"late-{n}.txt").write_text("written after the stop began\n")
        except OSError:
            pass
    _wait_for_ranks(comm)


def stop_while_publishing(staging: Path, out: Path) -> None:
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.5)  # the stop has begun: it must wait for the publication, not race it
    _publish(staging, out)


if WHEN == "writing":
    pipeline.runtime.outdir.wait_for_ranks = stop_while_writing
elif WHEN == "publishing":
    pipeline.runtime.outdir._publish = stop_while_publishing
else:
    raise SystemExit(f"WHEN: writing or publishing, not {WHEN!r}")

if __name__ == "__main__":
    sys.exit(main(sys.argv[2:], handle_signals=True))
