"""The .vtu writer: what VTK's zlib layout requires of each appended block, and that a
rank bound to one core compresses on every core and stays bound (mm, MPa in the arrays;
the writer itself is unit-free)."""
from __future__ import annotations

import os
import zlib

import meshio
import numpy as np
import pytest

from pipeline.output import vtu


def _blocks(payload: bytes) -> list[bytes]:
    """The chunks of one appended block, inflated: VTK's layout read back (UInt64 header:
    chunk count, chunk size, last chunk's size, each chunk's compressed size)."""
    n = int(np.frombuffer(payload[:8], dtype=np.uint64)[0])
    head = np.frombuffer(payload[:8 * (3 + n)], dtype=np.uint64)
    sizes, at, out = head[3:], 8 * (3 + n), []
    for s in sizes:
        out.append(zlib.decompress(payload[at:at + int(s)]))
        at += int(s)
    assert at == len(payload)
    return out


def test_a_block_compressed_by_threads_is_the_block_compressed_alone():
    data = np.cumsum(np.random.default_rng(1).normal(size=(3 * vtu.CHUNK_BYTES // 8 + 17))).tobytes()
    alone = vtu._compressed(data)
    with vtu._machine_wide_pool() as pool:
        threaded = vtu._compressed(data, pool)
    assert threaded == alone
    chunks = _blocks(threaded)
    assert len(chunks) == 4 and b"".join(chunks) == data


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity") or (os.cpu_count() or 1) < 2, reason="one core")
def test_a_thread_bound_to_one_core_is_bound_to_it_after_writing(tmp_path):
    before = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, {min(before)})
        pts = np.random.default_rng(2).random((40, 3))
        cells = np.arange(40).reshape(10, 4)
        vm = np.linspace(0.0, 100.0, 40)
        vtu.write_vtu(tmp_path / "f.vtu", pts, cells, "tetra", {"von_mises_MPa": vm}, scalars="von_mises_MPa")
        assert os.sched_getaffinity(0) == {min(before)}
    finally:
        os.sched_setaffinity(0, before)
    m = meshio.read(tmp_path / "f.vtu")
    np.testing.assert_array_equal(m.point_data["von_mises_MPa"], vm)
    np.testing.assert_array_equal(m.cells_dict["tetra"], cells)
