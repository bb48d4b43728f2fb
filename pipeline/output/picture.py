"""Off-screen picture of von Mises stress on the deformed part, peaks marked (mm, MPa).

Runs in its own process (``python -m pipeline.output.picture FOLDER``) and reads only files the
run wrote: fields.vtu (the displacement, and the reported von Mises at each node: the
quantity the report reports) and results.json (the peaks as reported). A separate process
because VTK's wheel crashes (std::regex, bad_alloc) when DOLFINx's libraries are loaded first.

Drawn with VTK's own classes, not pyvista's plotter: pyvista.plotting imports
matplotlib.pyplot, most of the picture's CPU time, while it runs beside the error-bar
solves on the same cores (docs/decisions/0007-drawing-and-field-files.md).
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.runtime.atomicfile import replacing
from pipeline.runtime.environment import CACHE_HOME

if TYPE_CHECKING:  # VTK loads only in the picture's own process (module docstring)
    from vtkmodules.vtkCommonCore import vtkLookupTable
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    from vtkmodules.vtkRenderingCore import vtkRenderer, vtkRenderWindow, vtkTextActor

PANEL_PX, SCALE_PX, HEIGHT_PX = 1000, 240, 950  # two panels, then the colour scale's column
WINDOW = (2 * PANEL_PX + SCALE_PX, HEIGHT_PX)  # pixels
# Viewport x-ranges (fractions of the window): the panels, then the colour scale in a
# column of its own, so that no part of the drawn crosshead lies under it.
PANELS = tuple((k * PANEL_PX / WINDOW[0], (k + 1) * PANEL_PX / WINDOW[0]) for k in range(2))
SCALE_COLUMN = (2 * PANEL_PX / WINDOW[0], 1.0)
TURBO_TABLE = CACHE_HOME / "colours" / "turbo-256.npy"  # turbo_rgba
# Left: from above, the seat, the bore and the ligament beside it. Right: from below and
# outside, the journal root, its shoulder fillet and the bottom face. A panel marks a peak
# only where the camera sees it (seen_from), so no label points at a hidden place.
VIEWS = ((-0.9, -1.5, 0.9), (0.5, 1.6, -1.0))
COLOURS = {"black": (0.0, 0.0, 0.0), "magenta": (0.8, 0.0, 0.8), "red": (0.85, 0.1, 0.1),
           "green": (0.1, 0.6, 0.2)}

_TET_FACES = np.array([(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)])   # outward for a positive tet
REPORTED = "von_mises_reported_MPa"   # pipeline.output.fields.REPORTED (no DOLFINx import here)


def outer_surface(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface of a connected mesh of tets (m×4 node indices, positively
    oriented): (nodes used, triangles numbered into that list, outward). A face is on the
    surface when no other tet has the same three nodes."""
    faces = tets[:, _TET_FACES].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    n = int(tets.max()) + 1
    if n ** 3 < 2 ** 63:   # one integer per face: a 1-D sort
        code = (key[:, 0] * n + key[:, 1]) * n + key[:, 2]
        order = np.argsort(code, kind="stable")
        ordered = code[order]
        differs = ordered[1:] != ordered[:-1]
        alone = order[np.r_[True, differs] & np.r_[differs, True]]
    else:
        _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
        alone = first[count == 1]
    used, tri = np.unique(faces[np.sort(alone)], return_inverse=True)
    return used, tri.reshape(-1, 3)


