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
