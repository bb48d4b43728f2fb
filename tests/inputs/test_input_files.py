"""The files a user gives (case files, study files) are read through one guarded reader
(pipeline/inputs/tomlfile.py): regular files only, at most 1 MiB, nested a few levels
deep. Anything else is refused with exit 2 and one line naming the file, before it can
hang the command (a FIFO), read without end (/dev/zero), or exhaust the stack (5000
nested arrays or tables gave exit 3 with a RecursionError). The lists of values
(pipeline/inputs/valuelist.py): two values equal to round-off are one value, -0.0 is 0.0.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from pipeline import cli
from pipeline.errors import InputError
from pipeline.inputs.case import read_case_file
from pipeline.inputs.valuelist import parse_loads, parse_values
from pipeline.study.plan import read_study

ROOT = Path(__file__).resolve().parents[2]
STUDY = '[sweep]\nsize = "05"\ndims = { rf = "1,1.5" }\n'
# Nested 5000 deep, each as the probe wrote it: arrays, inline tables, dotted keys.
DEEP = {"arrays": "x = " + "[" * 5000 + "]" * 5000 + "\n",
        "inline tables": "x = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n",
        "dotted keys": ".".join(["a"] * 5000) + " = 1\n"}


def call_main(argv: list[str]) -> tuple[int, str]:
    """(exit status, stderr) of the command line run in this process."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's usage errors
            code = exc.code if isinstance(exc.code, int) else 1
    return code, err.getvalue()


def one_line(code: int, stderr: str, *words: str) -> str:
    """Exit 2 and one line on stderr holding every word of ``words``."""
    assert code == 2, (code, stderr)
    lines = stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.mark.parametrize("kind", DEEP)
def test_deep_nesting_is_refused_with_one_line_naming_the_file(tmp_path, kind):
    """5000 levels of nesting in a study file or a case file: refused as input naming the
    file (tomllib recursed once per level: RecursionError, exit 3)."""
    study, case = tmp_path / "study.toml", tmp_path / "case.toml"
    study.write_text('[sweep]\nsize = "05"\n' + DEEP[kind])
    case.write_text('size = "05"\n' + DEEP[kind])
    with pytest.raises(InputError, match=f"^study: {study} nests tables or arrays more than 16 deep"):
        read_study(study)
    with pytest.raises(InputError, match=f"^case: {case} nests tables or arrays more than 16 deep"):
        read_case_file(case)
    out = tmp_path / "out"
    one_line(*call_main(["sweep", "--study", study, "--out", out]), "study", str(study), "deep")
    one_line(*call_main(["run", "--case", case, "--out", out]), "case", str(case), "deep")
    assert not out.exists()


def test_a_fifo_is_refused_without_opening_it_for_a_blocking_read(tmp_path):
    """A FIFO as the study file or the case file: refused at once (a read of it waited for
    a writer that never came: the command hung)."""
    fifo = tmp_path / "study.fifo"
    os.mkfifo(fifo)
    for reader, what in ((read_study, "study"), (read_case_file, "case")):
        said: list[BaseException] = []

        def read(reader=reader, said=said) -> None:
            try:
                reader(fifo)
            except BaseException as exc:  # noqa: BLE001 - handed to the test's thread
                said.append(exc)
        t = threading.Thread(target=read, daemon=True)
        t.start()
        t.join(20)
        if t.is_alive():  # hung in open(): a writer that closes at once lets it go on
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            t.join(20)
            pytest.fail(f"reading a FIFO as the {what} file blocked")
        assert isinstance(said[0], InputError) and str(said[0]) == \
            f"{what}: cannot read {fifo}: not a regular file (a FIFO)", said


def test_a_device_is_refused_before_a_byte_is_read():
    """/dev/null is a character device: refused as not a regular file (the study reader
    took it for an empty file). /dev/zero, which it read without limit, is tried in a
    process of bounded memory below; the case reader here."""
    for reader, what, device in ((read_study, "study", "/dev/null"), (read_case_file, "case", "/dev/null"),
                                 (read_case_file, "case", "/dev/zero")):
        with pytest.raises(InputError) as exc:
            reader(Path(device))
        assert str(exc.value) == f"{what}: cannot read {device}: not a regular file (a character device)"