def seen_from(points: np.ndarray, tri: np.ndarray, target: np.ndarray, eye: np.ndarray,
              tol_mm: float) -> bool:
    """True when no surface triangle crosses the line of sight from ``eye`` to ``target``
    (mm) more than ``tol_mm`` before the target: the camera sees that point of the surface.

    ``points`` (n×3, mm) and ``tri`` (m×3 indices) are the drawn surface. A ray-triangle
    test (Möller and Trumbore 1997) against every triangle at once; the triangles that
    meet at the target itself cross at the target and do not count.
    """
    a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
    ray = np.asarray(target, float) - np.asarray(eye, float)
    dist = float(np.linalg.norm(ray))
    e1, e2 = b - a, c - a
    pvec = np.cross(ray, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = np.abs(det) > 1e-14 * dist * np.einsum("ij,ij->i", e1, e1)
    det = np.where(ok, det, 1.0)
    tvec = np.asarray(eye, float) - a
    u = np.einsum("ij,ij->i", tvec, pvec) / det
    qvec = np.cross(tvec, e1)
    v = (qvec @ ray) / det
    t = np.einsum("ij,ij->i", e2, qvec) / det  # fraction of the way from eye to target
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1 - tol_mm / dist)
    return not bool(hit.any())


def mark_places(points0: np.ndarray, points: np.ndarray, tri: np.ndarray, loc, mirrored: bool,
                eyes: list[np.ndarray], tol_mm: float) -> list[np.ndarray | None]:
    """Where to mark a peak at ``loc`` (mm, undeformed) in each panel: the drawn (deformed)
    position of the nearest surface node, or None where the camera at that eye cannot see
    it. With ``mirrored`` (a quarter model drawn whole) each mirror image of the peak
    (±x, ±y) is an equal peak, and a panel marks the first one it sees."""
    images = [np.asarray(loc, float) * (sx, sy, 1.0) for sx in (1, -1) for sy in (1, -1)] if mirrored \
        else [np.asarray(loc, float)]
    drawn = [points[int(np.argmin(np.linalg.norm(points0 - q, axis=1)))] for q in images]
    return [next((p for p in drawn if seen_from(points, tri, p, eye, tol_mm)), None) for eye in eyes]


def read_fields(path: Path, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(points mm, each tet's four corner nodes (m×4), the point arrays ``names``) of a field
    file of 10-node tets (fields.vtu); only those arrays are read."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.UpdateInformation()
    selection = reader.GetPointDataArraySelection()
    selection.DisableAllArrays()
    for name in names:
        selection.EnableArray(name)
    reader.GetCellDataArraySelection().DisableAllArrays()
    reader.Update()
    grid = reader.GetOutput()
    xyz = vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    offsets = vtk_to_numpy(grid.GetCells().GetOffsetsArray())
    cells = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(len(offsets) - 1, -1)
    data = grid.GetPointData()
    return xyz, cells[:, :4].astype(np.int64), {name: vtk_to_numpy(data.GetArray(name)).astype(float) for name in names}


def _surface_actor(points: np.ndarray, tri: np.ndarray, values: np.ndarray, lut):
    """A VTK actor of triangles coloured by point values through ``lut``."""
    from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(points), deep=True))
    cells = vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(np.arange(0, 3 * len(tri) + 1, 3, dtype=np.int64), deep=True),
                  numpy_to_vtkIdTypeArray(np.ascontiguousarray(tri.ravel(), dtype=np.int64), deep=True))
    poly = vtkPolyData()
    poly.SetPoints(pts)
    poly.SetPolys(cells)
    poly.GetPointData().SetScalars(numpy_to_vtk(np.ascontiguousarray(values), deep=True))
    mapper = vtkPolyDataMapper()
    mapper.SetInputData(poly)
    mapper.SetLookupTable(lut)
    mapper.SetScalarRange(lut.GetRange())
    mapper.InterpolateScalarsBeforeMappingOn()  # colours from the values, not blended colours
    actor = vtkActor()
    actor.SetMapper(mapper)
    return actor


