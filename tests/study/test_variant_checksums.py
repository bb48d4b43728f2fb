"""A design study's variants carry the checksums of their files (pipeline/study/manifest.py).
A variant whose results.json was edited by hand (peak 148.36 -> 50 MPa was summarised as
found) or cut short (every resume ended with exit 3 and a JSONDecodeError naming no
variant) is named in one line and analysed again; the study's table and the size summary
never read it.
"""
from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from pipeline.runtime.folders import MARKER
from pipeline.study.manifest import (
    MANIFEST,
    VariantFault,
    folder_fault,
    read_failure,
    read_results,
    write_failure,
    write_manifest,
)
from pipeline.study.plan import Study, Task, failure_file, variant_folder
from pipeline.study.sweep import discard_damaged
from pipeline.study.table import rows_of

ROOT = Path(__file__).resolve().parents[2]
STUDY = ["--size", "05", "--dim", "rf=1,1.5", "--mesh-factor", "3", "--levels", "1"]


def a_variant(out: Path, key: str, results: dict) -> Path:
    """A finished variant's folder as a run and its study leave it: marker, results.json,
    then the checksums."""
    folder = variant_folder(out, key)
    folder.mkdir(parents=True)
    (folder / MARKER).write_text('{"tool": "crosshead"}\n')
    (folder / "results.json").write_text(json.dumps(results) + "\n")
    write_manifest(folder)
    return folder


