"""Every failure line is true and names what failed; closed, full or narrow standard
streams never give a traceback nor change the exit status (docs/design.md §8,
pipeline/runtime/streams.py, pipeline/cli.py).

- stdout on a full device: exit 2, "stdout" named, not ``--out``; "nothing written" only
  when the output folder is as it was, and after publication the line says the results
  were written;
- a failure in the form or run cache names the cache;
- stdout or stderr closed (``>&-``, ``2>&-``) or stderr full: no traceback, the status §8 gives;
- ``PYTHONIOENCODING=ascii``: every line comes out, "×" as "x".
"""
from __future__ import annotations

import errno
import io
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
FAST = ["run", "--size", "05", "--mesh-factor", "3", "--levels", "1", "--no-fields"]
ENV = dict(os.environ, PYTHONPATH=str(ROOT), CROSSHEAD_NO_CACHE="1")
BAD = ["run", "--size", "05", "--levels", "9"]  # levels must lie in 1..8 (docs/design.md §8: exit 2)


PROGRESS = re.compile(r"^\[\s*[0-9.]+ s\] ")   # a progress line's stamp (they go to stderr too)


def failure_lines(stderr: str) -> list[str]:
    """The lines of stderr that are not progress lines: the failure's own."""
    return [ln for ln in stderr.strip().splitlines() if not PROGRESS.match(ln)]

def load_of(out: Path) -> float:
    return json.loads((out / "results.json").read_text(encoding="utf-8"))["case"]["load_N"]


