"""The whole part from the quarter model's fields (the part, its loads and supports are
symmetric about x = 0 and y = 0; docs/design.md §3). numpy only."""
from __future__ import annotations

import numpy as np


def mirror_quarter(points, cells, vals, disp):
    """The whole part from the quarter x >= 0, y >= 0: four copies reflected in x = 0 and
    y = 0. A reflection flips the mirrored displacement component (u_x in x = 0); von
    Mises is a scalar and keeps its value; a singly reflected tet swaps two nodes to keep
    its orientation."""
    P, C, V, D = [], [], [], []
    for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (1, -1), (-1, -1))):
        s = np.array([sx, sy, 1.0])
        P.append(points * s)
        D.append(disp * s)
        V.append(vals)
        c = cells + k * len(points)
        C.append(c[:, [0, 2, 1, 3]] if sx * sy < 0 else c)
    return np.vstack(P), np.vstack(C), np.concatenate(V), np.vstack(D)
