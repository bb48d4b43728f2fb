"""Curved (second-order) tets: the quality measure (det J ratio) and the repair of badly
curved tets along the fillets.
"""
from __future__ import annotations

import math

import gmsh
import numpy as np

from .part import GeometryError

HO_TARGET = 0.3  # worst det J ratio accepted on a curved tet (see _relax_curved)
RELAX_STEP = 0.5  # how far _straighten pulls a mid-edge node per pass (× its bow); see there


def ensure_curved_quality(order: int) -> float:
    """Make sure the mesh really is of ``order``; then no curved tet below HO_TARGET.
    Returns the worst det J ratio.

    When the elements come out straight (seen on near-limit rows), elevate them. Then
    :func:`_relax_curved` pulls badly curved tets towards straight ones.
    """
    def curved() -> bool:
        return any(gmsh.model.mesh.getElementProperties(t)[2] >= 2
                   for t in gmsh.model.mesh.getElementTypes(3))

    if not curved():
        gmsh.model.mesh.setOrder(order)
    if not curved():
        raise GeometryError("mesh: gmsh could not make curved second-order elements for this part; "
                            "try another --mesh-factor")
    return _relax_curved(HO_TARGET)


_TET10_EDGES = np.array([(0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)])  # gmsh's nodes 4..9


def _tet10_shape_gradients() -> np.ndarray:
    """d N_n / d xi of the 10-node tet's shape functions at _SAMPLE: (samples, 3, 10)."""
    s = np.asarray(_SAMPLE, dtype=float)
    lam = np.column_stack([1 - s.sum(1), s])              # barycentric, (samples, 4)
    dlam = np.vstack([-np.ones(3), np.eye(3)])              # d lambda_i / d xi, (4, 3)
    grad = np.empty((len(s), 10, 3))
    grad[:, :4] = (4 * lam - 1)[:, :, None] * dlam[None]
    i, j = _TET10_EDGES.T
    grad[:, 4:] = 4 * (lam[:, i, None] * dlam[j] + lam[:, j, None] * dlam[i])
    return np.ascontiguousarray(grad.transpose(0, 2, 1))


def _tet10_det_ratios(x: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """min det J / max det J of each 10-node tet (node coordinates x, n×3; conn, m×10).

    Sampled at _SAMPLE, like :func:`jacobian_ratio` (which asks gmsh: a cross-check). The
    3×3 determinants are written out: numpy's LAPACK det of ~10⁵ small matrices took half of
    :func:`_relax_curved`'s time.
    """
    jac = np.matmul(_TET10_GRAD[None], x[conn][:, None])    # (tets, samples, 3, 3)
    a, b, c = jac[..., 0, 0], jac[..., 0, 1], jac[..., 0, 2]
    d, e, f = jac[..., 1, 0], jac[..., 1, 1], jac[..., 1, 2]
    g, h, k = jac[..., 2, 0], jac[..., 2, 1], jac[..., 2, 2]
    det = a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g)
    return det.min(1) / det.max(1)


def _relax_curved(target: float) -> float:
    """Repair curved tets with det J ratio < target; returns the worst ratio after it.

    The ratio is :func:`jacobian_ratio`'s, computed here in numpy from the node positions
    (tests/geometry/test_geometry.py checks the two agree): asking gmsh for every tet's Jacobians
    is slow, and this is on the path of every run.

    Why: curving second-order tets onto the shoulder fillet inverts some, and elements left
    near a ratio of 0.1 give spurious peaks
    (docs/decisions/0004-curved-tet-repair.md). The bad tets are slivers with all four vertices on the fillet
    near its tangent line with the body face: their boundary edges bow (follow the CAD
    surface) while their interior edge stays straight, which folds a tet thinner than the bow.

    Two steps: 1. :func:`_bend_with_surface` bends the bad tets with the surface;
    2. :func:`_straighten` pulls what is still bad towards straight. The nodes either moved
    are set in gmsh.

    It gives the peaks of gmsh's high-order optimiser on the same linear meshes to a few
    hundredths of a percent, in a fraction of its time; why step 1 and why steps of half
    the bow: docs/decisions/0004-curved-tet-repair.md.
    """
    mesh = _gmsh_tet10()
    if mesh is None:
        return 1.0
    tags, index, conn, x = mesh
    straight = _straight_positions(x, conn)
    movable = _movable_nodes(index, len(x))
    ratio = _ratios(x, conn, straight)
    bad = np.flatnonzero(ratio < target)
    if len(bad) == 0:
        return float(ratio.min())
    x, bent = _bend_with_surface(x, conn, straight, movable, ratio, bad, target)
    x, alpha, final = _straighten(x, conn, straight, ratio, bent, target)
    moved = np.union1d(np.flatnonzero(alpha < 1), bent)
    for n in moved:
        gmsh.model.mesh.setNode(int(tags[n]), x[n].tolist(), [])
    return float(final.min())


