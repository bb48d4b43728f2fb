"""The memory estimate made before meshing (pipeline/analysis/memory.py) against real meshes,
and the refusal of runs that cannot fit (exit 2 before any meshing)."""
from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest

from pipeline.inputs.case import resolve
from pipeline.fe.meshing import Mesher
from pipeline.analysis.memory import REFINED_PLACES, estimate, needs_probe, probe

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
@pytest.mark.parametrize("size,factor", [("05", 0.7), ("1.6", 0.8)])
def test_estimate_bounds_the_real_mesh(size, factor):
    """The estimated tet count (without the refined-places allowance) lies between the real
    count of the same mesh and twice it: conservative, never absurd. The real mesh is the
    independent source."""
    case = resolve(size)
    est = estimate(case, [factor], *probe(case))
    with Mesher(case.dims, case.model) as m:
        real = len(m.generate(replace(case.mesh_spec(factor), order=1)).cells)
    ratio = est.tets / REFINED_PLACES / real
    assert 1.0 <= ratio <= 2.0, (est.tets, real, ratio)


def test_default_runs_need_no_probe():
    case = resolve("05")
    assert not needs_probe(case, [1.0, 1.3, 1.69])
    assert needs_probe(case, [0.5])
    assert needs_probe(resolve("05", None, {"dims.rf": 0.5}), [1.0])


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--no-fields", *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("args", [["--mesh-factor", "0.05"], ["--order", "3", "--mesh-factor", "0.3"],
                                  ["--mesh-factor", "0.7", "--memory-limit", "0.01"]])
def test_runs_that_cannot_fit_are_refused_before_meshing(tmp_path, args):
    t0 = time.perf_counter()
    p = cli(*args, "--out", str(tmp_path / "out"))
    assert time.perf_counter() - t0 < 20
    assert p.returncode == 2, p.stderr
    line, = p.stderr.strip().splitlines()
    assert line.startswith("error: mesh_factor:") and "--memory-limit" in line and "GiB" in line
    assert not (tmp_path / "out").exists() and list(tmp_path.iterdir()) == []


def test_meshing_heartbeat_says_it_is_still_working():
    """gmsh gives no progress while it meshes: a heartbeat line every interval, none after."""
    from pipeline.fe.meshing import heartbeat
    lines: list[str] = []
    with heartbeat(lines.append, "meshing ×0.5", every_s=0.1):
        time.sleep(0.35)
    n = len(lines)
    time.sleep(0.25)
    assert 2 <= n <= 4 and len(lines) == n
    assert all(line.startswith("meshing ×0.5: still working") for line in lines)


GIB = 2.0 ** 30


def _tree(tmp_path: Path, cgroup: str, files: dict[str, str]) -> tuple[Path, Path]:
    """A /proc/self/cgroup of one line and a /sys/fs/cgroup tree with the given files."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    proc = tmp_path / "cgroup"
    proc.write_text(cgroup + "\n")
    root = tmp_path / "sys"
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text + "\n")
    return proc, root


def test_a_slurm_job_s_memory_limit_is_found_above_its_task(tmp_path):
    """cgroup v2 as Slurm sets it: --mem on the job's level (4 GiB, 1 GiB used), none on
    the task's: 3 GiB left, however much the node has free."""
    from pipeline.analysis.memory import cgroup_room_bytes
    proc, root = _tree(tmp_path, "0::/job_7/step_0/task_0", {
        "job_7/memory.max": str(int(4 * GIB)), "job_7/memory.current": str(int(GIB)),
        "job_7/step_0/task_0/memory.max": "max", "job_7/step_0/task_0/memory.current": str(int(0.5 * GIB))})
    assert cgroup_room_bytes(proc, root) == pytest.approx(3 * GIB)


def test_a_container_s_limit_is_read_at_its_own_root_and_no_limit_is_none(tmp_path):
    """cgroup v1 in a container: the group named in /proc/self/cgroup is not in the
    container's view of the tree, whose root is its own group (2 GiB, 0.5 used). A limit
    of 2^63 (v1's 'none') is no limit; nothing readable is no limit either."""
    from pipeline.analysis.memory import cgroup_room_bytes
    proc, root = _tree(tmp_path, "4:memory:/docker/abc", {
        "memory/memory.limit_in_bytes": str(int(2 * GIB)), "memory/memory.usage_in_bytes": str(int(0.5 * GIB))})
    assert cgroup_room_bytes(proc, root) == pytest.approx(1.5 * GIB)
    proc, root = _tree(tmp_path / "free", "4:memory:/", {
        "memory/memory.limit_in_bytes": "9223372036854771712", "memory/memory.usage_in_bytes": "1"})
    assert cgroup_room_bytes(proc, root) is None
    assert cgroup_room_bytes(tmp_path / "missing", root) is None


def test_a_part_outside_the_table_s_proportions_is_probed():
    """Every size-table row at the default mesh needs no probe; a part small in one feature
    against its length (h3 = 1 mm, dj = 0.5 mm, rf = 0.1 mm on No. 05: 626 159 tets on the
    default mesh, counted when the defect was reported) is probed, by the proportions it
    has outside the table's."""
    from geometry.table import load_table
    from pipeline.analysis.memory import unusual_proportions
    assert not any(needs_probe(resolve(size), [1.0, 1.3, 1.69]) for size in load_table())
    thin = resolve("05", None, {"dims.h3": 1.0, "dims.dj": 0.5, "dims.rf": 0.1})
    assert needs_probe(thin, [1.0]) and {"h3/b6", "dj/b6"} <= set(unusual_proportions(thin))


@pytest.mark.slow
def test_the_estimate_of_a_part_large_by_its_shape_bounds_its_mesh():
    thin = resolve("05", None, {"dims.h3": 1.0, "dims.dj": 0.5, "dims.rf": 0.1})
    est = estimate(thin, [1.0, 1.3, 1.69], *probe(thin))
    assert 626_159 <= est.tets <= 3 * 626_159
