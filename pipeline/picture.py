"""Off-screen picture of von Mises stress on the deformed part, peaks marked (mm, MPa).

Runs in its own process (``python -m pipeline.picture FOLDER``) and reads only files the
run wrote: von_mises.vtu (element-node von Mises and displacement: the unaveraged
reading of the peaks) and results.json (the peaks as reported). A separate process because VTK's
wheel crashes (std::regex, bad_alloc) when DOLFINx's libraries are loaded first.

Drawn with VTK's own classes, not pyvista's plotter: pyvista.plotting imports
matplotlib.pyplot, most of the picture's CPU time, while it runs beside the error-bar
solves on the same cores (docs/decisions.md).
"""
from __future__ import annotations

import json
import time
import sys
from pathlib import Path

import numpy as np

WINDOW = (2000, 950)  # pixels: two panels side by side
# Left: from above, the seat, the bore and the ligament beside it. Right: from below and
# outside, the journal root, its shoulder fillet and the bottom face. A panel marks a peak
# only where the camera sees it (seen_from), so no label points at a hidden place.
VIEWS = ((-0.9, -1.5, 0.9), (0.5, 1.6, -1.0))
COLOURS = {"black": (0.0, 0.0, 0.0), "magenta": (0.8, 0.0, 0.8), "red": (0.85, 0.1, 0.1),
           "green": (0.1, 0.6, 0.2)}

_TET_FACES = np.array([(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)])