def turbo_rgba(path: Path = TURBO_TABLE) -> np.ndarray:
    """matplotlib's turbo colour map at 256 evenly spaced points (256×4 RGBA, 0..1).

    Read from ``path`` once a picture has made it there from matplotlib: importing
    matplotlib costs the picture process about 0.2 s of CPU, and the picture is what a
    run with a changed load waits for last. The file is written under a temporary name
    and renamed, so pictures drawn at once never read half of it.
    """
    try:
        rgba = np.load(path)
        if rgba.shape == (256, 4):
            return rgba
    except (OSError, ValueError):
        pass  # not made yet, or unreadable: made again below
    from matplotlib import colormaps  # matplotlib.colors only, not pyplot
    rgba = colormaps["turbo"](np.linspace(0.0, 1.0, 256))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with replacing(path, "wb") as f:
            np.save(f, rgba)
    except OSError:
        pass  # a table that cannot be kept only costs time
    return rgba


def _turbo(vmin: float, vmax: float):
    """The turbo colour map (:func:`turbo_rgba`) as a VTK lookup table over [vmin, vmax] (MPa)."""
    from vtkmodules.vtkCommonCore import vtkLookupTable
    lut = vtkLookupTable()
    lut.SetNumberOfTableValues(256)
    for i, c in enumerate(turbo_rgba()):
        lut.SetTableValue(i, *c)
    lut.SetRange(vmin, vmax)
    lut.Build()
    return lut


def _text(text: str, size: int, colour: tuple[float, float, float], box: bool = False):
    """A 2-D text actor (font size in pixels); ``box``: on a light, mostly opaque box."""
    from vtkmodules.vtkRenderingCore import vtkTextActor
    actor = vtkTextActor()
    actor.SetInput(text)
    prop = actor.GetTextProperty()
    prop.SetFontSize(size)
    prop.SetColor(*colour)
    if box:
        prop.SetBold(True)
        prop.SetBackgroundColor(1.0, 1.0, 1.0)
        prop.SetBackgroundOpacity(0.8)
    return actor


def load_arrows(dims: dict, load_N: float, whole: bool) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(tail, vector, colour) of arrows (mm) showing where the loads act: the hook load
    pressing down on the seat annulus (red, 8 around it) and the side plates carrying the
    journals from below (green, at the middle of each bearing surface). ``whole``: the
    picture shows the whole part (else the quarter x >= 0, y >= 0)."""
    h, dj, b1, b6, rf = (float(dims[k]) for k in ("h3", "dj", "b1", "b6", "rf"))
    r_seat = 0.25 * (float(dims["seat_inner"]) + float(dims["seat_outer"]))
    size = 0.22 * h
    angles = np.arange(8) * np.pi / 4 + np.pi / 8
    arrows = []
    for a in angles:
        x, y = r_seat * np.cos(a), r_seat * np.sin(a)
        if whole or (x >= 0 and y >= 0):
            arrows.append((np.array([x, y, h + size]), np.array([0.0, 0.0, -size]), "red"))
    x_mid = 0.5 * (0.5 * b1 + rf + 0.5 * b6)
    for sx in ((1, -1) if whole else (1,)):
        tip = np.array([sx * x_mid, 0.0, 0.5 * h - 0.5 * dj])
        arrows.append((tip - np.array([0.0, 0.0, size]), np.array([0.0, 0.0, size]), "green"))
    return arrows


def _arrow_actor(tail: np.ndarray, vec: np.ndarray, colour: tuple[float, float, float]):
    from vtkmodules.vtkCommonTransforms import vtkTransform
    from vtkmodules.vtkFiltersGeneral import vtkTransformFilter
    from vtkmodules.vtkFiltersSources import vtkArrowSource
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper
    length = float(np.linalg.norm(vec))
    x = vec / length
    z = np.cross(x, [0.0, 1.0, 0.0] if abs(x[1]) < 0.9 else [1.0, 0.0, 0.0])
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    t = vtkTransform()
    t.Translate(*tail)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x * length, y * length, z * length
    t.Concatenate(m.ravel().tolist())
    arrow = vtkArrowSource()
    arrow.SetTipResolution(16)
    arrow.SetShaftResolution(16)
    f = vtkTransformFilter()
    f.SetTransform(t)
    f.SetInputConnection(arrow.GetOutputPort())
    mapper = vtkPolyDataMapper()
    mapper.SetInputConnection(f.GetOutputPort())
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(*colour)
    return actor


@dataclass(frozen=True)
class _Scene:
    """What both panels draw (mm, MPa), read once from a run's folder."""

    case: dict                  # results.json's case: size, load, model, support
    points: np.ndarray          # drawn surface nodes, mm, displaced by ``scale`` × displacement
    tri: np.ndarray             # surface triangles, indices into ``points``
    vm: np.ndarray              # von Mises at ``points``, MPa
    lut: vtkLookupTable         # colours over every node's von Mises range, MPa
    length: float               # b6, mm: sets the displacement scale, camera distance and ball size
    scale: float                # displacement magnification
    centre: np.ndarray          # where both cameras look, mm
    eyes: list[np.ndarray]      # camera positions of the panels, mm
    mirrored: bool              # a quarter model drawn whole
    arrows: list[tuple[np.ndarray, np.ndarray, str]]             # load_arrows
    marks: list[tuple[str, float, str, list[np.ndarray | None]]]  # (label, MPa, colour, place per panel)
    unseen: list[str]           # peaks no panel sees, named in the title instead


