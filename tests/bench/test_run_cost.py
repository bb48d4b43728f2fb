"""bench.run_cost: the medians and pairwise ratios of the sensitivity section's cost bench,
against figures worked by hand."""
from pathlib import Path

from bench.run_cost import command, launcher, summarise


def test_medians_and_pairwise_ratios_by_hand():
    walls = {"with": [20.0, 16.0, 30.0], "without": [10.0, 8.0, 12.0], "base": [8.0, 10.0, 10.0]}
    s = summarise(walls)
    assert s["with"]["median_s"] == 20.0 and s["base"]["median_s"] == 10.0
    # pairs 20/8 = 2.5, 16/10 = 1.6, 30/10 = 3.0: median 2.5 (not 20/10 of the medians)
    assert s["with_over_base"]["median"] == 2.5
    assert (s["with_over_base"]["min"], s["with_over_base"]["max"]) == (1.6, 3.0)
    assert s["with_over_without"]["median"] == 2.0  # 2.0, 2.0, 2.5
    assert s["met"] is False


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
