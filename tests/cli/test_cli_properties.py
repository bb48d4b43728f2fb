"""The command line as a property (hypothesis): every option of run,
converge and sweep, with values drawn from each option's domain, its edges and just
outside it, alone and in combination (a case file, a study file, an option given twice).
Whatever the arguments:

- the command ends with exit 0 or 2; on 2 with exactly one line on stderr, and nothing
  written (the temporary folder as it was, the work never reached);
- it never contradicts itself: an option it accepts is an option it uses. Each option given
  is found, with its value, in what reaches the work (the case and the run options, or a
  study's inputs and its first valid variant's case): an option that could not take effect
  must have been refused.

The work is stubbed as tests/cli/test_bad_input.py does (pipeline.api's ``write_run``; a
study's ``execute_sweep`` replaced by its planning, where its inputs are checked), and the
memory estimate's probe mesh too: only the command line and its checks run, a few
milliseconds an example. The deep variant (more examples) is slow.
"""
from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

import pipeline.api
import pipeline.cli.preflight
import pipeline.cli.summary
import pipeline.study.sweep
from pipeline import cli as cli_main
from pipeline.inputs.case import formula_bearing
from pipeline.inputs.valuelist import MOST_DIM_VALUES, parse_loads, parse_values
from pipeline.study.plan import plan

ROOT = Path(__file__).resolve().parents[2]

# No. 05's table row (mm): the edges of the rules below are worked from it by hand
# (b6 = b1 + 2·b2 = 70; the bearing surface from b1/2 + rf = 24 to b6/2 = 35 mm).
TABLE = {"b1": 45.0, "b2": 12.5, "b6": 70.0, "d14": 31.0, "d2": 21.0, "h3": 25.0, "dj": 20.0, "rf": 1.5,
         "seat_inner": 25.0, "seat_outer": 37.0}
NUM_BAD = ["0", "-1", "nan", "inf", "1_0", "x", ""]  # outside every positive number's domain, or no number

