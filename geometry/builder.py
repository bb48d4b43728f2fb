"""Parametric gmsh/OpenCASCADE model of a DIN 15412 type A crosshead (units: mm).

Axes (DESIGN §2): x along the journals, y across, z up; origin on the bore axis at the
bottom face. The quarter model is x >= 0, y >= 0; the full model is the whole part.

The journals are never made by cutting a filleted cylinder (OpenCASCADE booleans through
the journal axis can silently return nothing, STACK.md). Each journal is a profile
(end-face disk + concave shoulder fillet + cylinder) revolved about its axis in pieces:
lower and upper halves, so the loaded lower half of the bearing surface is a surface of
its own. Every boolean is followed by a volume check against the closed form.

Physical groups (names are the interface; code looks tags up by name):
  volume "body"; surfaces "seat" (loaded annulus on the top face), "journal_bearing"
  (lower half of each journal's bearing cylinder), "symmetry_x" (x = 0), "symmetry_y"
  (y = 0; both quarter model only), and "constraint_points" (points used to remove the
  rigid-body motion that the symmetry planes leave free).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import gmsh
import numpy as np

from .table import Dimensions

MODELS = ("quarter", "full")
HOTSPOT_SIZE = 0.4  # × the smaller of the feature and fillet sizes, at a pilot's stress peak
HOTSPOT_RADIUS = 0.024  # × h3: how far that size holds around the peak (not scaled by factor)
GRADE = 0.5  # largest growth of the element size per unit distance near the fillets


class GeometryError(RuntimeError):
    """The CAD kernel produced something other than the part (a silent boolean failure)."""


@dataclass(frozen=True)
class MeshSpec:
    """Mesh size controls, mm. ``factor`` scales every size together (refinement studies).

    size_body: size far from features; size_feature: size on the bore edges and the seat
    band edges; size_fillet: size on the shoulder fillets (the journal-root stress peak
    sits there); grading: distance over which sizes grow to size_body; order: geometric
    order of the elements (1 or 2).
    """

    size_body: float
    size_feature: float
    size_fillet: float
    grading: float
    factor: float = 1.0
    order: int = 2
    # Stress peaks found on a pilot mesh (mm, any quadrant: mirrored into all four):
    # size_hotspot within hotspot_radius of each, then growing like near the fillets.
    hotspots: tuple[tuple[float, float, float], ...] = ()
    size_hotspot: float = 0.0
    hotspot_radius: float = 0.0

    @staticmethod
    def default_for(d: Dimensions, factor: float = 1.0, order: int = 2) -> "MeshSpec":
        """Sizes proportional to the part so every row meshes alike.

        The ratios were chosen for No. 05 by the convergence study (`make converge`).
        """
        fillet = 0.25 * d.rf if d.rf > 0 else 0.02 * d.h3
        feature = 0.05 * d.h3
        return MeshSpec(size_body=0.16 * d.h3, size_feature=feature, size_fillet=fillet,
                        grading=0.4 * d.h3, factor=factor, order=order,
                        size_hotspot=HOTSPOT_SIZE * min(feature, fillet),
                        hotspot_radius=HOTSPOT_RADIUS * d.h3)


@dataclass(frozen=True)
class BuiltGeometry:
    """What the builder made: volume (mm³) and the points where constraints go (mm)."""

    model: str
    volume: float
    constraint_points: tuple[tuple[float, float, float], ...]


def analytic_volume(d: Dimensions, model: str = "quarter") -> float:
    """Closed-form volume of the part, mm³ (body − bore + two journals with fillets).

    The fillet ring (section rf² − π rf²/4 revolved about the journal axis) uses Pappus'
    theorem with the centroid of a square less a quarter disk.
    """
    rj, rf = d.dj / 2, d.rf
    body = d.b1 * d.b1 * d.h3 - math.pi * (d.d2 / 2) ** 2 * d.h3
    journal = math.pi * rj ** 2 * d.b2
    area = rf ** 2 * (1 - math.pi / 4)
    if area > 0:
        t_bar = rf * (5 / 6 - math.pi / 4) / (1 - math.pi / 4)
        journal += 2 * math.pi * (rj + t_bar) * area
    full = body + 2 * journal
    return full / 4 if model == "quarter" else full


def _journal_piece(d: Dimensions, side: int, phi0: float, dphi: float) -> int:
    """One angular piece of a journal (with fillet), revolved by dphi from angle phi0.

    The profile lies in the half-plane through the journal axis in direction
    e(phi) = (0, sin phi, -cos phi): phi = 0 points down, pi/2 to +y. side = +1 or -1
    picks the journal at +x or -x. Returns the OCC volume tag.
    """
    occ = gmsh.model.occ
    zc = d.h3 / 2
    rj, rf = d.dj / 2, d.rf
    x0, x1 = d.b1 / 2, d.b6 / 2
    ey, ez = math.sin(phi0), -math.cos(phi0)

    def pt(x: float, r: float) -> int:
        return occ.addPoint(side * x, r * ey, zc + r * ez)

    p_axis0 = pt(x0, 0.0)
    p_axis1 = pt(x1, 0.0)
    p_tip = pt(x1, rj)
    p_fil1 = pt(x0 + rf, rj)
    curves = []
    if rf > 0:
        p_fil0 = pt(x0, rj + rf)
        p_centre = pt(x0 + rf, rj + rf)
        curves.append(occ.addLine(p_axis0, p_fil0))
        curves.append(occ.addCircleArc(p_fil0, p_centre, p_fil1))
    else:
        curves.append(occ.addLine(p_axis0, p_fil1))
    curves += [occ.addLine(p_fil1, p_tip), occ.addLine(p_tip, p_axis1),
               occ.addLine(p_axis1, p_axis0)]
    face = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    out = occ.revolve([(2, face)], 0, 0, zc, side * 1.0, 0, 0, side * dphi)
    vols = [t for dim, t in out if dim == 3]
    if len(vols) != 1:
        raise GeometryError(f"journal revolve gave {len(vols)} volumes")
    if rf > 0:
        occ.remove([(0, p_centre)])
    return vols[0]


def build(d: Dimensions, model: str = "quarter") -> BuiltGeometry:
    """Create the part in the current gmsh model with named physical groups.

    Assumes ``d`` has passed :func:`geometry.table.validate`. Raises GeometryError if the
    kernel's volume differs from the closed form by more than 1e-6 relative.
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    occ = gmsh.model.occ
    quarter = model == "quarter"
    a, h = d.b1 / 2, d.h3
    if quarter:
        box = occ.addBox(0, 0, 0, a, a, h)
        bore = occ.addCylinder(0, 0, -1, 0, 0, h + 2, d.d2 / 2)
    else:
        box = occ.addBox(-a, -a, 0, 2 * a, 2 * a, h)
        bore = occ.addCylinder(0, 0, -1, 0, 0, h + 2, d.d2 / 2)
    body, _ = occ.cut([(3, box)], [(3, bore)])
    if quarter:
        # Quarter journals: the lower quarter (phi 0..90°, the loaded half) and the upper.
        pieces = [_journal_piece(d, +1, 0.0, math.pi / 2),
                  _journal_piece(d, +1, math.pi / 2, math.pi / 2)]
    else:
        pieces = []
        for side in (+1, -1):
            pieces.append(_journal_piece(d, side, -math.pi / 2, math.pi))   # lower half
            pieces.append(_journal_piece(d, side, math.pi / 2, math.pi))    # upper half
    ro, ri = d.seat_outer / 2, d.seat_inner / 2
    outer = occ.addDisk(0, 0, h, ro, ro)
    inner = occ.addDisk(0, 0, h, ri, ri)
    seat, _ = occ.cut([(2, outer)], [(2, inner)])
    if quarter:
        clip = occ.addRectangle(0, 0, h, ro + 1, ro + 1)
        seat, _ = occ.intersect(seat, [(2, clip)])
    # Points for the constraints that remove rigid-body motion (see pipeline.solve).
    if quarter:
        cpts = ((0.0, a, 0.0),)
    else:
        cpts = ((0.0, a, 0.0), (0.0, -a, 0.0), (a, 0.0, 0.0))
    point_tags = [occ.addPoint(*p) for p in cpts]
    objects = body + [(3, t) for t in pieces]
    out, out_map = occ.fragment(objects, seat + [(0, t) for t in point_tags])
    occ.synchronize()

    n_obj = len(objects)
    seat_surfs = sorted({t for i in range(len(seat)) for dim, t in out_map[n_obj + i] if dim == 2})
    cpt_tags = sorted({t for i in range(len(point_tags))
                       for dim, t in out_map[n_obj + len(seat) + i] if dim == 0})
    volumes = [t for dim, t in gmsh.model.getEntities(3)]
    vol = sum(occ.getMass(3, t) for t in volumes)
    expected = analytic_volume(d, model)
    if abs(vol - expected) > 1e-6 * expected:
        raise GeometryError(f"CAD volume {vol:.6g} mm³ differs from closed form {expected:.6g} mm³")
    seat_area = sum(occ.getMass(2, t) for t in seat_surfs)
    seat_expected = math.pi * (ro ** 2 - ri ** 2) / (4 if quarter else 1)
    if abs(seat_area - seat_expected) > 1e-6 * seat_expected:
        raise GeometryError(f"seat area {seat_area:.6g} mm² differs from {seat_expected:.6g} mm²")
    if len(cpt_tags) != len(cpts):
        raise GeometryError("constraint points were not imprinted on the part")

    groups = {"seat": seat_surfs, "journal_bearing": _bearing_surfaces(d)}
    if quarter:
        groups["symmetry_x"] = _planar_surfaces(axis=0, value=0.0, tol=_tol(d))
        groups["symmetry_y"] = _planar_surfaces(axis=1, value=0.0, tol=_tol(d))
    for name, tags in groups.items():
        if not tags:
            raise GeometryError(f"physical group {name!r} would be empty")
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, tags), name)
    gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, volumes), "body")
    gmsh.model.setPhysicalName(0, gmsh.model.addPhysicalGroup(0, cpt_tags), "constraint_points")
    return BuiltGeometry(model=model, volume=vol, constraint_points=cpts)


