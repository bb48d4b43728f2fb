"""Meshing the built part: element sizes at the features, fillets and refined places
(size fields), then second-order elements with their curved-tet repair.
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass
from typing import Mapping

import gmsh
import numpy as np

from .curved import ensure_curved_quality
from .meshspec import MeshSpec
from .part import GeometryError, geometric_tolerance
from .places import at_journal_root
from .table import Dimensions

GRADE = 0.5  # largest growth of the element size per unit distance near the fillets


def _balls(point: tuple[float, float, float], size: float, size_far: float, radius: float,
           thickness: float, part_box: tuple[float, ...]) -> list[int]:
    """gmsh Ball fields (mm): ``size`` within ``radius`` of the point and of those of its
    mirror images in the planes x = 0 and y = 0 (the part and its loads have that symmetry)
    that come within radius + thickness of the part's bounding box ``part_box`` (xmin,
    ymin, zmin, xmax, ymax, zmax), growing linearly to size_far over ``thickness``.

    A Ball is the same size function as a Threshold on a MathEval distance, but gmsh
    evaluates it natively, several times faster with ten refined places (docs/decisions/0004-curved-tet-repair.md).
    An image farther from the part is size_far = the largest size on all of it, which the
    Min of the fields takes from the others anyway: leaving it out gives the same mesh, node
    for node, and gmsh evaluates fewer fields at every point (docs/decisions/0031-meshing-options.md)."""
    x, y, z = abs(point[0]), abs(point[1]), point[2]
    field = gmsh.model.mesh.field
    tags = []
    for cx, cy in sorted({(sx * x, sy * y) for sx in (1, -1) for sy in (1, -1)}):
        if _box_distance((cx, cy, z), part_box) >= radius + thickness:
            continue
        tag = field.add("Ball")
        for name, value in (("XCenter", cx), ("YCenter", cy), ("ZCenter", z), ("Radius", radius),
                            ("Thickness", thickness), ("VIn", size), ("VOut", size_far)):
            field.setNumber(tag, name, value)
        tags.append(tag)
    return tags


def _box_distance(p: tuple[float, float, float], box: tuple[float, ...]) -> float:
    """Distance (mm) from point p to the box (xmin, ymin, zmin, xmax, ymax, zmax); 0 inside."""
    return math.sqrt(sum(max(lo - c, 0.0, c - hi) ** 2 for c, lo, hi in zip(p, box[:3], box[3:])))


def size_field(curves: list[int], size: float, size_far: float, dist_min: float,
               dist_max: float) -> int:
    """A gmsh Threshold field (mm): ``size`` within dist_min of the curves, growing linearly
    to size_far at dist_max; returns its tag. gmsh 4.8 option names (EdgesList,
    NNodesByEdge; newer gmsh: CurvesList, Sampling)."""
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "EdgesList", curves)
    field.setNumber(dist, "NNodesByEdge", 200)
    thr = field.add("Threshold")
    field.setNumber(thr, "IField", dist)
    field.setNumber(thr, "LcMin", size)
    field.setNumber(thr, "LcMax", size_far)
    field.setNumber(thr, "DistMin", dist_min)
    field.setNumber(thr, "DistMax", dist_max)
    return thr


@dataclass(frozen=True)
class Meshed:
    """What :func:`mesh` leaves besides gmsh's mesh: the worst det J ratio of the tets (see
    geometry.curved.jacobian_ratio; 1 for linear tets) and the wall and CPU time (s, the
    CPU time over all of gmsh's threads) of each stage, in the order they ran (STAGES).
    On a loaded machine the CPU time of one thread is the steadier measure."""

    quality: float
    stage_s: dict[str, float]
    stage_cpu_s: dict[str, float]


STAGES = ("1d", "2d", "3d", "optimise", "order", "repair")


def mesh(d: Dimensions, spec: MeshSpec, options: Mapping[str, float] | None = None) -> Meshed:
    """Mesh the current gmsh model: graded sizes, refined at the stress raisers.

    Size fields: distance from the bore edges, the seat band edges and the shoulder
    fillets; size_feature within that distance, growing linearly to size_body over
    ``grading``. Every size is multiplied by spec.factor. Second order if spec.order == 2.
    ``options``: gmsh options set after the project's own (:func:`_set_mesh_options`), for
    measuring alternatives (bench/meshing.py); the runs pass none.

    The stages (curves, surfaces, volumes, the optimisation passes, the element order, the
    curved-tet repair) are timed: :func:`_generate_by_stage`.
    """
    f = spec.factor
    hmax = spec.size_body * f
    fmin = _background_field(_size_fields(d, spec, hmax))
    hmin = min([spec.size_feature, spec.size_fillet]
               + ([spec.size_hotspot, spec.size_edge_hotspot] if spec.hotspots else [])) * f
    _set_mesh_options(spec.order, hmax, hmin)
    for name, value in (options or {}).items():
        gmsh.option.setNumber(name, value)
    stage_s, stage_cpu_s = _generate_by_stage(spec.order)
    t0, c0 = time.perf_counter(), time.process_time()
    quality = ensure_curved_quality(spec.order) if spec.order >= 2 else 1.0
    stage_s["repair"], stage_cpu_s["repair"] = time.perf_counter() - t0, time.process_time() - c0
    # DOLFINx's importer needs contiguous node tags.
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()
    # Remove the size fields, so that the next mesh of this part (pipeline.fe.meshing.Mesher)
    # starts from the state of a new session. They are 1..fmin: gmsh numbers a new field
    # after the largest, and there were none before this call (a new session, or the last
    # call removed its own).
    for tag in range(1, fmin + 1):
        gmsh.model.mesh.field.remove(tag)
    return Meshed(quality=quality, stage_s=stage_s, stage_cpu_s=stage_cpu_s)


# Mesh.HighOrderOptimize's values as gmsh.model.mesh.optimize methods, in gmsh's order.
_HIGH_ORDER_METHODS = {1: ("HighOrder",), 2: ("HighOrderElastic", "HighOrder"), 3: ("HighOrderElastic",),
                       4: ("HighOrderFastCurving",)}


_DONE = re.compile(r"Done meshing ([123])D \(Wall ([0-9.eE+-]+)s, CPU ([0-9.eE+-]+)s")


def _generate_by_stage(order: int) -> tuple[dict[str, float], dict[str, float]]:
    """gmsh's ``generate(3)`` under the options set, in stages; the wall and the CPU time
    (s) of each.

    The option values that generate(3) acts on at its end (optimisation passes, element
    order, high-order optimisation) are read, zeroed while one generate(3) call makes the
    linear mesh, acted on by their own calls, then put back: the same mesh, node for node,
    as a single generate(3). (Three calls generate(1), (2), (3) gave another mesh, one tet
    fewer on No. 05 ×1.69.) The 1-D, 2-D and 3-D times are gmsh's own, from its log."""
    get, opt = gmsh.option.getNumber, gmsh.option.setNumber
    passes = int(get("Mesh.Optimize")), int(get("Mesh.OptimizeNetgen"))
    high_order = int(get("Mesh.HighOrderOptimize"))
    for name in ("Mesh.Optimize", "Mesh.OptimizeNetgen", "Mesh.HighOrderOptimize"):
        opt(name, 0)
    opt("Mesh.ElementOrder", 1)
    stage_s: dict[str, float] = {}
    stage_cpu_s: dict[str, float] = {}
    try:
        gmsh.logger.start()
        try:
            gmsh.model.mesh.generate(3)
        except Exception as exc:
            raise GeometryError(f"gmsh could not mesh the part: {exc}") from None
        finally:
            log = gmsh.logger.get()
            gmsh.logger.stop()
        for line in log:
            done = _DONE.search(line)
            if done:
                stage_s[f"{done.group(1)}d"] = float(done.group(2))
                stage_cpu_s[f"{done.group(1)}d"] = float(done.group(3))
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(max(passes)):
            if passes[0] > i:
                gmsh.model.mesh.optimize("")
            if passes[1] > i:
                gmsh.model.mesh.optimize("Netgen")
        stage_s["optimise"], stage_cpu_s["optimise"] = time.perf_counter() - t0, time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        if order >= 2:
            gmsh.model.mesh.setOrder(order)
            for method in _HIGH_ORDER_METHODS.get(high_order, ()):
                gmsh.model.mesh.optimize(method)
        stage_s["order"], stage_cpu_s["order"] = time.perf_counter() - t0, time.process_time() - c0
    finally:
        opt("Mesh.Optimize", passes[0])
        opt("Mesh.OptimizeNetgen", passes[1])
        opt("Mesh.HighOrderOptimize", high_order)
        opt("Mesh.ElementOrder", order)
    return stage_s, stage_cpu_s


def _size_fields(d: Dimensions, spec: MeshSpec, hmax: float) -> list[int]:
    """The gmsh size fields of the part (mm, sizes times spec.factor, growing to ``hmax``):
    at the bore and seat edges, at the fillets, and in a ball around each hot spot (of the
    fillet's hot-spot size and radius on the journal root, of the edges' elsewhere:
    MeshSpec)."""
    f = spec.factor
    edges, fillets = _feature_curves(d)
    fields_ = [size_field(edges, spec.size_feature * f, hmax, 0.25 * spec.grading * f, spec.grading)]
    if fillets:
        # Fine only on the fillet, then sizes grow with slope <= 0.5: steeper growth gave
        # slivers that curve into inverted P2 elements (seen at rf/6 on No. 05). (Distance
        # from the fillet surface instead of its edge curves was tried: its curved meshes
        # changed from run to run at coarse factors, peaks by up to 3 %.)
        h_f = spec.size_fillet * f
        fields_.append(size_field(fillets, h_f, hmax, 0.5 * d.rf, 0.5 * d.rf + (hmax - h_f) / GRADE))
    on_root = at_journal_root(d, np.array(spec.hotspots, dtype=float).reshape(-1, 3))
    part_box = gmsh.model.getBoundingBox(-1, -1)
    made = set()
    for point, root in zip(spec.hotspots, on_root):
        # A place whose mirror image is another place (the full part's pilot finds both)
        # has the same Balls: made once, the Min is the same (docs/decisions/0031-meshing-options.md).
        mirror_class = (abs(point[0]), abs(point[1]), point[2], bool(root))
        if mirror_class in made:
            continue
        made.add(mirror_class)
        # The radius is a region, not a size: it stays put while the sizes are scaled, so
        # the DOFs grow with refinement like everywhere else (a scaled radius kept the
        # number of elements in the ball constant and stalled the error-bar ratios).
        h_s = (spec.size_hotspot if root else spec.size_edge_hotspot) * f
        r_s = spec.hotspot_radius if root else spec.edge_hotspot_radius
        fields_ += _balls(point, h_s, hmax, r_s, (hmax - h_s) / GRADE, part_box)
    return fields_


def _background_field(fields_: list[int]) -> int:
    """Make the smallest of the size fields gmsh's element size; the tag of that Min
    field, the largest field tag."""
    field = gmsh.model.mesh.field
    fmin = field.add("Min")
    field.setNumbers(fmin, "FieldsList", fields_)
    field.setAsBackgroundMesh(fmin)
    return fmin


def _set_mesh_options(order: int, hmax: float, hmin: float) -> None:
    """gmsh's options for the part's mesh: element sizes from the background field only,
    within 0.5 hmin..hmax (mm); Frontal-Delaunay surfaces, Delaunay volumes; elements of
    ``order``; one thread."""
    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeMax", hmax)
    opt("Mesh.MeshSizeMin", 0.5 * hmin)
    opt("Mesh.Algorithm", 6)
    opt("Mesh.Algorithm3D", 1)
    opt("Mesh.ElementOrder", order)
    # gmsh's own high-order optimiser is off: it spent most of the meshing time repairing a
    # few hundred curved tets; geometry/curved.py does it in a fraction (docs/decisions/0004-curved-tet-repair.md).
    opt("Mesh.HighOrderOptimize", 0)
    opt("General.NumThreads", 1)


def _feature_curves(d: Dimensions) -> tuple[list[int], list[int]]:
    """Curves where stress varies fast: (bore edges and seat circles, fillet edges)."""
    rb, rsi, rso = d.d2 / 2, d.seat_inner / 2, d.seat_outer / 2
    x_fillet = (d.b1 / 2, d.b1 / 2 + d.rf)
    tol = 10 * geometric_tolerance(d)
    tags, fillet = [], []
    for _, t in gmsh.model.getEntities(1):
        xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(1, t)
        if gmsh.model.getType(1, t) not in ("Circle", "Ellipse", "BSpline", "TrimmedCurve"):
            continue
        horizontal = abs(zmax - zmin) < geometric_tolerance(d)
        rmax = max(abs(xmin), abs(xmax), abs(ymin), abs(ymax))
        if horizontal and any(abs(rmax - r) < tol for r in (rb, rsi, rso)):
            tags.append(t)
            continue
        lo = min(abs(xmin), abs(xmax))
        hi = max(abs(xmin), abs(xmax))
        if abs(hi - lo) < geometric_tolerance(d) and any(abs(lo - xf) < tol for xf in x_fillet):
            fillet.append(t)
    return tags, fillet
