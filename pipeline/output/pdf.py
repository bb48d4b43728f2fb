"""report.pdf: report.html printed on A4 by headless Chromium (which tools/setup.sh installs),
in a process of its own started as soon as report.html is written, so that the run's last
files are written beside it and the run waits for it only at the end.

Each print has a fresh, temporary browser profile: the user's own (~/.config/chromium) is
neither read nor locked, and two runs that print at once do not meet in one browser. The
PDF's pages, footer and page numbers are report.html's print style (pipeline/output/report.py).
"""
from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome")  # the names a headless Chromium goes by
TIMEOUT_S = 120.0  # a print that takes longer is stopped; the run goes on without report.pdf
NO_PDF_ENV = "CROSSHEAD_NO_PDF"  # set (to anything but empty or 0): no report.pdf


def browser() -> str | None:
    """The path of the headless Chromium the run prints with, or None: not installed, or
    CROSSHEAD_NO_PDF set."""
    if os.environ.get(NO_PDF_ENV, "") not in ("", "0"):
        return None
    return next((p for p in map(shutil.which, BROWSERS) if p), None)


@dataclass
class Printing:
    """A print of report.html to report.pdf under way: the browser's process, its profile
    folder, the PDF it writes and when it started (perf_counter, s)."""

    proc: subprocess.Popen
    profile: tempfile.TemporaryDirectory
    pdf: Path
    started: float

    def finish(self, timeout_s: float = TIMEOUT_S) -> tuple[float, str | None]:
        """Wait for the print: (its wall time in s, None) when report.pdf was written, else
        (the time, why not, in a few words). A failed print leaves no report.pdf."""
        why = None
        try:
            _, err = self.proc.communicate(timeout=timeout_s)
            if self.proc.returncode != 0 or not _is_pdf(self.pdf):
                tail = [ln for ln in (err or "").splitlines() if ln.strip()][-1:] or ["no message"]
                why = f"the browser failed (exit {self.proc.returncode}: {tail[0][:200]})"
        except subprocess.TimeoutExpired:
            self.kill()
            why = f"the browser took more than {timeout_s:g} s"
        finally:
            self.profile.cleanup()
        if why is not None:
            self.pdf.unlink(missing_ok=True)
        return time.perf_counter() - self.started, why

    def kill(self) -> None:
        """Stop the browser, reap it and remove its profile (a stopped or failed run prints
        nothing and leaves no temporary folder)."""
        with contextlib.suppress(OSError):
            os.killpg(self.proc.pid, 9)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.proc.wait(timeout=5)
        with contextlib.suppress(OSError):
            self.profile.cleanup()


def _is_pdf(path: Path) -> bool:
    """Whether ``path`` holds a PDF (its first bytes)."""
    try:
        with path.open("rb") as fh:
            return fh.read(5) == b"%PDF-"
    except OSError:
        return False


def start_print(html: Path, pdf: Path, exe: str) -> Printing:
    """Start ``exe`` (a headless Chromium) printing ``html`` to ``pdf`` and return at once.
    The browser runs in a process group of its own (its helpers are stopped with it) on any
    core: a rank of mpirun is bound to one, and its child would share it."""
    profile = tempfile.TemporaryDirectory(prefix="crosshead-chromium-")
    args = [exe, "--headless", "--disable-gpu", "--no-pdf-header-footer", "--no-first-run",
            "--disable-extensions", f"--user-data-dir={profile.name}", f"--print-to-pdf={pdf}", html.resolve().as_uri()]
    if os.geteuid() == 0:  # Chromium refuses to run as root with its sandbox
        args.insert(1, "--no-sandbox")
    proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    with contextlib.suppress(AttributeError, OSError):  # no affinity outside Linux
        os.sched_setaffinity(proc.pid, range(os.cpu_count() or 1))
    return Printing(proc, profile, pdf, time.perf_counter())