def _tol(d: Dimensions) -> float:
    """Geometric matching tolerance, mm: relative to the part so any scale works."""
    return 1e-5 * d.b6


def _planar_surfaces(axis: int, value: float, tol: float) -> list[int]:
    """Surfaces lying in the plane x_axis = value (from their bounding boxes)."""
    tags = []
    for _, t in gmsh.model.getEntities(2):
        bb = gmsh.model.getBoundingBox(2, t)
        if abs(bb[axis] - value) < tol and abs(bb[axis + 3] - value) < tol:
            tags.append(t)
    return tags


def _bearing_surfaces(d: Dimensions) -> list[int]:
    """Lower-half journal bearing cylinders: from |x| = b1/2 + rf to the tip, below the axis."""
    tol = 10 * _tol(d)
    x0, x1, zc = d.b1 / 2 + d.rf, d.b6 / 2, d.h3 / 2
    tags = []
    for _, t in gmsh.model.getEntities(2):
        xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(2, t)
        lo, hi = (xmin, xmax) if xmin >= 0 else (-xmax, -xmin)
        if (abs(lo - x0) < tol and abs(hi - x1) < tol and zmax < zc + tol
                and zmin < zc - d.dj / 4 and gmsh.model.getType(2, t) != "Plane"):
            tags.append(t)
    return tags


