"""The tool never loses a user's files (docs/design.md §8).

- ``--out`` never replaces a folder the tool did not write: a user's folder, the working
  folder, the repository, ``/``, the home folder, mount points (symlinks judged by target);
- Ctrl-C and SIGTERM end a run with exit 130 / 143 and one line, leave no staging folder and
  leave the earlier result as it was, with one process and under MPI (pipeline.runtime.launch);
- a staging folder left by a killed run is removed by the next run to the same folder;
- a second run to a folder that is being written stops with exit 2 naming the other run;
- a closed stdout does not lose the result; a full disk is exit 2 with nothing written
  (closed, full and ASCII-only streams in detail: tests/runtime/test_failure_lines.py; a user's
  files in results folders, markers, names, modes, mounts: tests/runtime/test_user_files.py);
- a failure on one MPI rank alone ends every rank with one line (no hang), nothing written.

The runs are real subprocesses on coarse meshes (mesh factor 3, one level: a few seconds).
"""
from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
FAST = ["run", "--size", "05", "--mesh-factor", "3", "--levels", "1", "--no-fields"]
SLOW = ["run", "--size", "05", "--mesh-factor", "1.0", "--levels", "3", "--no-fields"]  # ~10 s
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def cli(args: list[str], cwd: Path = ROOT, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([PY, "-m", "pipeline", *map(str, args)], cwd=cwd, env=ENV,
                          capture_output=True, text=True, timeout=300, **kw)


PROGRESS = re.compile(r"^\[\s*[0-9.]+ s\] ")  # a progress line's stamp (progress goes to stderr)


def one_error_line(proc: subprocess.CompletedProcess, code: int, *words: str) -> str:
    """The one line (besides progress lines) a failed or stopped command says on stderr."""
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if not PROGRESS.match(ln)]
    assert len(lines) == 1, proc.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (relative path -> content)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def debris(parent: Path, name: str) -> list[str]:
    """Hidden staging, replaced-results or lock entries the tool left beside ``parent/name``."""
    return sorted(p.name for p in parent.glob(f".{name}.*"))


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """A finished results folder (the earlier result that must survive failures)."""
    out = tmp_path_factory.mktemp("earlier") / "res"
    proc = cli(FAST + ["--out", out])
    assert proc.returncode == 0, proc.stderr
    assert (out / ".crosshead-results").is_file() and (out / "results.json").is_file()
    return out


def fresh_copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


# ------------------------------------------------------------------ 1. folders that are not ours

def test_user_folder_with_a_file_is_refused_and_the_file_survives(tmp_path):
    user = tmp_path / "u"
    user.mkdir()
    (user / "thesis.tex").write_text("x")
    t0 = time.perf_counter()
    line = one_error_line(cli(FAST + ["--out", user]), 2, "out", str(user), "marker")
    assert time.perf_counter() - t0 < 20  # refused before any meshing
    assert (user / "thesis.tex").read_text() == "x" and len(list(user.iterdir())) == 1, line
    assert debris(tmp_path, "u") == []


@pytest.mark.slow
def test_symlink_is_judged_by_its_target(tmp_path):
    user = tmp_path / "target"
    user.mkdir()
    (user / "notes.txt").write_text("keep")
    link = tmp_path / "link"
    link.symlink_to(user)
    one_error_line(cli(FAST + ["--out", link]), 2, "out", str(user))
    assert (user / "notes.txt").read_text() == "keep" and link.is_symlink()


@pytest.mark.parametrize("out", ["", ".", "/", "~", "/proc", "geometry", "pipeline", ".git", ".."])
def test_protected_folders_are_refused_before_any_work(out):
    before = {p.name for p in ROOT.iterdir()}
    proc = cli(FAST + ["--out", out])
    one_error_line(proc, 2, "out", "refusing")
    assert {p.name for p in ROOT.iterdir()} == before


