"""bench.run_cost: the medians and pairwise ratios of the sensitivity section's cost bench,
against figures worked by hand."""
from pathlib import Path

import pytest

from bench.run_cost import command, launcher, summarise, targets


def test_medians_and_pairwise_ratios_by_hand():
    walls = {"with": [20.0, 16.0, 30.0], "without": [10.0, 8.0, 12.0], "base": [8.0, 10.0, 10.0]}
    s = summarise(walls)
    assert s["with"]["median_s"] == 20.0 and s["base"]["median_s"] == 10.0
    # pairs 20/8 = 2.5, 16/10 = 1.6, 30/10 = 3.0: median 2.5 (not 20/10 of the medians)
    assert s["with_over_base"]["median"] == 2.5
    assert (s["with_over_base"]["min"], s["with_over_base"]["max"]) == (1.6, 3.0)
    assert s["with_over_without"]["median"] == 2.0  # 2.0, 2.0, 2.5
    assert s["met"] is False  # 2.5 > 1.2


def test_the_earlier_tree_gets_its_own_launcher(tmp_path: Path):
    (tmp_path / "pipeline").mkdir()
    assert launcher(tmp_path) == "pipeline.launch"
    (tmp_path / "pipeline" / "runtime").mkdir()
    (tmp_path / "pipeline" / "runtime" / "launch.py").write_text("")
    assert launcher(tmp_path) == "pipeline.runtime.launch"
    cmd = command("without", tmp_path, tmp_path / "o")
    assert cmd[-1] == "--no-sensitivity" and cmd[cmd.index("--size") + 1] == "05"
    assert "--no-sensitivity" not in command("with", tmp_path, tmp_path / "o")


def test_cpu_ratios_pair_by_pair_by_hand():
    walls = {"with": [2.0, 2.0, 2.0], "without": [1.0, 1.0, 1.0], "base": [1.0, 1.0, 1.0]}
    cpus = {"with": [30.0, 36.0, 40.0], "without": [15.0, 18.0, 20.0], "base": [10.0, 20.0, 16.0]}
    s = summarise(walls, cpus)
    # pairs 30/10 = 3.0, 36/20 = 1.8, 40/16 = 2.5: median 2.5
    assert s["cpu_with_over_base"]["median"] == 2.5 and s["with"]["cpu_median_s"] == 36.0
    assert s["cpu_without_over_base"]["median"] == 1.25  # 1.5, 0.9, 1.25


def test_every_target_is_judged_on_its_own_side_by_hand():
    """make run 2.5x (wall, at most 1.2: no), CPU 1.25x (at most 1.5: yes), the re-run
    3/10 = 0.3 (at most 0.30: yes), the scene 3.3 s of CalculiX over 1.0 s = 3.3x (at
    least 3: yes); a screened study without sweeps.json: not measured."""
    walls = {"with": [20.0], "without": [10.0], "base": [8.0], "reload": [2.4], "scene": [1.0]}
    cpus = {"with": [30.0], "without": [15.0], "base": [24.0], "reload": [3.0], "scene": [1.0]}
    peer = {"comparison": {"critical_stays": {"peer": {"t_wall": 3.3}}}}
    rows = {r["target"].split(" <=")[0].split(" >=")[0].split(",")[0]: r
            for r in targets(summarise(walls, cpus), "83d9271", peer, None)}
    assert rows["make run wall"]["ratio"] == 2.5 and rows["make run wall"]["met"] is False
    assert rows["make run CPU"]["ratio"] == 1.25 and rows["make run CPU"]["met"] is True
    assert rows["changed-load re-run"]["ratio"] == pytest.approx(0.3) and rows["changed-load re-run"]["met"] is True
    assert rows["critical-peak scene"]["ratio"] == pytest.approx(3.3) and rows["critical-peak scene"]["met"] is True
    screened = next(r for k, r in rows.items() if k.startswith("screened"))
    assert screened["ratio"] is None and screened["met"] is None and "not measured" in screened["figures"]


def test_the_re_run_first_runs_its_part_at_the_old_load(tmp_path: Path):
    cmd = command("reload", tmp_path, tmp_path / "o", 1.202, 10000.0)
    assert cmd[cmd.index("--dim") + 1] == "rf=1.202" and cmd[cmd.index("--load") + 1] == "10000"
    scene = command("scene", tmp_path, tmp_path / "o")
    assert scene[1:4] == ["-m", "pipeline", "run"] and "critical" in scene and "--no-fields" in scene
