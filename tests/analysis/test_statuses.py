"""A peak's status, decided once (pipeline/analysis/words.py peak_status) and said alike by
every output: the words, their order of precedence, and agreement with the run's own test
of the tolerance (pipeline/analysis/tolerance.py within), the independent rule here."""
from __future__ import annotations

import pytest

from pipeline.analysis.tolerance import within
from pipeline.analysis.words import (ABOVE_TOLERANCE, NOT_ASKED, PEAK_STATUSES, SINGLE_MESH, SINGULAR,
                                     WITHIN_TOLERANCE, peak_status, verdict_word)


def test_a_peak_not_asked_for_or_singular_or_on_one_mesh_says_so_first():
    """not asked wins over singular (its growth is an unrefined mesh's), singular over a
    band (it has none to trust), no band is a single mesh."""
    assert peak_status(1.0, 100.0, 0.5, "edge", wanted=False) == NOT_ASKED
    assert peak_status(1.0, 100.0, 0.5, "edge", wanted=True) == SINGULAR
    assert peak_status(1.0, 100.0, None, None, wanted=True) == SINGLE_MESH
    assert set(PEAK_STATUSES) == {WITHIN_TOLERANCE, ABOVE_TOLERANCE, SINGLE_MESH, SINGULAR, NOT_ASKED}


@pytest.mark.parametrize("value,band,tolerance", [(113.77, 0.73, 1.0), (100.0, 1.0, 1.0), (100.0, 1.0000001, 1.0),
                                                  (114.28, 2.37, 1.0), (114.28, 2.37, 2.5), (66.22, 0.0, 0.1),
                                                  (100.0, 3.0, 0.5)])
def test_within_tolerance_is_the_run_s_own_test_of_its_accuracy(value, band, tolerance):
    """A peak (MPa) with its band (MPa) is within the tolerance (%) exactly when the run's
    accuracy says its band is (tolerance.within), the boundary included."""
    status = peak_status(tolerance, value, band, None, wanted=True)
    assert (status == WITHIN_TOLERANCE) == within({"global": 100 * band / value}, tolerance)
    assert status in (WITHIN_TOLERANCE, ABOVE_TOLERANCE)


def test_the_verdict_words_a_person_reads():
    assert [verdict_word(v) for v in ("pass", "fail", "undecided", "none")] == ["PASS", "FAIL", "UNDECIDED",
                                                                              "no verdict"]
