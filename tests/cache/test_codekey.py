"""The one code key (pipeline.cache.codekey) that every cache entry and study variant holds."""
import shutil
from pathlib import Path

from pipeline.cache import codekey

from pipeline.cache import runs as runcache

ROOT = Path(__file__).resolve().parents[2]


def _copy(tmp_path: Path) -> Path:
    for folder in codekey.PACKAGES:
        shutil.copytree(ROOT / folder, tmp_path / folder, ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def test_a_changed_byte_in_a_subfolder_changes_the_key(tmp_path):
    root = _copy(tmp_path)
    sub = root / "pipeline" / "somewhere" / "deeper"
    sub.mkdir(parents=True)
    (sub / "module.py").write_text("x = 1\n")
    before = codekey.code_key(root)
    (sub / "module.py").write_text("x = 2\n")
    codekey.code_key.cache_clear()
    assert codekey.code_key(root) != before


def test_a_file_moved_or_added_changes_the_key(tmp_path):
    root = _copy(tmp_path)
    before = codekey.code_key(root)
    (root / "geometry" / "new").mkdir()
    shutil.move(root / "geometry" / "places.py", root / "geometry" / "new" / "places.py")
    codekey.code_key.cache_clear()
    moved = codekey.code_key(root)
    assert moved != before
    (root / "geometry" / "new" / "extra.py").write_text("")
    codekey.code_key.cache_clear()
    assert codekey.code_key(root) != moved


def test_the_key_covers_every_source_file_and_the_tables():
    names = {f.relative_to(ROOT).as_posix() for f in codekey.source_files()}
    on_disk = {f.relative_to(ROOT).as_posix() for p in ("pipeline", "geometry") for f in (ROOT / p).rglob("*.py")
               if "__pycache__" not in f.parts}
    assert on_disk <= names
    assert "geometry/sizes.csv" in names


def test_every_cache_key_holds_the_code_key(monkeypatch):
    keys = set()
    for code in ("old", "new"):
        monkeypatch.setattr(runcache, "code_key", lambda code=code: code)
        keys.add(runcache.key("mesh", spec={"factor": 1.0}))
    assert len(keys) == 2
