"""report.pdf: report.html printed on A4 by headless Chromium (which tools/setup.sh installs).

The browser is started before the run's last files are made (while the plots are drawn),
so that its start-up is off the run's critical path; when report.html is written it loads
it and prints it (the DevTools protocol over a pair of pipes, Page.printToPDF with the
page's own CSS page size), and closes. Measured on No. 05's report (6 pages): 0.35 s from
report.html to report.pdf with the browser started, against 1.0 s for a one-shot
``chromium --headless --print-to-pdf`` (whose start-up and waits fall after report.html);
the two PDFs hold the same text on the same pages.

Each browser has a fresh, temporary profile: the user's own (~/.config/chromium) is neither
read nor locked, and two runs printing at once do not meet in one browser. The PDF's pages,
footer and page numbers are report.html's print style (pipeline/output/report.py).
"""
from __future__ import annotations

import base64
import contextlib
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from pipeline.runtime.cores import unbind

BROWSERS = ("chromium", "chromium-browser", "google-chrome")  # the names a headless Chromium goes by
TIMEOUT_S = 120.0  # a browser that takes longer to answer is stopped; the run goes on without report.pdf
NO_PDF_ENV = "CROSSHEAD_NO_PDF"  # set (to anything but empty or 0): no report.pdf
# The browser's end of the pipes: the protocol reads its commands from descriptor 3 and
# writes its answers to 4 (--remote-debugging-pipe), each a JSON text ended by a NUL byte.
PIPE_SHELL = 'exec 3<&0 4>&1 0</dev/null 1>/dev/null; exec "$@"'
PR_SET_CHILD_SUBREAPER = 36  # Linux prctl(2)
REAP_S = 1.0  # how long a killed browser's helpers are waited for (s); SIGKILL ends them in milliseconds


def browser() -> str | None:
    """The path of the headless Chromium the run prints with, or None: not installed, or
    CROSSHEAD_NO_PDF set."""
    if os.environ.get(NO_PDF_ENV, "") not in ("", "0"):
        return None
    return next((p for p in map(shutil.which, BROWSERS) if p), None)


