"""A command stopped while it is still loading (a test helper, one process).

usage: python tests/helpers/stop_while_loading.py SIGNAL MODULE ARGS...

Runs ``python -m MODULE ARGS`` (pipeline or pipeline.runtime.launch) and sends itself SIGNAL
(SIGINT or SIGTERM) just before pipeline.cli is imported: after the program has started
and before the run's own stop is set up (pipeline.runtime.interrupts.install). Sending it at a
chosen import, not after a delay, makes the moment the same on every machine.

The product must then end with the signal's exit status (130, 143) and one line, no
traceback, nothing written.
"""
from __future__ import annotations

import importlib.abc
import os
import runpy
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

SIGNAL = signal.Signals[sys.argv[1]]
MODULE = sys.argv[2]


class StopAtCli(importlib.abc.MetaPathFinder):
    """Sends SIGNAL when pipeline.cli is first looked for, then steps aside."""

    def find_spec(self, name, path, target=None):
        if name == "pipeline.cli":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), SIGNAL)
        return None


sys.meta_path.insert(0, StopAtCli())
sys.argv = [MODULE, *sys.argv[3:]]
runpy.run_module(MODULE, run_name="__main__", alter_sys=True)
