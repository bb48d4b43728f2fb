"""Post-processing: von Mises in a discontinuous space, read at the nodes, and its peaks (mm, MPa).

Von Mises is read two ways at each node (docs/design.md §5): *unaveraged*, the largest
element-node value there (for P2 displacements the stress in discontinuous P1, for Pk in
DG(k−1)), and *averaged*, the von Mises of the nodal-averaged stress. The reading rule
(:func:`reading`) makes one reported value of the two at every node, and a peak is the node
of the largest reported value: the same rule the field file's reported array holds.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from dolfinx import fem, la

from pipeline.fe.elasticity import Material, stress, von_mises_expr


@dataclass(frozen=True)
class Peak:
    """A peak von Mises stress (MPa) and where it sits ([x, y, z], mm)."""

    value_MPa: float
    location_mm: tuple[float, float, float]


MIDPOINT, UNAVERAGED = "midpoint", "unaveraged"  # rules for a NodalPeak's value


def reading(unaveraged, averaged, midpoint):
    """The reported von Mises (MPa) of a node's two readings: their midpoint where
    ``midpoint`` holds (the shoulder fillet), else the unaveraged one. Numbers or arrays."""
    return np.where(midpoint, 0.5 * (unaveraged + averaged), unaveraged)


@dataclass(frozen=True)
class NodalPeak:
    """A peak von Mises stress (MPa): the two readings at its node, and the value reported.

    ``unaveraged``: the largest element-node value at the node. ``averaged``: the von Mises
    of the nodal-averaged stress there. At a steep surface maximum resolved by few elements
    (No. 05's fillet) the first lies above the true peak (each element extrapolates its own
    linear stress to the node, and the largest of those scattered values is taken) and the
    second below (averaging smooths a maximum); ``rule`` MIDPOINT reports the middle of the
    two, UNAVERAGED the first (:func:`reading`, docs/design.md §5).
    """

    unaveraged: Peak
    averaged: Peak
    rule: str = MIDPOINT

    @property
    def value_MPa(self) -> float:
        return float(reading(self.unaveraged.value_MPa, self.averaged.value_MPa, self.rule == MIDPOINT))

    @property
    def half_width_MPa(self) -> float:
        """Half the gap between the two readings (MPa): the midpoint's own error bound."""
        return 0.5 * abs(self.unaveraged.value_MPa - self.averaged.value_MPa)

    @property
    def location_mm(self) -> tuple[float, float, float]:
        return self.unaveraged.location_mm


def von_mises(u: fem.Function, mat: Material) -> fem.Function:
    """Von Mises stress (MPa) interpolated into DG(order−1) (DG0 for P1)."""
    mesh = u.function_space.mesh
    order = u.function_space.ufl_element().degree()
    W = fem.FunctionSpace(mesh, ("DG", max(order - 1, 0)))
    vm = fem.Function(W, name="von_mises_MPa")
    vm.interpolate(fem.Expression(von_mises_expr(u, mat), W.element.interpolation_points()))
    if not np.all(np.isfinite(vm.x.array)):
        from pipeline.errors import NumericalError
        raise NumericalError("the von Mises stress contains NaN or Inf")
    return vm


def _owned(vm: fem.Function, region: Callable[[np.ndarray], np.ndarray] | None
           ) -> tuple[np.ndarray, np.ndarray]:
    """This rank's owned values of vm (MPa) and their coordinates (mm) inside ``region``."""
    W = vm.function_space
    n_owned = W.dofmap.index_map.size_local * W.dofmap.index_map_bs
    xyz = W.tabulate_dof_coordinates()[:n_owned]
    vals = vm.x.array[:n_owned]
    if region is None:
        return vals, xyz
    mask = region(xyz)
    return vals[mask], xyz[mask]


def peak(vm: fem.Function, region: Callable[[np.ndarray], np.ndarray] | None = None) -> Peak:
    """Largest nodal value of vm over the DOFs whose coordinates satisfy ``region``.

    region takes an (n, 3) array of points (mm) and returns a boolean mask. Collective
    over MPI; every rank gets the same answer.
    """
    vals, xyz = _owned(vm, region)
    return _gathered_max(vals, xyz, vm.function_space.mesh.comm)


def _gathered_max(vals: np.ndarray, xyz: np.ndarray, comm) -> Peak:
    """The largest of every rank's values (MPa) and where it sits (mm). Collective."""
    if len(vals):
        i = int(np.argmax(vals))
        local = (float(vals[i]), tuple(float(c) for c in xyz[i]))
    else:
        local = (-np.inf, (np.nan, np.nan, np.nan))
    # Ties broken by coordinates so the answer does not depend on the partition.
    best = max(comm.allgather(local), key=lambda p: (p[0], p[1]))
    return Peak(value_MPa=best[0], location_mm=best[1])


