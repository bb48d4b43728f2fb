"""Nothing reused from the run cache is trusted (pipeline/cache/runs.py and the modules of
each kind): a damaged, truncated, swapped or unreadable entry, or a cache folder that
cannot be read or written, gives the answer of a run with the cache off and one line on
stderr naming the entry; it never fails the run, hangs it, or runs code.

Every answer is compared with a run of the same case with ``CROSSHEAD_NO_CACHE=1`` (the
cache never read or written: independent of it), for equality to the last bit where the
cache is valid or the entry is made again: the reused work is the same mesh and, at the
same load and E, the same solution scaled by 1.
"""
from __future__ import annotations

import contextlib
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pipeline.cache.runs as rc
from pipeline.api import Outputs, RunOptions, write_run
from pipeline.inputs.case import resolve


LEVELS = 3  # the requested mesh and two error-bar meshes: every kind of entry is made
REPOSITORY = Path(__file__).resolve().parents[2]


def the_case():
    return resolve("05", None, {"mesh_factor": 3.0})


def numbers(res: dict) -> dict:
    """The FE block of a run without what differs when work is reused: times (s) and
    where a result was scaled from."""
    def strip(v):
        if isinstance(v, dict):
            return {k: strip(x) for k, x in v.items() if k not in ("time_s", "scaled_from")}
        if isinstance(v, list):
            return [strip(x) for x in v]
        return v
    return strip(res["fe"])


def run(out: Path) -> dict:
    return write_run(the_case(), RunOptions(levels=LEVELS, to_tolerance=False, sensitivity=False,
                                            outputs=Outputs(fields=False)), out)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict:
    """The run with the cache off."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CROSSHEAD_NO_CACHE", "1")
        return run(tmp_path_factory.mktemp("reference") / "out")


@pytest.fixture(scope="module")
def filled(tmp_path_factory, reference) -> Path:
    """A cache folder filled by one run of the case (whose answer is the reference's)."""
    root = tmp_path_factory.mktemp("filled") / "runs"
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CROSSHEAD_NO_CACHE", "0")
        mp.setattr(rc, "ROOT", root)
        assert numbers(run(root.parent / "out")) == numbers(reference)
    # pilot mesh, places, three meshes, three solutions, two error-bar levels' results and
    # the journal load at the two formulas' positions solved on the x1.3 mesh's operator
    assert len(list(root.glob("*.entry"))) == 12
    return root


@pytest.fixture
def cache(filled, tmp_path, monkeypatch) -> Path:
    """A copy of the filled cache as this test's cache folder."""
    root = tmp_path / "runs"
    shutil.copytree(filled, root)
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", root)
    return root


def cache_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("cache:")]


def entry_of(cache: Path, kind: str, largest: bool = True) -> Path:
    """The entry of ``kind`` with the most bytes (the requested mesh's mesh or solution), or
    with the fewest. A repeated run reads only the coarsest error-bar mesh's level entry: the
    first error-bar mesh also solves the hand formulas' load positions, which the level cache
    does not keep, so that mesh is solved again (its solution scaled from the cache)."""
    files = sorted(cache.glob(f"{kind}-*.entry"), key=lambda p: p.stat().st_size)
    return files[-1] if largest else files[0]


def decoded(path: Path) -> rc.Entry:
    return rc.decode(path.name.removesuffix(rc.SUFFIX), bytearray(path.read_bytes()))


def rewritten(path: Path, change) -> None:
    """Change the entry's content with ``change(entry)`` and write it with a valid sha256:
    what only the kind's own checks can catch."""
    e = decoded(path)
    e.arrays = {k: a.copy() for k, a in e.arrays.items()}
    change(e)
    path.write_bytes(rc.encode(path.name.removesuffix(rc.SUFFIX), e))


def array_offset(path: Path, key: str) -> int:
    """Where array ``key``'s first byte lies in the entry file."""
    data = path.read_bytes()
    start = data.index(b"\n") + 1
    n_header = int(data[:start].split()[3])
    offset = start + n_header
    for k, dtype, shape in json.loads(data[start:start + n_header])["arrays"]:
        if k == key:
            return offset
        offset += int(np.prod(shape)) * np.dtype(dtype).itemsize
    raise KeyError(key)