def _gmsh_tet10() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The 10-node tets of the current gmsh mesh, or None when it has none: (node tags,
    the index of each tag into the node arrays, the tets as node indices (m×10, gmsh's
    order), node coordinates (n×3, a copy)). Lengths are gmsh's: mm of the part scaled to
    h3 = 25 mm (pipeline/fe/meshing.py, meshing_scale)."""
    _, conn = gmsh.model.mesh.getElementsByType(11)
    if len(conn) == 0:
        return None
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    conn = index[conn.astype(np.int64)].reshape(-1, 10)
    x = coords.reshape(-1, 3).copy()
    return tags, index, conn, x


def _straight_positions(x: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Node positions (n×3, gmsh lengths) with every mid-edge node moved to the midpoint of
    its edge: the tets as straight-sided. ``x - straight`` is a node's bow, zero off curved
    surfaces and curves."""
    mids = conn[:, 4:].ravel()
    a = conn[:, _TET10_EDGES[:, 0]].ravel()
    b = conn[:, _TET10_EDGES[:, 1]].ravel()
    straight = x.copy()
    straight[mids] = 0.5 * (x[a] + x[b])
    return straight


def _movable_nodes(index: np.ndarray, n: int) -> np.ndarray:
    """Which of the ``n`` nodes :func:`_bend_with_surface` may move (bool per node):
    not those on a curve or on a named surface (symmetry planes, seat, bearing). A mid-edge
    node on a plane has no bow either, but must stay on its plane."""
    movable = np.ones(n, dtype=bool)
    pinned = [(1, t) for _, t in gmsh.model.getEntities(1)]
    pinned += [(2, t) for _, g in gmsh.model.getPhysicalGroups(2)
               for t in gmsh.model.getEntitiesForPhysicalGroup(2, g)]
    for dim, t in pinned:
        movable[index[gmsh.model.mesh.getNodes(dim, t, includeBoundary=True)[0].astype(np.int64)]] = False
    return movable


def _ratios(y: np.ndarray, conn: np.ndarray, straight: np.ndarray, known: np.ndarray | None = None,
            moved: np.ndarray | None = None) -> np.ndarray:
    """det J ratio of every tet for node positions ``y``, computed only for tets with a
    bowed mid-edge node: a straight tet has ratio 1 (and most are).

    Given the ratios ``known`` of a y that differs only at the nodes ``moved``, only the
    tets with a moved node are computed again (the repair moves few nodes per pass).
    """
    if known is None:
        todo = np.arange(len(conn))
        r = np.ones(len(conn))
    else:
        hit = np.zeros(len(y), dtype=bool)
        hit[moved] = True
        todo = np.flatnonzero(hit[conn[:, 4:]].any(axis=1))  # only mid-edge nodes move
        r = known.copy()
    mid = conn[todo, 4:]
    bowed = np.abs(y[mid] - straight[mid]).max(axis=(1, 2)) > 0
    r[todo] = 1.0
    r[todo[bowed]] = _tet10_det_ratios(y, conn[todo[bowed]])
    return r