def test_dev_zero_as_a_study_file_ends_with_one_line_in_a_process_of_bounded_memory():
    """The command as a shell sees it, in a process that may use 1.5 GiB of address space:
    exit 2 and one line, before any reading."""
    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29)); "
            "from pipeline.study.plan import read_study\n"
            "try:\n    read_study('/dev/zero')\nexcept Exception as e:\n    print(type(e).__name__, e); sys.exit(2)")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stdout == \
        "InputError study: cannot read /dev/zero: not a regular file (a character device)\n", (p.stdout, p.stderr)


def test_a_large_study_file_is_refused_with_the_limit_said(tmp_path):
    """A valid study followed by 50 MB of comment was read and planned; the limit (1 MiB)
    is in the line. A case file of the same size is refused the same way."""
    big = tmp_path / "big.toml"
    with big.open("w") as f:
        f.write(STUDY)
        f.write(("#" * 999 + "\n") * 50_000)
    assert big.stat().st_size > 50_000_000
    for reader, what in ((read_study, "study"), (read_case_file, "case")):
        with pytest.raises(InputError, match=f"^{what}: {big} is larger than 1 MiB"):
            reader(big)
    # Just within the limit: read.
    small = tmp_path / "small.toml"
    small.write_text(STUDY + "#" * ((1 << 20) - len(STUDY) - 1) + "\n")
    assert small.stat().st_size == 1 << 20 and read_study(small)["size"] == "05"


def test_a_study_file_s_relative_paths_are_taken_from_its_folder(tmp_path, monkeypatch):
    """``out`` and ``case`` in a study file name folders from the study file's folder,
    wherever the command starts (``out`` was taken from the working folder, a run's
    default from the repository: one study file wrote to two places)."""
    folder = tmp_path / "studies"
    folder.mkdir()
    study = folder / "s.toml"
    study.write_text(STUDY + 'out = "../results/s"\ncase = "base.toml"\n')
    for cwd in (tmp_path, folder, ROOT):
        monkeypatch.chdir(cwd)
        s = read_study(Path(os.path.relpath(study, cwd)))
        assert (cwd / s["out"]).resolve() == tmp_path / "results" / "s"
        assert (cwd / s["case"]).resolve() == folder / "base.toml"
    # An absolute path stays as it is; an empty one is refused.
    study.write_text(STUDY + f'out = "{tmp_path / "abs"}"\n')
    assert read_study(study)["out"] == tmp_path / "abs"
    study.write_text(STUDY + 'out = " "\n')
    with pytest.raises(InputError, match="^sweep.out: an empty path"):
        read_study(study)


def test_the_repository_s_study_file_writes_where_a_run_writes(monkeypatch, tmp_path):
    """cases/sweep-rf.toml's ``out`` is the repository's results/sweep-rf, started from
    anywhere: beside the default of a run (results/<name> in the repository)."""
    from pipeline.runtime.folders import default_out
    for cwd in (ROOT, tmp_path):
        monkeypatch.chdir(cwd)
        s = read_study(ROOT / "cases" / "sweep-rf.toml")
        assert s["out"].resolve() == default_out("sweep-rf") == ROOT / "results" / "sweep-rf"


@pytest.mark.parametrize("text, says", [
    ("1,1.0000000000000002", "1.0 and 1.0000000000000002 (equal to round-off) given twice"),
    ("-0.0,0", "0 given twice"),
    ("2,1.9999999999999998,3", "1.9999999999999998 and 2.0 (equal to round-off) given twice"),
])
def test_values_equal_to_round_off_are_one_value(text, says):
    """Two values a float's last bit apart are one variant, refused as a value given twice
    (they were analysed twice); so are -0.0 and 0."""
    with pytest.raises(InputError) as exc:
        parse_values(text, "dims.rf", 200)
    assert str(exc.value) == f"dims.rf: {text!r}: {says}"
    with pytest.raises(InputError, match="given twice"):
        parse_loads("10000,10000.000000000002")
    # Values that differ by far more than round-off are kept, however close.
    assert parse_values("1,1.000001", "dims.rf", 200) == [1.0, 1.000001]


def test_a_negative_zero_is_read_as_zero():
    """-0.0 is 0.0 with its sign bit set: it printed as -0 in the table and hashed to a key
    of its own. Read as 0.0."""
    for text in ("-0.0", "-0", "-0.0:1:2", "1,-0.0"):
        values = parse_values(text, "dims.x", 200)
        assert all(math.copysign(1.0, v) == 1.0 for v in values), (text, values)
        assert 0.0 in values