def _scene(folder: Path, res: dict) -> _Scene:
    """Read folder/fields.vtu and the peaks of ``res`` (results.json's case and fe keys)
    into what the panels draw: the outer surface displaced so its largest move is 4 % of
    b6 (mm), its colours, the load arrows and where each panel marks the peaks."""
    xyz, tets, arrays = read_fields(folder / "fields.vtu", ("displacement_mm", REPORTED))
    used, tri = outer_surface(tets)
    points0, vm, disp = xyz[used], arrays[REPORTED][used], arrays["displacement_mm"][used]
    length = float(res["case"]["dims"]["b6"])
    umax = float(np.linalg.norm(disp, axis=1).max()) or 1.0
    scale = 0.04 * length / umax
    points = points0 + scale * disp
    fe, case = res["fe"], res["case"]
    # The colour range of every node, not only the surface's: its top is the global peak.
    lut = _turbo(float(arrays[REPORTED].min()), float(arrays[REPORTED].max()))
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    whole = bool(points0[:, 0].min() < -1e-6 * length)
    arrows = load_arrows(res["case"]["dims"], res["case"]["load_N"], whole)
    eyes = [centre + length * np.asarray(d) for d in VIEWS]
    mirrored = whole and case["model"] == "quarter"
    marks, unseen = _peak_marks(fe, points0, points, tri, mirrored, eyes, length)
    return _Scene(case=case, points=points, tri=tri, vm=vm, lut=lut, length=length, scale=scale,
                  centre=centre, eyes=eyes, mirrored=mirrored, arrows=arrows, marks=marks, unseen=unseen)


def _peak_marks(fe: dict, points0: np.ndarray, points: np.ndarray, tri: np.ndarray, mirrored: bool,
                eyes: list[np.ndarray], length: float
                ) -> tuple[list[tuple[str, float, str, list[np.ndarray | None]]], list[str]]:
    """The global and critical peaks as (label, value MPa, colour, drawn place per panel or
    None), see :func:`mark_places`; and a line for each peak that no panel sees, so that the
    title names it rather than a label pointing at a hidden place. ``length`` (b6, mm) sets
    the tolerance of the line-of-sight test."""
    peaks = (("global peak", fe["peak_MPa"], fe["peak_location_mm"], "black"),
             ("critical peak", fe["critical_peak_MPa"], fe["critical_location_mm"], "magenta"))
    marks = [(label, value, colour, mark_places(points0, points, tri, loc, mirrored, eyes, 1e-3 * length))
             for label, value, loc, colour in peaks]
    unseen = [f"{label} ({value:.1f} MPa) at ({', '.join(f'{c:.1f}' for c in loc)}) mm is not in view"
              for (label, value, loc, _), (*_, places) in zip(peaks, marks) if all(p is None for p in places)]
    return marks, unseen


