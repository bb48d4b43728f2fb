"""Moving a mesh of the part onto the same part with another journal diameter dj, fillet
radius rf or seat annulus (seat_inner, seat_outer), instead of meshing that part again (mm).

Why: the sensitivity section analyses the nominal part and one variant per end of each
assumed dimension's range on meshes of the same size (pipeline/analysis/sensitivity.py).
A variant made by moving the nominal mesh's nodes keeps its topology, so its DOF numbering,
sparsity, compiled forms, facet tags and the nominal solution (a starting guess) carry over;
and the mesh's bias cancels better in variant / nominal, since both share every element
away from the changed feature (docs/decisions/0036-sensitivity-variants-by-morphing.md).

The move is an explicit map Φ of space onto itself that takes every face of the nominal
part onto the same face of the variant: the journal cylinder, the fillet torus, the body's
end face, the journal's tip and the seat annulus's circles land exactly on the variant's,
and every other face (bore, symmetry planes, outer faces, bottom) stays where it is.
Φ is composed of three maps with their own supports, applied in this order:

* the fillet (:func:`fillet_map`): in the half-plane through the journal axis, a uniform
  scaling by rf'/rf about the corner circle (x = b1/2, ρ = dj/2) inside radius rf of it,
  blended to the identity at ``R0 − dj/2`` (R0 = min(h3, b1)/2: where the end face meets the
  body's outer faces);
* the journal (:func:`journal_map`): radial (about the journal axis) by dj'/2 − dj/2 on the
  fillet and the end face next to it, proportional to ρ inside the journal, to nothing at
  R0 on the end face and over a length ``JOURNAL_DECAY``·(b1/2 − d2/2) into the body;
* the seat (:func:`seat_map`): radial (about the bore axis) on the top face, piecewise
  linear through the seat circles, nothing at the bore and from b1/2 out, fading towards
  the bottom face (nothing below h3·``SEAT_DEPTH``).

Second-order (10-node) tets: the vertices and the mid-edge nodes of curved edges move by Φ;
a straight edge's mid-edge node goes to the middle of its moved ends, so that an affine tet
stays affine (its straight-cell quadrature stays exact, elasticity.volume_measures) and a
planar face stays planar. Every geometry node, owned or ghost, moves on the rank that holds
it: no communication.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import basix
import numpy as np
from mpi4py import MPI

from geometry.part import analytic_volume
from geometry.table import Dimensions

from pipeline.fe.meshing import ImportedMesh

# What a move may change; every other dimension must be the nominal part's.
MOVABLE = ("dj", "rf", "seat_inner", "seat_outer")
# The journal's move fades into the body over this × (b1/2 − d2/2): short of the bore and the
# critical region |x| <= d2/2 (features.critical_region), which it leaves untouched.
JOURNAL_DECAY = 0.75
# The seat's move fades from the top face to nothing at this × h3 above the bottom face:
# the bottom bore edge (where the critical peak sits) keeps its elements.
SEAT_DEPTH = 0.5
# A straight edge: its mid-edge node within this × the edge's length of its middle
# (elasticity.curved_cells' test, 1e-10 of the cell's size).
STRAIGHT_TOL = 1e-10
# How far a move may squeeze or stretch a ring of elements between a surface it moves and
# one it keeps (the ring's new width over its old) and still read the peaks as a mesh made
# anew does: measured on No. 05's sensitivity meshes, the journal's end-face ring at 0.5
# (dj +5 %) and 2.0 (dj −10 %) and the fillet's blend ring at 0.7 (rf +20 %) and 1.3 held
# variant / nominal within the section's noise (docs/decisions/0036-sensitivity-variants-by-morphing.md).
RING_MIN, RING_MAX = 0.5, 2.0
# The ring between the bore and the seat's inner circle: when the seat comes near the bore
# the critical peak moves to the top bore edge, inside this ring. Squeezed to 0.535 (the
# default range's low end) it read the critical peak 0.17-0.22 % low on the ×2.2 mesh (3×
# the section's noise), to 0.65 0.11 %, to 0.75 0.02 %: below this, mesh the variant anew.
BORE_RING_MIN = 0.75

Map = Callable[[np.ndarray], np.ndarray]  # (n, 3) points (mm) -> (n, 3) moved points (mm)


class MorphError(ValueError):
    """The variant cannot be reached by moving the nominal mesh's nodes (another dimension
    changed, a fillet appears or vanishes, or a face would cross another): mesh it anew."""


def _smoothstep(s: np.ndarray) -> np.ndarray:
    """0 for s <= 0, 1 for s >= 1, 3s² − 2s³ between: C¹, flat at both ends."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def end_face_radius(d: Dimensions) -> float:
    """R0 (mm): the distance from the journal axis to the nearest edge of the body's end
    face x = b1/2 (the bottom, top or side face), min(h3, b1)/2. Nothing on the end face at
    or beyond it may move radially."""
    return min(d.h3, d.b1) / 2