# Each value option: values in its domain, at its edges and just outside (mm, N, MPa).
VALUES: dict[str, list[str]] = {
    "--size": ["05", "5", "1.6", "99", ""],
    "--load": ["10000", "12500", "5000,10000", "5000:20000:4", "1e-6", "1e15", "1.1e15", "5000,5000", "5000,,1",
               "1:inf:3", *NUM_BAD],
    "--support": ["bearing", "rigid", "glued"],
    "--bearing-shape": ["cosine", "uniform", "flat"],
    "--bearing-length": ["2.2", "11", "11.001", "4.4", *NUM_BAD],
    "--bearing-centre": ["29.5", "24.1", "34.9", "24", "35", "40", "27.05", *NUM_BAD],
    "--bearing-at": ["approximate", "exact", "middle"],
    "--want": ["both", "critical", "global", "all"],
    "--model": ["quarter", "full", "half"],
    "--E": ["210000", "70000", "1", "0.99", "1e12", "1.1e12", *NUM_BAD],
    "--nu": ["0.3", "0", "-0.99", "0.45", "0.4999", "0.49991", "-1", "0.5", "nan"],
    "--allowable": ["80", "120", "1e-6", "1e9", "1.1e9", *NUM_BAD],
    "--span-approximate": ["57.5", "48", "47.9", "70", "70.1", "1000", "1", *NUM_BAD],
    "--span-exact": ["70", "48", "47.9", "70.1", "40", "30", *NUM_BAD],
    "--order": ["1", "2", "3", "0", "4", "2.0", "\u0662", "x"],
    "--mesh-factor": ["3", "2.5", "20", "20.1", "0.05", "0.049", *NUM_BAD],
    "--size-body": ["4", "70", "71", "1e-9", *NUM_BAD],
    "--size-feature": ["1", "2", "70", "71", *NUM_BAD],
    "--size-fillet": ["0.4", "0.3", "71", "1e-12", *NUM_BAD],
    "--grading": ["10", "5", *NUM_BAD],
    "--solver": ["pmg", "gamg", "hypre", "mumps", "lu"],
    "--rtol": ["1e-8", "1e-10", "9.9e-4", "1e-3", *NUM_BAD],
    "--memory-limit": ["4", "64", "1e-3", *NUM_BAD],
    "--out": ["{tmp}/o", "{tmp}/afile/o", "{tmp}/afile"],
    "--case": ["{valid}", "{ranged}", "{documented}", "{rigid}", "{bad}", "{missing}"],
    "--levels": ["1", "3", "4", "5", "8", "2", "9", "0", "-1", "1_0", "x"],
    "--ratio": ["1.3", "1.1", "3", "1.5", "1.09", "3.01", *NUM_BAD],
    "--tolerance": ["1", "0.1", "50", "5", "0.09", "51", *NUM_BAD],
    "--vary": ["dj=18:21", "rf=1.2:1.8", "seat_inner=23:26", "bearing_centre_mm=27:29.5",
               "bearing_length_mm=4.4:11", "bearing_centre_mm=10:40", "rf=1:5", "dj=21:18", "rf=1.2",
               "zz=1:2", "rf=1_0:2"],
    "--document": ["part=Crosshead No. 05", "number=CN-0815", "revision=B", "author=A. Engineer",
                   "checker=[x](javascript:alert(1))", "author=<b>bold</b>", "part=a\tb", "part=", "nope=x", "part"],
    "--sizes": ["05,1", "05,1.6,2.5", "all", "05,05", "99", "05,,1"],
    "--study": ["{study}", "{study_bad}"],
}
# The values inside each option's domain (the first ones of VALUES'), drawn more often, so
# that many command lines reach the work and are checked for using what they were given.
GOOD = {opt: [v for v in values if v not in NUM_BAD][:3] for opt, values in VALUES.items()}
FLAGS = {"run": ["--no-fields", "--no-sensitivity", "--quarter-fields", "--quiet"],
         "converge": ["--quiet"], "sweep": ["--screen", "--sensitivity", "--quiet"]}
SHARED = ["--size", "--case", "--load", "--support", "--bearing-shape", "--bearing-length", "--bearing-centre",
          "--bearing-at", "--want", "--model", "--E", "--nu", "--allowable", "--span-approximate", "--span-exact",
          "--order", "--mesh-factor", "--size-body", "--size-feature", "--size-fillet", "--grading", "--solver",
          "--rtol", "--memory-limit", "--out"]
OPTIONS = {"run": SHARED + ["--dim", "--levels", "--ratio", "--tolerance", "--vary", "--document"],
           "converge": SHARED + ["--dim", "--levels", "--ratio"],
           "sweep": SHARED + ["--dim", "--levels", "--ratio", "--sizes", "--study"]}
# --dim: NAME=MM for run and converge, NAME=VALUES (a list or a range) for a study.
DIM_RUN = st.tuples(st.sampled_from(list(TABLE) + ["zz"]),
                    st.sampled_from(["{v}", "{v*1.02}", "{v*0.98}", "0", "-1", "1e3", "nan", "1_0"]))
DIM_SWEEP = st.tuples(st.sampled_from(list(TABLE) + ["zz"]),
                      st.sampled_from(["{v}", "{v},{v*1.02}", "{v*0.9}:{v*1.02}:3", "{v},{v}", "1:2:1", "1:2:201",
                                       "-1,1", "1_0,2"]))
# Keys of the case file a test's case files set, and the option that sets the same field.
CASE_FILES = {
    "valid": 'name = "05"\nsize = "05"\n[material]\nE_MPa = 210000.0\nallowable_MPa = 80.0\n',
    "ranged": 'size = "05"\n[sensitivity]\ndj = [18.0, 21.0]\n',
    "documented": 'size = "05"\n[document]\npart = "Crosshead [x](javascript:alert(1))"\nnumber = "CN-1"\n',
    "rigid": 'size = "05"\n[model]\nsupport = "rigid"\n',
    "bad": 'size = "05"\n[load]\nload_N = "heavy"\n',
}
STUDIES = {"study": '[sweep]\nsize = "05"\ndims = { rf = "1.0,1.5" }\nmesh_factor = 3.0\n',
           "study_bad": '[sweep]\nsize = "05"\ndims = { rf = "1.0,1.5" }\nlevels = 2\n'}


