"""A user's files survive every run, and only the tool's own marker makes a folder the tool's
(docs/design.md §8, pipeline/runtime/outdir.py).

- a re-run carries over the files the user added to a results folder (a file, a ParaView
  state in a subfolder); a user's file with a name a run writes is refused up front;
- an empty, unreadable, foreign or folder marker does not make a folder the tool's;
- a run killed between its two renames loses nothing: the next run finishes the carry-over
  or puts the earlier result back; another folder's staging folder is not a leftover;
- folder names up to 255 bytes work; results folders get 0777 and files 0666 under the umask;
- a bind mount is a mount point; ``--out`` inside a design study is refused naming the study;
- ``make clean`` keeps a user's files and folders that only look like the tool's.

The runs are real subprocesses on coarse meshes (a few seconds each).
"""
from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
FAST = ["run", "--size", "05", "--mesh-factor", "3", "--levels", "1", "--no-fields"]
ENV = dict(os.environ, PYTHONPATH=str(ROOT), CROSSHEAD_NO_CACHE="1")
MARKER = ".crosshead-results"  # docs/design.md §8 names it; spelled out, not imported


def cli(args: list, cwd: Path = ROOT, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([PY, "-m", "pipeline", *map(str, args)], cwd=cwd, env=kw.pop("env", ENV),
                          capture_output=True, text=True, timeout=300, **kw)


def one_error_line(proc: subprocess.CompletedProcess, code: int, *words: str) -> str:
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every entry under ``folder`` (relative path -> content; None for a folder)."""
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes())
            for p in sorted(folder.rglob("*"))}


def load_of(out: Path) -> float:
    return json.loads((out / "results.json").read_text(encoding="utf-8"))["case"]["load_N"]


@pytest.fixture(scope="module")
def earlier(tmp_path_factory) -> Path:
    """A finished results folder at Q = 5000 N."""
    out = tmp_path_factory.mktemp("earlier") / "res"
    proc = cli(FAST + ["--load", "5000", "--out", out, "--quiet"])
    assert proc.returncode == 0, proc.stderr
    return out


# ------------------------------------------------------------------ a re-run keeps the user's files

@pytest.mark.slow
def test_a_rerun_keeps_the_files_the_user_added(tmp_path, earlier):
    """notes.txt and sub/view.pvsm survive the re-run and the next one, byte for byte."""
    out = tmp_path / "res"
    shutil.copytree(earlier, out)
    (out / "notes.txt").write_text("my notes\n")
    (out / "sub").mkdir()
    (out / "sub" / "view.pvsm").write_text("<ParaView/>\n")
    proc = cli(FAST + ["--load", "20000", "--out", out, "--quiet"])
    assert proc.returncode == 0, proc.stderr
    assert load_of(out) == 20000.0  # the new result, the load given on the command line
    assert (out / "notes.txt").read_text() == "my notes\n"
    assert (out / "sub" / "view.pvsm").read_text() == "<ParaView/>\n"
    assert sorted(os.listdir(tmp_path)) == ["res"]  # nothing set aside or left beside it
    again = cli(FAST + ["--load", "10000", "--out", out, "--quiet"])  # and on the next re-run
    assert again.returncode == 0, again.stderr
    assert (out / "notes.txt").read_text() == "my notes\n" and load_of(out) == 10000.0


@pytest.mark.slow
def test_a_users_file_with_a_name_a_run_writes_is_refused_up_front(tmp_path, earlier):
    """A --no-fields run wrote no peaks.png; the user's peaks.png would be overwritten by a
    run with fields: refused before any work, named, everything as it was."""
    out = tmp_path / "res"
    shutil.copytree(earlier, out)
    (out / "peaks.png").write_bytes(b"mine")
    before = snapshot(out)
    one_error_line(cli(FAST + ["--out", out]), 2, "out", "peaks.png", "overwrite")
    assert snapshot(out) == before and sorted(os.listdir(tmp_path)) == ["res"]


@pytest.mark.parametrize("marker", ["", "{}", "not json", '{"tool": "paraview"}', "[1, 2]", "folder"])
def test_a_marker_that_is_not_the_tools_does_not_make_a_folder_the_tools(tmp_path, marker):
    """An entry named .crosshead-results that is not the tool's JSON leaves the user's folder
    the user's: refused, every file as it was, nothing (.<name>.old-PID) beside it."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("x\n")
    (out / "results.json").write_text("{}\n")  # even beside a file of a run's name
    if marker == "folder":
        (out / MARKER).mkdir()
    else:
        (out / MARKER).write_text(marker)
    before = snapshot(out)
    one_error_line(cli(FAST + ["--out", out]), 2, "out", str(out), "marker")
    assert snapshot(out) == before and sorted(os.listdir(tmp_path)) == ["mine"]


# ------------------------------------------------------------------ killed runs' leftovers

def _tool_folder(folder: Path, files: dict[str, str], listed: list[str]) -> Path:
    folder.mkdir()
    for name, text in files.items():
        (folder / name).write_text(text)
    (folder / MARKER).write_text(json.dumps({"tool": "crosshead", "files": listed}) + "\n")
    return folder


def test_a_run_killed_after_publishing_gives_the_users_files_to_the_next(tmp_path):
    """Killed between the publication and the carry-over: the earlier folder, set aside as
    .res.old-PID, still holds the user's notes: the next run moves them in, not deletes them."""
    from pipeline.runtime.outdir import remove_leftovers
    out = _tool_folder(tmp_path / "res", {"results.json": "new"}, ["results.json"])
    old = _tool_folder(tmp_path / ".res.old-4242", {"results.json": "old", "notes.txt": "mine"}, ["results.json"])
    (old / "sub").mkdir()
    (old / "sub" / "view.pvsm").write_text("state")
    remove_leftovers(out)
    assert not old.exists()
    assert (out / "notes.txt").read_text() == "mine" and (out / "sub" / "view.pvsm").read_text() == "state"
    assert (out / "results.json").read_text() == "new"


def test_a_run_killed_between_its_renames_gets_the_earlier_result_back(tmp_path):
    """Killed after setting the earlier result aside, the new one not yet in place: the next
    run puts it back instead of deleting it as a leftover."""
    from pipeline.runtime.outdir import remove_leftovers
    out = tmp_path / "res"
    _tool_folder(tmp_path / ".res.old-4242", {"results.json": "old", "notes.txt": "mine"}, ["results.json"])
    remove_leftovers(out)
    assert (out / "results.json").read_text() == "old" and (out / "notes.txt").read_text() == "mine"
    assert sorted(os.listdir(tmp_path)) == ["res"]


def test_another_folders_staging_folder_is_not_a_leftover(tmp_path):
    """``res.x``'s staging folder starts with ``.res.``; a run to ``res`` must not take it for
    its own (the glob ``.res.*`` matches it: a running run's staging folder)."""
    from pipeline.runtime.outdir import remove_leftovers
    other = tmp_path / ".res.x.abcd1234.partial"
    other.mkdir()
    (other / ".crosshead-staging").write_text("pid 1\n")
    own = tmp_path / ".res.wxyz9876.partial"
    own.mkdir()
    (own / ".crosshead-staging").write_text("pid 2\n")
    removed = remove_leftovers(tmp_path / "res")
    assert removed == [own] and other.is_dir() and not own.exists()


# ------------------------------------------------------------------ names, modes, mounts, studies

@pytest.mark.slow
@pytest.mark.parametrize("name", ["L" * 255, "é" * 120 + "L" * 15], ids=["255-ascii", "255-bytes-utf8"])
def test_a_folder_name_of_255_bytes_can_be_an_output_folder(tmp_path, name):
    """The names beside the folder (lock, staging, set-aside) must fit 255 bytes too: the
    name plus ".lock" or ".XXXXXXXX.partial" does not for names of 241-255 bytes."""
    assert len(name.encode()) == 255
    out = tmp_path / name
    proc = cli(FAST + ["--out", out, "--quiet"])
    assert proc.returncode == 0, proc.stderr
    assert (out / "results.json").is_file() and (out / MARKER).is_file()
    assert os.listdir(tmp_path) == [name]
    again = cli(FAST + ["--out", out, "--quiet"])  # a re-run sets the earlier aside beside it
    assert again.returncode == 0, again.stderr
    assert os.listdir(tmp_path) == [name]


@pytest.mark.slow
@pytest.mark.parametrize("umask,folder_mode,file_mode", [(0o022, 0o755, 0o644), (0o002, 0o775, 0o664)],
                         ids=["umask-022", "umask-002"])
def test_results_get_the_modes_the_umask_gives(tmp_path, umask, folder_mode, file_mode):
    """Like mkdir and any editor: folders 0777, files 0666, less the umask (not the staging
    folder's private 0700 from mkdtemp)."""
    out = tmp_path / "a" / "res"
    proc = subprocess.run([PY, "-m", "pipeline", *FAST, "--out", str(out), "--quiet"], cwd=ROOT, env=ENV,
                          capture_output=True, text=True, timeout=300, umask=umask)
    assert proc.returncode == 0, proc.stderr
    assert (out.stat().st_mode & 0o777, out.parent.stat().st_mode & 0o777) == (folder_mode, folder_mode)
    assert {p.name: p.stat().st_mode & 0o777 for p in out.iterdir()} == \
        {p.name: file_mode for p in out.iterdir()}


def _can_bind_mount() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-rm", "true"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _can_bind_mount(), reason="needs unshare -rm (user and mount namespaces)")
def test_a_bind_mount_on_the_same_file_system_is_a_mount_point(tmp_path):
    """A bind mount has its parent's device number, so os.path.ismount misses it: refused
    before any work, not at the end ("Device or resource busy" when renaming it)."""
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    dst.mkdir()
    (src / "data.txt").write_text("x\n")
    script = 'mount --bind "$1" "$2" && shift 2 && exec "$@"'
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script, "sh", str(src), str(dst), PY, "-m", "pipeline",
                           *FAST, "--out", str(dst)], cwd=ROOT, env=ENV, capture_output=True, text=True,
                          timeout=300)
    line = one_error_line(proc, 2, "out", str(dst), "mount point")
    assert "busy" not in line
    assert sorted(os.listdir(src)) == ["data.txt"] and sorted(os.listdir(tmp_path)) == ["dst", "src"]