def _panel(window: vtkRenderWindow, scene: _Scene, col: int) -> vtkRenderer:
    """Add panel ``col`` (0 left, 1 right) to ``window`` and return its renderer: the
    coloured surface, the load arrows and the peaks this panel's camera sees, looking from
    ``scene.eyes[col]`` at the part's centre with z up."""
    from vtkmodules.vtkRenderingCore import vtkLightKit, vtkRenderer
    ren = vtkRenderer()
    ren.SetViewport(PANELS[col][0], 0.0, PANELS[col][1], 1.0)
    ren.SetBackground(1.0, 1.0, 1.0)
    # smooth edges for less than the window's 8 samples per pixel cost (docs/decisions/0007-drawing-and-field-files.md)
    ren.UseFXAAOn()
    vtkLightKit().AddLightsToRenderer(ren)
    window.AddRenderer(ren)
    ren.AddActor(_surface_actor(scene.points, scene.tri, scene.vm, scene.lut))
    for tail, vec, colour in scene.arrows:
        ren.AddActor(_arrow_actor(tail, vec, COLOURS[colour]))
    for label, value, colour, places in scene.marks:
        p = places[col]
        if p is None:
            continue
        _peak_mark(ren, label, value, COLOURS[colour], p, 0.012 * scene.length)
    cam = ren.GetActiveCamera()
    cam.SetFocalPoint(*scene.centre)
    cam.SetPosition(*scene.eyes[col])
    cam.SetViewUp(0.0, 0.0, 1.0)
    ren.ResetCameraClippingRange()
    return ren


def _ball(place: np.ndarray, radius_mm: float, colour: tuple[float, float, float]):
    """A ball of ``radius_mm`` at ``place`` (mm): how a peak's place is marked."""
    from vtkmodules.vtkFiltersSources import vtkSphereSource
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper
    sphere = vtkSphereSource()
    sphere.SetCenter(*place)
    sphere.SetRadius(radius_mm)
    sphere.SetThetaResolution(24)
    sphere.SetPhiResolution(24)
    mapper = vtkPolyDataMapper()
    mapper.SetInputConnection(sphere.GetOutputPort())
    ball = vtkActor()
    ball.SetMapper(mapper)
    ball.GetProperty().SetColor(*colour)
    return ball


def _peak_mark(ren: vtkRenderer, label: str, value: float, colour: tuple[float, float, float],
               place: np.ndarray, radius_mm: float) -> None:
    """A ball of ``radius_mm`` at ``place`` (mm) and a label "label: value MPa" drawn on
    top of everything at the same place, so it stays readable where the ball is small."""
    ren.AddActor(_ball(place, radius_mm, colour))
    tag = _text(f"{label}: {value:.1f} MPa", 26, colour, box=True)
    tag.GetPositionCoordinate().SetCoordinateSystemToWorld()  # drawn on top, at the peak
    tag.GetPositionCoordinate().SetValue(*place)
    ren.AddViewProp(tag)


def _axes_inset(window: vtkRenderWindow, col: int, direction: tuple[float, float, float]) -> None:
    """x, y, z arrows in panel ``col``'s lower left corner, seen from the panel's
    ``direction``, on the window's upper layer so the part never hides them."""
    from vtkmodules.vtkRenderingAnnotation import vtkAxesActor
    from vtkmodules.vtkRenderingCore import vtkRenderer
    axes_ren = vtkRenderer()
    axes_ren.SetLayer(1)
    x0 = PANELS[col][0]
    axes_ren.SetViewport(x0, 0.0, x0 + 0.2 * (PANELS[col][1] - x0), 0.21)
    axes_ren.AddActor(vtkAxesActor())
    axes_cam = axes_ren.GetActiveCamera()
    axes_cam.SetFocalPoint(0.0, 0.0, 0.0)
    axes_cam.SetPosition(*(4.0 * np.asarray(direction) / np.linalg.norm(direction)))
    axes_cam.SetViewUp(0.0, 0.0, 1.0)
    axes_ren.ResetCameraClippingRange()
    window.AddRenderer(axes_ren)