def dim_text(name_value: tuple[str, str]) -> str:
    """NAME=VALUE with the table's value put in for {v}, {v*1.02}, ..."""
    name, value = name_value
    v = TABLE.get(name, 1.0)
    for pattern, x in (("{v*1.02}", v * 1.02), ("{v*0.98}", v * 0.98), ("{v*0.9}", v * 0.9), ("{v}", v)):
        value = value.replace(pattern, f"{x:.6g}")
    return f"{name}={value}"


# Options that act on one part of the run, two or three drawn together half the time: where one
# option can keep another from taking effect (the error bar's meshes, the sensitivity
# section, the journal load model, the files written).
FAMILIES = [["--levels", "--ratio", "--tolerance", "--mesh-factor"],
            ["--vary", "--no-sensitivity", "--want", "--sensitivity", "--screen", "--allowable", "--case"],
            ["--support", "--bearing-shape", "--bearing-length", "--bearing-centre", "--bearing-at", "--vary",
             "--span-approximate", "--span-exact"],
            ["--no-fields", "--quarter-fields", "--model", "--document"]]


@st.composite
def command_lines(draw) -> tuple[str, list[tuple[str, str | None]]]:
    """A command and its (option, value) pairs (value None for a flag): some of every
    command's options with values from VALUES (or some of one FAMILIES' options), a size
    most of the time, sometimes an option given twice."""
    command = draw(st.sampled_from(["run", "run", "run", "converge", "sweep", "sweep"]))
    pairs: list[tuple[str, str | None]] = []
    if draw(st.booleans()):
        family = [o for o in draw(st.sampled_from(FAMILIES)) if o in OPTIONS[command] + FLAGS[command]]
        for opt in draw(st.lists(st.sampled_from(family), min_size=min(2, len(family)), max_size=3, unique=True)):
            pairs.append((opt, None) if opt in FLAGS[command] else (opt, draw(st.sampled_from(GOOD[opt] * 2
                                                                                          + VALUES[opt]))))
    for _ in range(draw(st.integers(0, 4 - len(pairs)))):
        if draw(st.integers(0, 4)) == 0:
            pairs.append((draw(st.sampled_from(FLAGS[command])), None))
            continue
        opt = draw(st.sampled_from(OPTIONS[command]))
        if opt == "--dim":
            value = dim_text(draw(DIM_SWEEP if command == "sweep" else DIM_RUN))
        else:
            value = draw(st.sampled_from(GOOD[opt] * 8 + VALUES[opt]))
        pairs.append((opt, value))
    if draw(st.integers(0, 9)) and not any(o in ("--size", "--case", "--study", "--sizes") for o, _ in pairs):
        pairs.insert(0, ("--size", "05"))
    if command == "sweep" and draw(st.integers(0, 9)) and not any(o in ("--dim", "--sizes", "--study")
                                                                  for o, _ in pairs):
        pairs.append(("--dim", "rf=1,1.5"))
    if pairs and draw(st.integers(0, 9)) == 0:
        pairs.append(draw(st.sampled_from(pairs)))  # an option given twice
    if draw(st.integers(0, 5)) and not any(o == "--out" for o, _ in pairs):
        pairs.append(("--out", "{tmp}/o"))
    return command, pairs


@dataclass
class Reached:
    """What reached the work: run/converge's (case, options, out), a study's (Study, out)."""

    runs: list = field(default_factory=list)
    studies: list = field(default_factory=list)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    """The case and study files the values name, beside a regular file 'afile'."""
    d = tmp_path_factory.mktemp("cli-files")
    for name, text in {**CASE_FILES, **STUDIES}.items():
        (d / f"{name}.toml").write_text(text, encoding="utf-8")
    return d


