"""The whole part from the quarter model's fields (the part, its loads and supports are
symmetric about x = 0 and y = 0; docs/design.md §3). numpy only."""
from __future__ import annotations

import numpy as np

# A singly reflected tet swaps vertices 1 and 2 to keep its orientation; in VTK's 10-node
# order (mid-edge nodes of (0,1), (1,2), (2,0), (0,3), (1,3), (2,3)) their edges follow.
TET_SWAP = {4: [0, 2, 1, 3], 10: [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]}
COPIES = ((1, 1), (-1, 1), (1, -1), (-1, -1))  # (sign of x, sign of y) of each quarter
# A node this close to a symmetry plane (relative to the part's size) lies on it: gmsh and
# DOLFINx place such nodes within ~1e-13 of the plane, never exactly on it.
PLANE_TOLERANCE = 1e-9


def _reflected(name: str, a: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Point array ``a`` reflected by the signs ``s`` (3,): a vector's components change sign
    with their axis, a 3×3 tensor's (i, j) component with s_i·s_j, a scalar keeps its value."""
    if a.ndim == 2 and a.shape[1] == 3:
        return a * s
    if a.ndim == 2 and a.shape[1] == 9:
        return a * np.outer(s, s).ravel()
    return a


def mirror_quarter(points: np.ndarray, cells: np.ndarray, point_data: dict[str, np.ndarray],
                   merge: bool = True) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], list[np.ndarray]]:
    """The whole part from the quarter x >= 0, y >= 0: four copies reflected in x = 0 and
    y = 0, cells kept positively oriented (4-node tets, or 10-node tets in VTK order). With
    ``merge``, a node on a symmetry plane is one node of the whole part (placed exactly on the
    plane), so the part is connected; the copies of a discontinuous grid are not merged.
    Returns (points, cells, point arrays, ids): ids[k][i] is the whole part's number of
    the quarter's node i in copy k (order of COPIES)."""
    n = len(points)
    scale = float(np.abs(points).max()) if n else 1.0
    on_x = np.abs(points[:, 0]) <= PLANE_TOLERANCE * scale
    on_y = np.abs(points[:, 1]) <= PLANE_TOLERANCE * scale
    base = points.copy()
    if merge:
        base[on_x, 0] = 0.0
        base[on_y, 1] = 0.0
    ids = [np.arange(n) + k * n for k in range(4)]
    if merge:
        # A reflected copy's plane nodes are those of the copy it was reflected from.
        ids[1][on_x] = ids[0][on_x]
        ids[2][on_y] = ids[0][on_y]
        ids[3][on_x] = ids[2][on_x]
        ids[3][on_y] = ids[1][on_y]
    kept = np.unique(np.concatenate(ids))
    renumber = np.full(4 * n, -1, dtype=np.int64)
    renumber[kept] = np.arange(len(kept))
    ids = [renumber[i] for i in ids]
    all_points = np.vstack([base * np.array([sx, sy, 1.0]) for sx, sy in COPIES])[kept]
    data = {name: np.concatenate([_reflected(name, a, np.array([sx, sy, 1.0])) for sx, sy in COPIES])[kept]
            for name, a in point_data.items()}
    C = []
    for k, (sx, sy) in enumerate(COPIES):
        c = ids[k][cells]
        C.append(c[:, TET_SWAP[cells.shape[1]]] if sx * sy < 0 else c)
    return all_points, np.vstack(C), data, ids