def _journal_frame(d: Dimensions, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per point: ξ = |x| − b1/2 (mm, along the journal axis from the end face, > 0 in the
    journal), ρ (mm, from the journal axis) and the unit radial vector (0, e_y, e_z)
    (zero on the axis)."""
    xi = np.abs(x[:, 0]) - d.b1 / 2
    ey, ez = x[:, 1], x[:, 2] - d.h3 / 2
    rho = np.hypot(ey, ez)
    safe = np.where(rho > 0, rho, 1.0)
    return xi, rho, np.column_stack([np.zeros_like(rho), ey / safe, ez / safe])


def fillet_map(d: Dimensions, rf: float) -> Map:
    """Φ taking the part ``d``'s fillet of radius d.rf to one of radius ``rf`` (mm), dj kept.

    In the half-plane through the journal axis, with (ξ, η) = (|x| − b1/2, ρ − dj/2) measured
    from the corner circle C that the fillet rounds: inside distance d0 = d.rf of C the
    points scale by λ = rf/d.rf about C (the fillet's arc, centred (d.rf, d.rf), goes to the
    arc centred (rf, rf); the end face and the cylinder stay on themselves, moved along);
    their distance s from C then maps piecewise linearly to itself at d1 = R0 − dj/2, beyond
    which nothing moves. Raises MorphError without room: d1 <= max(d.rf, rf)."""
    if d.rf <= 0 or rf <= 0:
        raise MorphError("a fillet radius of 0 is another topology (a sharp corner): mesh it anew")
    lam = rf / d.rf
    d0 = d.rf
    d1 = end_face_radius(d) - d.dj / 2
    if not d1 > max(d0, lam * d0):
        raise MorphError(f"no room to move the fillet: rf {d.rf:g} -> {rf:g} mm within {d1:.3g} mm of its corner")
    rj = d.dj / 2

    def phi(x: np.ndarray) -> np.ndarray:
        xi, rho, e = _journal_frame(d, x)
        eta = rho - rj
        s = np.hypot(xi, eta)
        s_new = np.where(s <= d0, lam * s,
                         np.where(s < d1, lam * d0 + (s - d0) * (d1 - lam * d0) / (d1 - d0), s))
        k = np.where(s > 0, s_new / np.where(s > 0, s, 1.0), lam)
        dxi, deta = (k - 1.0) * xi, (k - 1.0) * eta
        out = x.copy()
        out[:, 0] += np.sign(x[:, 0]) * dxi
        out += deta[:, None] * e
        return out

    return phi


def journal_map(d: Dimensions, dj: float) -> Map:
    """Φ taking the part ``d``'s journal of diameter d.dj to one of ``dj`` (mm), the fillet
    radius d.rf kept (apply :func:`fillet_map` first for another one).

    Radial about the journal axis by Δ·f(ρ)·g(ξ), Δ = (dj − d.dj)/2: f = ρ/(d.dj/2) inside
    the journal, 1 across the fillet (ρ up to d.dj/2 + d.rf: the fillet and the journal
    cylinder move by Δ, unchanged in shape), falling linearly to 0 at R0 (the end face's
    edges); g = 1 from the end face outwards, falling smoothly to 0 at
    JOURNAL_DECAY·(b1/2 − d2/2) into the body. Raises MorphError unless the new fillet
    stays inside the end face: dj/2 + rf < R0."""
    rj, rf = d.dj / 2, d.rf
    delta = (dj - d.dj) / 2
    r0 = end_face_radius(d)
    outer = rj + rf
    if not (dj > 0 and dj / 2 + rf < r0 and outer < r0):
        raise MorphError(f"no room to move the journal: dj {d.dj:g} -> {dj:g} mm with rf {rf:g} mm, "
                         f"end face radius {r0:g} mm")
    depth = JOURNAL_DECAY * (d.b1 / 2 - d.d2 / 2)

    def phi(x: np.ndarray) -> np.ndarray:
        xi, rho, e = _journal_frame(d, x)
        f = np.where(rho <= rj, rho / rj, np.where(rho <= outer, 1.0, np.clip((r0 - rho) / (r0 - outer), 0.0, 1.0)))
        g = _smoothstep(1.0 + xi / depth)
        return x + (delta * f * g)[:, None] * e

    return phi


def seat_map(d: Dimensions, seat_inner: float, seat_outer: float) -> Map:
    """Φ taking the part ``d``'s seat annulus (diameters d.seat_inner..d.seat_outer on the
    top face) to ``seat_inner``..``seat_outer`` (mm).

    Radial about the bore axis by δ(r)·w(z): δ piecewise linear in r through 0 at the bore
    (d2/2), the inner circle's and the outer circle's change at their radii, and 0 at b1/2
    and beyond (the outer faces); w = 1 on the top face, falling smoothly to 0 at
    SEAT_DEPTH·h3. Raises MorphError unless the circles keep their order:
    d2 < seat_inner < seat_outer < b1."""
    rb, a = d.d2 / 2, d.b1 / 2
    ri, ro = d.seat_inner / 2, d.seat_outer / 2
    ri2, ro2 = seat_inner / 2, seat_outer / 2
    if not (rb < ri2 < ro2 < a and rb < ri < ro < a):
        raise MorphError(f"no room to move the seat: {d.seat_inner:g}..{d.seat_outer:g} -> "
                         f"{seat_inner:g}..{seat_outer:g} mm between the bore {d.d2:g} and b1 {d.b1:g} mm")
    knots = np.array([rb, ri, ro, a])
    moves = np.array([0.0, ri2 - ri, ro2 - ro, 0.0])
    z0 = SEAT_DEPTH * d.h3

    def phi(x: np.ndarray) -> np.ndarray:
        r = np.hypot(x[:, 0], x[:, 1])
        delta = np.interp(r, knots, moves, left=0.0, right=0.0)
        w = _smoothstep((x[:, 2] - z0) / (d.h3 - z0))
        safe = np.where(r > 0, r, 1.0)
        out = x.copy()
        out[:, 0] += delta * w * x[:, 0] / safe
        out[:, 1] += delta * w * x[:, 1] / safe
        return out

    return phi


def part_map(d: Dimensions, v: Dimensions) -> Map:
    """Φ taking part ``d`` onto part ``v`` (mm): the fillet, the journal, then the seat, each
    only if it changed. Raises MorphError if a dimension other than MOVABLE differs, or a
    map has no room (see each)."""
    other = [k for k in vars(d) if k not in MOVABLE and getattr(d, k) != getattr(v, k)]
    if other:
        raise MorphError(f"only {', '.join(MOVABLE)} can be moved to; {', '.join(other)} changed")
    maps: list[Map] = []
    if v.rf != d.rf:
        maps.append(fillet_map(d, v.rf))
    if v.dj != d.dj:
        maps.append(journal_map(replace(d, rf=v.rf), v.dj))
    if (v.seat_inner, v.seat_outer) != (d.seat_inner, d.seat_outer):
        maps.append(seat_map(d, v.seat_inner, v.seat_outer))

    def phi(x: np.ndarray) -> np.ndarray:
        for m in maps:
            x = m(x)
        return x

    return phi


def rings(d: Dimensions, v: Dimensions) -> dict[str, float]:
    """The rings of elements :func:`part_map` squeezes or stretches from part ``d`` to part
    ``v``, each as its new width over its old (1: untouched): the fillet's blend ring, the
    journal's core and its end-face ring, and the seat's rings between the bore, its circles
    and b1/2."""
    out: dict[str, float] = {}
    if v.rf != d.rf:
        d0, d1 = d.rf, end_face_radius(d) - d.dj / 2
        out["fillet blend ring"] = (d1 - v.rf) / (d1 - d0)
    if v.dj != d.dj:
        r0 = end_face_radius(d)
        out["journal core"] = v.dj / d.dj
        out["journal end-face ring"] = (r0 - v.dj / 2 - v.rf) / (r0 - d.dj / 2 - v.rf)
    if (v.seat_inner, v.seat_outer) != (d.seat_inner, d.seat_outer):
        old = np.diff([d.d2, d.seat_inner, d.seat_outer, d.b1]) / 2
        new = np.diff([d.d2, v.seat_inner, v.seat_outer, d.b1]) / 2
        out.update(zip(("bore-to-seat ring", "seat", "seat-to-side ring"), (new / old).tolist()))
    return out


def remesh_reason(d: Dimensions, v: Dimensions) -> str | None:
    """Why part ``v`` should be meshed anew rather than reached by moving a mesh of part
    ``d`` (the map cannot be made, or it squeezes or stretches a ring of elements beyond
    what was measured to read the peaks as a fresh mesh does: RING_MIN, RING_MAX,
    BORE_RING_MIN), or None."""
    try:
        part_map(d, v)
    except MorphError as exc:
        return str(exc)
    for name, ratio in rings(d, v).items():
        low = BORE_RING_MIN if name == "bore-to-seat ring" else RING_MIN
        if not low - 1e-9 <= ratio <= RING_MAX + 1e-9:
            return (f"the {name} would be {'squeezed' if ratio < 1 else 'stretched'} to {ratio:.3g} of its width "
                    f"(moves are measured to hold the peaks within {low:g}..{RING_MAX:g})")
    return None


# The 10-node tet's edges as DOLFINx (basix) numbers its nodes: node 4 + k sits on edge k.
TET10_EDGES = np.array(basix.topology(basix.CellType.tetrahedron)[1], dtype=np.int64)


@dataclass(frozen=True)
class MidEdges:
    """The mid-edge nodes of a mesh of 10-node tets, each once: its node number, its edge's
    two end nodes, and whether the edge is straight (mid-edge node at the middle)."""

    node: np.ndarray      # (m,) node numbers
    ends: np.ndarray      # (m, 2) node numbers
    straight: np.ndarray  # (m,) bool


def mid_edges(x: np.ndarray, cells: np.ndarray, edges: np.ndarray = TET10_EDGES) -> MidEdges:
    """The mid-edge nodes of the tets ``cells`` (m × 10 node numbers, ``edges`` giving node
    4 + k's end nodes as cell-local numbers) with nodes at ``x`` (n × 3, mm)."""
    mids = cells[:, 4:].ravel()
    ends = cells[:, edges].reshape(-1, 2)
    node, first = np.unique(mids, return_index=True)
    ends = ends[first]
    chord = x[ends[:, 1]] - x[ends[:, 0]]
    bow = np.linalg.norm(x[node] - 0.5 * (x[ends[:, 0]] + x[ends[:, 1]]), axis=1)
    return MidEdges(node=node, ends=ends, straight=bow <= STRAIGHT_TOL * np.linalg.norm(chord, axis=1))


def moved_nodes(x: np.ndarray, mids: MidEdges, phi: Map) -> np.ndarray:
    """The nodes ``x`` (n × 3, mm) moved by Φ: every node by Φ, then each straight edge's
    mid-edge node to the middle of its moved ends (:class:`MidEdges` of the same mesh)."""
    y = phi(x)
    s = mids.straight
    y[mids.node[s]] = 0.5 * (y[mids.ends[s, 0]] + y[mids.ends[s, 1]])
    return y


# Where det J is sampled in each tet: vertices, edge middles, centroid (geometry.curved's).
_SAMPLE = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (.5, 0, 0), (0, .5, 0), (0, 0, .5),
                    (.5, .5, 0), (0, .5, .5), (.5, 0, .5), (.25, .25, .25)], dtype=float)
