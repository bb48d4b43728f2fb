"""Off-screen picture of von Mises stress on the deformed part, peaks marked (mm, MPa).

Runs in its own process (``python -m pipeline.render FOLDER``) and reads only files the
run wrote: von_mises.vtu (element-node von Mises and displacement, the exact field the
peaks were taken from) and results.json (the peaks). A separate process because VTK's
wheel crashes (std::regex, bad_alloc) when DOLFINx's libraries are loaded first.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def render_folder(folder: Path, out_name: str = "von_mises.png") -> Path:
    """Draw folder/von_mises.vtu with the peaks of folder/results.json into a PNG."""
    import pyvista
    pyvista.OFF_SCREEN = True
    folder = Path(folder)
    res = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    grid = boundary_surface(pyvista.read(folder / "von_mises.vtu"))
    disp = np.asarray(grid.point_data["displacement_mm"])
    length = float(res["case"]["dims"]["b6"])
    umax = float(np.linalg.norm(disp, axis=1).max()) or 1.0
    scale = 0.04 * length / umax
    points0 = np.asarray(grid.points).copy()
    grid.points = points0 + scale * disp
    fe, case = res["fe"], res["case"]
    marks = (("global peak", fe["peak_MPa"], fe["peak_location_mm"], "black"),
             ("critical peak", fe["critical_peak_MPa"], fe["critical_location_mm"], "magenta"))
    c = np.asarray(grid.center)
    # Left: into the cut faces (symmetry planes), showing the ligament beside the bore and
    # the critical peak. Right: from below and outside, the journal root, its shoulder
    # fillet and the global peak. Each panel labels only the peak it shows.
    views = ([-0.9, -1.5, 0.9], [0.5, 1.6, -1.0])
    pl = pyvista.Plotter(off_screen=True, window_size=(2000, 950), shape=(1, 2), border=False)
    for col, direction in enumerate(views):
        pl.subplot(0, col)
        pl.add_mesh(grid.copy(), scalars="von_mises_MPa", cmap="turbo", show_scalar_bar=(col == 1),
                    scalar_bar_args={"title": "von Mises (MPa)", "vertical": True,
                                     "position_x": 0.85, "position_y": 0.15})
        for label, value, loc, colour in (marks[1],) if col == 0 else (marks[0],):
            idx = int(np.argmin(np.linalg.norm(points0 - np.asarray(loc), axis=1)))
            p = grid.points[idx]
            pl.add_mesh(pyvista.Sphere(radius=0.012 * length, center=p), color=colour)
            pl.add_point_labels([p], [f"{label}: {value:.1f} MPa"], font_size=18, point_size=1,
                                text_color=colour, shape_opacity=0.7, always_visible=True)
        pl.camera_position = [tuple(c + length * np.array(direction)), tuple(c), (0, 0, 1)]
        pl.add_axes()
    pl.subplot(0, 0)
    pl.add_text(f"Crosshead No. {case['size']}, Q = {case['load_N']:g} N, {case['model']} model, "
                f"{case['support']} support\nvon Mises (MPa) on the deformed part, displacement x{scale:.0f}",
                font_size=11)
    out = folder / out_name
    pl.screenshot(str(out))
    pl.close()
    return out


_TET_FACES = np.array([(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)])


def boundary_surface(grid):
    """The part's outer surface from a grid of disconnected tets (every cell its own nodes).

    Why: in such a grid every face of every tet is a free face, so VTK drew all of them
    (156 k triangles at No. 05 x1, 2.6 s in software rendering) to show the ~8 k on the
    part's boundary. A face is on the boundary when no other tet has the same three
    corner positions. The nodes keep their own values (von Mises, displacement).
    """
    import pyvista
    cells = np.asarray(grid.cells_dict[pyvista.CellType.TETRA])
    xyz = np.asarray(grid.points)
    # + 0.0 turns -0.0 into 0.0: equal positions must have equal bytes.
    rounded = np.ascontiguousarray(np.round(xyz, 9) + 0.0)
    _, corner = np.unique(rounded.view(np.dtype((np.void, rounded.itemsize * 3))).ravel(),
                          return_inverse=True)
    corner = corner.ravel().astype(np.int64)
    faces = cells[:, _TET_FACES].reshape(-1, 3)
    key = np.sort(corner[faces], axis=1)
    n = int(corner.max()) + 1
    _, which, count = np.unique((key[:, 0] * n + key[:, 1]) * n + key[:, 2],
                                return_inverse=True, return_counts=True)
    outer = faces[count[which.ravel()] == 1]
    used, tri = np.unique(outer, return_inverse=True)
    surf = pyvista.PolyData(xyz[used], np.column_stack([np.full(len(outer), 3), tri.reshape(-1, 3)]).ravel())
    for name in grid.point_data.keys():
        surf.point_data[name] = np.asarray(grid.point_data[name])[used]
    return surf


if __name__ == "__main__":
    render_folder(Path(sys.argv[1]))
