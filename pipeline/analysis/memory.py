"""Will the run fit in memory? An estimate of elements, DOFs and bytes before any meshing.

Element sizes scale with the mesh factor f, but the tet count grows more slowly than f^-3
at practical factors because much of the mesh sits in graded layers along the features
(measured on No. 05 with default sizes, no refined places: 1 927 / 5 954 / 23 204 / 50 255
tets at f = 4 / 2 / 1 / 0.7, a local exponent of 1.6 → 2.0 → 2.2). So a cheap probe mesh
at f = 2 is scaled by (2/f)^2.5: 45–65 % above the real count at f = 1 and 0.7, and
approaching the f^-3 of the body at fine factors. The pilot's refined places add about 70 %
(No. 05 ×1: 39 079 against 23 204 tets). Bytes per DOF come from `make bench`'s peak
memory (docs/performance.md), with a margin of 1.5.
"""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

from pipeline.errors import InputError
from pipeline.fe.meshing import Mesher
from pipeline.inputs.case import Case
from pipeline.runtime.environment import ADDRESS_FLOOR, GIB, address_space_limit

PROBE_FACTOR = 2.0
EXPONENT = 2.5
REFINED_PLACES = 1.7  # the pilot's balls: tets with / without them at No. 05 ×1
DOFS_PER_TET = {1: 0.6, 2: 4.7, 3: 15.3}  # vector DOFs per tet (No. 05 meshes)
# Bytes per DOF of the whole solve (matrix, preconditioner, vectors), P2; P3 × 1.7.
BYTES_PER_DOF = {"pmg": 1.2e3, "gamg": 2.1e3, "hypre": 6.0e3, "mumps": 7.6e3}
MARGIN = 1.5
BASE_BYTES = 250e6  # one process with DOLFINx, PETSc and gmsh loaded, no mesh
# The address space a drawing process needs (the picture's, with VTK and Mesa's OpenGL):
# 1.15 GiB measured for No. 05's default mesh, and a margin. A run with fields starts them.
DRAWING_ADDRESS = 1.3 * GIB


@dataclass(frozen=True)
class Estimate:
    """What the finest mesh and the whole run need (tets, DOFs, bytes)."""

    tets: int
    dofs: int
    bytes: float


def available_bytes() -> float:
    """Memory this process can have now, bytes: what the machine has free (MemAvailable of
    /proc/meminfo), or less when its control group caps it (a Slurm job's --mem, a
    container's limit: the kernel ends a process that passes it, however much the machine
    has free)."""
    free = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = float(line.split()[1]) * 1024
    except OSError:
        pass
    if free is None:
        free = float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    room = cgroup_room_bytes()
    return free if room is None else min(free, room)


NO_LIMIT = 2.0 ** 60  # cgroup v1 writes "no limit" as a number near 2^63


def cgroup_room_bytes(proc_cgroup: Path = Path("/proc/self/cgroup"),
                      root: Path = Path("/sys/fs/cgroup")) -> float | None:
    """What this process's memory control group and its ancestors still allow (limit −
    usage, the smallest over the levels that set a limit), bytes; None when no level sets
    one or nothing can be read. cgroup v2 (memory.max, memory.current) and v1 (the memory
    controller's limit_in_bytes, usage_in_bytes). A container sees its own group as the
    root of the tree; a Slurm job's limit sits on a level above its task's."""
    try:
        lines = proc_cgroup.read_text(encoding="utf-8").splitlines()
    except OSError:
        return None
    rooms = []
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        hierarchy, controllers, path = parts
        if hierarchy == "0" and controllers == "":
            base, names = root, ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):
            base, names = root / "memory", ("memory.limit_in_bytes", "memory.usage_in_bytes")
        else:
            continue
        group = base / path.strip("/")
        for level in [group, *group.parents]:
            if len(level.parts) < len(base.parts):
                break
            try:
                limit_text = (level / names[0]).read_text(encoding="utf-8").strip()
                used = float((level / names[1]).read_text(encoding="utf-8").strip())
            except (OSError, ValueError):
                continue
            if limit_text != "max" and float(limit_text) < NO_LIMIT:
                rooms.append(max(float(limit_text) - used, 0.0))
    return min(rooms) if rooms else None


# Proportions of the part whose extremes the size table spans: below them a part is small in
# one feature against its length (thin, or with thin journals or a small fillet), and the
# default sizes, set by the features, put far more tets into it than the table's rows have.
PROPORTIONS = {"h3/b6": lambda d: d.h3 / d.b6, "dj/b6": lambda d: d.dj / d.b6, "rf/dj": lambda d: d.rf / d.dj,
               "dj/b1": lambda d: d.dj / d.b1}
OUTSIDE_TABLE = 0.8  # a proportion below this fraction of the table's smallest is outside it


@functools.cache
def _table_proportions() -> dict[str, float]:
    """The smallest of each proportion over the rows of the size table (geometry/sizes.csv)."""
    from geometry.table import load_table
    rows = [r.dims for r in load_table().values()]
    return {name: min(f(d) for d in rows) for name, f in PROPORTIONS.items()}