def test_the_mount_table_is_read_with_its_escapes(tmp_path):
    """/proc/self/mountinfo writes a space in a mount point as \\040."""
    from pipeline.runtime.folders import mount_points
    table = tmp_path / "mountinfo"
    table.write_text("22 1 0:21 / / rw - ext4 /dev/vda rw\n"
                     "63 22 254:0 /data/a /srv/my\\040data rw,relatime - ext4 /dev/vda rw\n")
    assert mount_points(table) == {Path("/"), Path("/srv/my data")}


@pytest.fixture
def study(tmp_path, earlier) -> Path:
    """A design study's folder as docs/design.md §8 describes it: its marker says
    "sweep": true, and each finished variant is a run's folder under variants/."""
    folder = tmp_path / "study"
    (folder / "variants").mkdir(parents=True)
    (folder / MARKER).write_text('{"tool": "crosshead", "sweep": true}\n')
    shutil.copytree(earlier, folder / "variants" / "0123456789ab")
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("inside", ["variants/0123456789ab", "variants/new", "elsewhere/deeper"])
def test_a_run_inside_a_design_study_is_refused_naming_the_study(study, inside):
    """A run in variants/<key> (the variant carries a run marker) would be reported by the
    study's next resume as that variant's numbers: refused, naming the study."""
    before = snapshot(study)
    for command in (FAST, ["converge", "--size", "05", "--mesh-factor", "3", "--levels", "4"],
                    ["sweep", "--size", "05", "--dim", "rf=1,2", "--mesh-factor", "3", "--levels", "1"]):
        one_error_line(cli(command + ["--out", study / inside]), 2, "out", "design study", str(study))
    assert snapshot(study) == before
    assert sorted(os.listdir(study.parent)) == ["study"]