def test_a_variant_s_files_match_their_checksums_until_one_changes(tmp_path):
    """Written, the folder matches; a changed byte, a cut, a missing manifest, a missing
    results.json or a manifest that does not name it do not, each said as such."""
    folder = a_variant(tmp_path, "k1", {"fe": {"peak_MPa": 148.36}})
    assert folder_fault(folder) is None and read_results(folder) == {"fe": {"peak_MPa": 148.36}}
    text = (folder / "results.json").read_text()
    for changed in (text.replace("148.36", "50.00"), text[:len(text) // 2]):
        (folder / "results.json").write_text(changed)
        assert folder_fault(folder) == "results.json does not match its checksum"
        with pytest.raises(VariantFault, match="^results.json does not match its checksum$"):
            read_results(folder)
    (folder / "results.json").write_text(text)
    (folder / MARKER).write_text("{}")
    assert folder_fault(folder) == f"{MARKER} does not match its checksum"
    (folder / MARKER).write_text('{"tool": "crosshead"}\n')
    manifest = (folder / MANIFEST).read_text()
    (folder / MANIFEST).write_text(json.dumps({"sha256": {MARKER: json.loads(manifest)["sha256"][MARKER]}}))
    assert folder_fault(folder) == f"its checksums ({MANIFEST}) do not name results.json"
    (folder / MANIFEST).unlink()
    assert folder_fault(folder).startswith("results.json has no checksum")
    (folder / MANIFEST).write_text(manifest)
    assert folder_fault(folder) is None
    (folder / "results.json").unlink()
    assert folder_fault(folder) == "results.json is missing"


def test_a_failure_note_carries_its_checksum(tmp_path):
    note = {"error": "solver pmg did not converge", "size": "05", "parameters": {"dims.rf": 1.0}}
    path = tmp_path / "k.failed.json"
    write_failure(path, note)
    assert read_failure(path) == note
    path.write_text(path.read_text().replace("did not", "did"))
    with pytest.raises(VariantFault, match="k.failed.json does not match its checksum"):
        read_failure(path)
    path.write_text('{"error": ')
    with pytest.raises(VariantFault, match="cannot be read"):
        read_failure(path)


def test_the_table_never_reads_a_variant_whose_files_fail_their_checksums(tmp_path):
    """rows_of: an edited results.json and an edited failure note are listed as not run
    with why, never with their values (the edited peak of 50 MPa was a row of the table;
    a truncated one stopped the study with a JSONDecodeError)."""
    edited = a_variant(tmp_path, "k1", {"fe": {"peak_MPa": 148.36}})
    (edited / "results.json").write_text(json.dumps({"fe": {"peak_MPa": 50.0}}))
    cut = a_variant(tmp_path, "k2", {"fe": {"peak_MPa": 148.36}})
    (cut / "results.json").write_text('{"fe": {"pea')
    write_failure(failure_file(tmp_path, "k3"), {"error": "a failure", "size": "05", "parameters": {}})
    failure_file(tmp_path, "k3").write_text(failure_file(tmp_path, "k3").read_text().replace("a failure", "no"))
    case = SimpleNamespace(size="05")  # a valid task: rows_of reads only its size and its files
    tasks = [Task(k, {"dims.rf": rf}, case, (10_000.0,)) for k, rf in (("k1", 1.0), ("k2", 1.5), ("k3", 2.0))]
    rows = rows_of(tasks, tmp_path)
    assert [r["status"] for r in rows] == ["not run"] * 3
    assert [r["note"].split(":")[0] for r in rows] == ["results.json does not match its checksum"] * 2 + [
        "k3.failed.json does not match its checksum"]
    assert all("peak_MPa" not in r for r in rows)


def test_damaged_variants_are_named_and_removed_and_a_user_s_folder_stays(tmp_path):
    """discard_damaged: one line per variant, "variant <key> (<inputs>): <why>; analysed
    again"; a variant's folder and its claim are removed; a matching variant, an invalid
    task and a folder the tool did not write (no marker) stay."""
    good = a_variant(tmp_path, "good", {"x": 1})
    bad = a_variant(tmp_path, "bad", {"x": 1})
    (bad / "results.json").write_text('{"x": 2}\n')
    (tmp_path / ".claims").mkdir()
    (tmp_path / ".claims" / "bad").touch()
    mine = variant_folder(tmp_path, "mine")
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    case = SimpleNamespace(size="05")
    tasks = [Task("good", {"dims.rf": 1.0}, case, (1.0,)), Task("bad", {"dims.rf": 1.5}, case, (1.0,)),
             Task("mine", {"dims.rf": 2.0}, case, (1.0,)), Task("invalid", {"dims.rf": 9.0}, None, (1.0,))]
    said: list[str] = []
    assert discard_damaged(tmp_path, tasks, said.append) == ["bad", "mine"]
    assert said == ["sweep: variant bad (rf = 1.5 mm): results.json does not match its checksum; analysed again",
                    "sweep: variant mine (rf = 2 mm): results.json is missing; analysed again"]
    assert good.is_dir() and not bad.exists() and not (tmp_path / ".claims" / "bad").exists()
    assert (mine / "notes.txt").read_text() == "keep"


def test_a_user_s_file_in_a_damaged_variant_stays_and_is_named(tmp_path):
    """discard_damaged on a variant whose results.json was edited and beside which a user
    put notes.txt and a folder: the variant's own files go, the user's stay, named in the
    line; the folder stays the tool's (a marker that lists none of them), so that the next
    run of the variant replaces it and carries them over, never deleting them with it."""
    from pipeline.runtime.folders import MARKER, marker_data, user_names
    bad = a_variant(tmp_path, "bad", {"x": 1})
    (bad / "results.json").write_text('{"x": 2}\n')
    (bad / "notes.txt").write_text("mine")
    (bad / "paraview").mkdir()
    (bad / "paraview" / "state.pvsm").write_text("<x/>")
    said: list[str] = []
    assert discard_damaged(tmp_path, [Task("bad", {"dims.rf": 1.5}, SimpleNamespace(size="05"), (1.0,))],
                           said.append) == ["bad"]
    assert said == ["sweep: variant bad (rf = 1.5 mm): results.json does not match its checksum; analysed again; "
                    "kept bad/notes.txt, bad/paraview (not the study's)"]
    assert sorted(p.name for p in bad.iterdir()) == [MARKER, "notes.txt", "paraview"]
    assert marker_data(bad) == {"tool": "crosshead", "files": []} and user_names(bad) == ["notes.txt", "paraview"]
    assert (bad / "paraview" / "state.pvsm").read_text() == "<x/>"


def test_the_summary_of_a_study_names_a_variant_whatever_is_missing(tmp_path):
    """python -m pipeline.study.summary on a study's variants/: a variant whose results.json
    is deleted, and one whose whole folder is gone while sweep.json lists it as analysed,
    are each named, not dropped in silence."""
    from pipeline.runtime.folders import MARKER
    from pipeline.study.summary import collect
    out = tmp_path / "study"
    out.mkdir()
    (out / MARKER).write_text(json.dumps({"tool": "crosshead", "sweep": True}))
    a_variant(out, "gone", {"x": 1}).joinpath("results.json").unlink()
    (out / "variants" / "users").mkdir()  # a user's folder: not a variant, not named
    (out / "sweep.json").write_text(json.dumps({"rows": [{"variant": "gone", "status": "done"},
                                                          {"variant": "lost", "status": "done"},
                                                          {"variant": "bad", "status": "invalid"}]}))
    rows, skipped = collect(out / "variants", take_all=True)
    assert rows == [] and skipped == ["gone (results.json is missing; not summarised)",
                                      "lost (its folder is missing; not summarised)"]


def sweep(out: Path, *args: str) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, "-m", "pipeline", "sweep", *args, "--out", str(out)], cwd=ROOT,
                       capture_output=True, text=True, timeout=600, env=dict(os.environ, CROSSHEAD_NO_CACHE="1"))
    assert p.returncode == 0, p.stderr
    return p