def adopt_orphans() -> bool:
    """Make this process the reaper of its descendants' orphans (Linux; False elsewhere).

    Why: the browser's helpers are its children; killed with it, they are orphans, and
    their new parent would be init, which reaps them and keeps their CPU time. Adopted
    here, they are reaped by :meth:`Browser.kill`: the run's CPU time (what ``time`` and
    the bench count, the processes it started) includes them, and none is left over."""
    import ctypes
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def reap_group(pgid: int, wait_s: float = REAP_S) -> None:
    """Reap this process's children in process group ``pgid`` (a killed browser's helpers,
    adopted: :func:`adopt_orphans`) until none is left or ``wait_s`` has passed."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            pid, _ = os.waitpid(-pgid, os.WNOHANG)
        except ChildProcessError:
            return  # none of the group is this process's child any more
        if pid == 0:
            if time.monotonic() > deadline:
                return
            time.sleep(0.005)


class PrintError(Exception):
    """The browser did not print: it ended, did not answer in time, or answered an error."""


class Browser:
    """A headless Chromium started for one print, answering the DevTools protocol on a pair
    of pipes: made, it starts and returns at once; :meth:`print_pdf` prints a page (and says
    why not, never raises), :meth:`kill` ends it."""

    def __init__(self, exe: str):
        self.profile = tempfile.mkdtemp(prefix="crosshead-chromium-")
        # Chromium leaves a folder of its own (org.chromium.Chromium.*, its singleton
        # socket) in TMPDIR when it is killed: give it one inside the profile, removed with it.
        tmp = os.path.join(self.profile, "tmp")
        os.mkdir(tmp)
        self._buffer, self._id, self.session = b"", 0, None
        to_browser, self._to = os.pipe()
        self._from, from_browser = os.pipe()
        adopt_orphans()
        args = [exe, "--headless", "--disable-gpu", "--no-first-run", "--disable-extensions",
                "--remote-debugging-pipe", f"--user-data-dir={self.profile}", "about:blank"]
        if os.geteuid() == 0:  # Chromium refuses to run as root with its sandbox
            args.insert(1, "--no-sandbox")
        self.proc: subprocess.Popen | None = None
        self.failed: str | None = None  # why the browser could not be started
        try:
            self.proc = subprocess.Popen(["sh", "-c", PIPE_SHELL, "sh", *args], stdin=to_browser,
                                         stdout=from_browser, stderr=subprocess.DEVNULL, start_new_session=True,
                                         env=dict(os.environ, TMPDIR=tmp))
        except OSError as exc:
            self.failed = f"the browser could not be started ({exc.strerror or exc})"
        finally:
            os.close(to_browser)
            os.close(from_browser)
        if self.proc is not None:
            unbind(self.proc.pid)  # any core, not the rank's own alone

    def print_pdf(self, html: Path, pdf: Path, timeout_s: float = TIMEOUT_S) -> tuple[float, str | None]:
        """Load ``html`` and print it to ``pdf`` with the page's own CSS page size, margins
        and footer: (the wall time in s, None) when it did, else (the time, why not, in a
        few words: the browser ended, did not answer within ``timeout_s``, or answered an
        error), and no ``pdf``."""
        t0, deadline = time.perf_counter(), time.monotonic() + timeout_s
        why = self.failed
        try:
            if why is not None:
                raise PrintError(why)
            # A page to load into: the browser answers once it has started (meanwhile, by now).
            target = self._call("Target.createTarget", {"url": "about:blank"}, deadline)
            self.session = self._call("Target.attachToTarget", {"targetId": target["targetId"], "flatten": True},
                                      deadline)["sessionId"]
            self._call("Page.enable", {}, deadline)
            self._call("Page.navigate", {"url": Path(html).resolve().as_uri()}, deadline)
            self._wait(lambda m: m.get("method") == "Page.loadEventFired", deadline)
            data = self._call("Page.printToPDF", {"preferCSSPageSize": True, "printBackground": True,
                                                  "displayHeaderFooter": False}, deadline)["data"]
            Path(pdf).write_bytes(base64.b64decode(data))
        except subprocess.TimeoutExpired:
            why = f"the browser did not answer within {timeout_s:g} s"
        except (PrintError, KeyError, ValueError, OSError) as exc:
            why = str(exc) or type(exc).__name__
        if why is not None:
            Path(pdf).unlink(missing_ok=True)
        return time.perf_counter() - t0, why

    def kill(self) -> None:
        """Stop the browser and its helpers (its process group), reap them and remove its
        profile: a stopped or failed run prints nothing and leaves no temporary folder."""
        if self.proc is not None:
            with contextlib.suppress(OSError):
                os.killpg(self.proc.pid, 9)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=5)
            reap_group(self.proc.pid)
        for fd in (self._to, self._from):
            with contextlib.suppress(OSError):
                os.close(fd)
        shutil.rmtree(self.profile, ignore_errors=True)

    def _call(self, method: str, params: dict, deadline: float) -> dict:
        """Send one command (to the page's session once there is one) and return its result."""
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params}
        if self.session is not None:
            msg["sessionId"] = self.session
        try:
            os.write(self._to, json.dumps(msg).encode() + b"\0")
        except OSError:
            raise PrintError(self._ended()) from None
        answer = self._wait(lambda m: m.get("id") == msg["id"], deadline)
        if "error" in answer:
            raise PrintError(f"{method}: {answer['error'].get('message', answer['error'])}")
        return answer.get("result", {})

    def _wait(self, wanted, deadline: float) -> dict:
        """The browser's next message that ``wanted`` accepts (others are passed over)."""
        while True:
            while b"\0" in self._buffer:
                raw, self._buffer = self._buffer.split(b"\0", 1)
                msg = json.loads(raw)
                if wanted(msg):
                    return msg
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._from], [], [], left)[0]:
                raise subprocess.TimeoutExpired("chromium", left)
            chunk = os.read(self._from, 1 << 20)
            if not chunk:
                raise PrintError(self._ended())
            self._buffer += chunk

    def _ended(self) -> str:
        """Why the browser stopped answering, when its pipe closed: its exit status."""
        try:
            return f"the browser ended (exit {self.proc.wait(timeout=5)})"
        except subprocess.TimeoutExpired:
            return "the browser closed its pipe"