def boundary_surface(xyz: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface of disconnected tets (every tet its own nodes): (nodes used, triangles).

    ``xyz`` (n×3, mm) and ``tets`` (m×4 node indices). Returns the indices of the nodes
    the surface uses and its triangles numbered into that list, so every node keeps its
    own values (von Mises, displacement). Why: in such a grid every face of every tet is
    a free face, and VTK would draw all of them (twenty times those on the part's
    boundary, docs/decisions.md). A face is on the boundary when no
    other tet has the same three corner positions.
    """
    # + 0.0 turns -0.0 into 0.0: equal positions must have equal bytes.
    rounded = np.ascontiguousarray(np.round(xyz, 9) + 0.0)
    _, corner = np.unique(rounded.view(np.dtype((np.void, rounded.itemsize * 3))).ravel(),
                          return_inverse=True)
    corner = corner.ravel().astype(np.int64)
    faces = tets[:, _TET_FACES].reshape(-1, 3)
    key = np.sort(corner[faces], axis=1)
    n = int(corner.max()) + 1
    _, which, count = np.unique((key[:, 0] * n + key[:, 1]) * n + key[:, 2],
                                return_inverse=True, return_counts=True)
    outer = faces[count[which.ravel()] == 1]
    used, tri = np.unique(outer, return_inverse=True)
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


def read_vtu(path: Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(points mm, tets, point arrays by name) of a VTK XML unstructured grid of tets."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    xyz = vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    tets = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).astype(np.int64).reshape(-1, 4)
    pd = grid.GetPointData()
    arrays = {pd.GetArrayName(i): vtk_to_numpy(pd.GetArray(i)).astype(float)
              for i in range(pd.GetNumberOfArrays())}
    return xyz, tets, arrays


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


def _turbo(vmin: float, vmax: float):
    """matplotlib's turbo colour map as a VTK lookup table over [vmin, vmax] (MPa)."""
    from matplotlib import colormaps  # matplotlib.colors only, not pyplot
    from vtkmodules.vtkCommonCore import vtkLookupTable
    rgba = colormaps["turbo"](np.linspace(0.0, 1.0, 256))
    lut = vtkLookupTable()
    lut.SetNumberOfTableValues(256)
    for i, c in enumerate(rgba):
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


def render_folder(folder: Path, out_name: str = "von_mises.png") -> Path:
    """Draw folder/von_mises.vtu with the peaks of folder/results.json into a PNG."""
    import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the render window's backend)
    from vtkmodules.vtkFiltersSources import vtkSphereSource
    from vtkmodules.vtkIOImage import vtkPNGWriter
    from vtkmodules.vtkRenderingAnnotation import vtkAxesActor, vtkScalarBarActor
    from vtkmodules.vtkRenderingCore import (vtkActor, vtkLightKit, vtkPolyDataMapper, vtkRenderer,
                                             vtkRenderWindow, vtkWindowToImageFilter)

    folder = Path(folder)
    res = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    xyz, tets, arrays = read_vtu(folder / "von_mises.vtu")
    used, tri = boundary_surface(xyz, tets)
    points0, vm, disp = xyz[used], arrays["von_mises_MPa"][used], arrays["displacement_mm"][used]
    length = float(res["case"]["dims"]["b6"])
    umax = float(np.linalg.norm(disp, axis=1).max()) or 1.0
    scale = 0.04 * length / umax
    points = points0 + scale * disp
    fe, case = res["fe"], res["case"]
    # The colour range of every node, not only the surface's: the peak can sit on a tet
    # that touches the surface at a vertex only, whose value there is drawn by no triangle.
    lut = _turbo(float(arrays["von_mises_MPa"].min()), float(arrays["von_mises_MPa"].max()))
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    whole = bool(points0[:, 0].min() < -1e-6 * length)
    arrows = load_arrows(res["case"]["dims"], res["case"]["load_N"], whole)
    eyes = [centre + length * np.asarray(d) for d in VIEWS]
    mirrored = whole and case["model"] == "quarter"
    marks = [(label, value, colour, mark_places(points0, points, tri, loc, mirrored, eyes, 1e-3 * length))
             for label, value, loc, colour in (
                 ("global peak", fe["peak_MPa"], fe["peak_location_mm"], "black"),
                 ("critical peak", fe["critical_peak_MPa"], fe["critical_location_mm"], "magenta"))]
    unseen = [f"{label} ({value:.1f} MPa) at ({', '.join(f'{c:.1f}' for c in loc)}) mm is not in view"
              for (label, value, _, places), loc in zip(marks, (fe["peak_location_mm"], fe["critical_location_mm"]))
              if all(p is None for p in places)]

    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*WINDOW)
    window.SetNumberOfLayers(2)
    for col, direction in enumerate(VIEWS):
        ren = vtkRenderer()
        ren.SetViewport(0.5 * col, 0.0, 0.5 * (col + 1), 1.0)
        ren.SetBackground(1.0, 1.0, 1.0)
        vtkLightKit().AddLightsToRenderer(ren)
        window.AddRenderer(ren)
        ren.AddActor(_surface_actor(points, tri, vm, lut))
        for tail, vec, colour in arrows:
            ren.AddActor(_arrow_actor(tail, vec, COLOURS[colour]))
        for label, value, colour, places in marks:
            p = places[col]
            if p is None:
                continue
            sphere = vtkSphereSource()
            sphere.SetCenter(*p)
            sphere.SetRadius(0.012 * length)
            sphere.SetThetaResolution(24)
            sphere.SetPhiResolution(24)
            mapper = vtkPolyDataMapper()
            mapper.SetInputConnection(sphere.GetOutputPort())
            ball = vtkActor()
            ball.SetMapper(mapper)
            ball.GetProperty().SetColor(*COLOURS[colour])
            ren.AddActor(ball)
            tag = _text(f"{label}: {value:.1f} MPa", 26, COLOURS[colour], box=True)
            tag.GetPositionCoordinate().SetCoordinateSystemToWorld()  # drawn on top, at the peak
            tag.GetPositionCoordinate().SetValue(*p)
            ren.AddViewProp(tag)
        cam = ren.GetActiveCamera()
        cam.SetFocalPoint(*centre)
        cam.SetPosition(*eyes[col])
        cam.SetViewUp(0.0, 0.0, 1.0)
        ren.ResetCameraClippingRange()
        # x, y, z arrows in the panel's lower left corner, seen from the same direction.
        axes_ren = vtkRenderer()
        axes_ren.SetLayer(1)
        axes_ren.SetViewport(0.5 * col, 0.0, 0.5 * col + 0.1, 0.21)
        axes_ren.AddActor(vtkAxesActor())
        axes_cam = axes_ren.GetActiveCamera()
        axes_cam.SetFocalPoint(0.0, 0.0, 0.0)
        axes_cam.SetPosition(*(4.0 * np.asarray(direction) / np.linalg.norm(direction)))
        axes_cam.SetViewUp(0.0, 0.0, 1.0)
        axes_ren.ResetCameraClippingRange()
        window.AddRenderer(axes_ren)
        if col == 0:
            shown = f"{case['model']} model" + (", shown mirrored" if whole and case["model"] == "quarter" else "")
            title = _text(f"Crosshead No. {case['size']}, Q = {case['load_N']:g} N, {shown}, "
                          f"{case['support']} support\nvon Mises (MPa) on the deformed part, "
                          f"displacement x{scale:.0f}\nred: hook load on the seat, green: journal supports"
                          + "".join(f"\n{u}" for u in unseen),
                          22, (0.0, 0.0, 0.0))
            title.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
            title.GetPositionCoordinate().SetValue(0.01, 0.87)
            ren.AddViewProp(title)
        else:
            bar = vtkScalarBarActor()
            bar.SetLookupTable(lut)
            bar.SetTitle("von Mises (MPa)")
            bar.SetNumberOfLabels(5)
            bar.SetLabelFormat("%.1f")
            bar.GetPositionCoordinate().SetValue(0.83, 0.15)
            bar.SetWidth(0.1)
            bar.SetHeight(0.7)
            bar.UnconstrainedFontSizeOn()  # the font sizes below, not fitted to the bar
            for prop in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
                prop.SetFontSize(22)
                prop.SetColor(0.0, 0.0, 0.0)
                prop.SetItalic(False)
                prop.SetShadow(False)
            ren.AddViewProp(bar)
    window.Render()
    image = vtkWindowToImageFilter()
    image.SetInput(window)
    image.ReadFrontBufferOff()
    image.ShouldRerenderOff()  # rendered just above
    image.Update()
    out = folder / out_name
    writer = vtkPNGWriter()
    writer.SetFileName(str(out))
    writer.SetInputConnection(image.GetOutputPort())
    writer.Write()
    window.Finalize()
    return out