@pytest.mark.slow
def test_an_edited_or_truncated_variant_is_analysed_again_and_never_summarised(tmp_path):
    """The issue's probe. A study of two variants; one's results.json edited (its global
    peak set to 50 MPa), the other's cut in half. The resume names both in one line each,
    analyses them again and gives the rows of the first run (the same analysis, the
    independent reference here), not 50 MPa; before, it summarised the 50 and stopped
    with exit 3 on the cut file. The size summary leaves out a variant edited after that."""
    out = tmp_path / "study"
    sweep(out, *STUDY, "--quiet")
    first = json.loads((out / "sweep.json").read_text())["rows"]
    by_rf = {r["dims.rf"]: r["variant"] for r in first}
    edited, cut = (variant_folder(out, by_rf[rf]) / "results.json" for rf in (1.0, 1.5))
    res = json.loads(edited.read_text())
    assert res["fe"]["peak_MPa"] != 50.0
    res["fe"]["peak_MPa"] = 50.0
    edited.write_text(json.dumps(res))
    cut.write_bytes(cut.read_bytes()[:cut.stat().st_size // 2])
    (edited.parent / "notes.txt").write_text("mine")  # a user's file beside the edited results
    again = sweep(out, *STUDY)
    # The user's file stays, named, when the variant's folder is replaced.
    assert (edited.parent / "notes.txt").read_text() == "mine"
    assert f"kept {by_rf[1.0]}/notes.txt (not the study's)" in again.stdout + again.stderr
    for rf, text in ((1.0, "rf = 1 mm"), (1.5, "rf = 1.5 mm")):
        line = f"sweep: variant {by_rf[rf]} ({text}): results.json does not match its checksum; analysed again"
        assert (again.stdout + again.stderr).count(line) == 1, (again.stdout + again.stderr)
    assert "0 already done" in (again.stdout + again.stderr)
    strip = lambda rows: [{k: v for k, v in r.items() if k != "time_s"} for r in rows]  # noqa: E731
    assert strip(json.loads((out / "sweep.json").read_text())["rows"]) == strip(first)
    # The size summary of the study's variants: an edited one is named, not a row.
    as_written = edited.read_text()
    res = json.loads(as_written)
    res["fe"]["peak_MPa"] = 50.0
    edited.write_text(json.dumps(res))
    p = subprocess.run([sys.executable, "-m", "pipeline.study.summary", str(out / "variants"), "--all"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    with open(out / "summary" / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and float(rows[0]["peak_MPa"]) == pytest.approx(
        next(r["peak_MPa"] for r in first if r["dims.rf"] == 1.5))
    md = (out / "summary" / "summary.md").read_text(encoding="utf-8")
    assert f"{by_rf[1.0]} (results.json does not match its checksum; not summarised)" in md
    # A variant whose results.json is deleted is named too, not dropped in silence.
    edited.write_text(as_written)
    cut.unlink()
    p = subprocess.run([sys.executable, "-m", "pipeline.study.summary", str(out / "variants"), "--all"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    md = (out / "summary" / "summary.md").read_text(encoding="utf-8")
    assert f"{by_rf[1.5]} (results.json is missing; not summarised)" in md
    with open(out / "summary" / "summary.csv", newline="") as f:
        assert [float(r["peak_MPa"]) for r in csv.DictReader(f)] == pytest.approx(
            [next(r["peak_MPa"] for r in first if r["dims.rf"] == 1.0)])


def test_a_variant_changed_while_its_study_runs_is_analysed_again_before_the_summary(tmp_path, monkeypatch):
    """The study checks every variant once its work is done and analyses again one whose
    files changed since their checksums were written, before summarising: the table is
    made of files that match them. (The runs are replaced by ones that write a variant's
    files at once: what is checked here is the study's loop, not the analysis.)"""
    from pipeline.study import sweep as sweep_module
    runs: list[str] = []

    def run_task(task, out, study, screen=False, escalation=None):
        runs.append(task.key)
        folder = a_variant(out, task.key, {"run": len(runs)})
        if len(runs) == 1:  # changed after its checksums: by hand, or by another program
            (folder / "results.json").write_text('{"run": 0}\n')
    read: list[dict] = []
    monkeypatch.setattr(sweep_module, "run_task", run_task)
    monkeypatch.setattr(sweep_module, "write_outputs", lambda tasks, out, axes, allowable: read.extend(
        read_results(variant_folder(out, t.key)) for t in tasks))
    said: list[str] = []
    out = tmp_path / "study"
    sweep_module.execute_sweep(Study("05", None, {"mesh_factor": 3.0}, {"dims.rf": [1.0, 1.5]}, [], levels=1), out,
                               said.append)
    first, second = runs[:2]
    assert runs == [first, second, first]
    assert f"sweep: variant {first} (rf = 1 mm): results.json does not match its checksum; analysed again" in said
    assert sorted(r["run"] for r in read) == [2, 3]