def _balls(point: tuple[float, float, float], size: float, size_far: float, radius: float,
           thickness: float) -> list[int]:
    """gmsh Ball fields (mm): ``size`` within ``radius`` of the point and of its mirror
    images in the planes x = 0 and y = 0 (the part and its loads have that symmetry),
    growing linearly to size_far over ``thickness``.

    A Ball is the same size function as a Threshold on a MathEval distance, but gmsh
    evaluates it natively: with ten refined places the MathEval version made the first-order
    mesh 3x slower (No. 05 x2: 1.10 s against 0.34 s without places)."""
    x, y, z = abs(point[0]), abs(point[1]), point[2]
    field = gmsh.model.mesh.field
    tags = []
    for cx, cy in sorted({(sx * x, sy * y) for sx in (1, -1) for sy in (1, -1)}):
        tag = field.add("Ball")
        for name, value in (("XCenter", cx), ("YCenter", cy), ("ZCenter", z), ("Radius", radius),
                            ("Thickness", thickness), ("VIn", size), ("VOut", size_far)):
            field.setNumber(tag, name, value)
        tags.append(tag)
    return tags


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


def mesh(d: Dimensions, spec: MeshSpec) -> float:
    """Mesh the current gmsh model: graded sizes, refined at the stress raisers.

    Size fields: distance from the bore edges, the seat band edges and the shoulder
    fillets; size_feature within that distance, growing linearly to size_body over
    ``grading``. Every size is multiplied by spec.factor. Second order if spec.order == 2.
    Returns the mesh's worst det J ratio (see :func:`jacobian_ratio`; 1 for linear tets).
    """
    f = spec.factor
    hmax = spec.size_body * f
    edges, fillets = _feature_curves(d)
    field = gmsh.model.mesh.field

    def threshold(curves: list[int], size: float, dist_min: float, dist_max: float) -> int:
        return size_field(curves, size, hmax, dist_min, dist_max)

    fields_ = [threshold(edges, spec.size_feature * f, 0.25 * spec.grading * f, spec.grading)]
    if fillets:
        # Fine only on the fillet, then sizes grow with slope <= 0.5: steeper growth gave
        # slivers that curve into inverted P2 elements (seen at rf/6 on No. 05). (Distance
        # from the fillet surface instead of its edge curves was tried: its curved meshes
        # changed from run to run at coarse factors, peaks by up to 3 %.)
        h_f = spec.size_fillet * f
        fields_.append(threshold(fillets, h_f, 0.5 * d.rf, 0.5 * d.rf + (hmax - h_f) / GRADE))
    for point in spec.hotspots:
        # The radius is a region, not a size: it stays put while the sizes are scaled, so
        # the DOFs grow with refinement like everywhere else (a scaled radius kept the
        # number of elements in the ball constant and stalled the error-bar ratios).
        h_s, r_s = spec.size_hotspot * f, spec.hotspot_radius
        fields_ += _balls(point, h_s, hmax, r_s, (hmax - h_s) / GRADE)
    fmin = field.add("Min")
    field.setNumbers(fmin, "FieldsList", fields_)
    field.setAsBackgroundMesh(fmin)
    hmin = min([spec.size_feature, spec.size_fillet] + ([spec.size_hotspot] if spec.hotspots else [])) * f
    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeMax", hmax)
    opt("Mesh.MeshSizeMin", 0.5 * hmin)
    opt("Mesh.Algorithm", 6)
    opt("Mesh.Algorithm3D", 1)
    opt("Mesh.ElementOrder", spec.order)
    # gmsh's own high-order optimiser is off: it spent 3/4 of the meshing time (10 s of
    # 13.5 s at No. 05 x1) repairing ~400 curved tets; _relax_curved does it in < 1 s.
    opt("Mesh.HighOrderOptimize", 0)
    opt("General.NumThreads", 1)
    try:
        gmsh.model.mesh.generate(3)
    except Exception as exc:
        raise GeometryError(f"gmsh could not mesh the part: {exc}") from None
    quality = _ensure_curved_quality(spec.order) if spec.order >= 2 else 1.0
    # DOLFINx's importer needs contiguous node tags.
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()
    # Remove the size fields, so that the next mesh of this part (pipeline.mesh_io.Mesher)
    # starts from the state of a new session. They are 1..fmin: gmsh numbers a new field
    # after the largest, and there were none before this call (a new session, or the last
    # call removed its own).
    for tag in range(1, fmin + 1):
        field.remove(tag)
    return quality


