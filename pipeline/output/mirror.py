"""The whole part from the quarter model's fields (the part, its loads and supports are
symmetric about x = 0 and y = 0; docs/design.md §3). numpy only."""
from __future__ import annotations

import numpy as np


# A singly reflected tet swaps vertices 1 and 2 to keep its orientation; in VTK's 10-node
# order (mid-edge nodes of (0,1), (1,2), (2,0), (0,3), (1,3), (2,3)) their edges follow.
_SWAP = {4: [0, 2, 1, 3], 10: [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]}


def mirror_quarter(points, cells, vals, disp):
    """The whole part from the quarter x >= 0, y >= 0: four copies reflected in x = 0 and
    y = 0. A reflection flips the mirrored displacement component (u_x in x = 0); von
    Mises is a scalar and keeps its value (``vals`` may be None); cells are 4-node tets or
    10-node tets in VTK order, each reflected one kept positively oriented."""
    P, C, V, D = [], [], [], []
    for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (1, -1), (-1, -1))):
        s = np.array([sx, sy, 1.0])
        P.append(points * s)
        D.append(disp * s)
        V.append(vals)
        c = cells + k * len(points)
        C.append(c[:, _SWAP[cells.shape[1]]] if sx * sy < 0 else c)
    return np.vstack(P), np.vstack(C), None if vals is None else np.concatenate(V), np.vstack(D)
