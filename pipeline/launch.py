"""python -m pipeline.launch RANKS ARGS...: the command line on RANKS MPI ranks (mpirun).

mpirun answers Ctrl-C or SIGTERM by killing its ranks before they can clean up, and exits
with status 1 whatever the signal. So mpirun runs in its own session (a terminal's Ctrl-C
reaches this launcher only), and the launcher hands the signal it receives to the ranks
themselves, mpirun's children on this machine: each cleans up (pipeline.interrupts), rank
0 says how the run stopped, and the launcher exits as the single-process command does,
130 for Ctrl-C, 143 for SIGTERM. Ranks on other machines are stopped by mpirun (SIGTERM).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

EXIT_FOR = {signal.SIGINT: 130, signal.SIGTERM: 143}


def mpirun_command(ranks: int, args: list[str]) -> list[str]:
    """mpirun running ``python -m pipeline ARGS`` on ``ranks`` ranks."""
    root = ["--allow-run-as-root"] if os.geteuid() == 0 else []
    return ["mpirun", *root, "--quiet", "-n", str(ranks), sys.executable, "-m", "pipeline", *args]


def children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # the process ended while we looked
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        ranks = int(argv[0])
        if ranks < 1:
            raise ValueError
    except (IndexError, ValueError):
        sys.stderr.write("error: ranks: usage: python -m pipeline.launch RANKS ARGS... (RANKS >= 1)\n")
        return 2
    received: list[int] = []
    proc = subprocess.Popen(mpirun_command(ranks, argv[1:]), start_new_session=True)

    def forward(signum: int, frame) -> None:
        if received:
            return
        received.append(signum)
        local = children(proc.pid)
        for pid in local:
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass
        if len(local) < ranks:  # ranks elsewhere (or not started yet): mpirun stops them
            proc.send_signal(signal.SIGTERM)

    signal.signal(signal.SIGINT, forward)
    signal.signal(signal.SIGTERM, forward)
    status = proc.wait()
    if not received or status == 0:  # a run that finished before the signal stopped it
        return status
    return EXIT_FOR[received[0]]


if __name__ == "__main__":
    sys.exit(main())
