"""make bench-sweeps' arithmetic (bench/sweeps.py): medians, the paired throughput ratio
and the targets' verdicts, on made-up wall times (s) whose answers are worked out here."""
import json

import pytest

from bench.sweeps import STUDIES, command, coverage, differences, near, remove_study, summarise
from pipeline.runtime.outdir import MARKER


def _runs(*walls):
    return [{"wall_s": w, "variants": 19, "ok": 19} for w in walls]


def test_medians_ratio_and_verdicts():
    s = summarise({"sizes-2": _runs(50.0, 70.0, 55.0), "sizes-1": _runs(100.0, 120.0, 99.0),
                   "grid-2": _runs(95.0, 80.0, 91.0)})
    assert s["sizes-2"]["median_s"] == 55.0 and s["sizes-2"]["met"] is True          # <= 60 s
    assert s["grid-2"]["median_s"] == 91.0 and s["grid-2"]["met"] is False            # > 90 s
    # Pairs 100/50 = 2.0, 120/70 = 1.714..., 99/55 = 1.8: median 1.8, which meets >= 1.8.
    assert abs(s["speedup_2_over_1"]["median"] - 1.8) < 1e-12 and s["speedup_2_over_1"]["met"] is True
    assert "met" not in s["sizes-1"]


def test_commands_use_the_launcher_for_two_ranks(tmp_path):
    one = command(*STUDIES["sizes-1"][:2], tmp_path)
    two = command(*STUDIES["sizes-2"][:2], tmp_path)
    assert one[1:3] == ["-m", "pipeline"] and "sweep" in one
    assert two[1:4] == ["-m", "pipeline.runtime.launch", "2"] and two[-3:] == ["--out", str(tmp_path), "--quiet"]
    old = tmp_path / "v06"  # a checkout from before the runtime package: its own launcher
    (old / "pipeline").mkdir(parents=True)
    assert command(*STUDIES["near-full"][:2], tmp_path, old)[1:4] == ["-m", "pipeline.launch", "2"]


def test_every_step_a_variant_took_is_held_against_the_full_study():
    """A variant that took the cheap level, one mesh and the full error bar: each step's
    band is checked against the full value (made-up MPa); the near count reads the full
    study's peaks against its allowable (120 MPa, 5 %: 114-126)."""
    full = _outcome({"a": _r("fail", [125.0, 1.0])}, [])
    steps = [{"step": "cheap level", "peak": [131.0, 13.1], "critical": [66.0, 2.0]},
             {"step": "one mesh", "peak": [128.0, 2.5], "critical": [66.0, 1.0]}]
    screened = _outcome({"a": dict(_r("fail", [125.0, 1.0]), steps=steps)}, [])
    c = {(r["step"], r["peak"]): r["covers_band"] for r in coverage(full, screened)}
    # |125 - 131| + 1 = 7 <= 13.1; |125 - 128| + 1 = 4 > 2.5.
    assert c == {("cheap level", "peak"): True, ("cheap level", "critical"): True,
                 ("one mesh", "peak"): False, ("one mesh", "critical"): True}
    assert near(full) == 1 and near(_outcome({"a": _r("fail", [127.0, 1.0])}, [])) == 0


def test_only_a_sweep_folder_is_removed_between_repeats(tmp_path):
    """The bench deletes its previous repeat's sweep folder (the sweep's marker inside),
    never a folder of the user's that happens to sit at that path."""
    user = tmp_path / "sizes-2"
    user.mkdir()
    (user / "data.csv").write_text("1\n")
    with pytest.raises(SystemExit):
        remove_study(user)
    assert (user / "data.csv").read_text() == "1\n"
    (user / MARKER).write_text("{}\n")       # a marker the tool did not write: still the user's
    with pytest.raises(SystemExit):
        remove_study(user)
    assert (user / "data.csv").read_text() == "1\n"
    (user / MARKER).write_text(json.dumps({"tool": "crosshead", "sweep": True}))
    remove_study(user)
    assert not user.exists()
    remove_study(user)  # nothing there: nothing to do


