"""Meshes of the verification problems (gmsh OpenCASCADE → DOLFINx; mm).

Each builder returns a ``Problem``: the DOLFINx mesh, its facet tags and a map from the
name of each surface physical group to its facet marker. The closed-form solutions live
in tests/verification/test_verification.py; nothing here knows an expected answer.

Thin slabs (Lamé ring, plate with a hole) are a 2-D mesh extruded through the thickness
with a fixed number of element layers, so the through-thickness discretisation is the same
at every refinement level. Faces are picked by their bounding boxes, never by the
entity numbers OpenCASCADE happens to hand out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import gmsh
import numpy as np
from dolfinx.io import gmshio
from mpi4py import MPI

from geometry.sizing import size_field

# The verification bar: 200 mm long, h = 20 mm high (y), b = 10 mm wide (z).
BL, BH, BB = 200.0, 20.0, 10.0
BI = BB * BH ** 3 / 12  # second moment of area about z, mm⁴
BC = BH / 2             # distance of the extreme fibre, mm
TOL = 1e-6  # mm: geometric tolerance for picking planar faces by bounding box
CURVED_TOL = 1e-4  # relative: OCC pads the bounding boxes of curved entities slightly


@dataclass
class Problem:
    mesh: object
    facet_tags: object
    ids: dict[str, int]  # surface group name -> facet marker


def _start(name: str) -> None:
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add(name)


def _finish(groups: dict[str, list[int]], volumes: list[int], order: int,
            comm=MPI.COMM_WORLD) -> Problem:
    """Name the surface groups (markers 1, 2, ... in insertion order), mesh, import."""
    try:
        if comm.rank == 0:
            gmsh.model.addPhysicalGroup(3, volumes, 1)
            gmsh.model.setPhysicalName(3, 1, "body")
            for i, (name, surfs) in enumerate(groups.items(), start=1):
                if not surfs:
                    raise RuntimeError(f"surface group {name!r} is empty")
                gmsh.model.addPhysicalGroup(2, surfs, i)
                gmsh.model.setPhysicalName(2, i, name)
            gmsh.option.setNumber("Mesh.ElementOrder", order)
            gmsh.option.setNumber("Mesh.HighOrderOptimize", 1 if order >= 2 else 0)
            gmsh.model.mesh.generate(3)
        mesh, _, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    finally:
        gmsh.finalize()
    ids = {name: i for i, name in enumerate(groups, start=1)}
    return Problem(mesh=mesh, facet_tags=facet_tags, ids=ids)


def _surfaces(pred) -> list[int]:
    """Surfaces whose bounding box (xmin, ymin, zmin, xmax, ymax, zmax) satisfies pred."""
    return [t for _, t in gmsh.model.getEntities(2) if pred(np.array(gmsh.model.getBoundingBox(2, t)))]


def _plane(axis: int, value: float):
    return lambda bb: abs(bb[axis] - value) < TOL and abs(bb[axis + 3] - value) < TOL


def _sizes(lc_max: float, lc_min: float | None = None) -> None:
    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeExtendFromBoundary", 0 if lc_min is not None else 1)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeMax", lc_max)
    opt("Mesh.MeshSizeMin", 0.5 * (lc_min if lc_min is not None else lc_max))
    opt("Mesh.Algorithm", 6)
    opt("Mesh.Algorithm3D", 1)


def _refine_near(curves: list[int], size: float, size_far: float, dist_min: float,
                 dist_max: float) -> None:
    """Background size field: ``size`` within dist_min of the curves, growing to size_far."""
    gmsh.model.mesh.field.setAsBackgroundMesh(size_field(curves, size, size_far, dist_min, dist_max))


def _extrude(surface: int, thickness: float, layers: int) -> list[int]:
    """Extrude a planar surface along +z with a structured set of layers; the volumes."""
    out = gmsh.model.occ.extrude([(2, surface)], 0, 0, thickness, numElements=[layers])
    gmsh.model.occ.synchronize()
    return [t for d, t in out if d == 3]


def _check_volume(volumes: list[int], expected: float, rel: float = 1e-9) -> None:
    vol = sum(gmsh.model.occ.getMass(3, v) for v in volumes)
    if abs(vol - expected) > rel * expected:
        raise RuntimeError(f"CAD volume {vol} differs from the closed form {expected}")


def lame_quarter_ring(a: float, b: float, t: float, lc: float, order: int,
                      lc_bore: float | None = None, layers: int = 1) -> Problem:
    """Quarter of a thick ring a <= r <= b, x, y >= 0, 0 <= z <= t.

    Groups: "bore" (r = a), "outer" (r = b), "sym_x" (x = 0), "sym_y" (y = 0), "z0", "z1".
    ``lc`` is the in-plane element size; ``lc_bore`` (optional) a finer size at the bore,
    growing to lc over (b − a)/2.
    """
    _start("lame")
    occ = gmsh.model.occ
    ring = occ.cut([(2, occ.addDisk(0, 0, 0, b, b))], [(2, occ.addDisk(0, 0, 0, a, a))])[0]
    quarter = occ.intersect(ring, [(2, occ.addRectangle(0, 0, 0, b, b))])[0]
    occ.synchronize()
    if len(quarter) != 1:
        raise RuntimeError(f"quarter ring boolean gave {quarter}")
    vols = _extrude(quarter[0][1], t, layers)
    _check_volume(vols, math.pi / 4 * (b * b - a * a) * t)

    def on_cyl(r):
        # a quarter cylinder surface of radius r: its bbox spans [0, r] in x and y
        tol = CURVED_TOL * r
        return lambda bb: (abs(bb[0]) < tol and abs(bb[1]) < tol and abs(bb[3] - r) < tol
                           and abs(bb[4] - r) < tol and bb[5] - bb[2] > TOL)

    bore = [s for s in _surfaces(on_cyl(a)) if gmsh.model.getType(2, s) != "Plane"]
    outer = [s for s in _surfaces(on_cyl(b)) if gmsh.model.getType(2, s) != "Plane"]
    groups = {"bore": bore, "outer": outer, "sym_x": _surfaces(_plane(0, 0.0)),
              "sym_y": _surfaces(_plane(1, 0.0)), "z0": _surfaces(_plane(2, 0.0)),
              "z1": _surfaces(_plane(2, t))}
    if lc_bore is None:
        _sizes(lc)
    else:
        _sizes(lc, lc_bore)
        arcs = [c for _, c in gmsh.model.getEntities(1)
                if gmsh.model.getType(1, c) != "Line"
                and abs(max(gmsh.model.getBoundingBox(1, c)[3:5]) - a) < CURVED_TOL * a]
        _refine_near(arcs, lc_bore, lc, 0.0, 0.5 * (b - a))
    return _finish(groups, vols, order)


def plate_with_hole(d: float, W: float, L: float, t_half: float, lc_hole: float,
                    lc_far: float, order: int, layers: int = 1) -> Problem:
    """Eighth of a plate W wide, 2L long, 2 t_half thick with a central hole of diameter d.

    Region: x in [0, L] (load direction), y in [0, W/2], z in [0, t_half], less the hole
    x² + y² < (d/2)². Groups: "hole", "end" (x = L), "side" (y = W/2), "sym_x" (x = 0),
    "sym_y" (y = 0), "mid" (z = 0, the mid-plane), "face" (z = t_half).
    Size lc_hole on the hole edge, growing to lc_far over d.
    """
    r = d / 2
    _start("plate")
    occ = gmsh.model.occ
    cut = occ.cut([(2, occ.addRectangle(0, 0, 0, L, W / 2))], [(2, occ.addDisk(0, 0, 0, r, r))])[0]
    occ.synchronize()
    if len(cut) != 1:
        raise RuntimeError(f"plate boolean gave {cut}")
    vols = _extrude(cut[0][1], t_half, layers)
    _check_volume(vols, (L * W / 2 - math.pi * r * r / 4) * t_half)
    tol = CURVED_TOL * r
    hole = [s for s in _surfaces(lambda bb: abs(bb[3] - r) < tol and abs(bb[4] - r) < tol
                                 and abs(bb[0]) < tol and abs(bb[1]) < tol)
            if gmsh.model.getType(2, s) != "Plane"]
    groups = {"hole": hole, "end": _surfaces(_plane(0, L)), "side": _surfaces(_plane(1, W / 2)),
              "sym_x": _surfaces(_plane(0, 0.0)), "sym_y": _surfaces(_plane(1, 0.0)),
              "mid": _surfaces(_plane(2, 0.0)), "face": _surfaces(_plane(2, t_half))}
    _sizes(lc_far, lc_hole)
    arcs = [c for _, c in gmsh.model.getEntities(1) if gmsh.model.getType(1, c) != "Line"
            and abs(max(gmsh.model.getBoundingBox(1, c)[3:5]) - r) < tol]
    _refine_near(arcs, lc_hole, lc_far, 0.2 * r, 2.0 * d)
    return _finish(groups, vols, order)


def bar(length: float, h: float, b_half: float, lc: float, order: int) -> Problem:
    """Prismatic bar x in [0, length], y in [−h/2, h/2], z in [0, b_half] (half the width).

    Groups: "x0", "x1" (the ends), "z0" (z = 0, symmetry plane of a bar 2 b_half wide),
    "z1", "y0", "y1" (y = ∓h/2). Unstructured tetrahedra of size lc.
    """
    _start("bar")
    occ = gmsh.model.occ
    box = occ.addBox(0, -h / 2, 0, length, h, b_half)
    occ.synchronize()
    _check_volume([box], length * h * b_half)
    groups = {"x0": _surfaces(_plane(0, 0.0)), "x1": _surfaces(_plane(0, length)),
              "z0": _surfaces(_plane(2, 0.0)), "z1": _surfaces(_plane(2, b_half)),
              "y0": _surfaces(_plane(1, -h / 2)), "y1": _surfaces(_plane(1, h / 2))}
    _sizes(lc)
    return _finish(groups, [box], order)


def box(lx: float, ly: float, lz: float, lc: float, order: int) -> Problem:
    """Box [0, lx]×[0, ly]×[0, lz], unstructured tets graded from size lc/2 at the origin
    corner to lc at the opposite corner, so the elements are irregular.

    Groups: "x0", "x1", "y0", "y1", "z0", "z1".
    """
    _start("box")
    occ = gmsh.model.occ
    bx = occ.addBox(0, 0, 0, lx, ly, lz)
    occ.synchronize()
    _check_volume([bx], lx * ly * lz)
    groups = {}
    for axis, (n0, n1), l_ in zip(range(3), (("x0", "x1"), ("y0", "y1"), ("z0", "z1")), (lx, ly, lz)):
        groups[n0] = _surfaces(_plane(axis, 0.0))
        groups[n1] = _surfaces(_plane(axis, l_))
    _sizes(lc, 0.5 * lc)
    field = gmsh.model.mesh.field
    f = field.add("MathEval")
    field.setString(f, "F", f"{0.5 * lc} + {0.5 * lc} * Sqrt(x*x + y*y + z*z) / "
                            f"{math.sqrt(lx * lx + ly * ly + lz * lz)}")
    field.setAsBackgroundMesh(f)
    return _finish(groups, [bx], order)
