"""A peak's two nodal readings read again from plain arrays: a mesh's node positions and
cells (as the mesher made them, mm) and the displacement at its nodes (mm), as
pipeline/post/peaks.py reads them on the DOLFINx mesh (MPa). The run cache checks an
error-bar mesh's stored readings against what its stored mesh and solution give
(pipeline/cache/levels.py): a reading derives from them, and a checksum only proves that a
file is whole.

Both readings of a place need only the cells around it: the unaveraged one is the largest
von Mises of the stress each cell's own displacement gives at the node (for P2 the
discontinuous P1 value there; for P1 a cell's constant value, read at its centroid), the
averaged one the von Mises of the plain mean of those cells' stress tensors at the node.
The displacement's gradient comes from the cell's Lagrange basis (basix, the element
DOLFINx uses, in DOLFINx's node order) and the isoparametric map of its nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import basix
import numpy as np

from pipeline.post.peaks import von_mises_of

# Reference tetrahedron's vertices, in the order of a cell's first four nodes.
REFERENCE_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class MeshArrays:
    """A tetrahedral mesh of Lagrange degree 1 or 2: node positions (n, 3) in mm and cells
    (m, 4 or 10), each row its nodes in DOLFINx's order (vertices first, then edges)."""

    x_mm: np.ndarray
    cells: np.ndarray

    @property
    def degree(self) -> int:
        return {4: 1, 10: 2}[self.cells.shape[1]]


def stresses(mesh: MeshArrays, cells: np.ndarray, u_mm: np.ndarray, points: np.ndarray, E_MPa: float,
             nu: float) -> np.ndarray:
    """The stress tensors (len(cells), 3, 3), MPa, of the displacement ``u_mm`` (one row per
    node of ``mesh``) in each of ``cells`` (indices) at its reference point ``points[k]``:
    σ = 2μ ε + λ tr(ε) I, ε the symmetric gradient of the cell's own interpolant."""
    element = basix.create_element(basix.ElementFamily.P, basix.CellType.tetrahedron, mesh.degree,
                                   basix.LagrangeVariant.equispaced)
    mu = E_MPa / (2 * (1 + nu))
    lam = E_MPa * nu / ((1 + nu) * (1 - 2 * nu))
    out = np.empty((len(cells), 3, 3))
    for k, (c, ref) in enumerate(zip(cells, points)):
        d = element.tabulate(1, ref[None, :])[1:, 0, :, 0]  # (3, ndofs): d/dξ of each basis function
        nodes = mesh.cells[c]
        jac = mesh.x_mm[nodes].T @ d.T  # (3, 3): dx/dξ
        grad = (u_mm[nodes].T @ d.T) @ np.linalg.inv(jac)  # (3, 3): du/dx
        eps = 0.5 * (grad + grad.T)
        out[k] = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
    return out


def node_at(mesh: MeshArrays, point_mm: tuple[float, float, float], tol_mm: float) -> int | None:
    """The vertex of ``mesh`` at ``point_mm`` (within ``tol_mm``), or None."""
    vertices = np.unique(mesh.cells[:, :4])
    dist = np.linalg.norm(mesh.x_mm[vertices] - np.asarray(point_mm), axis=1)
    k = int(np.argmin(dist))
    return int(vertices[k]) if dist[k] <= tol_mm else None


def readings_at(mesh: MeshArrays, u_mm: np.ndarray, E_MPa: float, nu: float, unaveraged_mm, averaged_mm,
                tol_mm: float) -> tuple[float, float] | None:
    """(unaveraged, averaged) von Mises (MPa) of displacement ``u_mm`` read as the pipeline
    reads a peak: the unaveraged reading at ``unaveraged_mm``, the largest element-node
    value of the cells at that vertex (for P1 their constant values; a P1 reading at a
    cell's centroid is that cell's value), and the averaged one at the vertex
    ``averaged_mm``; None when a place is no node of the mesh (within ``tol_mm``)."""
    at = node_at(mesh, averaged_mm, tol_mm)
    if at is None:
        return None
    around, corner = np.nonzero(mesh.cells[:, :4] == at)
    s = stresses(mesh, around, u_mm, REFERENCE_VERTICES[corner], E_MPa, nu)
    averaged = float(von_mises_of(s.mean(axis=0)[None])[0])
    if mesh.degree == 1 and node_at(mesh, unaveraged_mm, tol_mm) is None:  # DG0 read at a cell's centroid
        centroids = mesh.x_mm[mesh.cells].mean(axis=1)
        dist = np.linalg.norm(centroids - np.asarray(unaveraged_mm), axis=1)
        c = int(np.argmin(dist))
        if dist[c] > tol_mm:
            return None
        s1 = stresses(mesh, np.array([c]), u_mm, np.array([[0.25, 0.25, 0.25]]), E_MPa, nu)
        return float(von_mises_of(s1)[0]), averaged
    at = node_at(mesh, unaveraged_mm, tol_mm)
    if at is None:
        return None
    around, corner = np.nonzero(mesh.cells[:, :4] == at)
    # P1: each cell's constant stress (read anywhere in it); P2: each cell's at the node.
    points = np.full((len(around), 3), 0.25) if mesh.degree == 1 else REFERENCE_VERTICES[corner]
    s = stresses(mesh, around, u_mm, points, E_MPa, nu)
    return float(von_mises_of(s).max()), averaged