def _feature_curves(d: Dimensions) -> tuple[list[int], list[int]]:
    """Curves where stress varies fast: (bore edges and seat circles, fillet edges)."""
    rb, rsi, rso = d.d2 / 2, d.seat_inner / 2, d.seat_outer / 2
    x_fillet = (d.b1 / 2, d.b1 / 2 + d.rf)
    tol = 10 * _tol(d)
    tags, fillet = [], []
    for _, t in gmsh.model.getEntities(1):
        xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(1, t)
        if gmsh.model.getType(1, t) not in ("Circle", "Ellipse", "BSpline", "TrimmedCurve"):
            continue
        horizontal = abs(zmax - zmin) < _tol(d)
        rmax = max(abs(xmin), abs(xmax), abs(ymin), abs(ymax))
        if horizontal and any(abs(rmax - r) < tol for r in (rb, rsi, rso)):
            tags.append(t)
            continue
        lo = min(abs(xmin), abs(xmax))
        hi = max(abs(xmin), abs(xmax))
        if abs(hi - lo) < _tol(d) and any(abs(lo - xf) < tol for xf in x_fillet):
            fillet.append(t)
    return tags, fillet


HO_TARGET = 0.3  # worst det J ratio accepted on a curved tet (see _relax_curved)
RELAX_STEP = 0.5  # how far _relax_curved pulls a mid-edge node per pass (× its bow); see there