def flip_bit(path: Path, at: int, bit: int) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 1 << bit
    path.write_bytes(bytes(data))


def check_one_line(err: str, path: Path, why: str) -> None:
    lines = cache_lines(err)
    assert len(lines) == 1, err
    assert str(path) in lines[0] and "failed its check" in lines[0] and why in lines[0], lines[0]


@contextlib.contextmanager
def no_hang(seconds: int):
    """Fail the test instead of hanging it (a FIFO opened for reading waits for a writer)."""
    def alarm(signum, frame):
        raise TimeoutError(f"the run hung for {seconds} s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.slow
def test_a_valid_cache_gives_the_cache_off_answer_bit_for_bit_and_says_nothing(cache, reference, tmp_path, capfd):
    res = run(tmp_path / "out")
    assert res["fe"]["scaled_from"] is not None  # reused, not solved
    assert numbers(res) == numbers(reference)
    assert cache_lines(capfd.readouterr().err) == []


# One bit of each kind of entry flipped (an exponent bit of a float where there is one):
# the sha256 differs. ``byte`` counts from the start of the array or, if None, of the JSON
# header (a digit of the numbers).
@pytest.mark.slow
@pytest.mark.parametrize("kind, largest, array, byte, bit", [
    ("mesh", True, "x", 8 * 3 * 100 + 7, 4),  # node 100's x: ×2^16
    ("solution", True, "u_mm", 8 * 3 * 50 + 7, 0),  # node 50's u_x
    ("level", False, None, 40, 0),
    ("pilot", True, None, 40, 0),
])
def test_a_flipped_bit_in_an_entry_is_caught_by_its_checksum(cache, reference, tmp_path, capfd,
                                                             kind, largest, array, byte, bit):
    path = entry_of(cache, kind, largest)
    at = (array_offset(path, array) if array else path.read_bytes().index(b"\n") + 1) + byte
    flip_bit(path, at, bit)
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, "sha256 differs")
    decoded(path)  # made again, whole: the next run reuses it
    run(tmp_path / "again")
    assert cache_lines(capfd.readouterr().err) == []


def _move_fillet_node(reference):
    def change(e: rc.Entry) -> None:
        x = e.arrays["x"]
        node = np.argmin(np.linalg.norm(x - reference["fe"]["peak_location_mm"], axis=1))
        x[node] += (0.0, 0.0, 0.06)  # mm, the probe
    return change


def _scale_one_displacement(e: rc.Entry) -> None:
    e.arrays["u_mm"][50] *= 1.01


def _seat_force(e: rc.Entry) -> None:
    e.meta["seat_force_N"] *= 1.001


def _unsorted_places(e: rc.Entry) -> None:
    e.meta["hotspots"] = e.meta["hotspots"][::-1]


@pytest.mark.slow
@pytest.mark.parametrize("kind, largest, why", [
    ("mesh", True, "volume"),
    ("solution", True, "relative residual"),
    ("level", False, "seat force"),
    ("pilot", True, "places"),
])
def test_an_entry_changed_with_a_valid_checksum_is_caught_by_its_own_checks(cache, reference, tmp_path, capfd,
                                                                           kind, largest, why):
    """The checksum rewritten to match: a fillet node moved 0.06 mm changes the mesh's
    volume; one displacement 1 % off leaves a residual far above the solver's tolerance; a
    level's seat force no longer −Q/4; the pilot's places not in the order a pilot writes."""
    path = entry_of(cache, kind, largest)
    change = {"mesh": _move_fillet_node(reference), "solution": _scale_one_displacement,
              "level": _seat_force, "pilot": _unsorted_places}[kind]
    rewritten(path, change)
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, why)


def _scaled_peaks(e: rc.Entry) -> None:
    """The issue's forgery: both readings of both peaks × 1.2, the checksum written again."""
    for which in ("peak", "critical"):
        for reading in ("unaveraged", "averaged"):
            e.meta[which][reading][0] *= 1.2


def _moved_peak(e: rc.Entry) -> None:
    """The critical peak's unaveraged place moved 0.5 mm along y: no node of the mesh."""
    e.meta["critical"]["unaveraged"][1][1] += 0.5