_P2 = basix.create_element(basix.ElementFamily.P, basix.CellType.tetrahedron, 2)
_GRAD = np.ascontiguousarray(_P2.tabulate(1, _SAMPLE)[1:4, :, :, 0].transpose(1, 0, 2))  # (samples, 3, 10)


def det_jacobians(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """det J (mm³ per reference volume) of each 10-node tet (DOLFINx node order) at the
    sample points: (tets, samples)."""
    jac = np.matmul(_GRAD[None], x[cells][:, None])  # (tets, samples, 3, 3): d x_j / d ξ_i
    a, b, c = jac[..., 0, 0], jac[..., 0, 1], jac[..., 0, 2]
    d, e, f = jac[..., 1, 0], jac[..., 1, 1], jac[..., 1, 2]
    g, h, k = jac[..., 2, 0], jac[..., 2, 1], jac[..., 2, 2]
    return a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g)


@dataclass(frozen=True)
class Quality:
    """How a move left the tets: the worst det J ratio min/max within a tet (the pipeline's
    measure, ImportedMesh.jacobian_ratio; <= 0: inverted), and the smallest and largest
    change of det J at a sample point against the nominal mesh (1: unchanged; <= 0: the tet
    turned inside out)."""

    jacobian_ratio: float
    squeeze: float
    stretch: float

    @property
    def valid(self) -> bool:
        return self.jacobian_ratio > 0 and self.squeeze > 0