def _ensure_curved_quality(order: int) -> float:
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
    (tests/test_geometry.py checks the two agree): asking gmsh for every tet's Jacobians
    cost 0.29 s at No. 05 x1, on the path of every run.

    Why: curving second-order tets onto the shoulder fillet inverts some (det J < 0 on
    No. 05), and elements left near a ratio of 0.1 gave spurious peaks (138 MPa instead of
    ~116 at No. 05 ×1.3). The bad tets are slivers with all four vertices on the fillet
    near its tangent line with the body face: their boundary edges bow (follow the CAD
    surface) while their interior edge stays straight, which folds a tet thinner than the bow.

    1. The mid-edge nodes of each bad tet move by the mean bow of its curved edges, so the
       sliver bends with the surface; a move is kept only if no tet it touches ends worse
       and below target. Nodes on curves and on named surfaces (symmetry planes, seat,
       bearing) stay. The others move: inside the volume, on a free plane (on No. 05 the
       body face beside the fillet leaves its plane by at most 0.021 mm at ×2.5 and
       0.0075 mm at ×1, measured) and on the free fillet itself, whose bowed nodes get the
       mean bow on top of their own (moving only the straight ones, as a variant, gave
       115.458 / 114.233 MPa at ×2.5 / ×1 below: not adopted, measured too late to re-bench).
    2. What is still bad: mid-edge nodes are pulled towards their edge's midpoint,
       RELAX_STEP of their bow per pass (a straight tet has ratio 1, so this ends); the
       boundary there becomes locally faceted. After both steps, fillet nodes lie off the
       torus by at most 0.059 mm at ×2.5 and 0.014 mm at ×1 (No. 05, measured).

    Against gmsh's high-order optimiser (HighOrderOptimize 1, same target) on the same
    linear mesh, No. 05 P2, global / critical peak (MPa): 115.43 / 66.275 against 115.46 /
    66.276 at ×2.5, 118.13 / 66.279 against 118.13 / 66.280 at ×2, 114.84 / 66.220 against
    114.83 / 66.221 at ×1.3, 114.26 / 66.235 against 114.23 / 66.236 at ×1 (P3 at ×2.5:
    114.47 against 114.51); at ×4 134.3 against 131.5 (both far from the converged ~114).
    Meshing at ×1: 1.9 s instead of 15.3 s (this function 0.3 s). Without step 1 the
    flattened tets reached into the fillet at ×2.5 (a spurious 119.6 MPa peak on the upper
    fillet); with step 1 moving only nodes inside the volume, 118.9 MPa. Step 0.5, not
    0.25: make run at mesh factors 0.95/1/1.05 (9 meshes, own pilots) had no global peak
    above 117 MPa with 0.5, but 3 spurious ones (119.9-123.5) with 0.25 (without step 1).
    """
    _, conn = gmsh.model.mesh.getElementsByType(11)
    if len(conn) == 0:
        return 1.0
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    conn = index[conn.astype(np.int64)].reshape(-1, 10)
    x = coords.reshape(-1, 3).copy()
    mids = conn[:, 4:].ravel()
    a = conn[:, _TET10_EDGES[:, 0]].ravel()
    b = conn[:, _TET10_EDGES[:, 1]].ravel()
    straight = x.copy()
    straight[mids] = 0.5 * (x[a] + x[b])
    bow = x - straight                           # zero off curved surfaces and curves
    # Nodes on a named surface (symmetry planes, seat, bearing) or on a curve stay put in
    # step 1: a mid-edge node on a plane has no bow either, but must stay on its plane.
    movable = np.ones(len(x), dtype=bool)
    pinned = [(1, t) for _, t in gmsh.model.getEntities(1)]
    pinned += [(2, t) for _, g in gmsh.model.getPhysicalGroups(2)
               for t in gmsh.model.getEntitiesForPhysicalGroup(2, g)]
    for dim, t in pinned:
        movable[index[gmsh.model.mesh.getNodes(dim, t, includeBoundary=True)[0].astype(np.int64)]] = False

    def ratios(y: np.ndarray, known: np.ndarray | None = None, moved: np.ndarray | None = None) -> np.ndarray:
        # Only tets with a bowed mid-edge node: a straight tet has ratio 1 (and most are).
        # Given the ratios ``known`` of a y that differs only at the nodes ``moved``, only
        # the tets with a moved node are computed again (the loop below moves few nodes).
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

    ratio = ratios(x)
    bad = np.flatnonzero(ratio < target)
    if len(bad) == 0:
        return float(ratio.min())
    # 1. Movable mid-edge nodes of bad tets move by the mean bow of the tet's bowed ones.
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
    r_trial = ratios(trial, ratio, bent)
    worse = np.flatnonzero((r_trial < ratio) & (r_trial < target))
    reject = np.zeros(len(x), dtype=bool)
    reject[conn[worse, 4:].ravel()] = True
    bent = bent[~reject[bent]]
    x[bent] = trial[bent]
    # 2. Pull what is still bad towards straight.
    curved = x.copy()
    alpha = np.ones(len(x))                      # 1 = as curved, 0 = straight
    final, nodes = ratio, bent
    while True:
        final = ratios(x, final, nodes)
        bad = final < target
        if not bad.any():
            break
        nodes = np.unique(conn[bad, 4:])
        nodes = nodes[alpha[nodes] > 0]
        if len(nodes) == 0:  # cannot happen: a tet with straight edges has ratio 1
            raise GeometryError("mesh: a tet stays inverted with straight edges")
        alpha[nodes] = np.maximum(alpha[nodes] - RELAX_STEP, 0.0)
        x[nodes] = straight[nodes] + alpha[nodes, None] * (curved[nodes] - straight[nodes])
    moved = np.union1d(np.flatnonzero(alpha < 1), bent)
    for n in moved:
        gmsh.model.mesh.setNode(int(tags[n]), x[n].tolist(), [])
    return float(final.min())


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