def _bend_with_surface(x: np.ndarray, conn: np.ndarray, straight: np.ndarray, movable: np.ndarray,
                       ratio: np.ndarray, bad: np.ndarray, target: float) -> tuple[np.ndarray, np.ndarray]:
    """Step 1 of :func:`_relax_curved`: returns (node positions, the nodes moved).

    The mid-edge nodes of each bad tet (``bad``, ratios ``ratio``) move by the mean bow of
    its curved edges, so the sliver bends with the surface; a move is kept only if no tet it
    touches ends worse and below ``target``. Nodes on curves and on named surfaces
    (symmetry planes, seat, bearing) stay (``movable``). The others move: inside the volume,
    on a free plane (the body face beside the fillet leaves its plane by hundredths of a mm)
    and on the free fillet itself, whose bowed nodes get the mean bow on top of their own.
    """
    bow = x - straight                           # zero off curved surfaces and curves
    m = conn[bad, 4:]
    bowed = np.abs(bow[m]).max(axis=2) > 0
    mean_bow = (bow[m] * bowed[..., None]).sum(1) / np.maximum(bowed.sum(1), 1)[:, None]
    take = movable[m] & bowed.any(1)[:, None]
    total = np.zeros_like(x)
    count = np.zeros(len(x))
    np.add.at(total, m[take], np.broadcast_to(mean_bow[:, None, :], m.shape + (3,))[take])
    np.add.at(count, m[take], 1)
    bent = np.flatnonzero(count > 0)
    trial = x.copy()
    trial[bent] += total[bent] / count[bent, None]
    r_trial = _ratios(trial, conn, straight, ratio, bent)
    worse = np.flatnonzero((r_trial < ratio) & (r_trial < target))
    reject = np.zeros(len(x), dtype=bool)
    reject[conn[worse, 4:].ravel()] = True
    bent = bent[~reject[bent]]
    x = x.copy()
    x[bent] = trial[bent]
    return x, bent


def _straighten(x: np.ndarray, conn: np.ndarray, straight: np.ndarray, ratio: np.ndarray,
                bent: np.ndarray, target: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step 2 of :func:`_relax_curved`: returns (node positions, each node's share of its
    bow left, 1 as curved and 0 straight, every tet's ratio).

    What is still below ``target`` after step 1 (which moved ``bent`` from positions
    with ratios ``ratio``): its mid-edge nodes are pulled towards their edge's midpoint,
    RELAX_STEP of their bow per pass (a straight tet has ratio 1, so this ends); the
    boundary there becomes locally faceted, and fillet nodes lie off the torus by
    hundredths of a mm (docs/accuracy.md).
    """
    curved = x                                   # as step 1 left them
    x = x.copy()
    alpha = np.ones(len(x))                      # 1 = as curved, 0 = straight
    final, nodes = ratio, bent
    while True:
        final = _ratios(x, conn, straight, final, nodes)
        bad = final < target
        if not bad.any():
            break
        nodes = np.unique(conn[bad, 4:])
        nodes = nodes[alpha[nodes] > 0]
        if len(nodes) == 0:  # cannot happen: a tet with straight edges has ratio 1
            raise GeometryError("mesh: a tet stays inverted with straight edges")
        alpha[nodes] = np.maximum(alpha[nodes] - RELAX_STEP, 0.0)
        x[nodes] = straight[nodes] + alpha[nodes, None] * (curved[nodes] - straight[nodes])
    return x, alpha, final


_SAMPLE = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (.5, 0, 0), (0, .5, 0), (0, 0, .5),
           (.5, .5, 0), (0, .5, .5), (.5, 0, .5), (.25, .25, .25)]
_TET10_GRAD = _tet10_shape_gradients()


def jacobian_ratio() -> float:
    """Worst element quality of the current gmsh mesh: min over tets of min det J / max det J.

    1 for straight undistorted tets; <= 0 means an inverted (tangled) curved element.
    Sampled at the vertices, edge midpoints and centroid of each tetrahedron.
    """
    worst = -math.inf if len(gmsh.model.mesh.getElementTypes(3)) == 0 else 1.0
    for etype in gmsh.model.mesh.getElementTypes(3):
        _, det, _ = gmsh.model.mesh.getJacobians(etype, [c for p in _SAMPLE for c in p])
        if len(det):
            det_arr = np.asarray(det).reshape(-1, len(_SAMPLE))
            worst = min(worst, float((det_arr.min(1) / det_arr.max(1)).min()))
    return worst