def stubbed(monkeypatch) -> Reached:
    """The work replaced by recorders: write_run records (case, options, out); a study is
    planned (its checks) and recorded; no probe mesh, no closing summary."""
    reached = Reached()

    def write_run(case, options, out_dir, ctx=None):
        reached.runs.append((case, options, Path(out_dir)))
        return {}

    def execute_sweep(study, out, say, comm=None):
        tasks = plan(study)  # where a study's inputs are checked against its variants
        reached.studies.append((study, Path(out), tasks))
        return {"counts": {"done": 0, "invalid": 0, "failed": 0, "not run": 0}, "rows": [], "crossings": [],
                "allowable_MPa": 80.0}
    monkeypatch.setattr(pipeline.api, "write_run", write_run)
    monkeypatch.setattr(pipeline.study.sweep, "execute_sweep", execute_sweep)
    monkeypatch.setattr(pipeline.cli.summary, "run_summary", lambda out: None)
    monkeypatch.setattr(pipeline.cli.preflight, "check_fits", lambda *a, **k: None)
    return reached


def argv_of(command: str, pairs: list[tuple[str, str | None]], files: Path, tmp: Path) -> list[str]:
    """The argument list, the placeholders filled in."""
    names = {f"{{{k}}}": str(files / f"{k}.toml") for k in (*CASE_FILES, *STUDIES)}
    names.update({"{missing}": str(files / "missing.toml"), "{tmp}": str(tmp)})
    out = [command]
    for opt, value in pairs:
        out.append(opt)
        if value is not None:
            for k, v in names.items():
                value = value.replace(k, v)
            out.append(value)
    return out