@pytest.mark.slow
def test_out_dot_in_a_scratch_copy_deletes_nothing(tmp_path):
    """From a scratch copy of the code: --out . and --out '' leave every file as it was."""
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    for name in ("pipeline", "geometry", "cases"):
        fresh_copy(ROOT / name, scratch / name)
    (scratch / "mywork.txt").write_text("precious")
    before = snapshot(scratch)
    env = dict(os.environ, PYTHONPATH=str(scratch))
    for out in (".", ""):
        proc = subprocess.run([PY, "-m", "pipeline", *FAST, "--out", out], cwd=scratch, env=env,
                              capture_output=True, text=True, timeout=120)
        one_error_line(proc, 2, "out", "refusing")
    after = snapshot(scratch)
    assert {k: v for k, v in after.items() if "__pycache__" not in k} == \
        {k: v for k, v in before.items() if "__pycache__" not in k}


@pytest.mark.slow
def test_one_kind_of_results_is_never_written_over_another(tmp_path, earlier):
    """A run (or converge) pointed at a design study's folder would have replaced it, its
    finished variants with it; a study pointed at a run's folder wrote its report.md over
    the run's. Both are refused before any work and leave every file as it was; each kind
    still replaces or resumes its own (the other tests)."""
    run_out = fresh_copy(earlier, tmp_path / "run")
    study = tmp_path / "study"
    assert cli(["sweep", "--size", "05", "--dim", "rf=1,2", "--mesh-factor", "3", "--levels", "1",
                "--quiet", "--out", study]).returncode == 0
    before = {p: snapshot(p) for p in (run_out, study)}
    one_error_line(cli(FAST + ["--out", study]), 2, "out", "a design study's results, not a run's")
    one_error_line(cli(["converge", "--size", "05", "--mesh-factor", "3", "--levels", "4", "--out", study]), 2,
                   "out", "a design study's results")
    one_error_line(cli(["sweep", "--size", "05", "--dim", "rf=1,2", "--mesh-factor", "3", "--levels", "1",
                        "--out", run_out]), 2, "out", "a run's results, not a design study's")
    assert {p: snapshot(p) for p in (run_out, study)} == before
    assert debris(tmp_path, "run") == [] and debris(tmp_path, "study") == []


@pytest.mark.slow
def test_an_empty_folder_and_our_own_results_are_replaced(tmp_path, earlier):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert cli(FAST + ["--out", empty, "--quiet"]).returncode == 0
    assert (empty / ".crosshead-results").is_file()
    ours = fresh_copy(earlier, tmp_path / "ours")
    (ours / "results.json").write_text("{}")  # replaced by the new run's
    assert cli(FAST + ["--out", ours, "--quiet"]).returncode == 0
    assert (ours / "results.json").read_text() != "{}"
    assert debris(tmp_path, "ours") == [] and debris(tmp_path, "empty") == []


# ------------------------------------------------------------------ 2. interrupts