def unusual_proportions(case: Case) -> list[str]:
    """The proportions of the case's part that lie below the size table's (named), where the
    estimate's tets-per-factor law, measured on table rows, does not hold."""
    least = _table_proportions()
    return [name for name, f in PROPORTIONS.items() if f(case.dims) < OUTSIDE_TABLE * least[name]]


def needs_probe(case: Case, factors: Sequence[float]) -> bool:
    """Whether the run could be large: finer than the default mesh, sizes set by hand, a
    fillet much smaller than the default (its elements are rf/4), or a part whose
    proportions lie outside the size table's (a part large by its shape)."""
    small_fillet = case.dims.rf < 0.03 * case.dims.h3  # half the default 0.06·h3
    by_hand = any(getattr(case, k) is not None for k in
                  ("size_body_mm", "size_feature_mm", "size_fillet_mm", "grading_mm"))
    return min(factors) < 0.8 or by_hand or small_fillet or bool(unusual_proportions(case))


def estimate(case: Case, factors: Sequence[float], probe_tets: int, probe_factor: float) -> Estimate:
    """Elements, DOFs and bytes of a run solving meshes at ``factors`` (the finest is the
    estimate's tets and DOFs; bytes add every mesh, since the error-bar meshes are solved
    at the same time on other ranks), from a probe mesh of ``probe_tets`` at ``probe_factor``."""
    per_dof = BYTES_PER_DOF[case.solver] * (1.7 if case.order == 3 else 1.0) * MARGIN

    def tets(f: float) -> float:
        return probe_tets * (probe_factor / f) ** EXPONENT * REFINED_PLACES
    finest = min(factors)
    dofs = [tets(f) * DOFS_PER_TET[case.order] for f in factors]
    return Estimate(tets=int(tets(finest)), dofs=int(max(dofs)),
                    bytes=BASE_BYTES + sum(d * per_dof for d in dofs))


def probe(case: Case) -> tuple[int, float]:
    """(tets, factor) of a quick first-order mesh at PROBE_FACTOR (no refined places)."""
    f = PROBE_FACTOR
    with Mesher(case.dims, case.model) as m:
        part = m.generate(replace(case.mesh_spec(f), order=1))
    return len(part.cells), f


def address_space_need(est: Estimate) -> float:
    """The address space (bytes) the run's own process needs: ADDRESS_FLOOR for what is
    loaded, and the estimate's bytes beyond a process without a mesh, without the
    estimate's margin (the floor has its own). No. 05's default run: 1.43 GiB, against
    1.03 GiB measured (VmPeak, sensitivity section included)."""
    return ADDRESS_FLOOR + (est.bytes - BASE_BYTES) / MARGIN


def check_fits(case: Case, factors: Sequence[float], limit_gb: float | None, copies: int = 1,
               what: str = "", drawing: bool = False) -> Estimate | None:
    """Refuse (InputError, exit 2) a run whose estimate exceeds ``limit_gb`` (default: the
    memory available now), or whose process would need more address space than its limit
    (``ulimit -v``: :func:`address_space_need`, ``drawing``: the run starts drawing
    processes); None when the run is plainly small and has no such limit (no probe
    needed). ``copies``: how many such runs this machine holds at once (a study's variants
    on the ranks that share its memory); ``what`` names the run in the line (a study's
    variant)."""
    room = address_space_limit()
    if not needs_probe(case, factors) and room is None:
        return None
    est = estimate(case, factors, *probe(case))
    if room is not None and address_space_need(est) > room:
        raise InputError(
            f"memory: {what}the address space is limited to {room / GIB:.2f} GiB (ulimit -v), and this run needs "
            f"about {address_space_need(est) / GIB:.1f} GiB of it (the finest mesh, factor {min(factors):g}: about "
            f"{est.dofs:.1e} DOFs); raise the limit, or use a coarser --mesh-factor")
    if room is not None and drawing and DRAWING_ADDRESS > room:
        raise InputError(
            f"memory: the address space is limited to {room / GIB:.2f} GiB (ulimit -v), and each drawing process (the "
            f"picture, the close-ups) needs about {DRAWING_ADDRESS / GIB:.1f} GiB of it; raise the limit, or give "
            "--no-fields")
    limit = available_bytes() if limit_gb is None else limit_gb * 1024 ** 3
    if est.bytes * copies > limit:
        finest = min(factors)
        at_once = f", {copies} at once {est.bytes * copies / 1024 ** 3:.1f} GiB" if copies > 1 else ""
        raise InputError(
            f"mesh_factor: {what}the finest mesh (factor {finest:g}) needs about {est.tets:.1e} tets, "
            f"{est.dofs:.1e} DOFs and {est.bytes / 1024 ** 3:.1f} GiB in all{at_once}; "
            f"{limit / 1024 ** 3:.1f} GiB {'allowed' if limit_gb is not None else 'available'} "
            f"(use a coarser --mesh-factor, or --memory-limit GB to override)")
    return est
