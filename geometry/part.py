"""The part: the crosshead built with OpenCASCADE from its dimensions (quarter or full),
with named physical groups for the faces that carry loads and constraints (mm).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import gmsh

from .table import MODELS, Dimensions, model_share


class GeometryError(RuntimeError):
    """The CAD kernel produced something other than the part (a silent boolean failure)."""


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
    return full * model_share(model)


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
    quarter = model == "quarter"
    body = _body(d, quarter)
    pieces = _journals(d, quarter)
    seat = _seat(d, quarter)
    cpts = _constraint_points(d, quarter)
    seat_surfs, cpt_tags = _fragment(body + [(3, t) for t in pieces], seat, cpts)
    volumes = [t for dim, t in gmsh.model.getEntities(3)]
    vol = _checked_volume(d, model, volumes, seat_surfs)
    if len(cpt_tags) != len(cpts):
        raise GeometryError("constraint points were not imprinted on the part")
    _name_groups(d, quarter, seat_surfs, volumes, cpt_tags)
    return BuiltGeometry(model=model, volume=vol, constraint_points=cpts)


def _body(d: Dimensions, quarter: bool) -> list[tuple[int, int]]:
    """The body block b1 × b1 × h3 (its x, y >= 0 quarter for the quarter model) less the
    bore of diameter d2 (mm); OCC (dim, tag) pairs."""
    occ = gmsh.model.occ
    a, h = d.b1 / 2, d.h3
    if quarter:
        box = occ.addBox(0, 0, 0, a, a, h)
    else:
        box = occ.addBox(-a, -a, 0, 2 * a, 2 * a, h)
    bore = occ.addCylinder(0, 0, -1, 0, 0, h + 2, d.d2 / 2)
    body, _ = occ.cut([(3, box)], [(3, bore)])
    return body


def _journals(d: Dimensions, quarter: bool) -> list[int]:
    """The journals with their fillets as OCC volume tags, in angular pieces: the lower
    (loaded) half of each bearing surface is then a face of its own (journal_bearing)."""
    if quarter:
        # Quarter journals: the lower quarter (phi 0..90°, the loaded half) and the upper.
        return [_journal_piece(d, +1, 0.0, math.pi / 2),
                _journal_piece(d, +1, math.pi / 2, math.pi / 2)]
    pieces = []
    for side in (+1, -1):
        pieces.append(_journal_piece(d, side, -math.pi / 2, math.pi))   # lower half
        pieces.append(_journal_piece(d, side, math.pi / 2, math.pi))    # upper half
    return pieces


def _seat(d: Dimensions, quarter: bool) -> list[tuple[int, int]]:
    """The seat annulus (diameters seat_inner..seat_outer, mm) in the top face z = h3, its
    x, y >= 0 quarter for the quarter model; OCC (dim, tag) pairs of its surfaces."""
    occ = gmsh.model.occ
    h = d.h3
    ro, ri = d.seat_outer / 2, d.seat_inner / 2
    outer = occ.addDisk(0, 0, h, ro, ro)
    inner = occ.addDisk(0, 0, h, ri, ri)
    seat, _ = occ.cut([(2, outer)], [(2, inner)])
    if quarter:
        clip = occ.addRectangle(0, 0, h, ro + 1, ro + 1)
        seat, _ = occ.intersect(seat, [(2, clip)])
    return seat


def _constraint_points(d: Dimensions, quarter: bool) -> tuple[tuple[float, float, float], ...]:
    """Points (mm) for the constraints that remove rigid-body motion (see pipeline.fe.solve), at
    the middles of the body's bottom edges: one for the quarter (on its plane x = 0), three
    for the full part."""
    a = d.b1 / 2
    if quarter:
        return ((0.0, a, 0.0),)
    return ((0.0, a, 0.0), (0.0, -a, 0.0), (a, 0.0, 0.0))


def _fragment(objects: list[tuple[int, int]], seat: list[tuple[int, int]],
              cpts: tuple[tuple[float, float, float], ...]) -> tuple[list[int], list[int]]:
    """Fragment the volumes with the seat and the constraint points, so that the mesh
    conforms to both and they can carry physical groups; the seat's surface tags and the
    points' tags in the fragmented model (both sorted)."""
    occ = gmsh.model.occ
    point_tags = [occ.addPoint(*p) for p in cpts]
    _, out_map = occ.fragment(objects, seat + [(0, t) for t in point_tags])
    occ.synchronize()
    n_obj = len(objects)
    seat_surfs = sorted({t for i in range(len(seat)) for dim, t in out_map[n_obj + i] if dim == 2})
    cpt_tags = sorted({t for i in range(len(point_tags))
                       for dim, t in out_map[n_obj + len(seat) + i] if dim == 0})
    return seat_surfs, cpt_tags


def _checked_volume(d: Dimensions, model: str, volumes: list[int], seat_surfs: list[int]) -> float:
    """The part's volume (mm³) after checking it and the seat's area (mm²) against their
    closed forms to 1e-6 relative: a failed boolean can leave a part without an error."""
    occ = gmsh.model.occ
    vol = sum(occ.getMass(3, t) for t in volumes)
    expected = analytic_volume(d, model)
    if abs(vol - expected) > 1e-6 * expected:
        raise GeometryError(f"CAD volume {vol:.6g} mm³ differs from closed form {expected:.6g} mm³")
    ro, ri = d.seat_outer / 2, d.seat_inner / 2
    seat_area = sum(occ.getMass(2, t) for t in seat_surfs)
    seat_expected = math.pi * (ro ** 2 - ri ** 2) * model_share(model)
    if abs(seat_area - seat_expected) > 1e-6 * seat_expected:
        raise GeometryError(f"seat area {seat_area:.6g} mm² differs from {seat_expected:.6g} mm²")
    return vol


def _name_groups(d: Dimensions, quarter: bool, seat_surfs: list[int], volumes: list[int],
                 cpt_tags: list[int]) -> None:
    """The physical groups the loads and supports are put on: the seat, the journal
    bearings, the symmetry planes (quarter), the body and the constraint points."""
    groups = {"seat": seat_surfs, "journal_bearing": _bearing_surfaces(d)}
    if quarter:
        groups["symmetry_x"] = _planar_surfaces(axis=0, value=0.0, tol=geometric_tolerance(d))
        groups["symmetry_y"] = _planar_surfaces(axis=1, value=0.0, tol=geometric_tolerance(d))
    for name, tags in groups.items():
        if not tags:
            raise GeometryError(f"physical group {name!r} would be empty")
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, tags), name)
    gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, volumes), "body")
    gmsh.model.setPhysicalName(0, gmsh.model.addPhysicalGroup(0, cpt_tags), "constraint_points")


def geometric_tolerance(d: Dimensions) -> float:
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
    tol = 10 * geometric_tolerance(d)
    x0, x1, zc = d.b1 / 2 + d.rf, d.b6 / 2, d.h3 / 2
    tags = []
    for _, t in gmsh.model.getEntities(2):
        xmin, ymin, zmin, xmax, ymax, zmax = gmsh.model.getBoundingBox(2, t)
        lo, hi = (xmin, xmax) if xmin >= 0 else (-xmax, -xmin)
        if (abs(lo - x0) < tol and abs(hi - x1) < tol and zmax < zc + tol
                and zmin < zc - d.dj / 4 and gmsh.model.getType(2, t) != "Plane"):
            tags.append(t)
    return tags