def start(args: list[str], launcher_ranks: int | None = None) -> subprocess.Popen:
    cmd = [PY, "-m", "pipeline", *map(str, args)] if launcher_ranks is None else \
        [PY, "-m", "pipeline.runtime.launch", str(launcher_ranks), *map(str, args)]
    return subprocess.Popen(cmd, cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def wait_for_staging(parent: Path, name: str, proc: subprocess.Popen, timeout: float = 120) -> None:
    t0 = time.monotonic()
    while not list(parent.glob(f".{name}.*.partial")):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout
        time.sleep(0.05)
    time.sleep(1.0)  # well inside the run: pilot meshing or solving


@pytest.mark.slow
@pytest.mark.parametrize("sig,code,word", [(signal.SIGINT, 130, "interrupted"),
                                           (signal.SIGTERM, 143, "terminated")])
@pytest.mark.parametrize("ranks", [None, 2], ids=["one-process", "mpi-2-ranks"])
def test_signal_mid_run_cleans_up_and_keeps_the_earlier_result(tmp_path, earlier, sig, code, word, ranks):
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    proc = start(SLOW + ["--out", out], launcher_ranks=ranks)
    wait_for_staging(tmp_path, "res", proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    lines = [ln for ln in err.strip().splitlines() if ln and not PROGRESS.match(ln)]
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in err, err
    assert snapshot(out) == before
    assert debris(tmp_path, "res") == []


@pytest.mark.parametrize("sig,code,word", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
@pytest.mark.parametrize("module,args", [("pipeline", []), ("pipeline.runtime.launch", ["2"])])
def test_a_stop_while_the_program_loads_says_so_in_one_line(tmp_path, sig, code, word, module, args):
    """Ctrl-C or SIGTERM before the run's own stop is set up ends the process with its
    status and one line, not Python's traceback or silence."""
    out = tmp_path / "res"
    p = subprocess.run([PY, str(ROOT / "tests" / "helpers" / "stop_while_loading.py"), sig, module, *args,
                        *map(str, FAST), "--out", str(out)],
                       cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=120)
    assert p.returncode == code, p.stderr
    lines = [ln for ln in p.stderr.strip().splitlines() if ln and not PROGRESS.match(ln)]
    assert len(lines) == 1 and word in lines[0] and "nothing written" in lines[0], p.stderr
    assert "Traceback" not in p.stderr
    assert sorted(os.listdir(tmp_path)) == []


@pytest.mark.slow
def test_staging_left_by_sigkill_is_removed_by_the_next_run(tmp_path, earlier):
    out = fresh_copy(earlier, tmp_path / "res")
    proc = start(SLOW + ["--out", out])
    wait_for_staging(tmp_path, "res", proc)
    proc.kill()
    proc.communicate()
    assert any(n.endswith(".partial") for n in debris(tmp_path, "res"))
    again = cli(FAST + ["--out", out])
    assert again.returncode == 0, again.stderr
    assert "removed" in (again.stdout + again.stderr)
    assert debris(tmp_path, "res") == []


@pytest.mark.slow
def test_a_stopped_sweep_says_it_keeps_what_it_finished_and_resumes(tmp_path):
    """Ctrl-C in a study after its first variant is finished: its folder keeps the finished
    variants (it is resumable), so the line says so, not "nothing written" nor that one
    variant's results were written (each variant publishes its own folder); the lock
    beside the folder is gone; the same command then finishes the study."""
    out = tmp_path / "study"
    args = ["sweep", "--size", "05", "--dim", "rf=0.8,1.0,1.5,2.0", "--mesh-factor", "3", "--levels", "1",
            "--out", out]
    proc = start(args)
    t0 = time.monotonic()
    while not list(out.glob("variants/*/results.json")):
        assert proc.poll() is None and time.monotonic() - t0 < 120, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = [ln for ln in err.strip().splitlines() if not PROGRESS.match(ln)]
    assert len(lines) == 1 and "resumes" in lines[0] and str(out) in lines[0], err
    assert debris(tmp_path, "study") == []
    again = cli(args[:-2] + ["--out", out, "--quiet"])
    assert again.returncode == 0, again.stderr
    rows = json.loads((out / "sweep.json").read_text(encoding="utf-8"))["rows"]
    assert [r["status"] for r in rows] == ["done"] * 4


def stopped_at_the_end(out: Path, when: str, load_N: float) -> subprocess.CompletedProcess:
    """FAST at ``load_N`` with tests/helpers/stop_while_writing.py's stop ``when``."""
    return subprocess.run([PY, str(ROOT / "tests" / "helpers" / "stop_while_writing.py"), when, *map(str, FAST),
                           "--load", str(load_N), "--out", str(out)],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_a_stop_while_the_run_still_writes_keeps_the_earlier_result(tmp_path, earlier):
    """Ctrl-C when every file is staged, the main thread still writing into the staging
    folder: the stop removes the staging folder whole (none of the late files revives it)
    and the earlier result stays as it was. A clean-up racing the writes would leave a
    staging folder without its mark for good, or let the main thread's failure speak
    (exit 2 or 3) instead of the stop."""
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    proc = stopped_at_the_end(out, "writing", 12_000.0)
    one_error_line(proc, 130, "interrupted", "nothing written")
    assert snapshot(out) == before
    assert debris(tmp_path, "res") == []


@pytest.mark.slow
def test_a_stop_during_a_solve_acts_before_the_solve_ends(tmp_path, earlier):
    """Ctrl-C as the first Krylov solve starts (tests/helpers/stop_while_solving.py): the stop's
    clean-ups run while that solve is still iterating (PETSc's reason 0), the solve never
    ends, and the earlier result stays. PETSc's solve holds the interpreter lock to its
    end unless a monitor lets the stop in at every iteration (docs/decisions/0016-stops.md);
    without it the clean-ups would find the solver already destroyed."""
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    where = tmp_path / "where.txt"
    proc = subprocess.run([PY, str(ROOT / "tests" / "helpers" / "stop_while_solving.py"), str(where), *map(str, FAST),
                           "--load", "12000", "--out", str(out)],
                          cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=120)
    one_error_line(proc, 130, "interrupted", "nothing written")
    assert re.fullmatch(r"reason 0 at iteration \d+", where.read_text().strip()), where.read_text()
    assert snapshot(out) == before and debris(tmp_path, "res") == []


@pytest.mark.slow
def test_a_stop_during_publication_waits_for_it_and_says_so(tmp_path, earlier):
    """Ctrl-C just as the finished result replaces the earlier one: the stop waits for the
    replacement (two renames) and then says the results were written, instead of claiming
    that nothing was; the new result is whole (its load, its marker), nothing beside it."""
    out = fresh_copy(earlier, tmp_path / "res")
    proc = stopped_at_the_end(out, "publishing", 12_000.0)
    line = one_error_line(proc, 130, "interrupted", "already written", str(out))
    assert "nothing written" not in line
    res = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert res["case"]["load_N"] == pytest.approx(12_000.0)
    assert (out / ".crosshead-results").is_file()
    assert debris(tmp_path, "res") == []


# ------------------------------------------------------------------ 3. two runs, one folder

@pytest.mark.slow
def test_second_run_to_a_folder_being_written_exits_2_naming_the_other(tmp_path, earlier):
    out = fresh_copy(earlier, tmp_path / "res")
    first = start(SLOW + ["--out", out])
    wait_for_staging(tmp_path, "res", first)
    second = cli(FAST + ["--out", out])
    line = one_error_line(second, 2, "out", str(out), "another run", f"pid {first.pid}")
    first.communicate(timeout=300)
    assert first.returncode == 0, line
    assert (out / ".crosshead-results").is_file() and debris(tmp_path, "res") == []


# ------------------------------------------------------------------ 4. failures are one line

@pytest.mark.slow
def test_closed_stdout_does_not_lose_the_result(tmp_path):
    out = tmp_path / "res"
    proc = subprocess.Popen([PY, "-m", "pipeline", *FAST, "--out", str(out)], cwd=ROOT, env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.readline()  # like `| head -n 1`: read one line, then close the pipe
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 0, err
    assert "Traceback" not in err
    assert (out / "results.json").is_file() and (out / ".crosshead-results").is_file()


@pytest.mark.slow
def test_disk_full_is_exit_2_with_nothing_written(tmp_path, earlier, monkeypatch, capsys):
    """The disk fills up while results.json is written (in-process: a file-size limit would
    also stop MPI's shared-memory start-up): exit 2, one line, nothing written, and the
    parent folders the run created are gone again."""
    import pipeline.output.folder
    from pipeline import cli as cli_main

    def full(path, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    monkeypatch.setattr(pipeline.output.folder, "write_json", full)
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    for target in (out, tmp_path / "a" / "b" / "c"):
        code = cli_main.main([*FAST, "--out", str(target), "--quiet"])
        err = capsys.readouterr().err
        assert code == 2 and len([ln for ln in err.strip().splitlines() if not PROGRESS.match(ln)]) == 1, err
        assert "out: cannot write" in err and "No space left" in err and "nothing written" in err
    assert snapshot(out) == before and debris(tmp_path, "res") == []
    assert not (tmp_path / "a").exists()


@pytest.mark.slow
def test_a_failed_replacement_puts_the_earlier_result_back(tmp_path, earlier, monkeypatch, capsys):
    """Publishing is two renames (the earlier result aside, the new one in). When the
    second fails, the earlier result goes back in its place: left aside, the next run to
    the folder would remove it as a leftover. Exit 2, one line, nothing beside it."""
    from pipeline import cli as cli_main
    rename = Path.rename

    def second_fails(self, target):
        if str(self).endswith(".partial") and Path(target).name == "res":
            raise OSError(errno.EXDEV, os.strerror(errno.EXDEV), str(self))
        return rename(self, target)
    monkeypatch.setattr(Path, "rename", second_fails)
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    code = cli_main.main([*FAST, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len([ln for ln in err.strip().splitlines() if not PROGRESS.match(ln)]) == 1 \
        and "nothing written" in err, err
    assert snapshot(out) == before and debris(tmp_path, "res") == []


# ------------------------------------------------------------------ 5. one MPI rank fails alone

def one_rank_fails(out: Path, how: str) -> tuple[subprocess.CompletedProcess, float]:
    """FAST on 2 ranks with tests/helpers/one_rank_fails.py's failure ``how``: (process, seconds)."""
    cmd = [shutil.which("mpirun"), "--allow-run-as-root", "--oversubscribe", "--quiet", "-n", "2", PY,
           str(ROOT / "tests" / "helpers" / "one_rank_fails.py"), how, *map(str, FAST), "--out", str(out)]
    t0 = time.monotonic()
    proc = subprocess.run(cmd, cwd=ROOT, env=dict(os.environ), capture_output=True, text=True, timeout=120)
    return proc, time.monotonic() - t0


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not installed")
@pytest.mark.parametrize("failing_rank", [0, 1])
def test_a_failure_on_one_rank_ends_every_rank_with_one_line(tmp_path, earlier, failing_rank):
    """One rank raises before a solve that the other has entered (tests/helpers/one_rank_fails.py).
    Without pipeline.runtime.rankfailure the other rank would wait in the solve's
    collectives for ever; the run ends within seconds, exit 3, one line naming the
    failure, the earlier result as it was and nothing left beside it."""
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    proc, seconds = one_rank_fails(out, str(failing_rank))
    one_error_line(proc, 3, "failure", "RuntimeError", f"injected on rank {failing_rank} alone",
                   "nothing written")
    assert seconds < 60
    assert snapshot(out) == before
    assert debris(tmp_path, "res") == []


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun not installed")
def test_a_failure_while_rank_0_cannot_listen_still_ends_the_run(tmp_path, earlier):
    """Rank 1 fails while rank 0 holds Python's lock in a long C call, so its listener
    cannot take the line: after HAND_OVER_WAIT_S rank 1 writes it and ends, mpirun ends
    rank 0 (exit 3, one line, the earlier result as it was), and the staging folder rank 0
    could not remove is removed by the next run to the same folder."""
    from pipeline.runtime.rankfailure import HAND_OVER_WAIT_S, SAME_FAILURE_WAIT_S
    out = fresh_copy(earlier, tmp_path / "res")
    before = snapshot(out)
    proc, seconds = one_rank_fails(out, "1:busy")
    one_error_line(proc, 3, "failure", "RuntimeError", "injected on rank 1 alone", "nothing written")
    assert SAME_FAILURE_WAIT_S + HAND_OVER_WAIT_S <= seconds < 60
    assert snapshot(out) == before
    again = cli(FAST + ["--out", out])
    assert again.returncode == 0, again.stderr
    assert debris(tmp_path, "res") == []
