"""pipeline.cache.forms: interrupted form compiles are cleaned up, nothing else is touched."""
import os

from pipeline.cache.forms import STALE_AFTER_S, remove_interrupted


def _touch(path, age_s, now):
    path.write_text("")
    os.utime(path, (now - age_s, now - age_s))


def test_only_old_claims_without_their_mark_are_removed(tmp_path):
    now = 1_000_000.0
    old = STALE_AFTER_S + 60
    _touch(tmp_path / "libffcx_forms_dead.c", old, now)               # killed compile: remove
    _touch(tmp_path / "libffcx_forms_busy.c", 5, now)                 # compiling now: keep
    _touch(tmp_path / "libffcx_forms_done.c", old, now)               # compiled: keep
    _touch(tmp_path / "libffcx_forms_done.c.cached", old, now)
    _touch(tmp_path / "libffcx_forms_done.cpython-311-x86_64-linux-gnu.so", old, now)
    removed = remove_interrupted(tmp_path, now=now)
    assert [p.name for p in removed] == ["libffcx_forms_dead.c"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "libffcx_forms_busy.c", "libffcx_forms_done.c", "libffcx_forms_done.c.cached",
        "libffcx_forms_done.cpython-311-x86_64-linux-gnu.so"]


def test_missing_cache_directory_is_not_an_error(tmp_path):
    assert remove_interrupted(tmp_path / "none") == []