def _no_derivation(e: rc.Entry) -> None:
    del e.meta["derives_from"]


def _solution_changed(e: rc.Entry) -> None:
    """The solution entry it derives from written again with another content (a key it does
    not read: the same displacement, another sha256)."""
    path = rc.path_of(e.meta["derives_from"]["solution"])
    rewritten(path, lambda sol: sol.meta.__setitem__("rewritten", True))


@pytest.mark.slow
@pytest.mark.parametrize("change, why", [
    (_scaled_peaks, "are not what its solution gives there"),
    (_moved_peak, "places are not nodes of its mesh"),
    (_no_derivation, "it names no mesh and solution it derives from"),
    (_solution_changed, "the solution it derives from has changed since"),
])
def test_a_level_is_checked_against_the_mesh_and_solution_it_derives_from(cache, reference, tmp_path, capfd,
                                                                            change, why):
    """An error-bar mesh's stored readings are read again from the mesh and solution entries
    they derive from before reuse: a checksum proves an entry whole, not true (peaks × 1.2
    with a rewritten checksum would pass it and widen the error bars). Each of these
    is refused with one line, and the run's answer, error bars included, is the reference's
    to the last bit (its mesh solved again)."""
    path = entry_of(cache, "level", largest=False)
    rewritten(path, change)
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, why)


@pytest.mark.slow
def test_a_level_whose_solution_was_evicted_is_dropped_without_a_line(cache, reference, tmp_path, capfd):
    """The solution entries gone (the cache drops the least recently used): each error-bar
    level that derives from one is stale, not damaged: dropped without a line, its mesh
    solved again, the answer the reference's to the last bit."""
    for p in cache.glob("solution-*.entry"):
        p.unlink()
    assert numbers(run(tmp_path / "out")) == numbers(reference)
    assert cache_lines(capfd.readouterr().err) == []


@pytest.mark.slow
def test_an_honest_level_is_read_again_to_its_stored_readings(cache, reference, tmp_path, capfd):
    """The stored readings of both error-bar meshes equal those read again from their mesh
    and solution entries (pipeline/post/reread.py against DOLFINx's reading, to 1e-6; the
    repeated run says nothing), and a run at another load reuses them, scaled."""
    import pipeline.cache.levels as cl
    for path in cache.glob("level-*.entry"):
        m = decoded(path).meta
        assert cl.derivation_problem(m, the_case()) is None, path
    from dataclasses import replace
    res = write_run(replace(the_case(), load_N=12_500.0), RunOptions(levels=LEVELS, to_tolerance=False,
                                                                     sensitivity=False, outputs=Outputs(fields=False)),
                    tmp_path / "out")
    assert cache_lines(capfd.readouterr().err) == []
    assert res["fe"]["levels"][2]["scaled_from"] == {"load_N": 10_000.0, "E_MPa": 210_000.0}
    assert res["fe"]["levels"][2]["peak_MPa"] == pytest.approx(1.25 * reference["fe"]["levels"][2]["peak_MPa"],
                                                               rel=1e-12)


