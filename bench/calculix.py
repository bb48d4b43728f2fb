"""The crosshead in CalculiX (ccx 2.20, C3D10) on the very mesh DOLFINx solves (mm, N, MPa).

The peer of the bench: the same gmsh second-order mesh, the same supports and
the same loads, so that CalculiX and this pipeline solve the same discrete problem and
differ only in element formulation (quadrature) and linear solver.

- Nodes: the second-order gmsh nodes as DOLFINx imported them (``mesh.geometry.x``),
  numbered 1..N; elements: ``mesh.geometry.dofmap`` reordered to the C3D10 node order
  (DOLFINx tetra10 → C3D10 is ``DOLFINX_TO_C3D10``; it equals gmsh's tetra10 order with
  the last two nodes swapped, docs/stack.md). Curved (isoparametric) mid-side nodes are kept.
- Supports: the DOFs the pipeline's own Dirichlet conditions fix (pipeline.fe.solve), as
  node sets with ``*BOUNDARY``.
- Loads: ``*CLOAD`` nodal forces equal to the consistent load vector DOLFINx assembles
  for the same tractions (P2 on P2 geometry: one vector DOF block per geometry node).
- Output: ``*NODE PRINT`` of U to the .dat file, read back into a DOLFINx P2 function
  so von Mises and its peaks come from pipeline.post.peaks, exactly as for the pipeline.

CalculiX reads every number from a field of at most 20 characters (docs/stack.md): floats are
written with 12 significant digits (``%.12g``: at most 19 characters), every input line
stays below CalculiX's 132-character limit. Serial only (one MPI rank).
"""
from __future__ import annotations

import os
import resource
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from pipeline.api import (LevelTask, LoadCase, Material, NumericalError, RunContext, dirichlet_bc, peaks_of,
                          resolve_case, set_up, solve_level)

# Local node i of a C3D10 element is DOLFINx tetra10 node DOLFINX_TO_C3D10[i].
# DOLFINx: vertices 0-3, then edges (2,3) (1,3) (1,2) (0,3) (0,2) (0,1).
# C3D10:   vertices 0-3, then edges (0,1) (1,2) (2,0) (0,3) (1,3) (2,3).
DOLFINX_TO_C3D10 = np.array([0, 1, 2, 3, 9, 6, 8, 7, 5, 4])
# Reordering of a C3D10 connectivity that swaps vertices 1 and 2 (flips the orientation).
C3D10_FLIP = np.array([0, 2, 1, 3, 6, 5, 4, 7, 9, 8])
FIELD_MAX = 20          # CalculiX's field width
LINE_MAX = 132          # CalculiX's input line width
SIG_DIGITS = 12


def fmt(x: float) -> str:
    """A float for a CalculiX field: 12 significant digits, at most 19 characters."""
    s = f"{x:.{SIG_DIGITS}g}"
    assert len(s) <= FIELD_MAX, s
    return s


@dataclass
class CcxModel:
    """The CalculiX model of one mesh: C3D10 connectivity (1-based), loads and supports.

    ``dof_node[k]`` is the geometry node (0-based) of vector-P2 DOF block k, so a nodal
    field U (nodes × 3) becomes DOLFINx DOF values by ``U[dof_node]``.
    """

    nodes: np.ndarray            # (N, 3) mm
    elements: np.ndarray         # (E, 10) 1-based node ids, C3D10 order
    fixed: dict[int, np.ndarray]  # component (0..2) -> 1-based node ids with u_comp = 0
    loads: np.ndarray            # (N, 3) N, consistent nodal forces
    dof_node: np.ndarray         # (DOF blocks,) 0-based node index
    V: object                    # the DOLFINx vector P2 space
    flipped: int = 0             # elements whose orientation had to be reversed


def build_model(mesh, facet_tags, lc: LoadCase) -> CcxModel:
    """Nodes, C3D10 elements, fixed node sets and consistent nodal loads of ``mesh``.

    The mesh must have second-order (tetra10) geometry and live on one rank.
    """
    if mesh.comm.size != 1:
        raise NumericalError("the CalculiX peer runs on one MPI rank only")
    nodes, cells = _used_nodes(mesh.geometry)
    V = fem.VectorFunctionSpace(mesh, ("Lagrange", 2))
    dof_node = _dof_nodes(V, cells, nodes)
    elems, flipped = _c3d10_elements(cells, nodes)
    fixed_ids = _fixed_nodes(V, facet_tags, lc, dof_node)
    loads = _nodal_loads(mesh, V, facet_tags, lc, dof_node, nodes)
    return CcxModel(nodes=nodes, elements=elems + 1, fixed=fixed_ids, loads=loads,
                    dof_node=dof_node, V=V, flipped=flipped)