def shell(redirect: str, args: list, env: dict = ENV) -> subprocess.CompletedProcess:
    """``python -m pipeline ARGS`` with the shell redirection ``redirect`` (``>&-``, say)."""
    quoted = " ".join(f"'{a}'" for a in map(str, args))
    return subprocess.run(["sh", "-c", f"exec '{PY}' -m pipeline {quoted} {redirect}"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """A finished results folder at Q = 5000 N."""
    out = tmp_path_factory.mktemp("earlier") / "res"
    proc = subprocess.run([PY, "-m", "pipeline", *FAST, "--load", "5000", "--out", str(out), "--quiet"],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out


# ------------------------------------------------------------------ stdout on a full device

@pytest.mark.slow
def test_stdout_on_a_full_device_names_stdout_and_says_what_was_written(tmp_path, earlier):
    """The line names stdout, not --out ("error: out: cannot write: No space left ..." would
    send the user after the wrong thing), and says what became of the output: stdout takes
    only the results (progress goes to stderr), so the run completes, puts its results in
    place (5000 N -> 20000 N) and the line says they were written."""
    out = tmp_path / "res"
    shutil.copytree(earlier, out)
    proc = shell("> /dev/full", FAST + ["--load", "20000", "--out", out])
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    lines = failure_lines(proc.stderr)
    assert len(lines) == 1 and "stdout" in lines[0] and "No space left" in lines[0], proc.stderr
    assert not lines[0].startswith("error: out:") and "--out" not in lines[0]
    assert "nothing written" not in lines[0] and f"written to {out}" in lines[0] and load_of(out) == 20000.0
    assert sorted(os.listdir(tmp_path)) == ["res"]


class FullAtTheSummary(io.StringIO):
    """A stdout that fails (ENOSPC) from the closing summary on (the progress lines go to
    stderr): a disk that fills up while the run publishes its result."""

    full = False

    def write(self, text: str) -> int:
        if self.full or text.startswith("global peak"):
            self.full = True
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(text)

    def flush(self) -> None:
        if self.full:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.mark.slow
def test_stdout_full_after_publication_says_the_results_were_written(tmp_path, earlier, monkeypatch, capsys):
    """The results are in place (5000 N -> 20000 N) when stdout fails: the line says so, and
    not "nothing written, the output folder is as it was"."""
    from pipeline import cli
    out = tmp_path / "res"
    shutil.copytree(earlier, out)
    stdout = FullAtTheSummary()
    monkeypatch.setattr(sys, "stdout", stdout)
    code = cli.main([*FAST, "--load", "20000", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = failure_lines(err)
    assert len(lines) == 1 and "stdout" in lines[0] and "No space left" in lines[0], err
    assert "nothing written" not in lines[0] and "written to" in lines[0] and str(out) in lines[0], err
    assert load_of(out) == 20000.0 and "imports" in err  # the progress lines went out
    assert sorted(os.listdir(tmp_path)) == ["res"]


@pytest.mark.slow
def test_a_cache_failure_names_the_cache(tmp_path, earlier, monkeypatch, capsys):
    """A read-only form cache (any OSError on a path under the cache folder): the line names
    the cache and its path, not --out ("out: cannot write <the cache's file>" is untrue)."""
    import pipeline.output.folder
    from pipeline import cli
    from pipeline.runtime.environment import CACHE_HOME
    place = CACHE_HOME / "fenics" / "libffcx_forms_x.c"

    def read_only(*a, **k):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(place))
    monkeypatch.setattr(pipeline.output.folder, "run", read_only)
    out = tmp_path / "res"
    shutil.copytree(earlier, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code = cli.main([*FAST, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: cache:") and str(place) in lines[0], err
    assert "Read-only" in lines[0] and "nothing written" in lines[0] and "out:" not in lines[0]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(os.listdir(tmp_path)) == ["res"]


# ------------------------------------------------------------------ closed and full streams

@pytest.mark.slow
@pytest.mark.parametrize("quiet", [[], ["--quiet"]], ids=["progress", "quiet"])
def test_a_closed_stdout_still_writes_the_result(tmp_path, quiet):
    """No traceback (sys.stdout is None when descriptor 1 is closed at start), exit 0, the
    result written; the closing lines that stdout could not take are said to be lost, once,
    on stderr. --quiet shows none, so says none."""
    from pipeline.cli.terminal import CLOSED_STDOUT
    out = tmp_path / "res"
    proc = shell(">&-", FAST + quiet + ["--out", out])
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert (out / "results.json").is_file() and (out / ".crosshead-results").is_file()
    assert proc.stderr.count(CLOSED_STDOUT) == (0 if quiet else 1), proc.stderr


@pytest.mark.parametrize("redirect", ["2>&-", "2>/dev/full"], ids=["closed", "full"])
def test_bad_input_with_stderr_closed_or_full_is_still_exit_2(tmp_path, redirect):
    """The line cannot be written; the status still says bad input (2, not 1)."""
    proc = shell(redirect, BAD + ["--out", tmp_path / "res"])
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert os.listdir(tmp_path) == []


@pytest.mark.slow
def test_a_run_with_stderr_closed_finishes(tmp_path):
    out = tmp_path / "res"
    proc = shell("2>&-", FAST + ["--quiet", "--out", out])
    assert proc.returncode == 0, proc.stderr
    assert (out / "results.json").is_file()


@pytest.mark.slow
def test_an_ascii_stdout_gets_every_line(tmp_path):
    """With PYTHONIOENCODING=ascii every line comes out, "×" as "x" (the first "×", the
    pilot's "×4", must not silence the rest of the run)."""
    out = tmp_path / "res"
    proc = subprocess.run([PY, "-m", "pipeline", *FAST, "--out", str(out)], cwd=ROOT,
                          env=dict(ENV, PYTHONIOENCODING="ascii"), capture_output=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout.decode("ascii") + proc.stderr.decode("ascii")  # nothing but ASCII
    assert "mesh x3:" in text and "global peak" in text and f"written to {out}/" in text, text


def test_an_ascii_error_line_keeps_its_words(tmp_path):
    """A failure line with a character ASCII lacks comes out whole, with ASCII text."""
    bad = tmp_path / "0×5.toml"
    bad.write_text("[case\n", encoding="utf-8")
    proc = subprocess.run([PY, "-m", "pipeline", "run", "--case", str(bad), "--out", str(tmp_path / "res")],
                          cwd=ROOT, env=dict(ENV, PYTHONIOENCODING="ascii"), capture_output=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    line = proc.stderr.decode("ascii").strip()
    assert len(line.splitlines()) == 1 and "0x5.toml" in line, line


def test_help_on_a_full_stdout_is_one_line(tmp_path):
    """argparse lets the write's error through: one line naming stdout, exit 2, no traceback."""
    proc = shell("> /dev/full", ["run", "--help"])
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "stdout" in lines[0] and "No space left" in lines[0], proc.stderr


def test_a_full_stdout_met_by_the_meshing_heartbeat_is_reported_by_the_main_thread(monkeypatch):
    """The heartbeat (pipeline/fe/meshing.py) prints from its own thread: an error there must
    not end that thread with a traceback and be lost; the main thread's next line reports it."""
    import threading

    from pipeline import cli
    from pipeline.cli import terminal

    class Full(io.StringIO):
        def write(self, text: str) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(sys, "stdout", Full())
    died = []
    monkeypatch.setattr(threading, "excepthook", died.append)
    beat = threading.Thread(target=terminal.show, args=("meshing: still working (10 s so far)",))
    beat.start()
    beat.join()
    assert died == []
    with pytest.raises(cli.StdoutError, match="stdout: cannot write .No space left"):
        terminal.show("the next progress line")


# ------------------------------------------------------------------ out of memory

def no_leftovers(folder: Path) -> list[str]:
    """What a run left in ``folder`` (its --out's parent): staging folders, locks, the folder."""
    return sorted(p.name for p in folder.iterdir())


def test_memory_running_out_mid_run_is_one_line_and_nothing_left(tmp_path, monkeypatch, capsys):
    """A MemoryError while computing (what an estimate that let the run start can meet):
    exit 3, one line saying memory ran out and that nothing was written; no staging folder,
    no lock, no output folder."""
    import pipeline.output.folder
    from pipeline.cli import main

    def starved(*a, **k):
        raise MemoryError()
    monkeypatch.setattr(pipeline.output.folder, "run", starved)
    assert main(FAST + ["--quiet", "--out", str(tmp_path / "res")]) == 3
    lines = failure_lines(capsys.readouterr().err)
    assert len(lines) == 1 and lines[0].startswith("out of memory: MemoryError") and "nothing written" in lines[0]
    assert no_leftovers(tmp_path) == []


def test_a_thread_or_library_that_cannot_be_had_is_out_of_memory():
    """What DOLFINx's and Python's failures say when the address space runs out, each read
    as memory running out (pipeline.errors.out_of_memory); an ordinary failure is not."""
    from pipeline.errors import OutOfMemory, out_of_memory
    for exc in (MemoryError(), RuntimeError("can't start new thread"),
                ImportError("libpetsc_real.so.3.18: failed to map segment from shared object"),
                OSError(errno.ENOMEM, "Cannot allocate memory"), OutOfMemory("drawing: MemoryError")):
        assert out_of_memory(exc), exc
    assert not out_of_memory(RuntimeError("drawing failed")) and not out_of_memory(ValueError("x"))


def test_a_drawing_process_s_failure_is_its_error_line_not_a_warning():
    """The drawing process's stderr ends in VTK's coloured warnings: the line names its error,
    without escapes (not a warning about the X server), and a memory error is OutOfMemory."""
    from pipeline.errors import OutOfMemory
    from pipeline.output.drawing import failure
    warn = "\x1b[0m\x1b[33m2026 vtkXOpenGLRenderWindow.:1452 WARN| bad X server connection.\x1b[0m"
    exc = failure(f"Traceback\n  File x\nMemoryError\n{warn}\n", 1)
    assert isinstance(exc, OutOfMemory) and str(exc) == "drawing: MemoryError"
    exc = failure(f"ValueError: no data\n{warn}\n", 1)
    assert type(exc) is RuntimeError and str(exc) == "drawing failed: ValueError: no data"
    assert "exit status -9" in str(failure("", -9))


def _limited(gib: float):
    """A child's address space limited to ``gib`` GiB (ulimit -v)."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (int(gib * 1024 ** 3), resource.RLIM_INFINITY))
    return limit


@pytest.mark.slow
@pytest.mark.parametrize("gib, says", [
    (0.2, "needs 0.9 GiB before it meshes anything"),   # no thread could start: a traceback before
    (0.6, "needs 0.9 GiB before it meshes anything"),   # PETSc could not be loaded
    (1.2, "this run needs about 1.4 GiB of it"),         # OpenBLAS waited for memory forever
])
def test_a_run_under_an_address_space_limit_is_refused_before_any_work(tmp_path, gib, says):
    """Under ``ulimit -v``: exit 2, one line naming the limit and what the run needs, and
    nothing written: no output folder, no staging folder, no lock, no traceback, no exit
    139 and no process left running. No. 05's default
    run needs 1.03 GiB (VmPeak measured) and the picture's process 1.15 GiB."""
    proc = subprocess.run([PY, "-m", "pipeline", "run", "--size", "05", "--out", str(tmp_path / "res")], cwd=ROOT,
                          env=ENV, capture_output=True, text=True, timeout=300, preexec_fn=_limited(gib))
    assert proc.returncode == 2, proc.stderr
    lines = failure_lines(proc.stderr)
    assert len(lines) == 1 and lines[0].startswith("error: memory: the address space is limited") and says in lines[0]
    assert no_leftovers(tmp_path) == []