def _title(scene: _Scene) -> vtkTextActor:
    """The left panel's title: the case (N), what is drawn and how much the displacement
    is magnified, the colours of the load arrows and any peak no panel sees."""
    case = scene.case
    shown = f"{case['model']} model" + (", shown mirrored" if scene.mirrored else "")
    title = _text(f"Crosshead No. {case['size']}, Q = {case['load_N']:g} N, {shown}, "
                  f"{case['support']} support\nvon Mises (MPa) on the deformed part, "
                  f"displacement x{scene.scale:.0f}\nred: hook load on the seat, green: journal supports"
                  + "".join(f"\n{u}" for u in scene.unseen),
                  22, (0.0, 0.0, 0.0))
    title.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    title.GetPositionCoordinate().SetValue(0.01, 0.87)
    return title


def _scale_bar(lut: vtkLookupTable) -> vtkScalarBarActor:
    """The colour scale of von Mises (MPa) for the window's right column (SCALE_COLUMN):
    five labels, in black text."""
    from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("von Mises (MPa)")
    bar.SetNumberOfLabels(5)
    bar.SetLabelFormat("%.1f")
    bar.GetPositionCoordinate().SetValue(0.275, 0.15)  # centred: the title is wider than the bar
    bar.SetWidth(0.45)
    bar.SetHeight(0.7)
    bar.UnconstrainedFontSizeOn()  # the font sizes below, not fitted to the bar
    for prop in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
        prop.SetFontSize(22)
        prop.SetColor(0.0, 0.0, 0.0)
        prop.SetItalic(False)
        prop.SetShadow(False)
    return bar


def _scale_column(lut: vtkLookupTable) -> vtkRenderer:
    """The window's right column (SCALE_COLUMN) on a white background, holding the colour
    scale."""
    from vtkmodules.vtkRenderingCore import vtkRenderer
    ren = vtkRenderer()
    ren.SetViewport(SCALE_COLUMN[0], 0.0, SCALE_COLUMN[1], 1.0)
    ren.SetBackground(1.0, 1.0, 1.0)
    ren.AddViewProp(_scale_bar(lut))
    return ren


def _write_png(window: vtkRenderWindow, out: Path) -> None:
    """Render ``window`` once, off screen, and write its pixels to ``out`` (PNG)."""
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter
    window.Render()
    image = vtkWindowToImageFilter()
    image.SetInput(window)
    image.ReadFrontBufferOff()
    image.ShouldRerenderOff()  # rendered just above
    image.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(str(out))
    writer.SetInputConnection(image.GetOutputPort())
    writer.Write()


def render_folder(folder: Path, res: dict, out_name: str = "von_mises.png") -> Path:
    """Draw folder's fields with the peaks of ``res`` (results.json's case and fe keys) into a PNG."""
    import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the render window's backend)
    from vtkmodules.vtkRenderingCore import vtkRenderWindow

    folder = Path(folder)
    scene = _scene(folder, res)
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*WINDOW)
    window.SetMultiSamples(0)  # each panel smooths its edges itself (FXAA, _panel)
    window.SetNumberOfLayers(2)
    for col, direction in enumerate(VIEWS):
        ren = _panel(window, scene, col)
        _axes_inset(window, col, direction)
        if col == 0:
            ren.AddViewProp(_title(scene))
    window.AddRenderer(_scale_column(scene.lut))
    out = folder / out_name
    _write_png(window, out)
    window.Finalize()
    return out


if __name__ == "__main__":  # a finished run's folder, drawn again from its results.json
    render_folder(Path(sys.argv[1]), json.loads((Path(sys.argv[1]) / "results.json").read_text(encoding="utf-8")))
