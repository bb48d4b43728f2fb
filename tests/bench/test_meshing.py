"""bench.meshing: bad arguments stop with exit 2 and one line; the table lays out every stage."""
from bench import meshing
from geometry.sizing import STAGES


def test_unknown_option_set_and_bad_factors_exit_2(capsys):
    assert meshing.main(["--variants", "default,nope"]) == 2
    assert meshing.main(["--factors", "1,x"]) == 2
    assert meshing.main(["--repeats", "0"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["--variants: unknown nope", "--factors: not numbers: 1,x", "--repeats: at least 1"]


def test_table_has_a_column_per_stage_and_marks_a_failed_set():
    row = {"mesh": "05 ×1", "variant": "default", "dofs": 9, "stage_cpu_s": {s: 0.5 for s in STAGES},
           "total_cpu_s": 3.0, "total_s": 4.0, "ratio_cpu_s": 1.0, "ratio_s": 1.0, "same_mesh": True}
    failed = {"mesh": "05 ×1", "variant": "netgen", "error": "not compiled"}
    lines = meshing.table([row, failed]).splitlines()
    assert len({line.count("|") for line in lines}) == 1      # every row as wide as the header
    assert lines[2].split("|")[4:10] == [" 0.50 "] * len(STAGES)
    assert "failed: not compiled" in lines[3]


def test_volumes_go_to_ranks_longest_first():
    assert meshing.lpt({1: 0.25, 2: 0.14, 3: 0.08}, 2) == [[1], [2, 3]]
    assert meshing.lpt({1: 0.41, 2: 0.10, 3: 0.07, 4: 0.10, 5: 0.07}, 2) == [[1], [2, 4, 3, 5]]


def test_volumes_table_lays_out_every_volume():
    row = {"mesh": "05 ×1", "volumes": [{"volume": 1, "tets": 30, "cpu_s": 0.3}, {"volume": 2, "tets": 10, "cpu_s": 0.1}],
           "stage_cpu_s_whole": {s: 0.4 for s in STAGES}, "total_cpu_s_whole": 2.4, "bound_cpu_s": 2.1,
           "total_cpu_s_split": 2.4, "ratio": 0.875, "ratio_rest_split": 0.7, "same_linear_mesh": True,
           "linear_tets_differing": 0, "same_mesh": True}
    lines = meshing.volumes_table([row]).splitlines()
    assert len({line.count("|") for line in lines}) == 1
    assert lines[2].split("|")[3:5] == [" 30 + 10 ", " 0.30 + 0.10 "]