# ------------------------------------------------------------------ make clean

@pytest.mark.slow
def test_make_clean_keeps_what_the_tool_did_not_write(tmp_path, earlier):
    """Only the tool's JSON marker makes a folder removable, only the files it lists are
    removed (a user's notes inside stay), and the lock of a run still writing stays."""
    results = tmp_path / "results"
    results.mkdir()
    run = results / "05"
    shutil.copytree(earlier, run)
    (run / "notes.txt").write_text("mine\n")
    plain = results / "06"
    shutil.copytree(earlier, plain)
    fake = results / "fake"
    fake.mkdir()
    (fake / MARKER).write_text("")
    (fake / "thesis.tex").write_text("x\n")
    dirmark = results / "dirmark"
    (dirmark / MARKER).mkdir(parents=True)
    (results / ".gone.lock").write_text("pid 1\n")
    held = results / ".busy.lock"
    held.write_text("pid 2\n")
    fd = os.open(held, os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        proc = subprocess.run(["make", "-f", str(ROOT / "Makefile"), "clean", f"PY={PY}"], cwd=tmp_path,
                              env=ENV, capture_output=True, text=True, timeout=120)
    finally:
        os.close(fd)
    assert proc.returncode == 0, proc.stderr
    assert not plain.exists() and not (results / ".gone.lock").exists()
    assert sorted(p.name for p in run.iterdir()) == [MARKER, "notes.txt"]
    assert (run / "notes.txt").read_text() == "mine\n"
    assert sorted(p.name for p in fake.iterdir()) == [MARKER, "thesis.tex"] and (dirmark / MARKER).is_dir()
    assert held.exists()
    for name in ("05", "fake", "dirmark", ".busy.lock"):
        assert f"results/{name}" in proc.stdout, proc.stdout


def test_clean_removes_a_studys_files_and_keeps_a_users_file_among_its_variants(tmp_path):
    """A design study's folder (docs/design.md §8: its marker says "sweep": true): its table,
    report, plots, variants' run folders and failure notes go; a user's file in variants/
    stays, named, with the folders that hold it."""
    from pipeline.runtime.folders import clean
    results = tmp_path / "results"
    study = results / "study"
    variant = study / "variants" / "0123456789ab"
    variant.mkdir(parents=True)
    (variant / "results.json").write_text("{}\n")
    (variant / MARKER).write_text('{"tool": "crosshead", "files": ["results.json"]}\n')
    (study / "variants" / "fedcba987654.failed.json").write_text("{}\n")
    (study / "variants" / "notes.txt").write_text("mine\n")
    for name in ("sweep.csv", "sweep.json", "report.md", "peak_vs_rf.png"):
        (study / name).write_text("x\n")
    (study / MARKER).write_text('{"tool": "crosshead", "sweep": true}\n')
    said = []
    clean(results, said.append)
    assert snapshot(results) == {"study": None, f"study/{MARKER}": b'{"tool": "crosshead", "sweep": true}\n',
                                 "study/variants": None, "study/variants/notes.txt": b"mine\n"}
    assert len(said) == 1 and "results/study" in said[0] and "variants/notes.txt" in said[0], said
    (study / "variants" / "notes.txt").unlink()
    clean(results, said.append)
    assert not results.exists()
