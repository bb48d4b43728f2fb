"""report.pdf's print (pipeline/output/pdf.py) with stand-in browsers: a print that writes
a PDF is kept, one that fails or hangs leaves no report.pdf and says why, and none leaves
its temporary profile behind. The real browser's print: tests/output/test_report.py."""
from __future__ import annotations

import stat
import time
from pathlib import Path

import pytest

from pipeline.output import pdf


def _browser(tmp_path: Path, body: str) -> str:
    """A stand-in browser: a shell script given the arguments pdf.start_print passes."""
    exe = tmp_path / "browser"
    exe.write_text("#!/bin/sh\n" + body + "\n")
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return str(exe)


WRITES = 'for a in "$@"; do case "$a" in --print-to-pdf=*) printf "%%PDF-1.4\\n" > "${a#--print-to-pdf=}";; esac; done'


def test_a_print_that_writes_a_pdf_is_kept(tmp_path):
    html, out = tmp_path / "report.html", tmp_path / "report.pdf"
    html.write_text("<p>x</p>")
    printing = pdf.start_print(html, out, _browser(tmp_path, WRITES))
    seconds, why = printing.finish()
    assert why is None and out.read_bytes().startswith(b"%PDF-") and seconds >= 0
    assert not Path(printing.profile.name).exists()


@pytest.mark.parametrize("body,words", [(WRITES + "\nexit 3", "exit 3"), ("echo broken >&2; exit 0", "broken")])
def test_a_failed_print_leaves_no_pdf_and_says_why(tmp_path, body, words):
    """A browser that fails (exit 3: its half-written PDF is removed), or that exits 0
    without writing a PDF (its last line of stderr is the reason given)."""
    html, out = tmp_path / "report.html", tmp_path / "report.pdf"
    html.write_text("<p>x</p>")
    printing = pdf.start_print(html, out, _browser(tmp_path, body))
    _, why = printing.finish()
    assert why is not None and words in why and not out.exists()
    assert not Path(printing.profile.name).exists()


def test_a_print_that_hangs_is_stopped_with_its_helpers(tmp_path):
    html, out = tmp_path / "report.html", tmp_path / "report.pdf"
    html.write_text("<p>x</p>")
    helper = tmp_path / "helper.pid"
    printing = pdf.start_print(html, out, _browser(tmp_path, f"sleep 60 & echo $! > {helper}; sleep 60"))
    t0 = time.perf_counter()
    _, why = printing.finish(timeout_s=0.5)
    assert "took more than 0.5 s" in why and time.perf_counter() - t0 < 10 and not out.exists()
    time.sleep(0.2)
    assert not _running(int(helper.read_text()))  # the helper (same process group) is stopped too
    assert not Path(printing.profile.name).exists()


def _running(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie left for its new parent to reap does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def test_no_browser_is_asked_for_when_the_pdf_is_turned_off(monkeypatch):
    monkeypatch.setenv(pdf.NO_PDF_ENV, "1")
    assert pdf.browser() is None
    monkeypatch.setenv(pdf.NO_PDF_ENV, "0")
    monkeypatch.setenv("PATH", "/nonexistent")
    assert pdf.browser() is None  # and none installed: no report.pdf either