@pytest.mark.slow
def test_a_solution_of_another_mesh_with_the_same_counts_is_not_used(cache, reference, tmp_path, capfd):
    """The stored node positions moved 1e-5 mm (what another mesh of the same counts
    would have): the solution is solved again."""
    path = entry_of(cache, "solution")
    rewritten(path, lambda e: e.arrays["nodes_mm"].__iadd__(1e-5))
    assert numbers(run(tmp_path / "out")) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, "nodes are not this mesh's")


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["truncated", "garbage", "pickle", "huge length", "oversized", "empty"])
def test_a_damaged_entry_is_dropped_with_one_line(cache, reference, tmp_path, capfd, monkeypatch, damage):
    """Truncated to half; random bytes; a pickle of an unsupported protocol (``\\x80\\x63``)
    and one that would make a file if it were unpickled; a first line claiming 10^11
    bytes; a file above the size bound; an empty file."""
    path = entry_of(cache, "solution")
    marker = tmp_path / "unpickled"
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[:len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(np.random.default_rng(1).bytes(5000))
    elif damage == "pickle":
        path.write_bytes(b"\x80\x63" + pickle.dumps(None)[2:])
        evil = pickle.dumps(_Touch(str(marker)))
        (cache / f"{path.stem}.pickle").write_bytes(evil)  # the old format's name: never read
        data = evil
    elif damage == "huge length":
        first = data[:data.index(b"\n")].split()
        path.write_bytes(b" ".join(first[:3] + [b"99999999999", first[4]]) + data[data.index(b"\n"):])
    elif damage == "oversized":
        bound = max(p.stat().st_size for p in cache.iterdir())  # bytes: every other entry fits
        monkeypatch.setattr(rc, "MAX_ENTRY_BYTES", bound)
        path.write_bytes(data + bytes(bound + 1 - len(data)))
    else:
        path.write_bytes(b"")
    with no_hang(120):
        res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    err = capfd.readouterr().err
    check_one_line(err, path, "")
    assert not marker.exists()
    if damage == "pickle":  # an evil entry in the new name is only bytes too
        path.write_bytes(evil)
        run(tmp_path / "again")
        assert not marker.exists()


class _Touch:
    """A pickle that makes a file when it is loaded."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (Path.touch, (Path(self.path),))


@pytest.mark.slow
@pytest.mark.parametrize("what", ["fifo", "symlink to a fifo", "symlink to a valid copy"])
def test_an_entry_that_is_not_a_regular_file_is_not_opened(cache, reference, tmp_path, capfd, what):
    """A FIFO (opening it for reading would wait for a writer for ever) and symlinks are
    refused without reading through them, dropped (the link, never its target) and made
    again."""
    path = entry_of(cache, "solution")
    target = tmp_path / "elsewhere"
    if what == "fifo":
        path.unlink()
        os.mkfifo(path)
    elif what == "symlink to a fifo":
        os.mkfifo(target)
        path.unlink()
        path.symlink_to(target)
    else:
        shutil.copy(path, target)
        path.unlink()
        path.symlink_to(target)
    with no_hang(120):
        res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, "not a regular file" if what == "fifo" else "symbolic link")
    assert path.is_file() and not path.is_symlink()  # made again
    assert target.exists() or what == "fifo"


@pytest.mark.slow
@pytest.mark.parametrize("content", [False, True])
def test_a_folder_named_like_an_entry(cache, reference, tmp_path, capfd, content):
    """An empty folder is removed and the entry made again; a folder with something in it
    is left alone (not the cache's to delete); either way one line, and the run's answer."""
    path = entry_of(cache, "level", largest=False)  # the level a run reads
    path.unlink()
    path.mkdir()
    if content:
        (path / "someone's file").write_text("kept")
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    check_one_line(capfd.readouterr().err, path, "folder")
    if content:
        assert (path / "someone's file").read_text() == "kept"
    else:
        assert path.is_file()


@pytest.mark.slow
def test_a_cache_folder_that_is_a_file_costs_one_line_each_way(reference, tmp_path, capfd, monkeypatch):
    """The cache folder is a file: nothing can be read or written there. The run gives the
    cache-off answer, one line for reading and one for writing, naming the cache folder."""
    root = tmp_path / "runs"
    root.write_text("not a folder")
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", root)
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    lines = cache_lines(capfd.readouterr().err)
    assert len(lines) == 2 and all(str(root) in line for line in lines), lines
    assert root.read_text() == "not a folder"


@pytest.mark.slow
def test_a_full_disk_costs_one_line(cache, reference, tmp_path, capfd, monkeypatch):
    """Every write fails as on a full disk (ENOSPC); the entries there are still read."""
    import errno

    @contextlib.contextmanager
    def full(path, mode="w", **kw):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        yield
    for p in cache.glob("solution-*.entry"):
        p.unlink()  # the solutions must be written again: and cannot
    monkeypatch.setattr(rc, "replacing", full)
    res = run(tmp_path / "out")
    assert numbers(res) == numbers(reference)
    lines = cache_lines(capfd.readouterr().err)
    assert len(lines) == 1 and "No space left on device" in lines[0] and str(cache) in lines[0], lines


@pytest.mark.slow
def test_the_command_line_names_the_cache_not_the_output_folder(filled, tmp_path):
    """The issue's probes through the command line: an entry starting ``\\x80\\x63`` and a
    folder named like an entry end no run (exit 0) and the lines name the cache entries,
    never --out."""
    root = tmp_path / "runs"
    shutil.copytree(filled, root)
    bad = entry_of(root, "solution")
    bad.write_bytes(b"\x80\x63" + bytes(100))
    folder = entry_of(root, "level", largest=False)  # the level a run reads
    folder.unlink()
    folder.mkdir()
    (folder / "x").write_text("x")
    for stray in ("stray.pickle", "stray.entry"):  # folders never looked up: eviction passes them
        (root / stray).mkdir()
    code = ("import sys; from pathlib import Path; import pipeline.cache.runs as rc; "
            f"rc.ROOT = Path({str(root)!r}); from pipeline.cli import main; "
            "sys.exit(main(sys.argv[1:]))")
    out = tmp_path / "out"
    # --no-sensitivity: the sensitivity's load-model ends are solved on the coarsest mesh, which
    # then reads no level entry (the level cache keeps no variants)
    proc = subprocess.run([sys.executable, "-c", code, "run", "--size", "05", "--mesh-factor", "3",
                           "--levels", str(LEVELS), "--no-fields", "--no-sensitivity", "--out", str(out)],
                          cwd=REPOSITORY, env=dict(os.environ, CROSSHEAD_NO_CACHE="0", OPENBLAS_NUM_THREADS="1"),
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    lines = cache_lines(proc.stderr)
    assert len(lines) == 2, proc.stderr
    assert any(str(bad) in line for line in lines) and any(str(folder) in line for line in lines)
    assert "--out" not in proc.stderr and (out / "results.json").is_file()


def test_eviction_subtracts_what_it_removed(tmp_path, monkeypatch):
    """Three small entries and, newest, one above the whole bound: only that one goes
    (it counted towards the total before, and emptied the cache)."""
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path)
    for i, size in enumerate((100, 100, 100, 10_000)):
        (tmp_path / f"x-{i}.entry").write_bytes(bytes(size))
        os.utime(tmp_path / f"x-{i}.entry", ns=(10**18, 10**9 * (100 + i)))
    removed = rc.evict(1_000)
    assert [p.name for p in removed] == ["x-3.entry"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x-0.entry", "x-1.entry", "x-2.entry"]


def test_an_entry_above_the_bound_is_not_kept_and_evicts_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path)
    rc.store("small", rc.Entry({"n": 1}))
    monkeypatch.setattr(rc, "MAX_BYTES", 2 * (tmp_path / "small.entry").stat().st_size)
    rc.store("large", rc.Entry({"n": 2}, {"a": np.zeros(1000)}))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.entry"]
    assert rc.load("small", "redo").meta == {"n": 1}


def _signed(header: bytes, payload: bytes = b"") -> bytearray:
    """An entry file around ``header`` and ``payload`` with a valid sha256 and lengths."""
    import hashlib
    digest = hashlib.sha256(header + payload).hexdigest()
    return bytearray(f"{rc.MAGIC} {rc.VERSION} {digest} {len(header)} {len(payload)}\n".encode() + header + payload)


@pytest.mark.parametrize("header, payload", [
    (b"[" * 100_000 + b"]" * 100_000, b""),  # deeper than the JSON reader's recursion
    (b'{"name": "e", "meta": {}, "arrays": [["a", "|O", [1]]]}', bytes(8)),  # objects
    (b'{"name": "e", "meta": {}, "arrays": [["a", "<f8", [-1]]]}', b""),
    (b'{"name": "e", "meta": {}, "arrays": [["a", "<f8", [10]]]}', bytes(8)),  # runs past the end
    (b'{"name": "e", "meta": {}, "arrays": []}', bytes(8)),  # bytes left over
    (b'{"name": "other", "meta": {}, "arrays": []}', b""),  # another entry's file
    (b'{"name": "e", "meta": [], "arrays": []}', b""),
    (b'{"name": "e", "meta": {}, "arrays": [1]}', b""),
    (b"\xff\xfe", b""),
    (b'{"name": "e", "meta": {}, "arrays": [["a", "<f4", [2]]]}', bytes(8)),  # a number type numpy reads, not one of DTYPES
])
def test_a_well_signed_entry_that_is_not_one_is_refused_as_corrupt(header, payload):
    """What a checksum cannot catch (an entry written to pass it) still gives Corrupt, the
    one failure that drops an entry with its line, never another error that ends the run."""
    with pytest.raises(rc.Corrupt):
        rc.decode("e", _signed(header, payload))


def test_an_entry_reads_back_as_written():
    """Numbers and arrays of each allowed type, an empty array among them, round-trip exactly."""
    e = rc.Entry({"load_N": 10_000.0, "names": {"seat": 3}, "text": "pmg"},
                 {"x": np.linspace(0.0, 1.0, 12).reshape(4, 3), "ids": np.arange(5, dtype=np.int64),
                  "tags": np.arange(3, dtype=np.int32), "msh": np.frombuffer(b"$MeshFormat", dtype=np.uint8),
                  "none": np.zeros((0, 3))})
    back = rc.decode("e", bytearray(rc.encode("e", e)))
    assert back.meta == e.meta
    assert back.arrays.keys() == e.arrays.keys()
    for k, a in e.arrays.items():
        assert back.arrays[k].dtype == a.dtype and np.array_equal(back.arrays[k], a)


def _flipped(data: bytes, at: int) -> bytearray:
    out = bytearray(data)
    out[at] ^= 0x01
    return out


def test_the_checksum_is_sha256_of_everything_after_the_first_line():
    """The first line's digest is hashlib's sha256 of the header and payload bytes that
    follow it, worked out here over the file's bytes, not only over the header."""
    import hashlib
    data = rc.encode("e", rc.Entry({"n": 1}, {"x": np.arange(6, dtype=np.float64)}))
    end = data.index(b"\n")
    digest = data[:end].split(b" ")[2].decode()
    assert digest == hashlib.sha256(data[end + 1:]).hexdigest()


@pytest.mark.parametrize("where", ["header", "payload", "last byte"])
def test_a_flipped_bit_anywhere_after_the_first_line_fails_the_checksum(where):
    """One bit flipped in the JSON header, in an array's bytes, or in the file's last byte:
    Corrupt("sha256 differs"), whatever part the bit is in."""
    data = rc.encode("e", rc.Entry({"n": 1}, {"x": np.arange(6, dtype=np.float64)}))
    start = data.index(b"\n") + 1
    n_header = int(data[:start].split()[3])
    at = {"header": start + n_header // 2, "payload": start + n_header + 12, "last byte": len(data) - 1}[where]
    rc.decode("e", bytearray(data))  # the unflipped entry reads
    with pytest.raises(rc.Corrupt, match="sha256 differs"):
        rc.decode("e", _flipped(data, at))


@pytest.mark.parametrize("size, limit, kept", [(100, 100, True), (101, 100, False), (100, 50, False)])
def test_a_file_above_the_bound_is_not_read(tmp_path, size, limit, kept):
    """read_regular reads a regular file of at most ``limit`` bytes whole, and refuses a
    larger one as Corrupt before reading it (MAX_ENTRY_BYTES for an entry)."""
    path = tmp_path / "x.entry"
    path.write_bytes(bytes(range(256))[:1] * size)
    if kept:
        assert bytes(rc.read_regular(path, limit)) == path.read_bytes()
    else:
        with pytest.raises(rc.Corrupt, match="above the bound"):
            rc.read_regular(path, limit)


@pytest.mark.slow
def test_a_p1_level_is_read_again_to_its_stored_readings(tmp_path, monkeypatch):
    """P1 (its unaveraged reading a cell's constant value, DG0): both error-bar levels of a
    run read back from their mesh and solution entries to their stored readings."""
    import pipeline.cache.levels as cl
    monkeypatch.setenv("CROSSHEAD_NO_CACHE", "0")
    monkeypatch.setattr(rc, "ROOT", tmp_path / "runs")
    case = resolve("05", None, {"mesh_factor": 3.0, "order": 1})
    write_run(case, RunOptions(levels=LEVELS, to_tolerance=False, sensitivity=False, outputs=Outputs(fields=False)),
              tmp_path / "out")
    levels = list((tmp_path / "runs").glob("level-*.entry"))
    assert len(levels) == 2
    for path in levels:
        assert cl.derivation_problem(decoded(path).meta, case) is None, path
