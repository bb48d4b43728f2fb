"""The whole part's gmsh mesh from a quarter model's mesh.msh (mm): on request, not by every
run (the whole part's file is about four times the quarter's, beside a run folder's budget).

    python -m pipeline.output.wholemesh FOLDER    # writes FOLDER/mesh_whole.msh

The quarter's nodes, tets and boundary triangles are reflected in x = 0 and y = 0 by
pipeline.output.mirror (nodes on a symmetry plane shared, every element kept positively
oriented), with their physical groups; the symmetry planes' groups, inside the whole part,
and the quarter's point constraint are left out. MSH 2.2 binary (gmsh and meshio read it),
with a $Comments section saying what it holds.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from pipeline.output.mirror import COPIES, TET_SWAP, mirror_quarter

FILE = "mesh_whole.msh"
NOTE = ("the whole crosshead, mirrored in x = 0 and y = 0 from the quarter model of mesh.msh "
        "(nodes on the symmetry planes shared); mm")
# Groups of the quarter that the whole part does not have: its symmetry planes lie inside
# the whole part, and its point constraint is the quarter's.
DROPPED = ("symmetry_x", "symmetry_y", "constraint_points")
# A singly reflected triangle swaps vertices 1 and 2 to keep its orientation; its mid-edge
# nodes (0,1), (1,2), (2,0) follow (a tet's swap: pipeline.output.mirror.TET_SWAP).
TRIANGLE_SWAP = {3: [0, 2, 1], 6: [0, 2, 1, 5, 4, 3]}


def whole_mesh(quarter: Path, out: Path) -> int:
    """Write the whole part's mesh to ``out`` from the quarter's gmsh file ``quarter``
    (x >= 0, y >= 0, mm); returns its number of tets."""
    import meshio
    m = meshio.read(quarter)
    dropped = {int(tag) for name, (tag, _dim) in m.field_data.items() if name in DROPPED}
    physical = m.cell_data["gmsh:physical"]
    geometrical = m.cell_data.get("gmsh:geometrical", physical)
    tets = np.vstack([b.data for b in m.cells if b.type.startswith("tetra")])
    points, _, _, ids = mirror_quarter(m.points, tets, {})
    blocks, phys, geom = [], [], []
    for block, p, g in zip(m.cells, physical, geometrical):
        swaps = TET_SWAP if block.type.startswith("tetra") else TRIANGLE_SWAP if block.type.startswith("triangle") \
            else None
        if swaps is None or int(p[0]) in dropped:
            continue
        for k, (sx, sy) in enumerate(COPIES):
            c = ids[k][block.data]
            blocks.append((block.type, c[:, swaps[c.shape[1]]] if sx * sy < 0 else c))
            phys.append(p)
            geom.append(g)
    field_data = {name: v for name, v in m.field_data.items() if name not in DROPPED}
    meshio.write(out, meshio.Mesh(points, blocks, cell_data={"gmsh:physical": phys, "gmsh:geometrical": geom},
                                  field_data=field_data), file_format="gmsh22", binary=True)
    data = out.read_bytes()
    end = data.index(b"$EndMeshFormat\n") + len(b"$EndMeshFormat\n")
    out.write_bytes(data[:end] + f"$Comments\ncrosshead {FILE}: {NOTE}\n$EndComments\n".encode("ascii") + data[end:])
    return sum(len(c) for t, c in blocks if t.startswith("tetra"))


if __name__ == "__main__":
    folder = Path(sys.argv[1])
    n = whole_mesh(folder / "mesh.msh", folder / FILE)
    print(f"{folder / FILE}: {n} tets, whole part")
