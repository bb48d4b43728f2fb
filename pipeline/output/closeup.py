"""Close-ups of the mesh at the two peaks, element edges drawn, for the report (mm, MPa).

Runs in a drawing process of its own (``python -m pipeline.output.closeup FOLDER``, started
by pipeline.output.drawing beside the error-bar solves) and reads only what the run wrote:
fields.vtu (the requested mesh: its tets' vertices and the reported von Mises there) and
results.json (the peaks as reported). One PNG, ``mesh_closeup.png``: a panel per peak
(global, critical), the undeformed surface seen along its outward normal at the peak,
coloured by the reported von Mises (the report's reading rule at each node), each surface
triangle's edges drawn (the curved tets' straight chords), the peak's node marked. A reviewer sees how many elements resolve
each peak.
"""
from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.output.picture import (COLOURS, REPORTED, _ball, _scale_column, _surface_actor, _text, _turbo,
                                     _write_png, outer_surface, read_fields)

FILE = "mesh_closeup.png"
PANEL_PX, SCALE_PX, HEIGHT_PX = 720, 240, 560  # 0.6 MB of PNG for No. 05
WINDOW = (2 * PANEL_PX + SCALE_PX, HEIGHT_PX)  # pixels
PANELS = tuple((k * PANEL_PX / WINDOW[0], (k + 1) * PANEL_PX / WINDOW[0]) for k in range(2))
ELEMENTS_ACROSS = 8     # the view's half-height in local surface edge lengths
NEAREST_TRIANGLES = 60  # the triangles around a peak whose edges and normals set its view


@dataclass(frozen=True)
class View:
    """Where one panel looks (mm): the peak's surface node, the outward normal there, the
    view's half-height and the local surface edge length."""

    node: np.ndarray
    normal: np.ndarray
    half_height_mm: float
    edge_mm: float


def peak_view(points: np.ndarray, tri: np.ndarray, loc, h_mm: float) -> View:
    """The view of the surface (``points`` mm, outward-oriented triangles ``tri``) at a
    peak at ``loc`` (mm): centred on the surface node nearest to it, looking against the
    area-weighted outward normal of the NEAREST_TRIANGLES triangles nearest to that node,
    ELEMENTS_ACROSS of their median edge length to each side, kept within 0.04–0.4 of the
    part's height ``h_mm``."""
    node = points[int(np.argmin(np.linalg.norm(points - np.asarray(loc, float), axis=1)))]
    centroids = points[tri].mean(axis=1)
    near = tri[np.argsort(np.linalg.norm(centroids - node, axis=1))[:NEAREST_TRIANGLES]]
    a, b, c = points[near[:, 0]], points[near[:, 1]], points[near[:, 2]]
    normal = np.cross(b - a, c - a).sum(axis=0)  # twice the area-weighted normal
    normal /= max(float(np.linalg.norm(normal)), 1e-300)
    edge = float(np.median(np.linalg.norm(np.concatenate([b - a, c - b, a - c]), axis=1)))
    half = min(max(ELEMENTS_ACROSS * edge, 0.04 * h_mm), 0.4 * h_mm)
    return View(node=node, normal=normal, half_height_mm=half, edge_mm=edge)


def _edged_surface(points: np.ndarray, tri: np.ndarray, values: np.ndarray, lut):
    """The coloured surface with every triangle's edges drawn in dark grey."""
    actor = _surface_actor(points, tri, values, lut)
    prop = actor.GetProperty()
    prop.EdgeVisibilityOn()
    prop.SetEdgeColor(0.15, 0.15, 0.15)
    prop.SetLineWidth(1.0)
    return actor


def _panel(window, col: int, surface, view: View, title: str, colour: tuple[float, float, float]):
    """Panel ``col``: ``surface`` seen along ``-view.normal`` with a parallel projection of
    half-height ``view.half_height_mm``, a ball at the peak's node and the panel's title."""
    from vtkmodules.vtkRenderingCore import vtkLightKit, vtkRenderer
    ren = vtkRenderer()
    ren.SetViewport(PANELS[col][0], 0.0, PANELS[col][1], 1.0)
    ren.SetBackground(1.0, 1.0, 1.0)
    vtkLightKit().AddLightsToRenderer(ren)
    window.AddRenderer(ren)
    ren.AddActor(surface)
    ren.AddActor(_ball(view.node, 0.25 * view.edge_mm, colour))
    cam = ren.GetActiveCamera()
    cam.ParallelProjectionOn()
    cam.SetFocalPoint(*view.node)
    cam.SetPosition(*(view.node + 20.0 * view.half_height_mm * view.normal))
    up = np.array([0.0, 0.0, 1.0]) if abs(view.normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    cam.SetViewUp(*up)
    cam.SetParallelScale(view.half_height_mm)
    ren.ResetCameraClippingRange()
    text = _text(title, 16, (0.0, 0.0, 0.0), box=True)
    text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    text.GetPositionCoordinate().SetValue(0.02, 0.86)
    ren.AddViewProp(text)
    return ren


def panel_title(label: str, block: dict, view: View) -> str:
    """A panel's title: which peak, its reported value (MPa), where (mm), and the scale."""
    loc = ", ".join(f"{v + 0.0:.2f}" for v in np.round(block["location_mm"], 2))  # no "-0.00"
    return (f"{label}: {block['value_MPa']:.2f} MPa, {block['feature']}\nat ({loc}) mm; "
            f"view {2 * view.half_height_mm:.2f} mm high, surface edges ~{view.edge_mm:.2f} mm")


def render_closeup(folder: Path, res: dict) -> Path:
    """Draw folder/mesh_closeup.png from folder/fields.vtu and the peaks of ``res``
    (results.json's case and fe keys)."""
    import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
    import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the render window's backend)
    from vtkmodules.vtkRenderingCore import vtkRenderWindow

    folder = Path(folder)
    xyz, tets, arrays = read_fields(folder / "fields.vtu", (REPORTED,))
    used, tri = outer_surface(tets)
    points, vm = xyz[used], arrays[REPORTED][used]
    lut = _turbo(float(arrays[REPORTED].min()), float(arrays[REPORTED].max()))
    h = float(res["case"]["dims"]["h3"])
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(*WINDOW)
    window.SetMultiSamples(4)  # thin edge lines: multisampling keeps them even
    for col, (key, label, colour) in enumerate((("peak", "global peak", "black"),
                                                 ("critical", "critical peak", "magenta"))):
        block = res["fe"][key]
        view = peak_view(points, tri, block["location_mm"], h)
        _panel(window, col, _edged_surface(points, tri, vm, lut), view, panel_title(label, block, view),
               COLOURS[colour])
    scale = _scale_column(lut)
    scale.SetViewport(2 * PANEL_PX / WINDOW[0], 0.0, 1.0, 1.0)  # this window's column, no gap
    window.AddRenderer(scale)
    out = folder / FILE
    _write_png(window, out)
    window.Finalize()
    return out


if __name__ == "__main__":  # a finished run's folder, drawn again from its results.json
    render_closeup(Path(sys.argv[1]), json.loads((Path(sys.argv[1]) / "results.json").read_text(encoding="utf-8")))
