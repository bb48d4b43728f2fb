"""Places on the part named from its dimensions alone (mm); no mesh, no solution."""
from __future__ import annotations

import numpy as np

from .table import Dimensions


def at_journal_root(d: Dimensions, xyz: np.ndarray) -> np.ndarray:
    """Which points (n × 3, mm) lie on the journal's root: the shoulder fillet, or the sharp
    corner when rf = 0, with a margin of 0.02·h3 (mirror images in x = 0 and y = 0 included)."""
    tol = 0.02 * d.h3
    x = np.abs(xyz[:, 0])
    r = np.hypot(np.abs(xyz[:, 1]), xyz[:, 2] - d.h3 / 2)
    return (x >= d.b1 / 2 - tol) & (x <= d.b1 / 2 + d.rf + tol) & (r < d.dj / 2 + d.rf + tol)
