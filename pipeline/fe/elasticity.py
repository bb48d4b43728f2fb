"""The physics: linear elasticity of the part (material, tractions, constraints, strain,
stress, von Mises) and the volume quadrature on straight and curved tets (units: mm, N, MPa).
"""
from __future__ import annotations

from dataclasses import dataclass

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx.mesh import CellType, meshtags
from petsc4py import PETSc


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material: Young's modulus E (MPa), Poisson's ratio nu."""

    E: float = 210_000.0
    nu: float = 0.3

    @property
    def lame(self) -> tuple[float, float]:
        """Lamé parameters (mu, lambda), MPa."""
        mu = self.E / (2 * (1 + self.nu))
        lam = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        return mu, lam


@dataclass
class Traction:
    """Surface load t (MPa, a UFL vector of x) on the facets marked ``marker``."""

    marker: int
    value: object


@dataclass
class Constraint:
    """u_component = value (mm) on facets marked ``marker`` or at ``points`` (n×3, mm).

    component None fixes all three components. ``points`` are matched to mesh nodes
    within ``tol`` mm; a point that matches no node is an error.
    """

    component: int | None
    value: float = 0.0
    marker: int | None = None
    points: np.ndarray | None = None
    tol: float = 1e-6


def strain(u):
    """Small-strain tensor of displacement u (mm/mm)."""
    return ufl.sym(ufl.grad(u))


def stress(u, mat: Material):
    """Cauchy stress (MPa) of displacement u.

    The Lamé parameters enter as runtime constants, not literals: a form compiled once
    serves every E and nu (a literal made each new material a new form, ~2 s to compile).
    """
    mesh = u.ufl_function_space().mesh
    mu, lam = (fem.Constant(mesh, PETSc.ScalarType(v)) for v in mat.lame)
    return 2.0 * mu * strain(u) + lam * ufl.tr(strain(u)) * ufl.Identity(len(u))


def von_mises_expr(u, mat: Material):
    """Von Mises equivalent stress (MPa) as a UFL expression."""
    s = stress(u, mat)
    dev = s - ufl.tr(s) / 3 * ufl.Identity(len(u))
    return ufl.sqrt(1.5 * ufl.inner(dev, dev))


STRAIGHT, CURVED = 1, 2  # cell markers of the quadrature split (volume_measures)


def local_cells(mesh) -> int:
    """Number of cells on this rank, owned and ghost (the rows of the cell dofmaps)."""
    cells = mesh.topology.index_map(mesh.topology.dim)
    return cells.size_local + cells.num_ghosts


def curved_cells(mesh) -> np.ndarray:
    """Per local cell (owned, then ghosts): True if its geometry map is not affine.

    A 10-node tet is affine when every mid-edge node sits at its edge's midpoint (to 1e-10
    of the cell's size); 4-node tets always are. Other cells count as curved.
    """
    n = local_cells(mesh)
    nodes = mesh.geometry.dofmap.array.reshape(n, -1)
    if mesh.topology.cell_type != CellType.tetrahedron or nodes.shape[1] not in (4, 10):
        return np.ones(n, dtype=bool)
    if nodes.shape[1] == 4:
        return np.zeros(n, dtype=bool)
    x = mesh.geometry.x[nodes]
    # Mid-edge node k sits on the reference edge k (basix numbering: (2,3), (1,3), ...).
    a, b = np.array(basix.topology(basix.CellType.tetrahedron)[1]).T
    bow = np.abs(x[:, 4:] - 0.5 * (x[:, a] + x[:, b])).max(axis=(1, 2))
    size = np.abs(x[:, 1:4] - x[:, :1]).max(axis=(1, 2))
    return bow > 1e-10 * size


def volume_integral(integrand, measures: tuple[ufl.Measure, ufl.Measure]):
    """integrand·dx over the whole mesh, split into the two :func:`volume_measures`."""
    straight, curved = measures
    return integrand * straight + integrand * curved


def volume_measures(mesh, order: int, like: tuple[ufl.Measure, ufl.Measure] | None = None
                    ) -> tuple[ufl.Measure, ufl.Measure]:
    """dx over the straight cells, with degree 2(k−1), and dx over the curved ones.

    Why: on an affine tet the stiffness integrand of Pk is a polynomial of degree 2(k−1),
    which that degree integrates exactly; UFL picks degree 5 for P2 on the curved (P2
    geometry) mesh, for every cell, while most tets (those not touching the fillet, bore
    and journal surfaces) are straight. Curved cells keep UFL's degree (docs/decisions/0003-quadrature-split-straight-curved.md).
    ``like``: measures of this mesh made before, whose cell split is reused.
    """
    if like is not None:
        tags = like[0].subdomain_data()
    else:
        curved = curved_cells(mesh)
        cells = np.arange(len(curved), dtype=np.int32)
        tags = meshtags(mesh, mesh.topology.dim, cells,
                        np.where(curved, CURVED, STRAIGHT).astype(np.int32))
    dx = ufl.Measure("dx", domain=mesh, subdomain_data=tags)
    exact = {"quadrature_degree": max(2 * (order - 1), 0)}
    return dx(STRAIGHT, metadata=exact), dx(CURVED)
