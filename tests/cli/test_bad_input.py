"""Bad input never gets past validation (docs/design.md §7, §8).

Every bad case must give exit status 2, exactly one line on stderr naming the field and
the rule, no traceback, and nothing written: no --out folder and no hidden staging
folder beside it. Most cases run in-process through ``pipeline.cli.main`` with the
mesher/solver replaced by a tripwire (so a check that lets a bad case through fails the
test instead of starting a solve); a handful run as real subprocesses. Then property
tests: random case files into ``resolve()``, random argument lists into ``main()``.
A numerical failure gives exit status 3 and writes nothing either.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import pipeline.analysis.level
import pipeline.api
import pipeline.cli.summary
import pipeline.fe.solve
import pipeline.output.folder
from geometry.part import GeometryError
from pipeline import cli as cli_main
from pipeline.inputs.case import SCHEMA, Case, check, resolve
from pipeline.errors import InputError

from helpers.answers import answer

ROOT = Path(__file__).resolve().parents[2]
VALID_TOML = (ROOT / "cases" / "05.toml").read_text()


# --------------------------------------------------------------------------- helpers

def call_main(argv: list[str]) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of the CLI run in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli_main.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse usage errors
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


PROGRESS = re.compile(r"^\[\s*[0-9.]+ s\] ")  # a progress line's stamp: progress goes to stderr too


def assert_exit_2(code: int, stderr: str, expect: tuple[str, ...]) -> str:
    """Exit 2, one stderr line (besides progress lines) starting 'error:' and containing every
    expected word."""
    assert code == 2, (code, stderr)
    assert "Traceback" not in stderr
    lines = [ln for ln in stderr.splitlines() if not PROGRESS.match(ln)]
    assert len(lines) == 1 and stderr.endswith("\n"), stderr
    line = lines[0]
    assert line.startswith("error: "), line
    for word in expect:
        assert word in line, (word, line)
    return line


def listing(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


@pytest.fixture
def tripwire(monkeypatch):
    """Meshing or solving anything fails the test: validation must stop bad input first.

    ``run`` is what ``write_run`` calls inside ``staged_dir``, so the real output-folder
    checks still run before the wire.
    """
    def boom(*a, **k):
        raise AssertionError("bad input reached the mesher/solver")
    monkeypatch.setattr(pipeline.output.folder, "run", boom)


# --------------------------------------------------------------------------- corpus
# (id, argv after the command-less prefix, TOML text or None, expected words in the line)
# "{case}" in argv is replaced by the case file written from the TOML text; without
# "--out" in argv, "--out <tmp>/out" is added.

RUN = ["run", "--size", "05"]

CORPUS = [
    # dimensions and loads from the command line: negative, zero, NaN, infinite
    ("dim-negative", RUN + ["--dim", "b1=-45"], None, ("b1", "> 0")),
    ("dim-zero", RUN + ["--dim", "h3=0"], None, ("h3", "> 0")),
    ("dim-nan", RUN + ["--dim", "d2=nan"], None, ("d2", "finite")),
    ("dim-inf", RUN + ["--dim", "dj=inf"], None, ("dj", "finite")),
    ("dim-rf-negative", RUN + ["--dim", "rf=-1"], None, ("rf", ">= 0")),
    ("dim-not-a-number", RUN + ["--dim", "b1=abc"], None, ("--dim", "b1", "not a number")),
    ("dim-no-equals", RUN + ["--dim", "b1"], None, ("--dim", "NAME=VALUE")),
    ("dim-unknown-name", RUN + ["--dim", "zz=3"], None, ("--dim", "unknown dimension")),
    ("load-negative", RUN + ["--load", "-5"], None, ("load_N", "> 0")),
    ("load-zero", RUN + ["--load", "0"], None, ("load_N", "> 0")),
    ("load-nan", RUN + ["--load", "nan"], None, ("load_N", "finite")),
    ("load-inf", RUN + ["--load", "inf"], None, ("load_N", "finite")),
    ("load-overflow", RUN + ["--load", "1e400"], None, ("load_N", "finite")),
    ("load-not-a-number", RUN + ["--load", "ten"], None, ("--load", "not a number")),
    # the same in a case file
    ("toml-dim-negative", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nb2 = -12.5\n', ("b2", "> 0")),
    ("toml-dim-zero", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nh3 = 0\n', ("h3", "> 0")),
    ("toml-dim-nan", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nd14 = nan\n', ("d14", "finite")),
    ("toml-dim-inf", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nseat_outer = inf\n', ("seat_outer", "finite")),
    ("toml-load-negative", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = -10000\n', ("load_N", "> 0")),
    ("toml-load-zero", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = 0\n', ("load_N", "> 0")),
    ("toml-load-nan", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = nan\n', ("load_N", "finite")),
    ("toml-load-minus-inf", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = -inf\n', ("load_N", "finite")),
    # shape rules of geometry.table.validate (No. 05: b1 45, b2 12.5, b6 70, d14 31, d2 21,
    # h3 25, dj 20, rf 1.5, seat 25..37)
    ("bore-equals-body", RUN + ["--dim", "d2=45"], None, ("d2", "smaller than the body width")),
    ("bore-wider-than-body", RUN + ["--dim", "d2=60"], None, ("d2", "smaller than the body width")),
    ("seat-outside-body", RUN + ["--dim", "seat_outer=46"], None, ("seat_outer", "smaller than the body width")),
    ("seat-inside-bore", RUN + ["--dim", "seat_inner=20"], None, ("seat_inner", "larger than the bore")),
    ("seat-reversed", ["run", "--case", "{case}"],
     'size = "05"\n[dimensions]\nseat_inner = 38.0\nseat_outer = 37.0\n', ("seat_inner", "smaller than seat_outer")),
    ("track-outside-seat", RUN + ["--dim", "d14=40"], None, ("d14", "inside the seat annulus")),
    ("journal-exceeds-height", RUN + ["--dim", "dj=24"], None, ("dj, rf:", "h3/2")),
    ("journal-plus-fillet-exceeds-height", RUN + ["--dim", "rf=3"], None, ("dj, rf:", "dj/2 + rf", "h3/2")),
    ("fillet-longer-than-journal", RUN + ["--dim", "b2=1", "--dim", "b6=47"], None, ("rf", "shorter than the journal")),
    ("b6-mismatch", RUN + ["--dim", "b6=71"], None, ("b6", "b1 + 2*b2")),
    ("toml-b6-mismatch", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nb1 = 50.0\n', ("b6", "b1 + 2*b2")),
    # which hook
    ("unknown-size", ["run", "--size", "99"], None, ("size", "unknown hook number")),
    ("empty-size", ["run", "--size", ""], None, ("size", "unknown hook number")),
    ("no-size-no-case", ["run"], None, ("size", "--size")),
    ("toml-unknown-size", ["run", "--case", "{case}"], 'size = "7"\n', ("size", "unknown hook number")),
    ("toml-no-size", ["run", "--case", "{case}"], '[load]\nload_N = 10000.0\n', ("size", "no hook number")),
    # option values
    ("support-unknown", RUN + ["--support", "glued"], None, ("--support", "invalid choice")),
    ("model-unknown", RUN + ["--model", "half"], None, ("--model", "invalid choice")),
    ("solver-unknown", RUN + ["--solver", "cg"], None, ("--solver", "invalid choice")),
    ("order-7", RUN + ["--order", "7"], None, ("order", "1, 2 or 3")),
    ("order-0", RUN + ["--order", "0"], None, ("order", "1, 2 or 3")),
    ("order-not-int", RUN + ["--order", "two"], None, ("--order", "invalid int")),
    ("toml-support-unknown", ["run", "--case", "{case}"],
     'size = "05"\n[model]\nsupport = "glued"\n', ("support", "must be one of")),
    ("toml-model-unknown", ["run", "--case", "{case}"], 'size = "05"\n[model]\nmodel = "half"\n', ("model", "must be one of")),
    ("toml-solver-unknown", ["run", "--case", "{case}"], 'size = "05"\n[solver]\nsolver = "lu"\n', ("solver", "must be one of")),
    ("toml-order-5", ["run", "--case", "{case}"], 'size = "05"\n[mesh]\norder = 5\n', ("order", "1, 2 or 3")),
    ("E-zero", RUN + ["--E", "0"], None, ("E_MPa", "> 0")),
    ("E-negative", RUN + ["--E", "-210000"], None, ("E_MPa", "> 0")),
    ("nu-half", RUN + ["--nu", "0.5"], None, ("nu", "(-1, 0.5)")),
    ("nu-nan", RUN + ["--nu", "nan"], None, ("nu", "(-1, 0.5)")),
    ("allowable-negative", RUN + ["--allowable", "-80"], None, ("allowable_MPa", "> 0")),
    ("span-exact-negative", RUN + ["--span-exact", "-1"], None, ("exact_span_mm", "> 0")),
    ("span-approximate-inf", RUN + ["--span-approximate", "inf"], None, ("approximate_span_mm", "finite")),
    ("rtol-zero", RUN + ["--rtol", "0"], None, ("rtol", "> 0")),
    ("rtol-loose", RUN + ["--rtol", "0.01"], None, ("rtol", "below 1e-3")),
    ("rtol-nan", RUN + ["--rtol", "nan"], None, ("rtol", "finite")),
    # mesh factor and sizes
    ("mesh-factor-zero", RUN + ["--mesh-factor", "0"], None, ("mesh_factor", "> 0")),
    ("mesh-factor-negative", RUN + ["--mesh-factor", "-1"], None, ("mesh_factor", "> 0")),
    ("mesh-factor-tiny", RUN + ["--mesh-factor", "1e-9"], None, ("mesh_factor", "[0.05, 20]")),
    ("mesh-factor-huge", RUN + ["--mesh-factor", "1e9"], None, ("mesh_factor", "[0.05, 20]")),
    ("mesh-factor-nan", RUN + ["--mesh-factor", "nan"], None, ("mesh_factor", "finite")),
    ("mesh-factor-inf", RUN + ["--mesh-factor", "inf"], None, ("mesh_factor", "finite")),
    ("toml-mesh-factor-string", ["run", "--case", "{case}"], 'size = "05"\n[mesh]\nfactor = "fine"\n',
     ("mesh.factor", "expected int or float")),
    ("size-body-tiny", RUN + ["--size-body", "1e-9"], None, ("size_body_mm", "more elements")),
    ("size-body-larger-than-part", RUN + ["--size-body", "500"], None, ("size_body_mm", "larger than the part")),
    ("size-fillet-zero", RUN + ["--size-fillet", "0"], None, ("size_fillet_mm", "> 0")),
    ("size-feature-nan", RUN + ["--size-feature", "nan"], None, ("size_feature_mm", "finite")),
    ("grading-negative", RUN + ["--grading", "-1"], None, ("grading_mm", "> 0")),
    ("tiny-fillet-radius", RUN + ["--dim", "rf=1e-9"], None, ("size_fillet_mm", "more elements")),
    ("converge-finest-too-fine", ["converge", "--size", "05", "--levels", "8", "--ratio", "3"], None,
     ("levels", "finest mesh", "mesh_factor")),
    # levels and ratio
    ("levels-0", RUN + ["--levels", "0"], None, ("levels", "1..8")),
    ("levels-9", RUN + ["--levels", "9"], None, ("levels", "1..8")),
    ("levels-negative", RUN + ["--levels", "-1"], None, ("levels", "1..8")),
    ("levels-two", RUN + ["--levels", "2"], None, ("levels", "2 meshes give no error bar")),
    ("sweep-levels-two", ["sweep", "--size", "05", "--dim", "rf=1,2", "--levels", "2"], None,
     ("levels", "2 meshes give no error bar")),
    ("levels-not-int", RUN + ["--levels", "x"], None, ("--levels", "invalid int")),
    ("converge-levels-3", ["converge", "--size", "05", "--levels", "3"], None, ("levels", "at least 4")),
    ("converge-ratio-small", ["converge", "--size", "05", "--ratio", "1.2"], None, ("ratio", ">= 1.3")),
    ("ratio-1", RUN + ["--ratio", "1.0"], None, ("ratio", "[1.1, 3]")),
    ("ratio-nan", RUN + ["--ratio", "nan"], None, ("ratio", "[1.1, 3]")),
    # malformed case files
    ("toml-unclosed-section", ["run", "--case", "{case}"], 'size = "05"\n[load\nload_N = 1.0\n', ("case", "not valid TOML")),
    ("toml-leading-zero-number", ["run", "--case", "{case}"], 'size = 05\n', ("case", "not valid TOML")),
    ("toml-duplicate-key", ["run", "--case", "{case}"], 'size = "05"\nsize = "05"\n', ("case", "not valid TOML")),
    ("toml-garbage", ["run", "--case", "{case}"], "this is not = = a case file {{{\n", ("case", "not valid TOML")),
    ("toml-5000-digit-integer", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = ' + "9" * 5000 + "\n",
     ("case", "not valid TOML")),
    # wrong types
    ("toml-load-string", ["run", "--case", "{case}"],
     'size = "05"\n[load]\nload_N = "10000"\n', ("load.load_N", "expected int or float")),
    ("toml-load-bool", ["run", "--case", "{case}"],
     'size = "05"\n[load]\nload_N = true\n', ("load.load_N", "expected int or float")),
    ("toml-nu-list", ["run", "--case", "{case}"],
     'size = "05"\n[material]\nnu = [0.3]\n', ("material.nu", "expected int or float")),
    ("toml-size-number", ["run", "--case", "{case}"], 'size = 5\n', ("size", "expected str")),
    ("toml-dim-table", ["run", "--case", "{case}"], 'size = "05"\n[dimensions]\nb1 = {x = 1}\n', ("dimensions.b1", "expected")),
    ("toml-order-float", ["run", "--case", "{case}"], 'size = "05"\n[mesh]\norder = 2.0\n', ("mesh.order", "expected int")),
    ("toml-support-number", ["run", "--case", "{case}"],
     'size = "05"\n[model]\nsupport = 1\n', ("model.support", "expected str")),
    ("toml-date", ["run", "--case", "{case}"],
     'size = "05"\n[load]\nload_N = 1979-05-27\n', ("load.load_N", "expected int or float")),
    ("toml-integer-too-large", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload_N = ' + "9" * 400 + "\n",
     ("load.load_N", "too large")),
    # unknown keys and sections
    ("toml-unknown-section", ["run", "--case", "{case}"],
     'size = "05"\n[geometry]\nb1 = 45.0\n', ("geometry", "unknown section")),
    ("toml-empty-section-name", ["run", "--case", "{case}"], 'size = "05"\n[""]\nx = 1\n', ("unknown section",)),
    ("toml-unknown-key", ["run", "--case", "{case}"], 'size = "05"\n[load]\nload = 1.0\n', ("load.load", "unknown key")),
    ("toml-unknown-top-key", ["run", "--case", "{case}"], 'size = "05"\ncolour = "red"\n', ("colour", "unknown key")),
    ("toml-section-as-value", ["run", "--case", "{case}"], 'size = "05"\ndimensions = 5\n', ("dimensions", "section")),
    ("toml-array-of-tables", ["run", "--case", "{case}"], 'size = "05"\n[[load]]\nload_N = 1.0\n', ("load", "section")),
    ("toml-nested-table", ["run", "--case", "{case}"], 'size = "05"\n[load.extra]\nx = 1\n', ("load.extra", "unknown key")),
    ("toml-dim-key-at-top", ["run", "--case", "{case}"], 'size = "05"\nb1 = 45.0\n', ("b1", "unknown key")),
    # names that cannot be folders
    ("name-slash", ["run", "--case", "{case}"], 'size = "05"\nname = "a/b"\n', ("name", "folder name")),
    ("name-dotdot", ["run", "--case", "{case}"], 'size = "05"\nname = ".."\n', ("name", "folder name")),
    ("name-newline", ["run", "--case", "{case}"], 'size = "05"\nname = "a\\nb"\n', ("name", "folder name")),
    ("name-too-long", ["run", "--case", "{case}"], 'size = "05"\nname = "' + "a" * 300 + '"\n', ("name", "folder name")),
    # case file missing or unreadable
    ("case-missing", ["run", "--case", "{tmp}/nope.toml"], None, ("case", "not found")),
    ("case-is-a-folder", ["run", "--case", "{tmp}"], None, ("case", "cannot read")),
    ("case-binary", ["run", "--case", "{case}"], b"\xff\xfe\x00garbage\x80", ("case", "cannot read")),
    # output folder that cannot be written (root ignores permissions, so use a file as parent)
    ("out-under-a-file", RUN + ["--levels", "1", "--out", "{tmp}/afile/out"], None, ("out", "cannot write")),
    ("out-in-proc", RUN + ["--levels", "1", "--out", "/proc/crosshead-never/out"], None, ("out", "cannot write")),
    ("out-is-a-file", RUN + ["--levels", "1", "--out", "{tmp}/afile"], None, ("out", "not a folder")),
    # command line itself
    ("unknown-option", RUN + ["--colour", "red"], None, ("unrecognized arguments",)),
    ("unknown-command", ["solve", "--size", "05"], None, ("invalid choice",)),
    ("no-command", [], None, ("command", "run, converge or sweep")),
    ("option-without-value", RUN + ["--load"], None, ("--load", "expected one argument")),
    # physical ranges and consistency (docs/design.md §3, §4)
    ("load-tiny", RUN + ["--load", "1e-300"], None, ("load_N", "must lie in")),
    ("load-huge", RUN + ["--load", "1e20"], None, ("load_N", "must lie in")),
    ("E-tiny", RUN + ["--E", "1e-300"], None, ("E_MPa", "must lie in")),
    ("allowable-tiny", RUN + ["--allowable", "1e-300"], None, ("allowable_MPa", "must lie in")),
    ("load-range-inf", RUN + ["--load", "1:inf:3"], None, ("load_N", "finite")),
    ("span-approximate-no-lever", RUN + ["--span-approximate", "1"], None, ("approximate_span_mm", "Dm/pi")),
    ("span-both-no-lever", RUN + ["--span-exact", "1", "--span-approximate", "1"], None, ("span_mm",)),
    ("span-exact-inside-ring", RUN + ["--span-exact", "30"], None, ("exact_span_mm", "ring")),
    ("size-conflicts-case-file", ["run", "--size", "10", "--case", "{case}"], 'size = "05"\n', ("size", "conflicts")),
    ("case-not-regular", ["run", "--case", "/dev/zero"], None, ("case", "not a regular file")),
    ("case-too-large", ["run", "--case", "{case}"], "#" * (2 << 20) + "\n", ("case", "larger than")),
    # each of these would otherwise run, or fail with exit 3
    ("memory-limit-nan", RUN + ["--memory-limit", "nan"], None, ("memory_limit", "> 0")),
    ("memory-limit-negative", RUN + ["--memory-limit", "-1"], None, ("memory_limit", "> 0")),
    ("error-bar-mesh-too-coarse", RUN + ["--mesh-factor", "3", "--levels", "8", "--ratio", "3"], None,
     ("levels", "coarsest", "mesh_factor")),
    ("converge-two-loads", ["converge", "--size", "05", "--load", "1000,2000"], None, ("load_N", "one load")),
    ("load-twice", RUN + ["--load", "5000,5000"], None, ("load_N", "5000 given twice")),
    ("load-empty-item", RUN + ["--load", "5000,,6000"], None, ("load_N", "empty item")),
    # a range with equal ends is one value given twice, and a range's count error names the count
    ("load-range-of-one-value", RUN + ["--load", "5000:5000:3"], None, ("load_N", "5000 given twice")),
    ("sweep-range-of-one-count", ["sweep", "--size", "05", "--dim", "rf=0.5:3:1"], None,
     ("dims.rf", "2..200 values, got 1")),
    # a study is estimated for memory before its variants run, under --memory-limit
    ("sweep-too-large", ["sweep", "--size", "05", "--dim", "rf=1,2", "--mesh-factor", "0.6", "--memory-limit", "0.5"],
     None, ("mesh_factor", "variant rf = 1 mm", "0.5 GiB allowed")),
    ("study-negative-load", ["sweep", "--study", "{case}"], '[sweep]\nsize = "05"\nload = "-5,10000"\n',
     ("load_N", "must be > 0, got -5")),
    ("name-blank", ["run", "--case", "{case}"], 'name = " "\nsize = "05"\n', ("name", "folder name")),
    ("sweep-value-twice", ["sweep", "--size", "05", "--dim", "rf=1,1"], None, ("dims.rf", "given twice")),
    ("sweep-range-of-one-value", ["sweep", "--size", "05", "--dim", "rf=1:1:3"], None, ("dims.rf", "given twice")),
    ("sweep-empty-item", ["sweep", "--size", "05", "--dim", "rf=1,,2"], None, ("dims.rf", "empty item")),
    ("sweep-dim-twice", ["sweep", "--size", "05", "--dim", "rf=1,2", "--dim", "rf=3,4"], None, ("dim", "rf given twice")),
    ("sweep-all-invalid", ["sweep", "--size", "05", "--dim", "rf=-1,-2"], None, ("every variant is invalid", "rf")),
    # an input every variant shares is refused in the run's own line, not blamed on the variants
    ("sweep-shared-input-invalid", ["sweep", "--size", "05", "--dim", "rf=1,2", "--nu", "0.7"], None,
     ("nu", "Poisson's ratio must lie in (-1, 0.5), got 0.7")),
    ("sweep-size-and-sizes", ["sweep", "--sizes", "05,1", "--size", "1.6"], None, ("--size", "--sizes", "not both")),
    ("study-size-and-sizes", ["sweep", "--sizes", "05,1", "--study", "{case}"],
     '[sweep]\nsize = "1.6"\ndims = { rf = "1,2" }\n', ("study file's size", "--sizes", "not both")),
    ("sweep-sizes-twice", ["sweep", "--sizes", "05,05"], None, ("sizes", "05 given twice")),
    ("sweep-sizes-empty-item", ["sweep", "--sizes", "05,,1"], None, ("sizes", "empty item")),
    ("sweep-error-bar-mesh-too-coarse", ["sweep", "--size", "05", "--dim", "rf=1,2", "--mesh-factor", "3",
                                         "--levels", "8", "--ratio", "3"], None, ("levels", "coarsest")),
    ("study-unknown-dim", ["sweep", "--study", "{case}"], '[sweep]\nsize = "05"\ndims = { zz = "1,2" }\n',
     ("sweep.dims.zz", "unknown dimension")),
    ("study-dims-not-a-table", ["sweep", "--study", "{case}"], '[sweep]\nsize = "05"\ndims = "rf=1,2"\n',
     ("sweep.dims", "a table")),
    ("study-out-not-a-string", ["sweep", "--study", "{case}"],
     '[sweep]\nsize = "05"\ndims = { rf = "1,2" }\nout = 5\n', ("sweep.out", "a string")),
    ("study-other-table", ["sweep", "--study", "{case}"],
     '[sweep]\nsize = "05"\ndims = { rf = "1,2" }\n[material]\nE_MPa = 1\n', ("study", "material", "case file")),
    ("study-mesh-factor-a-string", ["sweep", "--study", "{case}"],
     '[sweep]\nsize = "05"\ndims = { rf = "1,2" }\nmesh_factor = "3"\n', ("sweep.mesh_factor", "a number")),
    # numbers as an engineer writes them: Python's float() and int() read "1_0" as 10
    ("load-underscore", RUN + ["--load", "1_0000"], None, ("--load", "not a number")),
    ("bearing-length-underscore", RUN + ["--bearing-length", "1_0"], None, ("--bearing-length", "not a number")),
    ("levels-underscore", RUN + ["--levels", "1_0"], None, ("--levels", "invalid integer")),
    ("order-unicode-digit", RUN + ["--order", "\u0662"], None, ("--order", "invalid integer")),
    ("load-list-underscore", RUN + ["--load", "5000,1_0000"], None, ("load_N", "not a number")),
    ("sweep-dim-unicode-digits", ["sweep", "--size", "05", "--dim", "rf=\u0661,2"], None, ("dims.rf", "not a number")),
    ("sweep-range-count-underscore", ["sweep", "--size", "05", "--dim", "rf=1:2:1_0"], None,
     ("dims.rf", "not an integer")),
    # values the part does not allow, refused with the rule they break
    ("span-off-the-part", RUN + ["--span-approximate", "1000"], None, ("approximate_span_mm", "bearing surface")),
    ("span-inside-the-fillet", RUN + ["--span-exact", "40"], None, ("exact_span_mm", "bearing surface", "24")),
    ("size-feature-larger-than-part", RUN + ["--size-feature", "100"], None, ("size_feature_mm", "larger than the part")),
    ("vary-centre-off-the-journal", RUN + ["--vary", "bearing_centre_mm=10:40"], None,
     ("sensitivity.bearing_centre_mm", "low end", "outside what the part allows")),
    ("vary-rf-breaks-a-rule", RUN + ["--vary", "rf=1:5"], None, ("sensitivity.rf", "high end", "dj/2 + rf")),
    ("toml-range-length-too-long", ["run", "--case", "{case}"], 'size = "05"\n[sensitivity]\nbearing_length_mm = [4.0, 20.0]\n',
     ("sensitivity.bearing_length_mm", "high end", "bearing_length_mm")),
    # an option given twice: refused everywhere, as --document twice always was
    ("option-twice", RUN + ["--load", "5000", "--load", "6000"], None, ("--load", "given twice")),
    ("flag-twice", RUN + ["--no-fields", "--no-fields"], None, ("--no-fields", "given twice")),
    ("dim-twice", RUN + ["--dim", "rf=1", "--dim", "rf=2"], None, ("dim", "rf given twice")),
    ("vary-twice", RUN + ["--vary", "dj=18:21", "--vary", "dj=17:22"], None, ("vary", "dj given twice")),
    ("document-twice", RUN + ["--document", "part=a", "--document", "part=b"], None, ("document", "part given twice")),
    ("sweep-option-twice", ["sweep", "--size", "05", "--dim", "rf=1,2", "--levels", "1", "--levels", "3"], None,
     ("--levels", "given twice")),
    # an option that cannot take effect is refused, whatever its source
    ("vary-no-sensitivity", RUN + ["--vary", "dj=18:21", "--no-sensitivity"], None,
     ("sensitivity.dj", "--no-sensitivity")),
    ("vary-want-critical", RUN + ["--vary", "dj=18:21", "--want", "critical"], None, ("sensitivity.dj", "want = critical")),
    ("toml-sensitivity-no-sensitivity", ["run", "--case", "{case}", "--no-sensitivity"],
     'size = "05"\n[sensitivity]\ndj = [18.0, 21.0]\n', ("sensitivity.dj", "--no-sensitivity")),
    ("toml-sensitivity-want-global", ["run", "--case", "{case}"],
     'size = "05"\n[model]\nwant = "global"\n[sensitivity]\ndj = [18.0, 21.0]\n', ("sensitivity.dj", "want = global")),
    ("toml-sensitivity-converge", ["converge", "--case", "{case}"], 'size = "05"\n[sensitivity]\ndj = [18.0, 21.0]\n',
     ("sensitivity.dj", "convergence study")),
    ("toml-sensitivity-sweep", ["sweep", "--case", "{case}", "--dim", "rf=1,2"],
     'size = "05"\n[sensitivity]\ndj = [18.0, 21.0]\n', ("sensitivity.dj", "--sensitivity")),
    ("vary-load-model-rigid", RUN + ["--support", "rigid", "--vary", "bearing_centre_mm=27:29"], None,
     ("sensitivity.bearing_centre_mm", "support = bearing only")),
    ("tolerance-one-mesh", RUN + ["--tolerance", "2", "--levels", "1"], None, ("tolerance_pct", "--levels 1")),
    ("toml-tolerance-converge", ["converge", "--case", "{case}"], 'size = "05"\n[mesh]\ntolerance_pct = 2.0\n',
     ("tolerance_pct", "convergence study")),
    ("ratio-one-mesh", RUN + ["--ratio", "1.5", "--levels", "1"], None, ("ratio", "--levels 1")),
    ("quarter-fields-no-fields", RUN + ["--quarter-fields", "--no-fields"], None, ("quarter_fields", "--no-fields")),
    ("quarter-fields-full-model", RUN + ["--quarter-fields", "--model", "full"], None, ("quarter_fields", "model = full")),
    ("bearing-at-rigid", RUN + ["--bearing-at", "exact", "--support", "rigid"], None,
     ("bearing_at", "support = bearing only")),
    ("toml-bearing-at-rigid", ["run", "--case", "{case}"], 'size = "05"\n[model]\nsupport = "rigid"\nbearing_at = "exact"\n',
     ("bearing_at", "support = bearing only")),
    ("sweep-screen-sensitivity", ["sweep", "--size", "05", "--dim", "rf=1,2", "--screen", "--sensitivity",
                                  "--allowable", "140"], None, ("sensitivity", "--screen")),
    ("sweep-screen-coarse", ["sweep", "--size", "05", "--dim", "rf=1,2", "--screen", "--mesh-factor", "2"], None,
     ("screen", "--mesh-factor 1")),
    ("toml-sweep-screen-coarse", ["sweep", "--case", "{case}", "--dim", "rf=1,2", "--screen"],
     'size = "05"\n[mesh]\nfactor = 1.5\n', ("screen", "at 1.5")),
    ("sweep-sensitivity-want", ["sweep", "--size", "05", "--dim", "rf=1,2", "--sensitivity", "--want", "critical"], None,
     ("sensitivity", "want = critical")),
    ("sweep-levels-nine", ["sweep", "--size", "05", "--dim", "rf=1,2", "--levels", "9"], None, ("levels", "1..8")),
    # user text is text: control characters refused from the case file as from --document
    ("document-control-character", RUN + ["--document", "part=a\tb"], None, ("document.part", "control character")),
    ("toml-document-control-character", ["run", "--case", "{case}"], 'size = "05"\n[document]\npart = "a\\u0000b"\n',
     ("document.part", "control character")),
    ("toml-document-newline", ["run", "--case", "{case}"], 'size = "05"\n[document]\nauthor = "a\\nb"\n',
     ("document.author", "control character")),
]


def build_argv(tmp_path: Path, argv: list[str], toml) -> tuple[list[str], Path]:
    """Write the case file (if any) and an existing regular file 'afile'; fill placeholders."""
    (tmp_path / "afile").write_text("a regular file, not a folder\n")
    case = tmp_path / "case.toml"
    if toml is not None:
        (case.write_bytes if isinstance(toml, bytes) else case.write_text)(toml)
    argv = [a.replace("{case}", str(case)).replace("{tmp}", str(tmp_path)) for a in argv]
    if "--out" not in argv and argv:
        argv += ["--out", str(tmp_path / "out")]
    out = Path(argv[argv.index("--out") + 1]) if "--out" in argv else tmp_path / "out"
    return argv, out


def assert_nothing_written(tmp_path: Path, before: set[str], out: Path) -> None:
    assert not out.exists() or out == tmp_path / "afile"
    assert listing(tmp_path) == before, listing(tmp_path) - before
    if out.parent.is_dir() and out.parent != Path("/proc"):
        assert not [p for p in out.parent.iterdir() if p.name.endswith(".partial")]


def test_corpus_is_big_and_unique():
    ids = [c[0] for c in CORPUS]
    assert len(ids) >= 30 and len(set(ids)) == len(ids)


@pytest.mark.slow
@pytest.mark.parametrize("argv,toml,expect", [c[1:] for c in CORPUS], ids=[c[0] for c in CORPUS])
def test_bad_input_in_process(tmp_path, tripwire, argv, toml, expect):
    argv, out = build_argv(tmp_path, argv, toml)
    before = listing(tmp_path)
    code, _, err = call_main(argv)
    assert_exit_2(code, err, expect)
    assert_nothing_written(tmp_path, before, out)


# A few as real processes: the exit status and stderr a shell sees, with no mocking.
SUBPROCESS_IDS = ("load-negative", "order-7", "toml-unclosed-section", "toml-unknown-section",
                  "case-missing", "out-under-a-file", "no-command", "memory-limit-nan", "study-unknown-dim")


@pytest.mark.slow
@pytest.mark.parametrize("argv,toml,expect", [c[1:] for c in CORPUS if c[0] in SUBPROCESS_IDS],
                         ids=[c[0] for c in CORPUS if c[0] in SUBPROCESS_IDS])
def test_bad_input_subprocess(tmp_path, argv, toml, expect):
    argv, out = build_argv(tmp_path, argv, toml)
    before = listing(tmp_path)
    p = subprocess.run([sys.executable, "-m", "pipeline", *argv], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert_exit_2(p.returncode, p.stderr, expect)
    assert_nothing_written(tmp_path, before, out)


def launch(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline.runtime.launch", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_launch_refuses_more_ranks_than_cores_with_one_line(tmp_path):
    """mpirun under --quiet refused silently (exit 1, nothing said) to start more ranks
    than the machine has cores."""
    too_many = len(os.sched_getaffinity(0)) + 1
    p = launch(too_many, "run", "--size", "05", "--out", tmp_path / "out")
    assert_exit_2(p.returncode, p.stderr, ("ranks", f"{too_many} ranks", "cores"))
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args,expect", [(["run", "--bogus"], ("--bogus",)), (["bogus"], ("invalid choice",)),
                                         ([], ("command", "run, converge or sweep"))])
def test_launch_checks_the_arguments_once_not_once_per_rank(tmp_path, args, expect):
    """A usage error under N ranks was written N times (every rank parsed the arguments)."""
    p = launch(min(2, len(os.sched_getaffinity(0))), *args)
    assert_exit_2(p.returncode, p.stderr, expect)


def test_default_out_folder_not_created_on_bad_input(tmp_path, tripwire, monkeypatch):
    """Without --out the default results/<name>/ must not appear either."""
    monkeypatch.chdir(tmp_path)
    code, _, err = call_main(["run", "--size", "05", "--load", "-1"])
    assert_exit_2(code, err, ("load_N",))
    assert listing(tmp_path) == set()


# --------------------------------------------------------------------------- exit 3

@pytest.fixture
def no_stage_left(tmp_path):
    out = tmp_path / "out"

    def check_clean():
        assert not out.exists()
        assert listing(tmp_path) == set(), listing(tmp_path)
    return out, check_clean


def test_geometry_failure_exit_3(monkeypatch, no_stage_left):
    out, check_clean = no_stage_left

    def fail(*a, **k):
        raise GeometryError("OpenCASCADE could not fuse the journal")
    monkeypatch.setattr(pipeline.analysis.level, "make_mesh", fail)
    code, _, err = call_main(["run", "--size", "05", "--levels", "1", "--quiet", "--out", out])
    assert code == 3 and "Traceback" not in err
    assert err.splitlines() == ["numerical failure: OpenCASCADE could not fuse the journal; nothing written, "
                                "the output folder is as it was"]
    check_clean()


@pytest.mark.slow
def test_solver_not_converging_exit_3(monkeypatch, no_stage_left):
    """One real coarse mesh and solve, with CG stopped after one iteration."""
    out, check_clean = no_stage_left
    real = pipeline.fe.solve.solver_options

    def one_iteration(name, rtol):
        return dict(real(name, rtol), ksp_max_it=1)
    monkeypatch.setattr(pipeline.fe.solve, "solver_options", one_iteration)
    code, _, err = call_main(["run", "--size", "05", "--mesh-factor", "2.5", "--levels", "1",
                              "--no-fields", "--quiet", "--out", out])
    assert code == 3, err
    lines = err.splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("numerical failure: solver pmg did not converge") and "nothing written" in lines[0]
    check_clean()


# --------------------------------------------------------------------------- properties

DIM_VALUES = {"b1": 45.0, "b2": 12.5, "b6": 70.0, "d14": 31.0, "d2": 21.0, "h3": 25.0,
              "dj": 20.0, "rf": 1.5, "seat_inner": 25.0, "seat_outer": 37.0}
PLAUSIBLE = {
    "name": st.sampled_from(["05", "my case", "x-1", "", "a/b", ".."]),
    "size": st.sampled_from(["05", "5", "99", ""]),
    "load_N": st.sampled_from([10000.0, 12500, 1.0]),
    "E_MPa": st.sampled_from([210000.0, 70000]),
    "nu": st.sampled_from([0.3, 0.0, -0.5, 0.49]),
    "allowable_MPa": st.sampled_from([80.0, 120]),
    "model": st.sampled_from(["quarter", "full", "half"]),
    "support": st.sampled_from(["bearing", "rigid", "glued"]),
    "order": st.sampled_from([1, 2, 3, 4]),
    "factor": st.sampled_from([1.0, 0.5, 2, 20.0, 0.05]),
    "solver": st.sampled_from(["gamg", "hypre", "mumps", "lu"]),
    "rtol": st.sampled_from([1e-10, 1e-6, 1e-3]),
    **{k: st.sampled_from([v, v * 1.1, v * 0.9]) for k, v in DIM_VALUES.items()},
}
WILD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, -0.0, 1e-300, 1e300, 1e308, -1e308, 2 ** 63 - 1]),
    st.integers(min_value=-10 ** 30, max_value=10 ** 30),
    st.integers(min_value=10 ** 300, max_value=10 ** 400),
    st.booleans(),
    st.text(max_size=12),
)
VALUE = st.one_of(WILD, st.lists(WILD, max_size=3), st.dictionaries(st.text(max_size=4), WILD, max_size=2))
KEYS = sorted({k for sec in SCHEMA.values() for k in sec})
SECTIONS = [s for s in SCHEMA if s]


def toml_string(s: str) -> str:
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")  # JSON escapes are TOML's


def toml_key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) and k.isascii() else toml_string(k)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"


@st.composite
def key_value(draw, section: str):
    known = list(SCHEMA.get(section, {})) or KEYS
    key = draw(st.one_of(st.sampled_from(known), st.sampled_from(known), st.sampled_from(KEYS),
                         st.text(min_size=1, max_size=6)))
    plausible = PLAUSIBLE.get(key, WILD)
    value = draw(st.one_of(plausible, plausible, VALUE))  # one_of picks each branch alike
    return toml_key(key), toml_value(value)


@st.composite
def case_text(draw) -> str:
    pairs = draw(st.lists(key_value(""), max_size=3, unique_by=lambda kv: kv[0]))
    if draw(st.integers(0, 3)) and "size" not in dict(pairs):
        pairs.insert(0, ("size", '"05"'))
    lines = [f"{k} = {v}" for k, v in pairs]
    sections = st.one_of(st.sampled_from(SECTIONS), st.text(max_size=6))
    for section in draw(st.lists(sections, max_size=3, unique_by=toml_key)):
        lines.append(f"[{toml_key(section)}]")
        lines += [f"{k} = {v}" for k, v in draw(st.lists(key_value(section), max_size=3, unique_by=lambda kv: kv[0]))]
    if draw(st.integers(0, 4)) == 0:  # garbage somewhere
        lines.insert(draw(st.integers(0, len(lines))), draw(st.text(max_size=30)))
    return "\n".join(lines) + "\n"


@st.composite
def near_valid_text(draw) -> str:
    """cases/05.toml with up to three entries replaced, dropped or added."""
    import tomllib
    doc = tomllib.loads(VALID_TOML)
    doc["dimensions"] = dict(DIM_VALUES)
    for _ in range(draw(st.integers(0, 3))):
        section = draw(st.sampled_from(SECTIONS + [""]))
        table = doc if section == "" else doc.setdefault(section, {})
        key = draw(st.sampled_from(list(SCHEMA[section])))
        how = draw(st.integers(0, 3))
        if how == 0:
            table.pop(key, None)
        else:
            plausible = PLAUSIBLE.get(key, PLAUSIBLE.get(SCHEMA[section][key][0], WILD))
            table[key] = draw(plausible if how < 3 else VALUE)
    top = [f"{toml_key(k)} = {toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    rest = [f"[{toml_key(k)}]\n" + "\n".join(f"{toml_key(kk)} = {toml_value(vv)}" for kk, vv in v.items())
            for k, v in doc.items() if isinstance(v, dict)]
    return "\n".join(top + rest) + "\n"


# Overrides as the CLI makes them: floats (any) for numbers, ints for order, str for choices.
FLOATS = st.one_of(st.floats(), st.sampled_from([0.0, -1.0, 1e-300, 1e300, 0.3, 1e-10, 1.0, 10000.0]))
OVERRIDE = {
    **{k: FLOATS for k in ("load_N", "E_MPa", "nu", "allowable_MPa", "approximate_span_mm",
                           "exact_span_mm", "mesh_factor", "size_body_mm", "size_feature_mm",
                           "size_fillet_mm", "grading_mm", "rtol")},
    **{f"dims.{k}": st.one_of(st.just(v), FLOATS) for k, v in DIM_VALUES.items()},
    "order": st.integers(-5, 10) | st.integers(),
    "model": st.text(max_size=8) | st.sampled_from(["quarter", "full"]),
    "support": st.text(max_size=8) | st.sampled_from(["bearing", "rigid"]),
    "solver": st.text(max_size=8) | st.sampled_from(["gamg", "hypre", "mumps"]),
}
OVERRIDES = st.lists(st.sampled_from(sorted(OVERRIDE)), max_size=3, unique=True).flatmap(
    lambda keys: st.fixed_dictionaries({k: OVERRIDE[k] for k in keys}))


def assert_usable(case: Case) -> None:
    assert check(case) is case
    for f in fields(case):
        v = getattr(case, f.name)
        if isinstance(v, float):
            assert math.isfinite(v), f.name
    for v in vars(case.dims).values():
        assert math.isfinite(v) and v >= 0


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.one_of(case_text(), near_valid_text()), size=st.sampled_from([None, None, "05", "99"]), overrides=OVERRIDES)
def test_resolve_random_case_files(tmp_path, text, size, overrides):
    """resolve() on any case file returns a usable Case or raises InputError, nothing else."""
    path = tmp_path / "random.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        case = resolve(size, path, overrides)
    except InputError as exc:
        msg = cli_main.one_line(exc)
        assert msg and ": " in msg, msg
        field = msg.split(":", 1)[0]
        event("InputError: " + (field if field.replace(".", "_").isidentifier() and field.isascii() else "other"))
    else:
        assert_usable(case)
        event("valid case")


# CLI argument lists through main(), with the run/converge work replaced by a stub.

OPTION_VALUES = {
    "--size": st.sampled_from(["05", "99", "", "1.6"]),
    "--load": st.sampled_from(["10000", "-5", "0", "nan", "inf", "1e400", "abc", "12500"]),
    "--dim": st.tuples(st.sampled_from(list(DIM_VALUES) + ["zz", ""]),
                       st.sampled_from(["45", "-1", "0", "nan", "inf", "x", "1.5", "20", "70"])
                       ).map(lambda t: f"{t[0]}={t[1]}") | st.sampled_from(["b1", "="]),
    "--support": st.sampled_from(["bearing", "rigid", "glued"]),
    "--model": st.sampled_from(["quarter", "full", "half"]),
    "--E": st.sampled_from(["210000", "0", "-1", "nan"]),
    "--nu": st.sampled_from(["0.3", "0.5", "-1", "nan"]),
    "--allowable": st.sampled_from(["80", "0", "inf"]),
    "--span-approximate": st.sampled_from(["57.5", "-1", "nan"]),
    "--span-exact": st.sampled_from(["70", "0", "inf"]),
    "--order": st.sampled_from(["1", "2", "3", "7", "0", "2.5", "x"]),
    "--mesh-factor": st.sampled_from(["1", "2.5", "0.05", "1e-9", "1e9", "nan", "-1", "20"]),
    "--size-body": st.sampled_from(["4", "1e-9", "500", "nan"]),
    "--size-feature": st.sampled_from(["1.25", "0", "inf"]),
    "--size-fillet": st.sampled_from(["0.375", "-1", "1e-12"]),
    "--grading": st.sampled_from(["10", "0", "nan"]),
    "--solver": st.sampled_from(["gamg", "hypre", "mumps", "cg"]),
    "--rtol": st.sampled_from(["1e-10", "1e-3", "0", "1e-300", "nan"]),
    "--levels": st.sampled_from(["1", "3", "4", "8", "0", "9", "-1", "x"]),
    "--ratio": st.sampled_from(["1.3", "1.1", "3", "1.0", "4", "nan"]),
    "--case": st.sampled_from(["{valid}", "{bad}", "{missing}", "{tmp}"]),
    "--out": st.sampled_from(["{tmp}/o", "{tmp}/afile/o", "{tmp}/afile", "/proc/crosshead-never/o"]),
}
FLAGS = ["--quiet", "--no-fields"]


@st.composite
def argv_lists(draw) -> list[str]:
    argv = [draw(st.sampled_from(["run", "run", "converge", "solve"]))]
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.integers(0, 9))
        if kind == 0:
            argv.append(draw(st.sampled_from(FLAGS)))
        elif kind == 1:
            argv.append(draw(st.text(max_size=8)))  # garbage token
        else:
            opt = draw(st.sampled_from(sorted(OPTION_VALUES)))
            argv += [opt, draw(OPTION_VALUES[opt])]
    if draw(st.integers(0, 3)):
        argv[1:1] = ["--size", "05"]
    return argv


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "valid.toml").write_text(VALID_TOML)
    (d / "bad.toml").write_text('size = "05"\n[load]\nload_N = "heavy"\n')
    (d / "afile").write_text("not a folder\n")
    return d


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(argv=argv_lists())
def test_cli_random_arguments(monkeypatch, fuzz_dir, argv):
    """Any argument list gives exit 0 (work reached with a usable case) or 2 (one line)."""
    calls = []

    def stub(case, options, out_dir, ctx=None):
        calls.append((case, Path(out_dir), options.levels, options.ratio))
        return {}
    monkeypatch.setattr(pipeline.api, "write_run", stub)
    monkeypatch.setattr(pipeline.cli.summary, "run_summary", lambda out: None)
    argv = [a.replace("{valid}", str(fuzz_dir / "valid.toml")).replace("{bad}", str(fuzz_dir / "bad.toml"))
            .replace("{missing}", str(fuzz_dir / "missing.toml")).replace("{tmp}", str(fuzz_dir)) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(fuzz_dir / "o")]
    code, stdout, err = call_main(argv)
    assert "Traceback" not in err
    if code == 2:
        assert_exit_2(code, err, ())
        assert not calls
        event("exit 2")
    else:
        assert code == 0, (code, err)
        if calls:
            case, _, levels, ratio = calls[0]
            assert_usable(case)
            assert 1 <= levels <= 8 and 1.1 <= ratio <= 3
            event("reached the work")
        else:  # -h/--help (or an abbreviation of it) among the garbage tokens
            assert "usage:" in stdout
    assert not (fuzz_dir / "o").exists()


def test_byte_order_mark_is_accepted(tmp_path):
    """Editors that write a UTF-8 byte-order mark still give a valid case file."""
    f = tmp_path / "bom.toml"
    f.write_bytes("\ufeff".encode() + VALID_TOML.encode())
    assert resolve(None, f).size == "05"


def test_singular_peak_has_no_safety_factor():
    """verdicts.safety_factor: a peak at a singular feature gets None and a note; others
    allowable / peak (arithmetic checked by hand: 80 / 40 = 2)."""
    from pipeline.analysis.verdicts import safety_factor
    from pipeline.output.texts import safety_text
    singular = safety_factor(80.0, answer(812.0, singular="edge of the rigid patch"))
    plain = safety_factor(80.0, answer(40.0))
    assert singular.value is None and "singular" in singular.note
    assert plain.value == 2.0 and plain.note is None
    fe = {"safety_factor": singular.value, "safety_factor_note": singular.note,
          "critical_safety_factor": plain.value, "critical_safety_factor_note": plain.note}
    assert safety_text(fe["safety_factor"]) == "none" and safety_text(fe["critical_safety_factor"]) == "2.00"


def test_verdict_pass_fail_undecided_and_capacity():
    """results.verdict against 80 MPa at Q = 10 000 N, worked by hand: 40 ± 1 passes with
    margin +100 % and capacity 20 000 N (19 512-20 513 N from the band); 100 fails; 79 ± 2
    straddles 80 (undecided); a singular peak and a nominal stress without band (null,
    not 0: a band of zero would claim an exact value)."""
    from pipeline.analysis.verdicts import verdicts
    v = {k: x.as_dict() for k, x in verdicts(80.0, 10_000.0, {
        "a": (40.0, answer(40.0, 1.0)), "b": (100.0, answer(100.0)), "c": (79.0, answer(79.0, 2.0)),
        "s": (500.0, answer(500.0, singular="edge of the rigid patch")), "n": (50.0, None)}).items()}
    assert v["a"]["verdict"] == "pass" and v["a"]["margin_pct"] == pytest.approx(100.0)
    assert v["a"]["capacity_N"] == pytest.approx(20_000.0)
    assert v["a"]["capacity_range_N"] == pytest.approx([80e4 / 41, 80e4 / 39])
    assert v["b"]["verdict"] == "fail" and v["b"]["margin_pct"] == pytest.approx(-20.0)
    assert v["c"]["verdict"] == "undecided"
    assert v["s"]["verdict"] == "none" and v["s"]["capacity_N"] is None and "singular" in v["s"]["why"]
    assert v["a"]["why"] is None and set(v["a"]) == set(v["s"])  # the same keys, null where none applies
    assert v["n"]["verdict"] == "pass" and v["n"]["band_MPa"] is None and v["n"]["capacity_range_N"] is None
    assert v["b"]["band_MPa"] is None and v["b"]["capacity_range_N"] is None  # one mesh: no band, not a band of 0


@pytest.mark.slow
def test_rigid_support_run_gives_no_global_safety_factor(tmp_path):
    """Through the CLI on coarse meshes: the rigid patch's edge is singular, so stdout,
    results.json and report.md give no safety factor for that peak."""
    out = tmp_path / "rigid"
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--support", "rigid",
                        "--mesh-factor", "3", "--out", str(out)], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    fe = json.loads((out / "results.json").read_text())["fe"]
    assert fe["peak"].get("singular_feature") and fe["safety_factor"] is None
    assert fe["verdict"]["global_peak"]["verdict"] == "none"
    assert "singular" in fe["verdict"]["global_peak"]["why"]
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("global peak"))
    assert "  singular  no verdict  SF none  " in line
    row = next(ln for ln in (out / "report.md").read_text().splitlines() if ln.startswith("| global peak"))
    assert "| singular |" in row and "| **no verdict** |" in row and "| 0." not in row  # no safety factor


def test_zero_fillet_peak_is_named_the_journal_root():
    """rf = 0: a point on the journal root circle is named as the sharp corner it is."""
    from pipeline.post.features import describe_location
    case = resolve("05", None, {"dims.rf": 0.0})
    d = case.dims
    assert "journal root" in describe_location(case, (d.b1 / 2, 0.0, d.h3 / 2 - d.dj / 2))
