"""python -m pipeline.runtime.launch RANKS ARGS...: the command line on RANKS MPI ranks (mpirun).

mpirun answers Ctrl-C or SIGTERM by killing its ranks before they can clean up, and exits
with status 1 whatever the signal. So mpirun runs in its own session (a terminal's Ctrl-C
reaches this launcher only), and the launcher hands the signal it receives to the ranks
themselves, mpirun's children on this machine: each cleans up (pipeline.runtime.interrupts), rank
0 says how the run stopped, and the launcher exits as the single-process command does,
130 for Ctrl-C, 143 for SIGTERM. Ranks on other machines are stopped by mpirun (SIGTERM).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from pipeline.runtime.interrupts import EXIT_FOR, stop_before_start


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


USAGE = "usage: python -m pipeline.runtime.launch RANKS ARGS... (RANKS >= 1; ARGS: those of python -m pipeline)"


def refusal(argv: list[str]) -> tuple[int, str] | None:
    """(exit status, line) when the launch cannot start: RANKS not a whole number from 1
    to the cores this process may use (mpirun refuses more, silently under --quiet), or
    ARGS that the command line refuses (checked here once, not once per rank)."""
    try:
        ranks = int(argv[0])
        if ranks < 1:
            raise ValueError
    except (IndexError, ValueError):
        return 2, f"error: ranks: {USAGE}"
    from pipeline.runtime.environment import address_space_refusal
    refused = address_space_refusal()  # said once here, not once per rank
    if refused is not None:
        return 2, f"error: {refused}"
    cores = len(os.sched_getaffinity(0))
    if ranks > cores:
        return 2, (f"error: ranks: {ranks} ranks, but this machine gives {cores} cores; pipeline.runtime.launch runs "
                   "one rank per core here (on a cluster: mpirun or srun, docs/sweeps.md)")
    from pipeline.cli import NO_COMMAND, make_parser  # argparse only: no numerics are loaded
    try:
        args = make_parser().parse_args(argv[1:])
    except SystemExit as exc:  # the parser wrote its one line (or the help, status 0)
        return int(exc.code or 0), ""
    if args.command is None:
        return 2, NO_COMMAND
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["-h"], ["--help"]):
        print(__doc__.split("\n\n")[0] + "\n" + USAGE)
        return 0
    refused = refusal(argv)
    if refused is not None:
        code, line = refused
        if line:
            sys.stderr.write(line + "\n")
        return code
    ranks = int(argv[0])
    received: list[int] = []
    handed: list[int] = []
    proc: subprocess.Popen | None = None

    def hand_over(signum: int) -> None:
        """Send ``signum`` to the ranks on this machine (once); mpirun stops the others."""
        if handed:
            return
        handed.append(signum)
        local = children(proc.pid)
        for pid in local:
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass
        if len(local) < ranks:  # ranks elsewhere (or not started yet): mpirun stops them
            proc.send_signal(signal.SIGTERM)

    def forward(signum: int, frame) -> None:
        if received:
            return
        received.append(signum)
        if proc is not None:
            hand_over(signum)

    # Set before mpirun starts, so that no signal finds the loading program's handler
    # (pipeline.runtime.interrupts.stop_before_start) once there are ranks to stop.
    signal.signal(signal.SIGINT, forward)
    signal.signal(signal.SIGTERM, forward)
    try:
        proc = subprocess.Popen(mpirun_command(ranks, argv[1:]), start_new_session=True)
    except FileNotFoundError:
        sys.stderr.write("error: mpirun: not found on PATH (make setup installs Open MPI)\n")
        return 2
    if received:  # a signal came while mpirun was starting
        hand_over(received[0])
    status = proc.wait()
    if not received or status == 0:  # a run that finished before the signal stopped it
        return status
    return EXIT_FOR[received[0]]


if __name__ == "__main__":
    from pipeline.runtime.streams import make_safe
    make_safe()  # closed standard streams on /dev/null, before mpirun and its ranks inherit them
    # Until mpirun starts, Ctrl-C or SIGTERM ends the launcher with its one line.
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, stop_before_start)
    sys.exit(main())
