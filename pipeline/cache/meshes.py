"""Meshes kept in the run cache (pipeline/cache/runs.py): a mesh as plain arrays (node
positions in mm, cells, boundary facets, their tags) with the gmsh file written beside it.

Besides the entry's sha256, a reused mesh is checked against what it must be: the counts
of nodes, cells and facets it was stored with, every cell's and facet's node numbers
within the nodes, finite positions, and the volume of its tets (mm³, each as the straight
tet of its four corners) recomputed and equal to the stored one to 1e-9: a surface node moved
after the entry was written shows in the volume even when the checksum was rewritten.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.part import BuiltGeometry
from pipeline.cache import runs as runcache

REDO = "meshed again"


@dataclass
class StoredMesh:
    """A mesh as the fields of pipeline.fe.meshing.MeshedPart (lengths mm) and its gmsh
    file (bytes, in mm), if one was written."""

    fields: dict
    msh: bytes | None


def corner_volume_mm3(x_mm: np.ndarray, cells: np.ndarray) -> float:
    """The summed volume (mm³) of the straight tets through each cell's first four nodes
    (its corners, in gmsh's order): the mesh's volume without the curved edges' bulge."""
    a, b, c, d = (x_mm[cells[:, i]] for i in range(4))
    return float(np.abs(np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a)).sum() / 6.0)


def store(name: str, fields: dict, msh: bytes | None) -> None:
    """Keep the mesh ``fields`` (MeshedPart's, without timings) and its gmsh file under ``name``."""
    built: BuiltGeometry = fields["built"]
    meta = {"cell_type": int(fields["cell_type"]), "names": {str(k): int(v) for k, v in fields["names"].items()},
            "built": {"model": built.model, "volume": float(built.volume),
                      "constraint_points": [[float(c) for c in p] for p in built.constraint_points]},
            "scale": float(fields["scale"]), "quality": float(fields["quality"]),
            "counts": {"nodes": len(fields["x"]), "cells": len(fields["cells"]), "facets": len(fields["facets"])},
            "volume_mm3": corner_volume_mm3(fields["x"], fields["cells"]), "msh": msh is not None}
    arrays = {k: np.asarray(fields[k], dtype=t) for k, t in
              (("x", np.float64), ("cells", np.int64), ("cell_values", np.int32),
               ("facets", np.int64), ("facet_values", np.int32))}
    if msh is not None:
        arrays["msh"] = np.frombuffer(msh, dtype=np.uint8)
    runcache.store(name, runcache.Entry(meta, arrays))


def earlier(name: str) -> StoredMesh | None:
    """The mesh stored under ``name`` if it passes every check above, else None (a failed
    entry is dropped, with one line)."""
    entry = runcache.load(name, REDO)
    if entry is None:
        return None
    why = problem(entry)
    if why is not None:
        runcache.reject(name, why, REDO)
        return None
    m, a = entry.meta, entry.arrays
    b = m["built"]
    built = BuiltGeometry(model=b["model"], volume=b["volume"],
                          constraint_points=tuple(tuple(p) for p in b["constraint_points"]))
    fields = {"x": a["x"], "cells": a["cells"], "cell_values": a["cell_values"], "facets": a["facets"],
              "facet_values": a["facet_values"], "cell_type": m["cell_type"], "names": m["names"], "built": built,
              "scale": m["scale"], "quality": m["quality"]}
    return StoredMesh(fields, a["msh"].tobytes() if m["msh"] else None)


def problem(entry: runcache.Entry) -> str | None:
    """What is wrong with a mesh entry (a few words), or None if it is what it must be."""
    m, a = entry.meta, entry.arrays
    try:
        x, cells, facets = a["x"], a["cells"], a["facets"]
        counts, b = m["counts"], m["built"]
        shapes_ok = (x.ndim == 2 and x.shape[1] == 3 and cells.ndim == 2 and cells.shape[1] in (4, 10)
                     and facets.ndim == 2 and facets.shape[1] in (3, 6)
                     and a["cell_values"].shape == (len(cells),) and a["facet_values"].shape == (len(facets),)
                     and (not m["msh"] or a["msh"].ndim == 1))
        if not shapes_ok or not isinstance(m["names"], dict) or not isinstance(b["model"], str):
            return "arrays of the wrong shape"
        if (len(x), len(cells), len(facets)) != (counts["nodes"], counts["cells"], counts["facets"]):
            return "counts differ from the stored ones"
        if not (runcache.finite(m["cell_type"], m["scale"], m["quality"], m["volume_mm3"], b["volume"])
                and all(runcache.finite(*p) and len(p) == 3 for p in b["constraint_points"])):
            return "a stored number is not finite"
        if not np.all(np.isfinite(x)):
            return "a node position is not finite"
        for k in ("cells", "facets"):
            if len(a[k]) and (a[k].min() < 0 or a[k].max() >= len(x)):
                return f"{k} name nodes that do not exist"
        volume = corner_volume_mm3(x, cells)
        if abs(volume - m["volume_mm3"]) > 1e-9 * abs(m["volume_mm3"]):
            return f"volume {volume:.9g} mm³, stored {m['volume_mm3']:.9g} mm³"
    except (KeyError, TypeError, ValueError, AttributeError, IndexError):
        return "a field missing or of the wrong type"
    return None