def _used_nodes(geo) -> tuple[np.ndarray, np.ndarray]:
    """The geometry nodes the cells use (N × 3, mm), renumbered 0..N-1 (an unused node
    would be an orphan in CalculiX), and the cells' tetra10 connectivity in that numbering
    (DOLFINx node order)."""
    gdm = geo.dofmap.array.reshape(-1, geo.dofmap.offsets[1])
    if gdm.shape[1] != 10:
        raise ValueError(f"CalculiX C3D10 needs a second-order tetrahedral mesh, got {gdm.shape[1]} nodes per cell")
    used = np.unique(gdm)
    x = geo.x[:, :3]
    new = np.full(x.shape[0], -1, dtype=np.int64)
    new[used] = np.arange(used.size)
    return x[used], new[gdm]


def _dof_nodes(V, cells: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The node (0-based) of each DOF block of the vector P2 space V, checked to sit at
    that node (to 1e-9 relative): nodal values then map to DOF values one to one."""
    vdm = V.dofmap.list.array.reshape(-1, 10)
    n_blocks = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    dof_node = np.full(n_blocks, -1, dtype=np.int64)
    dof_node[vdm.ravel()] = cells.ravel()
    if np.any(dof_node < 0):
        raise NumericalError("some P2 DOFs have no geometry node")
    mismatch = np.abs(V.tabulate_dof_coordinates() - nodes[dof_node]).max()
    if mismatch > 1e-9 * max(1.0, np.abs(nodes).max()):
        raise NumericalError(f"P2 DOF coordinates differ from the geometry nodes by {mismatch:.3g} mm")
    return dof_node


def _c3d10_elements(cells: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, int]:
    """The cells in C3D10 node order (0-based), each turned to a positive signed corner
    volume (CalculiX stops on a negative Jacobian), and how many had to be turned."""
    elems = cells[:, DOLFINX_TO_C3D10]
    p = nodes[elems[:, :4]]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    neg = vol < 0
    elems[neg] = elems[neg][:, C3D10_FLIP]
    return elems, int(neg.sum())


def _fixed_nodes(V, facet_tags, lc: LoadCase, dof_node: np.ndarray) -> dict[int, np.ndarray]:
    """Per component (0..2), the nodes (1-based) whose displacement is held at 0: exactly
    the DOFs the pipeline's Dirichlet conditions fix."""
    fixed: dict[int, list[np.ndarray]] = {0: [], 1: [], 2: []}
    for c in lc.constraints:
        if c.value != 0.0:
            raise NotImplementedError("only homogeneous constraints are written for CalculiX")
        _, dofs = dirichlet_bc(V, facet_tags, c)
        comps = [0, 1, 2] if c.component is None else [c.component]
        for comp, d_ in zip(comps, dofs):
            # d_ indexes the unrolled vector space: block = d // 3, component = d % 3.
            d_ = np.asarray(d_)
            assert np.all(d_ % 3 == comp)
            fixed[comp].append(dof_node[d_ // 3])
    return {k: np.unique(np.concatenate(v)) + 1 for k, v in fixed.items() if v}


def _nodal_loads(mesh, V, facet_tags, lc: LoadCase, dof_node: np.ndarray,
                 nodes: np.ndarray) -> np.ndarray:
    """Consistent nodal forces (N × 3, N): the load vector of the same linear form the
    pipeline assembles for the tractions, moved from DOF blocks to their nodes."""
    v = ufl.TestFunction(V)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
    L = ufl.inner(fem.Constant(mesh, PETSc.ScalarType((0.0, 0.0, 0.0))), v) * ufl.dx
    for t in lc.tractions:
        L += ufl.inner(t.value, v) * ds(t.marker)
    b = assemble_vector(fem.form(L))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    loads = np.zeros_like(nodes)
    np.add.at(loads, dof_node[:V.dofmap.index_map.size_local],
              b.array_r.reshape(-1, 3)[:V.dofmap.index_map.size_local])
    b.destroy()
    return loads


def _id_lines(ids: np.ndarray, per_line: int = 10) -> list[str]:
    ids = [str(int(i)) for i in ids]
    return [", ".join(ids[k:k + per_line]) for k in range(0, len(ids), per_line)]


def inp_text(model: CcxModel, mat: Material, solver: str = "spooles", title: str = "crosshead",
             model_lines: Sequence[str] = (), step_lines: Sequence[str] | None = None,
             output_lines: Sequence[str] = ()) -> str:
    """The CalculiX input deck of ``model`` (one static step).

    A contact model (bench/contact.py) adds its surfaces and interactions as
    ``model_lines`` (before the step), replaces the step's ``*STEP``/``*STATIC`` lines by
    ``step_lines`` (increments of a nonlinear step) and asks for more output with
    ``output_lines`` (before ``*END STEP``); the defaults give the linear peer's deck.
    """
    out = [f"*HEADING\n{title[:80]}", "*NODE, NSET=NALL"]
    ids = np.arange(1, model.nodes.shape[0] + 1)
    out += [f"{i},{fmt(a)},{fmt(b)},{fmt(c)}" for i, (a, b, c) in zip(ids, model.nodes.tolist())]
    out.append("*ELEMENT, TYPE=C3D10, ELSET=EALL")
    out += [f"{e}," + ",".join(map(str, row)) for e, row in
            zip(range(1, model.elements.shape[0] + 1), model.elements.tolist())]
    names = {0: "FIXX", 1: "FIXY", 2: "FIXZ"}
    for comp, nids in model.fixed.items():
        out.append(f"*NSET, NSET={names[comp]}")
        out += _id_lines(nids)
    out += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{fmt(mat.E)},{fmt(mat.nu)}",
            "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL", *model_lines]
    if step_lines is None:
        out += ["*STEP", "*STATIC" if solver == "spooles" else "*STATIC, SOLVER=ITERATIVE CHOLESKY"]
    else:
        out += list(step_lines)
    out.append("*BOUNDARY")
    out += [f"{names[comp]},{comp + 1},{comp + 1}" for comp in model.fixed]
    # Loads on fixed DOFs would only go into reactions; DOLFINx zeroes them too (set_bc).
    f = model.loads.copy()
    for comp, nids in model.fixed.items():
        f[nids - 1, comp] = 0.0
    scale = np.abs(f).max()
    out.append("*CLOAD")
    for comp in range(3):
        nz = np.flatnonzero(np.abs(f[:, comp]) > 1e-14 * scale)
        out += [f"{n + 1},{comp + 1},{fmt(val)}" for n, val in zip(nz.tolist(), f[nz, comp].tolist())]
    out += [*output_lines, "*NODE PRINT, NSET=NALL", "U", "*END STEP", ""]
    return "\n".join(out)


def read_dat_displacements(path: Path, n_nodes: int) -> np.ndarray:
    """Nodal displacements (n_nodes × 3, mm) from a CalculiX .dat file (*NODE PRINT U): the
    last block printed, which is the end of the step when a nonlinear step has several
    increments."""
    lines = Path(path).read_text().splitlines()
    heads = [k for k, s in enumerate(lines) if s.strip().startswith("displacements (vx,vy,vz)")]
    start = heads[-1] if heads else None
    if start is None:
        raise NumericalError(f"no displacement block in {path}")
    U = np.full((n_nodes, 3), np.nan)
    for s in lines[start + 1:]:
        parts = s.split()
        if not parts:
            continue
        if len(parts) != 4 or not parts[0].isdigit():
            break
        U[int(parts[0]) - 1] = [float(p) for p in parts[1:]]
    if not np.all(np.isfinite(U)):
        raise NumericalError(f"CalculiX .dat {path} lacks displacements for some nodes (or has NaN)")
    return U


def read_frd_stress(path: Path, n_nodes: int) -> np.ndarray:
    """Nodal stresses (n_nodes × 6, MPa: xx, yy, zz, xy, yz, zx) from a CalculiX ASCII .frd
    file (``*EL FILE`` with ``S``): the values ccx extrapolates from the integration points
    to the nodes and averages over the elements that share a node, as CalculiX GraphiX
    shows them. The last STRESS block is read (the end of the step)."""
    lines = Path(path).read_text().splitlines()
    heads = [k for k, s in enumerate(lines) if s.startswith(" -4") and s[3:].split()[:1] == ["STRESS"]]
    if not heads:
        raise NumericalError(f"no STRESS block in {path}")
    S = np.full((n_nodes, 6), np.nan)
    for s in lines[heads[-1] + 1:]:
        if s.startswith(" -3"):
            break
        if not s.startswith(" -1"):
            continue
        # Fixed columns: " -1", the node number in 10 characters, then 12 per value.
        node = int(s[3:13])
        S[node - 1] = [float(s[13 + 12 * k:25 + 12 * k]) for k in range(6)]
    if not np.all(np.isfinite(S)):
        raise NumericalError(f"CalculiX .frd {path} lacks stresses for some nodes (or has NaN)")
    return S


@dataclass
class CcxResult:
    """CalculiX's displacement as a DOLFINx P2 function, with what it took (s, KiB)."""

    u: fem.Function
    model: CcxModel
    timings: dict[str, float] = field(default_factory=dict)  # loads, write, ccx, read
    ccx_maxrss_kib: int = 0
    inp_path: Path | None = None
    log: str = ""
    nodal_stress: np.ndarray | None = None  # (N, 6) MPa from the .frd, when asked for


def run_job(wd: Path, threads: int = 1, ccx: str = "ccx", job: str = "job") -> tuple[str, float, int]:
    """Run ``ccx -i job`` in folder ``wd`` on ``threads`` threads; (log, wall time s, the
    children's peak resident memory KiB). Raises NumericalError if ccx fails or its log
    has an ``*ERROR``."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_STIFFNESS=str(threads),
               CCX_NPROC_EQUATION_SOLVER=str(threads), CCX_NPROC_RESULTS=str(threads),
               NUMBER_OF_CPUS=str(threads), OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    proc = subprocess.run([ccx, "-i", job], cwd=wd, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    maxrss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    log = proc.stdout + proc.stderr
    if proc.returncode != 0 or "*ERROR" in log:
        tail = " | ".join(log.strip().splitlines()[-5:])
        raise NumericalError(f"ccx failed (exit {proc.returncode}): {tail}")
    return log, seconds, int(maxrss)


def solve_ccx(mesh, facet_tags, lc: LoadCase, mat: Material, threads: int = 1,
              solver: str = "spooles", workdir: Path | None = None, keep: bool = False,
              ccx: str = "ccx", nodal_stress: bool = False) -> CcxResult:
    """Write the .inp, run ``ccx -i job`` and read U back into a DOLFINx P2 function.

    Times (s): ``loads`` (nodal loads and node sets from DOLFINx), ``write`` (the .inp
    text and file), ``ccx`` (wall time of the ccx process), ``read`` (parse .dat, fill
    the function, and with ``nodal_stress`` ccx's nodal stresses from the .frd, which
    ``*EL FILE`` asks ccx for: :func:`read_frd_stress`). ``threads`` sets OMP_NUM_THREADS and CCX_NPROC_* for ccx. The work
    folder is a temporary one, removed afterwards unless ``keep`` or ``workdir`` is given.
    """
    if shutil.which(ccx) is None:
        raise FileNotFoundError(f"{ccx}: CalculiX not found (Debian package calculix-ccx; tools/setup.sh installs it)")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    model = build_model(mesh, facet_tags, lc)
    timings["loads"] = time.perf_counter() - t0
    own_tmp = workdir is None
    wd = Path(tempfile.mkdtemp(prefix="ccx-")) if own_tmp else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        inp = wd / "job.inp"
        inp.write_text(inp_text(model, mat, solver=solver,
                                output_lines=("*EL FILE", "S") if nodal_stress else ()))
        timings["write"] = time.perf_counter() - t0
        log, timings["ccx"], maxrss = run_job(wd, threads, ccx)
        t0 = time.perf_counter()
        U = read_dat_displacements(wd / "job.dat", model.nodes.shape[0])
        u = fem.Function(model.V, name="displacement_mm")
        u.x.array[:] = U[model.dof_node].ravel()
        u.x.scatter_forward()
        S = read_frd_stress(wd / "job.frd", model.nodes.shape[0]) if nodal_stress else None
        timings["read"] = time.perf_counter() - t0
    finally:
        if own_tmp and not keep:
            shutil.rmtree(wd, ignore_errors=True)
    return CcxResult(u=u, model=model, timings=timings,
                     ccx_maxrss_kib=int(maxrss),
                     inp_path=None if (own_tmp and not keep) else inp, log=log, nodal_stress=S)


# Voigt order of ccx's .frd stresses: xx, yy, zz, xy, yz, zx.
VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))


def nodal_von_mises(S: np.ndarray) -> np.ndarray:
    """Von Mises stress (MPa) of nodal stresses S (n × 6, MPa, ccx's Voigt order)."""
    from pipeline.api import von_mises_of
    T = np.empty((S.shape[0], 3, 3))
    for k, (a, b) in enumerate(VOIGT):
        T[:, a, b] = T[:, b, a] = S[:, k]
    return von_mises_of(T)


def frd_peaks(case, nodes: np.ndarray, S: np.ndarray) -> dict:
    """The peaks a CalculiX user reads from the .frd: the largest nodal von Mises (MPa) over
    all nodes (global) and over the ligaments beside the bore (critical), with their nodes
    (mm). ``nodes`` (n × 3, mm) and ``S`` (n × 6, MPa) in ccx's node order."""
    from pipeline.api import critical_region
    vm = nodal_von_mises(S)
    crit = np.flatnonzero(critical_region(case)(nodes))
    g, c = int(np.argmax(vm)), int(crit[np.argmax(vm[crit])])
    return {"peak_MPa": float(vm[g]), "peak_location_mm": nodes[g].tolist(),
            "critical_MPa": float(vm[c]), "critical_location_mm": nodes[c].tolist()}


def compare(case, factor: float, threads: int = 1, solver: str = "mumps",
            ccx_solver: str = "spooles", workdir: Path | None = None) -> dict:
    """Solve ``case`` on one mesh with DOLFINx (P2) and CalculiX (C3D10); compare (MPa, mm).

    Returns both peaks of both codes, their relative differences and the largest
    displacement difference relative to the largest displacement.
    """
    from dataclasses import replace

    if case.order != 2:
        raise ValueError("the CalculiX comparison needs the P2 (C3D10) case")
    case = replace(case, solver=solver, rtol=1e-12)
    alone = RunContext(comm=MPI.COMM_SELF)
    prob = set_up(case, LevelTask(factor), alone)
    lv = solve_level(case, LevelTask(factor, keep_fields=True), alone, problem=prob)
    cx = solve_ccx(prob.mesh.mesh, prob.mesh.facet_tags, prob.loads, prob.material, threads=threads,
                   solver=ccx_solver, workdir=workdir)
    _, pk, cr = peaks_of(case, cx.u, prob.material)
    out: dict = {"mesh_factor": factor, "dofs": lv.dofs, "cells": lv.cells}
    for name, (glob, crit) in (("dolfinx", (lv.peak, lv.critical)), ("calculix", (pk, cr))):
        out[name] = {"peak_MPa": glob.value_MPa, "peak_location_mm": list(glob.location_mm),
                     "critical_MPa": crit.value_MPa, "critical_location_mm": list(crit.location_mm)}
    u = lv.fields[0]
    d, c = out["dolfinx"], out["calculix"]
    ua, ub = u.x.array.reshape(-1, 3), cx.u.x.array.reshape(-1, 3)
    out["rel_diff"] = {
        "peak": (c["peak_MPa"] - d["peak_MPa"]) / d["peak_MPa"],
        "critical": (c["critical_MPa"] - d["critical_MPa"]) / d["critical_MPa"],
        "u_max": float(np.linalg.norm(ua - ub, axis=1).max() / np.linalg.norm(ua, axis=1).max()),
    }
    out["ccx_timings_s"] = cx.timings
    out["flipped_elements"] = cx.model.flipped
    return out


def main(argv: list[str] | None = None) -> int:
    """python -m bench.calculix [--size 05] [--factor 2.0]: DOLFINx vs CalculiX on one mesh."""
    import argparse
    import json

    p = argparse.ArgumentParser(prog="python -m bench.calculix",
                                description="Solve one mesh with DOLFINx P2 and CalculiX C3D10; compare peaks.")
    p.add_argument("--size", default="05")
    p.add_argument("--factor", type=float, default=2.0, help="mesh factor (default 2.0, coarse)")
    p.add_argument("--threads", type=int, default=1, help="ccx threads (default 1)")
    p.add_argument("--ccx-solver", choices=("spooles", "iterative"), default="spooles")
    p.add_argument("--keep", type=Path, help="keep the ccx work folder here")
    a = p.parse_args(argv)
    case = resolve_case(a.size, overrides={"mesh_factor": a.factor, "order": 2})
    res = compare(case, a.factor, threads=a.threads, ccx_solver=a.ccx_solver, workdir=a.keep)
    print(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