@pytest.mark.parametrize("module", ["bench.run", "bench.sweeps", "bench.fillet_reference"])
def test_a_bench_tool_refuses_a_folder_it_did_not_write(tmp_path, module, capsys):
    """--out holding a user's file: exit 2 and one line before any work, the file as it
    was (a bench tool writes only into a new, empty or its own folder)."""
    import importlib
    user = tmp_path / "mine"
    user.mkdir()
    (user / "thesis.tex").write_text("x\n")
    assert importlib.import_module(module).main(["--out", str(user)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refusing" in err and "thesis.tex" in err, err
    assert [p.name for p in user.iterdir()] == ["thesis.tex"]


def _outcome(rows: dict, crossings: list) -> dict:
    return {"rows": rows, "crossings": crossings, "allowable_MPa": 120.0}


def _r(verdict, peak, cheap=None, decided_by=""):
    return {"status": "done", "verdict": verdict, "critical_verdict": "pass", "peak": peak, "critical": [66.0, 0.1],
            "decided_by": decided_by, "steps": [] if cheap is None else [dict(cheap, step="cheap level")]}


def test_a_screened_study_is_compared_with_its_full_one_decision_by_decision():
    x = {"peak": "global peak", "axis": "dims.rf", "fixed": {"size": "05"}, "falls_below": True,
         "only_crossing": True, "last": 2.5, "range_reaches": [], "at": 2.2, "range": [2.1, 2.3]}
    full = _outcome({"a": _r("fail", [130.0, 1.0]), "b": _r("pass", [110.0, 1.0])}, [x])
    same = _outcome({"a": _r("fail", [130.0, 1.0]), "b": _r("pass", [110.0, 1.0])}, [dict(x)])
    assert differences(full, same) == []
    moved = _outcome({"a": _r("fail", [130.0, 1.0]), "b": _r("undecided", [110.0, 1.0])},
                     [dict(x, range=[2.1, 2.4])])
    d = differences(full, moved)
    assert len(d) == 2 and "verdict pass (full) against undecided (screened)" in d[0] and "crossing" in d[1]
    # Cheap 125 ± 12.5 holds 130 but not 130 ± 1 (|130 - 125| + 1 = 6 <= 12.5: it does);
    # cheap 100 ± 10 holds 110 only at the edge (10 <= 10) and not 110 ± 1.
    cheap = _outcome({"a": _r("fail", None, {"peak": [125.0, 12.5], "critical": [66.0, 2.0]}),
                      "b": _r("pass", None, {"peak": [100.0, 10.0], "critical": [66.0, 2.0]})}, [x])
    c = {(r["row"], r["peak"]): (r["covers_value"], r["covers_band"]) for r in coverage(full, cheap)}
    assert c == {("a", "peak"): (True, True), ("a", "critical"): (True, True),
                 ("b", "peak"): (True, False), ("b", "critical"): (True, True)}
    s = summarise({"grid-full": [dict(full, wall_s=120.0, variants=2, ok=2)],
                   "grid-screen": [dict(cheap, wall_s=30.0, variants=2, ok=2)]})["grid-screen_against_full"]
    assert s["median_ratio"] == 4.0 and s["met"] is True and s["identical_decisions"] is True
    assert (s["cover_values"], s["cover_bands"], s["cheap_bands"]) == (4, 3, 4)


def test_the_margins_a_full_study_needs_follow_from_its_coarser_readings():
    """One variant, global peak 100 ± 1 MPa on the full error bar; x1.3 reads 102 (half
    bracket 0.5), x1.69 reads 104 (half bracket 0.5). One mesh must hold 100 ± 1 from 104:
    |104 - 100| + 1 = 5, 5/104 of the value. Two meshes: |102 - 100| + 1 = 3 against the
    rule's own 0.5 + 3 × 2 = 6.5: no fraction needed. The critical peak reads 60 ± 0.1 on
    every mesh with a 0.2 half bracket: never needs one."""
    from bench.sweeps import needed_margins
    row = dict(_r("pass", [100.0, 1.0]), critical=[60.0, 0.1],
               meshes={"peak": [[100.0, 0.5], [102.0, 0.5], [104.0, 0.5]],
                       "critical": [[60.0, 0.2], [60.0, 0.2], [60.0, 0.2]]})
    need = needed_margins(_outcome({"a": row}, []))
    assert need["one mesh"]["peak"] == pytest.approx(5.0 / 104.0)
    assert need["two meshes"] == {"peak": 0.0, "critical": 0.0} and need["one mesh"]["critical"] == 0.0