def call(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = cli_main.main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def number(text: str) -> float:
    return float(text)


# ------------------------------------------------------------------ what "used" means

CASE_FIELD = {"--support": "support", "--bearing-shape": "bearing_shape", "--want": "want", "--model": "model",
              "--solver": "solver", "--E": "E_MPa", "--nu": "nu", "--allowable": "allowable_MPa",
              "--span-approximate": "approximate_span_mm", "--span-exact": "exact_span_mm",
              "--mesh-factor": "mesh_factor", "--size-body": "size_body_mm", "--size-feature": "size_feature_mm",
              "--size-fillet": "size_fillet_mm", "--grading": "grading_mm", "--rtol": "rtol",
              "--bearing-length": "bearing_length_mm", "--bearing-centre": "bearing_centre_mm", "--order": "order"}


def same(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return math.isclose(float(a), float(b), rel_tol=1e-12)
    return a == b


def used_by_a_run(command: str, given: dict, case, options, out: Path, argv_out: str | None) -> None:
    """Each option given to run or converge, found with its value in the case and options
    that reached the work."""
    for opt, value in given.items():
        if opt in CASE_FIELD:
            want = value if opt in ("--support", "--bearing-shape", "--want", "--model", "--solver") else (
                int(value) if opt == "--order" else number(value))
            assert same(getattr(case, CASE_FIELD[opt]), want), (opt, value, case)
            if opt == "--mesh-factor":
                assert case.mesh_pinned
        elif opt == "--size":
            from geometry.table import lookup
            assert case.size == lookup(value).size
        elif opt == "--load":
            loads = parse_loads(value)
            assert same(case.load_N, loads[0]) and options.loads == (tuple(loads) if len(loads) > 1 else ())
        elif opt == "--bearing-at":
            centre, length = formula_bearing(case.dims, value, given.get("--bearing-length") and
                                             number(given["--bearing-length"]),
                                             case.approximate_span_mm if value == "approximate" else case.exact_span_mm)
            assert same(case.bearing_centre_mm, centre) and same(case.bearing_length_mm, length)
            assert case.support == "bearing"
        elif opt == "--memory-limit":
            assert same(options.memory_limit_gb, number(value))
        elif opt == "--levels":
            assert options.levels == int(value)
        elif opt == "--ratio":
            assert same(options.ratio, number(value)) and options.levels > 1
        elif opt == "--tolerance":
            assert same(case.tolerance_pct, number(value)) and options.to_tolerance and options.levels >= 3
        elif opt == "--no-fields":
            assert not options.outputs.fields
        elif opt == "--quarter-fields":
            assert options.outputs.quarter_fields and options.outputs.fields and case.model == "quarter"
        elif opt == "--no-sensitivity":
            assert not options.sensitivity
        elif opt == "--out":
            assert out == Path(argv_out)
    for value in given.get("--dim*", []):
        name, v = value.split("=")
        assert same(getattr(case.dims, name), number(v)) and name not in case.assumed
    for value in given.get("--vary*", []):
        name, rng = value.split("=")
        lo, hi = (number(x) for x in rng.split(":"))
        assert (name, lo, hi) in case.sensitivity_ranges and options.sensitivity and case.want == "both"
    for value in given.get("--document*", []):
        name, text = value.split("=", 1)
        assert getattr(case.document, name) == (text.strip() or None)
    if command == "converge":
        assert not options.sensitivity and not options.to_tolerance and options.levels >= 4


def used_by_a_study(given: dict, study, out: Path, tasks, argv_out: str | None) -> None:
    """Each option given to sweep, found with its value in the study and in its first valid
    variant's case."""
    first = next(t.case for t in tasks if t.case is not None)
    for opt, value in given.items():
        if opt in CASE_FIELD:
            want = value if opt in ("--support", "--bearing-shape", "--want", "--model", "--solver") else (
                int(value) if opt == "--order" else number(value))
            assert same(study.base[CASE_FIELD[opt]], want) and same(getattr(first, CASE_FIELD[opt]), want), opt
        elif opt == "--bearing-at":
            assert study.base["bearing_at"] == value and first.bearing_centre_mm is not None
        elif opt == "--load":
            loads = parse_loads(value)
            assert study.loads == loads
        elif opt == "--sizes":
            assert study.sizes is not None and (value == "all" or study.sizes == value.split(","))
        elif opt == "--levels":
            assert study.levels == int(value)
        elif opt == "--ratio":
            assert same(study.ratio, number(value)) and study.levels > 1
        elif opt == "--screen":
            assert study.screen
        elif opt == "--sensitivity":
            assert study.sensitivity and first.want == "both"
        elif opt == "--memory-limit":
            assert same(study.memory_limit_gb, number(value))
        elif opt == "--out":
            assert out == Path(argv_out)
    for value in given.get("--dim*", []):
        name, values = value.split("=")
        assert study.axes[f"dims.{name}"] == parse_values(values, f"dims.{name}", MOST_DIM_VALUES)


def check(command: str, pairs, files: Path, tmp: Path, monkeypatch) -> None:
    """One command line: exit 0 or 2, one line and nothing written on 2, and on 0 every
    option given used."""
    (tmp / "afile").write_text("a regular file, not a folder\n")
    before = listing(tmp)
    reached = stubbed(monkeypatch)
    argv = argv_of(command, pairs, files, tmp)
    code, stdout, err = call(argv)
    assert "Traceback" not in err, err
    assert code in (0, 2), (argv, code, err)
    if code == 2:
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
        assert not reached.runs and not reached.studies, argv
        assert listing(tmp) == before, argv
        event("exit 2: " + lines[0].split(":")[1].strip()[:24])
        return
    if not reached.runs and not reached.studies:  # --help among the values? (none is drawn): never
        raise AssertionError((argv, stdout, err))
    given: dict = {}
    for opt, value in pairs:  # the values as the command saw them, placeholders filled in
        filled = argv_of(command, [(opt, value)], files, tmp)[2:]
        if opt in ("--dim", "--vary", "--document"):
            given.setdefault(f"{opt}*", []).append(filled[0])
        else:
            given[opt] = filled[0] if filled else None
    argv_out = given.get("--out")
    if command == "sweep":
        (study, out, tasks), = reached.studies
        used_by_a_study(given, study, out, tasks, argv_out)
    else:
        (case, options, out), = reached.runs
        used_by_a_run(command, given, case, options, out, argv_out)
    event(f"{command}: reached the work")


# Each pair of options one of which can keep the other from taking effect, tried in every run
# of the property besides what it draws (the draws find them too, but not every time).
O = ("--out", "{tmp}/o")
KNOWN = [("run", [("--size", "05"), ("--levels", "1"), ("--tolerance", "2"), O]),
         ("run", [("--size", "05"), ("--levels", "1"), ("--ratio", "1.5"), O]),
         ("run", [("--size", "05"), ("--vary", "dj=18:21"), ("--no-sensitivity", None), O]),
         ("run", [("--size", "05"), ("--vary", "dj=18:21"), ("--want", "critical"), O]),
         ("run", [("--case", "{ranged}"), ("--no-sensitivity", None), O]),
         ("run", [("--size", "05"), ("--quarter-fields", None), ("--no-fields", None), O]),
         ("run", [("--size", "05"), ("--quarter-fields", None), ("--model", "full"), O]),
         ("run", [("--size", "05"), ("--bearing-at", "exact"), ("--support", "rigid"), O]),
         ("run", [("--size", "05"), ("--support", "rigid"), ("--vary", "bearing_centre_mm=27:29.5"), O]),
         ("run", [("--size", "05"), ("--bearing-at", "exact"), ("--bearing-length", "2.2"), O]),
         ("run", [("--size", "05"), ("--load", "5000,10000"), ("--vary", "rf=1.2:1.8"), O]),
         ("converge", [("--case", "{ranged}"), O]),
         ("sweep", [("--case", "{ranged}"), ("--dim", "rf=1,1.5"), O]),
         ("sweep", [("--size", "05"), ("--dim", "rf=1,1.5"), ("--screen", None), ("--sensitivity", None),
                    ("--allowable", "140"), O]),
         ("sweep", [("--size", "05"), ("--dim", "rf=1,1.5"), ("--sensitivity", None), ("--want", "critical"), O]),
         ("sweep", [("--size", "05"), ("--dim", "rf=1,1.5"), ("--levels", "1"), ("--ratio", "1.5"), O]),
         ("sweep", [("--size", "05"), ("--dim", "rf=1,1.5"), ("--bearing-at", "approximate"), O])]


def with_known(test):
    """``test`` with every KNOWN command line as an explicit example."""
    for line in reversed(KNOWN):
        test = example(line=line)(test)
    return test


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                    HealthCheck.too_slow])
@with_known
@given(line=command_lines())
def test_every_command_line_is_exit_0_or_2_and_an_option_accepted_is_used(files, tmp_path_factory, monkeypatch,
                                                                          line):
    command, pairs = line
    with monkeypatch.context() as mp:
        check(command, pairs, files, tmp_path_factory.mktemp("cli"), mp)


@pytest.mark.slow
@settings(max_examples=6000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                     HealthCheck.too_slow])
@given(line=command_lines())
def test_every_command_line_deep(files, tmp_path_factory, monkeypatch, line):
    command, pairs = line
    with monkeypatch.context() as mp:
        check(command, pairs, files, tmp_path_factory.mktemp("cli"), mp)


def test_the_options_drawn_are_every_option_of_every_command():
    """The property draws every option run, converge and sweep have (their parsers say
    which), so a new option is drawn, or this fails."""
    parser = cli_main.make_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for command, p in sub.choices.items():
        have = {s for a in p._actions for s in a.option_strings if s.startswith("--") and s != "--help"}
        assert have == set(OPTIONS[command]) | set(FLAGS[command]), (command, have ^ (set(OPTIONS[command])
                                                                                     | set(FLAGS[command])))