def hot_spots(vm: fem.Function, threshold_MPa: float,
              separation_mm: float | Callable[[np.ndarray], np.ndarray], limit: int,
              region: Callable[[np.ndarray], np.ndarray] | None = None) -> list[tuple[float, float, float]]:
    """Points (mm) over ``region`` where vm is at least threshold_MPa: the highest first, each
    at least separation_mm from those before, at most ``limit`` of them. ``separation_mm``
    may depend on the place: a function of the points (n × 3, mm) giving one length each.

    On a coarse mesh the peak of one feature can swap with a nearly equal one elsewhere
    (the bore's top and bottom edges differ by ~1 %), so every near-peak place is kept.
    Collective over MPI; every rank gets the same list.
    """
    vals, xyz = _owned(vm, region)
    keep = vals >= threshold_MPa
    cand = vm.function_space.mesh.comm.allgather((vals[keep], xyz[keep]))
    v = np.concatenate([c[0] for c in cand])
    p = np.concatenate([c[1] for c in cand]).reshape(-1, 3)
    # Values rounded to 1e-6 of the threshold before ordering: 1 and 2 MPI ranks differ by
    # ~1e-9 (solver tolerance), and the greedy choice must not depend on that.
    vq = np.round(v / threshold_MPa, 6) if threshold_MPa > 0 else v
    sep = np.broadcast_to(separation_mm(p) if callable(separation_mm) else separation_mm, len(p))
    chosen: list[np.ndarray] = []
    for i in np.lexsort((p[:, 2], p[:, 1], p[:, 0], -vq)):
        if len(chosen) == limit:
            break
        if all(np.linalg.norm(p[i] - q) >= sep[i] for q in chosen):
            chosen.append(p[i])
    return [tuple(float(c) for c in q) for q in chosen]


def averaged_stress(u: fem.Function, mat: Material) -> fem.Function:
    """The nodal-averaged stress tensor (MPa) in CG(q), q = max(order − 1, 1): at each node
    the plain average of the stresses of the elements meeting there (each cell counts once,
    as commercial codes' "averaged nodal stress"). Owned and ghost values set. Collective."""
    mesh = u.function_space.mesh
    q = max(u.function_space.ufl_element().degree() - 1, 1)
    T = fem.TensorFunctionSpace(mesh, ("DG", q))
    C = fem.FunctionSpace(mesh, ("CG", q))
    sigma = fem.Function(T)
    sigma.interpolate(fem.Expression(stress(u, mat), T.element.interpolation_points()))
    owned_cells = mesh.topology.index_map(mesh.topology.dim).size_local
    # DG(q) and CG(q) number a cell's nodes alike, so row k of both dofmaps is one node.
    dg = T.dofmap.list.array.reshape(-1, T.dofmap.dof_layout.num_dofs)[:owned_cells].ravel()
    cg = C.dofmap.list.array.reshape(-1, C.dofmap.dof_layout.num_dofs)[:owned_cells].ravel()
    imap = C.dofmap.index_map
    n_local, n_owned = imap.size_local + imap.num_ghosts, imap.size_local
    # Per node: the 9 stress components summed over its cells, and the number of cells.
    sums = la.vector(imap, bs=10)
    values = sigma.x.array.reshape(-1, 9)[dg]
    sums.array[:] = np.column_stack([np.bincount(cg, values[:, j], n_local) for j in range(9)]
                                    + [np.bincount(cg, minlength=n_local)]).ravel()
    sums.scatter_reverse(la.ScatterMode.add)   # cells of other ranks that share this rank's nodes
    node = sums.array.reshape(-1, 10)[:n_owned]
    averaged = fem.Function(fem.TensorFunctionSpace(mesh, ("CG", q)), name="stress_MPa")
    averaged.x.array.reshape(-1, 9)[:n_owned] = node[:, :9] / node[:, 9, None]
    averaged.x.scatter_forward()
    return averaged


def von_mises_of(s: np.ndarray) -> np.ndarray:
    """Von Mises stress (MPa) of stress tensors s (n, 3, 3), MPa."""
    dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("nij,nij->n", dev, dev))


@dataclass(frozen=True)
class NodeReadings:
    """Von Mises (MPa) read at this rank's owned nodes of CG(q), q = max(k − 1, 1) for Pk
    displacements (the vertices for P2), both ways, and the value reported there.

    ``unaveraged``: the largest element-node value at the node, over every element that
    has the node (on any rank). ``averaged``: the von Mises of the nodal-averaged stress
    (:func:`averaged_stress`). ``midpoint``: the nodes whose reported value is the midpoint
    of the two (the shoulder fillet's); every other node reports its unaveraged value
    (docs/design.md §5). ``vm`` is the element-node field the readings came from."""

    vm: fem.Function
    space: fem.FunctionSpace
    xyz: np.ndarray
    unaveraged: np.ndarray
    averaged: np.ndarray
    midpoint: np.ndarray

    @property
    def reported(self) -> np.ndarray:
        """The reported von Mises (MPa) at each owned node: the reading rule applied there."""
        return reading(self.unaveraged, self.averaged, self.midpoint)

    def as_function(self, values: np.ndarray, name: str) -> fem.Function:
        """``values`` (one per owned node) as a function of CG(q), ghost values set. Collective."""
        f = fem.Function(self.space, name=name)
        f.x.array[:len(values)] = values
        f.x.scatter_forward()
        return f