def draw_folder(folder: Path, wait_s: float = 3600.0) -> None:
    """Everything drawn for a run, in this process beside the error-bar solves: the picture;
    when the results carry section stresses, sections.png; and once the run has written
    the results of every mesh (at most ``wait_s`` s later), peaks.png (pipeline/plots.py).
    The run stops this process if it fails, so the wait ends either way."""
    render_folder(folder)
    res = json.loads((Path(folder) / "results.json").read_text(encoding="utf-8"))
    sections = res["fe"].get("sections")
    from .plots import peaks_plot, sections_plot
    if sections:
        sections_plot(Path(folder) / "sections.png", sections, res["analytic"], float(res["case"]["dims"]["h3"]))
    final = _all_levels(Path(folder), wait_s)
    if final is not None:
        peaks_plot(Path(folder) / "peaks.png", final)


def _all_levels(folder: Path, wait_s: float) -> dict | None:
    """results.json once it holds every mesh's results (its timings have the error-bar
    meshes' total), polled every 20 ms; None after ``wait_s`` s."""
    end = time.monotonic() + wait_s
    while time.monotonic() < end:
        res = json.loads((folder / "results.json").read_text(encoding="utf-8"))
        if "error_bar_meshes" in res.get("timings_s", {}):
            return res
        time.sleep(0.02)
    return None


if __name__ == "__main__":
    draw_folder(Path(sys.argv[1]))
