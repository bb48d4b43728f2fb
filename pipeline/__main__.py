"""python -m pipeline: the command line (pipeline.cli)."""
import signal
import sys

from pipeline.cli import main

if __name__ == "__main__":
    code = main(handle_signals=True)
    # The command has ended and said so. A signal from here on would only cut the exit
    # short: Python's shutdown puts back the default action, which ends the process with
    # no line and no exit status of its own. Ignored, the exit goes on with its status.
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)
    sys.exit(code)