def quality(x0: np.ndarray, x1: np.ndarray, cells: np.ndarray) -> Quality:
    """The :class:`Quality` of the tets ``cells`` moved from ``x0`` to ``x1`` (mm)."""
    if len(cells) == 0:
        return Quality(1.0, 1.0, 1.0)
    d0, d1 = det_jacobians(x0, cells), det_jacobians(x1, cells)
    sign = np.sign(d0.sum(axis=1, keepdims=True))
    d1s = d1 * sign
    ratio = float((d1s.min(axis=1) / np.abs(d1s).max(axis=1)).min())
    change = d1s / np.abs(d0)
    return Quality(ratio, float(change.min()), float(change.max()))


def tet10_cells(mesh) -> np.ndarray:
    """The geometry dofmap of a DOLFINx mesh of 10-node tets: (local cells, 10) node numbers
    into mesh.geometry.x, owned and ghost cells."""
    cmap = mesh.geometry.dofmap.array
    if cmap.size % 10:
        raise MorphError("only meshes of 10-node tets can be moved")
    return cmap.reshape(-1, 10)


@dataclass
class Mover:
    """A DOLFINx mesh of part ``nominal`` that can be moved to a variant and back in place:
    ``mover.move_to(v)`` puts its nodes onto part v (every rank its own nodes), returning
    the :class:`Quality`; ``mover.reset()`` puts them back. Forms, function spaces, facet
    tags and matrices made on the mesh stay valid: only the coordinates change (mm)."""

    mesh: object
    nominal: Dimensions
    x0: np.ndarray
    cells: np.ndarray
    mids: MidEdges
    at: Dimensions

    @classmethod
    def of(cls, mesh, nominal: Dimensions) -> "Mover":
        """A Mover of ``mesh`` (10-node tets) whose nodes are now where part ``nominal``
        puts them."""
        x0 = mesh.geometry.x.copy()
        cells = tet10_cells(mesh)
        return cls(mesh=mesh, nominal=nominal, x0=x0, cells=cells, mids=mid_edges(x0, cells), at=nominal)

    def move_to(self, v: Dimensions, strict: bool = True) -> Quality:
        """Put the nodes onto part ``v``; the mesh's quality after it. Raises MorphError
        (nodes left at the nominal part) if the map cannot be made, a tet turns inside out,
        or (``strict``) part v should be meshed anew (:func:`remesh_reason`)."""
        why = remesh_reason(self.nominal, v) if strict else None
        if why is not None:
            self.reset()
            raise MorphError(why)
        y = moved_nodes(self.x0, self.mids, part_map(self.nominal, v))
        q = quality(self.x0, y, self.cells)
        comm = self.mesh.comm
        q = Quality(comm.allreduce(q.jacobian_ratio, op=MPI.MIN), comm.allreduce(q.squeeze, op=MPI.MIN),
                    comm.allreduce(q.stretch, op=MPI.MAX))
        if not q.valid:
            self.reset()
            raise MorphError(f"moving the mesh to the variant turns a tet inside out (det J ratio "
                             f"{q.jacobian_ratio:.3g}, smallest det J change {q.squeeze:.3g})")
        self.mesh.geometry.x[:] = y
        self.at = v
        return q

    def reset(self) -> None:
        """Put the nodes back where the nominal part has them."""
        self.mesh.geometry.x[:] = self.x0
        self.at = self.nominal


def as_variant(m: ImportedMesh, v: Dimensions, q: Quality, move_s: float = 0.0) -> ImportedMesh:
    """The ImportedMesh ``m`` (whose nodes a :class:`Mover` has put onto part ``v``) as the
    variant's: the same DOLFINx mesh, tags and names, with the variant's CAD volume (mm³),
    the moved tets' worst det J ratio, and as timings (s) no geometry, meshing or import but
    the move's ``move_s``."""
    return replace(m, volume_cad=analytic_volume(v, m.model), jacobian_ratio=q.jacobian_ratio,
                   timings={"geometry": 0.0, "mesh": 0.0, "import": 0.0, "morph": move_s})
