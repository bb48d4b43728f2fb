"""report.pdf's print (pipeline/output/pdf.py) with stand-in browsers that speak the
DevTools protocol on descriptors 3 and 4 as headless Chromium does: a print that answers is
written, one that answers an error, ends or hangs leaves no report.pdf and says why, and
no browser leaves a helper running or its temporary profile behind. The real browser's
print: tests/output/test_report.py."""
from __future__ import annotations

import stat
import sys
import time
from pathlib import Path

import pytest

from pipeline.output import pdf

STAND_IN = '''#!{python}
"""A stand-in browser: answers each command read from descriptor 3 on descriptor 4 ({mode})."""
import base64, json, os, subprocess, sys, time
MODE = "{mode}"
# As Chromium does: a folder of its own in the temporary folder it is given (its singleton
# socket's), which a killed browser never removes; and where that was, for the test.
os.makedirs(os.path.join(os.environ.get("TMPDIR", "/tmp"), "org.chromium.Chromium.standin"), exist_ok=True)
open("{helper}.tmpdir", "w").write(os.environ.get("TMPDIR", ""))
if MODE == "hang":
    helper = subprocess.Popen(["sleep", "60"])
    open("{helper}", "w").write(str(helper.pid))
if MODE == "burn":  # a helper that works for 0.5 s of CPU, says so, then idles as Chromium's do
    helper = subprocess.Popen([sys.executable, "-c", "import time\\nt = time.process_time()\\n"
                               "while time.process_time() - t < 0.5: pass\\n"
                               "open('{helper}', 'w').write('done')\\ntime.sleep(60)"])
buf = b""
while True:
    chunk = os.read(3, 65536)
    if not chunk:
        sys.exit(0)
    buf += chunk
    while b"\\0" in buf:
        raw, buf = buf.split(b"\\0", 1)
        msg = json.loads(raw)
        method, out = msg["method"], {{"id": msg["id"], "result": {{}}}}
        if method == "Target.createTarget":
            out["result"] = {{"targetId": "T1"}}
        elif method == "Target.attachToTarget":
            out["result"] = {{"sessionId": "S1"}}
        elif method == "Page.printToPDF":
            while MODE == "burn" and not os.path.exists("{helper}"):
                time.sleep(0.01)
            if MODE == "hang":
                time.sleep(60)
            if MODE == "die":
                sys.exit(3)
            if MODE == "error":
                out = {{"id": msg["id"], "error": {{"message": "Printing failed"}}}}
            else:
                out["result"] = {{"data": base64.b64encode(b"%PDF-1.4 stand-in").decode()}}
        os.write(4, json.dumps(out).encode() + b"\\0")
        if method == "Page.navigate":
            os.write(4, json.dumps({{"method": "Page.loadEventFired", "params": {{}}}}).encode() + b"\\0")
'''


def _browser(tmp_path: Path, mode: str) -> str:
    exe = tmp_path / f"browser-{mode}"
    exe.write_text(STAND_IN.format(python=sys.executable, mode=mode, helper=tmp_path / "helper.pid"))
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return str(exe)


def _print(tmp_path: Path, mode: str, timeout_s: float = 30.0) -> tuple[pdf.Browser, Path, str | None]:
    html, out = tmp_path / "report.html", tmp_path / "report.pdf"
    html.write_text("<p>x</p>")
    browser = pdf.Browser(_browser(tmp_path, mode))
    try:
        _, why = browser.print_pdf(html, out, timeout_s)
    finally:
        browser.kill()
    return browser, out, why


def _running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie left for its new parent to reap does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def test_a_print_the_browser_answers_is_written(tmp_path):
    browser, out, why = _print(tmp_path, "ok")
    assert why is None and out.read_bytes() == b"%PDF-1.4 stand-in"
    assert not Path(browser.profile).exists() and not _running(browser.proc.pid)
    # The browser's own temporary folders went inside its profile, and with it.
    tmp = Path((tmp_path / "helper.pid.tmpdir").read_text())
    assert tmp.is_relative_to(browser.profile) and not tmp.exists()


@pytest.mark.parametrize("mode,words", [("error", "Page.printToPDF: Printing failed"),
                                        ("die", "the browser ended (exit 3)")])
def test_a_failed_print_leaves_no_pdf_and_says_why(tmp_path, mode, words):
    browser, out, why = _print(tmp_path, mode)
    assert why == words and not out.exists() and not Path(browser.profile).exists()


def test_a_print_that_hangs_is_stopped_with_its_helpers(tmp_path):
    t0 = time.perf_counter()
    browser, out, why = _print(tmp_path, "hang", timeout_s=1.0)
    assert why == "the browser did not answer within 1 s" and time.perf_counter() - t0 < 10 and not out.exists()
    time.sleep(0.2)
    assert not _running(int((tmp_path / "helper.pid").read_text()))  # its process group is stopped whole
    assert not Path(browser.profile).exists()


BURN = """
import resource, sys
from pathlib import Path
from pipeline.output import pdf
tmp = Path(sys.argv[1])
(tmp / "report.html").write_text("<p>x</p>")
browser = pdf.Browser(sys.argv[2])
try:
    _, why = browser.print_pdf(tmp / "report.html", tmp / "report.pdf", 30.0)
finally:
    browser.kill()
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(why, r.ru_utime + r.ru_stime)
"""


def test_the_browser_s_helpers_are_reaped_by_the_run_and_their_cpu_counted(tmp_path):
    """A helper the browser started and the kill orphaned is the run's child when it dies:
    its CPU time is in the run's (the processes it started), not init's."""
    import subprocess
    out = subprocess.run([sys.executable, "-c", BURN, str(tmp_path), _browser(tmp_path, "burn")],
                         capture_output=True, text=True, cwd=Path(pdf.__file__).resolve().parents[2], timeout=60)
    why, cpu = out.stdout.split()
    assert why == "None" and (tmp_path / "helper.pid").read_text() == "done"
    assert float(cpu) >= 0.45  # the helper's 0.5 s of work, less the clock's grain


def test_a_browser_that_cannot_start_is_said_not_raised(tmp_path):
    html, out = tmp_path / "report.html", tmp_path / "report.pdf"
    html.write_text("<p>x</p>")
    browser = pdf.Browser(str(tmp_path / "no-such-browser"))
    _, why = browser.print_pdf(html, out, 10.0)
    browser.kill()
    assert why is not None and why.startswith("the browser ended (exit 127)") and not out.exists()


def test_no_browser_is_asked_for_when_the_pdf_is_turned_off(monkeypatch):
    monkeypatch.setenv(pdf.NO_PDF_ENV, "1")
    assert pdf.browser() is None
    monkeypatch.setenv(pdf.NO_PDF_ENV, "0")
    monkeypatch.setenv("PATH", "/nonexistent")
    assert pdf.browser() is None  # and none installed: no report.pdf either