def node_readings(u: fem.Function, mat: Material, midpoint: Callable[[np.ndarray], np.ndarray] | None,
                  vm: fem.Function | None = None) -> NodeReadings:
    """Both readings of the von Mises of displacement ``u`` (mm) at the nodes of CG(q), the
    midpoint taken where ``midpoint`` (a function of the nodes' coordinates, mm, giving a
    mask; None: nowhere); ``vm`` the element-node field (:func:`von_mises`), if made
    already. Collective over MPI."""
    vm = von_mises(u, mat) if vm is None else vm
    averaged = averaged_stress(u, mat)
    q = averaged.function_space.ufl_element().degree()
    C = fem.FunctionSpace(u.function_space.mesh, ("CG", q))
    n_owned = C.dofmap.index_map.size_local
    xyz = C.tabulate_dof_coordinates()[:n_owned]
    unaveraged = _element_node_max(vm, C)
    a = von_mises_of(averaged.x.array.reshape(-1, 3, 3)[:n_owned])
    mask = np.zeros(n_owned, dtype=bool) if midpoint is None else np.asarray(midpoint(xyz), dtype=bool)
    return NodeReadings(vm=vm, space=C, xyz=xyz, unaveraged=unaveraged, averaged=a, midpoint=mask)


def _element_node_max(vm: fem.Function, C: fem.FunctionSpace) -> np.ndarray:
    """At each owned node of CG(q) ``C``, the largest value of the element-node field ``vm``
    (DG(q), or DG0 for P1: each element's constant) over the elements that have the node,
    the elements of every rank. Collective."""
    mesh = C.mesh
    q = C.ufl_element().degree()
    if vm.function_space.ufl_element().degree() != q:   # DG0 (P1): exact in DG1
        v = fem.Function(fem.FunctionSpace(mesh, ("DG", q)))
        v.interpolate(vm)
        vm = v
    W = vm.function_space
    owned_cells = mesh.topology.index_map(mesh.topology.dim).size_local
    # DG(q) and CG(q) number a cell's nodes alike, so row k of both dofmaps is one node.
    dg = W.dofmap.list.array.reshape(-1, W.dofmap.dof_layout.num_dofs)[:owned_cells].ravel()
    cg = C.dofmap.list.array.reshape(-1, C.dofmap.dof_layout.num_dofs)[:owned_cells].ravel()
    imap = C.dofmap.index_map
    n_owned = imap.size_local
    best = np.full(n_owned + imap.num_ghosts, -np.inf)
    np.maximum.at(best, cg, vm.x.array[dg])
    # The cells of other ranks at this rank's nodes: each rank's values at its ghost nodes
    # (global numbers) go to every rank, and the owner keeps the largest.
    start = imap.local_range[0]
    for ghosts, values in mesh.comm.allgather((np.asarray(imap.ghosts, dtype=np.int64), best[n_owned:])):
        mine = (ghosts >= start) & (ghosts < start + n_owned)
        np.maximum.at(best, ghosts[mine] - start, values[mine])
    return best[:n_owned]


def node_peak(r: NodeReadings, region: Callable[[np.ndarray], np.ndarray] | None = None) -> NodalPeak:
    """The node of the largest reported value over ``region`` (None: everywhere) and both
    readings there, its rule the node's (MIDPOINT on the fillet, else UNAVERAGED): its
    ``value_MPa`` is the reported value at that node. Ties broken by coordinates, so the
    answer does not depend on the partition. Collective over MPI; every rank gets it."""
    values = r.reported
    inside = np.ones(len(values), dtype=bool) if region is None else np.asarray(region(r.xyz), dtype=bool)
    idx = np.flatnonzero(inside)
    if len(idx):
        i = int(idx[np.argmax(values[idx])])
        local = (float(values[i]), tuple(float(c) for c in r.xyz[i]), float(r.unaveraged[i]),
                 float(r.averaged[i]), bool(r.midpoint[i]))
    else:
        local = (-np.inf, (np.nan, np.nan, np.nan), -np.inf, -np.inf, False)
    _, at, u, a, mid = max(r.space.mesh.comm.allgather(local), key=lambda p: (p[0], p[1]))
    return NodalPeak(unaveraged=Peak(u, at), averaged=Peak(a, at), rule=MIDPOINT if mid else UNAVERAGED)
