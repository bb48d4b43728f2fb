"""The ParaView field file of a run, ``fields.vtu`` (into the staging folder that
pipeline.runtime.outdir puts in place when the run is complete); what it holds and how to
read a peak from it: docs/design.md §7.

The part on its curved 10-node tets (a quarter model mirrored to the whole part, the
symmetry planes' nodes shared, so the part is one connected mesh), with point data:
displacement_mm, the nodal-averaged stress tensor stress_MPa (xx, yy, zz, xy, yz, xz), its
von Mises von_mises_averaged_MPa and principal stresses principal_stress_1/2/3_MPa (largest
first); von_mises_unaveraged_MPa, the largest element-node von Mises at each node; and
von_mises_reported_MPa, the report's reading rule at each node (pipeline.post.peaks.NodeReadings),
the active scalars: a probe at a reported place reads the reported value, and its largest
value is the global peak. Every array has one value per node of the solution's CG(q)
space, interpolated linearly (P2) to the mid-edge nodes.

VTK XML, not XDMF: DOLFINx 0.5.2's XDMF writer drops P2 mid-edge values and cannot place DG
values on this curved mesh. Points and values are Float32 (7 significant digits: the
reported array's value at a reported place is the reported value to 1e-7).
"""
from __future__ import annotations

import base64
import math
import sys
from pathlib import Path

import numpy as np

from pipeline.fe.elasticity import Material
from pipeline.output.mirror import COPIES, mirror_quarter
from pipeline.output.vtu import write_vtu
from pipeline.post.peaks import NodeReadings, averaged_stress, von_mises_of

FILE = "fields.vtu"
REPORTED = "von_mises_reported_MPa"   # the array whose value at a reported place is the reported value
TENSOR_ORDER = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2)]  # VTK's symmetric-tensor components


def write_fields(folder: Path, u, readings: NodeReadings, mat: Material, whole_part: bool = False) -> dict[str, str]:
    """Write fields.vtu of displacement ``u`` (mm), the nodal-averaged stress of ``u`` in
    material ``mat`` and the von Mises ``readings`` of u at the nodes (MPa; the unaveraged one
    and the reported one, pipeline.post.peaks.node_readings) into ``folder``, mirrored to the
    whole part when ``whole_part``. Returns the file names by key. Collective; rank 0 writes."""
    scalars = {"von_mises_unaveraged_MPa": readings.as_function(readings.unaveraged, "unaveraged"),
               REPORTED: readings.as_function(readings.reported, "reported")}
    part = _gather_p2_grid(u, averaged_stress(u, mat), scalars)
    if u.function_space.mesh.comm.rank == 0:
        points, cells, point_data = part
        if whole_part:
            points, cells, point_data, _ = mirror_quarter(points, cells, point_data)
        write_vtu(Path(folder) / FILE, points, cells, "tetra10", _with_invariants(point_data),
                  points_dtype=np.float32, scalars=REPORTED)
    return {"fields": FILE}


def _with_invariants(point_data: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The point arrays to write (Float32): displacement, the stress tensor in VTK's
    six-component order, its von Mises and principal stresses, and every other array given
    (the von Mises readings at the nodes), MPa."""
    s = point_data["stress_MPa"].reshape(-1, 3, 3)
    s = 0.5 * (s + s.transpose(0, 2, 1))
    principal = np.linalg.eigvalsh(s)[:, ::-1]
    out = {"displacement_mm": point_data["displacement_mm"],
           "stress_MPa": np.column_stack([s[:, i, j] for i, j in TENSOR_ORDER]),
           "von_mises_averaged_MPa": von_mises_of(s),
           "principal_stress_1_MPa": principal[:, 0],
           "principal_stress_2_MPa": principal[:, 1],
           "principal_stress_3_MPa": principal[:, 2]}
    out.update({k: v for k, v in point_data.items() if k not in out})
    return {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in out.items()}


# VTK's 10-node tet from DOLFINx's (basix) node order: basix numbers the mid-edge nodes of
# edges (2,3), (1,3), (1,2), (0,3), (0,2), (0,1); VTK of (0,1), (1,2), (2,0), (0,3), (1,3), (2,3).
VTK_TET10 = [0, 1, 2, 3, 9, 6, 8, 7, 5, 4]


def _p2(mesh, f, shape: str):
    """``f`` in continuous P2 of its value shape (exact for P2 and for CG1 data)."""
    from dolfinx import fem
    space = {"scalar": fem.FunctionSpace, "vector": fem.VectorFunctionSpace,
             "tensor": fem.TensorFunctionSpace}[shape](mesh, ("CG", 2))
    if f.function_space.ufl_element().degree() == 2 and f.function_space.ufl_element().family() in ("P", "Q"):
        return f
    g = fem.Function(space)
    g.interpolate(f)
    return g


def _gather_p2_grid(u, stress, scalars: dict):
    """(points, 10-node tets in VTK order, {displacement_mm, stress_MPa (9 components), and
    each of ``scalars`` by name}) on continuous P2 nodes, on rank 0 (None elsewhere). Nodes
    shared between cells and ranks are written once."""
    mesh = u.function_space.mesh
    u = _p2(mesh, u, "vector")
    s = _p2(mesh, stress, "tensor")
    others = {name: _p2(mesh, f, "scalar") for name, f in scalars.items()}
    V = u.function_space
    imap = V.dofmap.index_map
    n_owned, n_local = imap.size_local, imap.size_local + imap.num_ghosts
    to_global = imap.local_to_global(np.arange(n_local, dtype=np.int32))
    n_cells = mesh.topology.index_map(3).size_local
    cells = to_global[V.dofmap.list.array.reshape(-1, 10)[:n_cells]][:, VTK_TET10]
    xyz = V.tabulate_dof_coordinates()[:n_owned]
    # The tensor and scalar spaces' nodes are the vector space's (same element and mesh), node by node.
    sval = s.x.array.reshape(-1, 9)[:n_owned]
    disp = u.x.array.reshape(-1, 3)[:n_owned]
    values = {name: f.x.array[:n_owned] for name, f in others.items()}
    parts = mesh.comm.gather((to_global[:n_owned], xyz, disp, sval, values, cells), root=0)
    if mesh.comm.rank != 0:
        return None
    n = imap.size_global
    points, d, t = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 9))
    data = {name: np.zeros(n) for name in scalars}
    for idx, p, dd, ss, vv, _ in parts:
        points[idx], d[idx], t[idx] = p, dd, ss
        for name, v in vv.items():
            data[name][idx] = v
    return points, np.vstack([c[-1] for c in parts]), {"displacement_mm": d, "stress_MPa": t, **data}


PEAKS_FILE = "peaks.vtp"
PEAK_NAMES = (("peak", "global peak"), ("critical", "critical peak"))   # results.json's fe key, name


def write_peaks(folder: Path, fe: dict, whole_part: bool = False) -> dict[str, str]:
    """Write peaks.vtp into ``folder``: the reported places of results.json's ``fe`` block
    (the global and the critical peak; with ``whole_part``, a quarter model drawn whole,
    their mirror images in x = 0 and y = 0 too) as VTK PolyData points (mm) with point data
    ``name``, ``label`` (name, value and band in words, for ParaView's point labels),
    ``feature``, ``value_MPa``, ``band_MPa`` (NaN: no band) and ``mirror_image`` (0 the
    place itself, 1 an image). VTK XML, a few lines: the numbers inline in base64 (VTK's
    ASCII reader cannot read NaN), the rest as text. Returns the file name by key."""
    rows = []
    for key, name in PEAK_NAMES:
        p = fe[key]
        est = p.get("error_estimate") or {}
        band = est.get("band")
        band = float("nan") if band is None else float(band)
        label = f"{name} {p['value_MPa']:.2f}" + ("" if band != band else f" ± {band:.2f}") + " MPa"
        for k, at in enumerate(_images(p["location_mm"], whole_part)):
            rows.append((at, name, label, p["feature"], float(p["value_MPa"]), band, int(k > 0)))
    points = "\n".join(" ".join(repr(float(c)) for c in r[0]) for r in rows)
    n = len(rows)

    def text(i: int) -> str:
        return " ".join(str(b) for r in rows for b in (*r[i].encode("utf-8"), 0))

    def numbers(i: int) -> str:   # VTK's inline binary: base64 of the byte count (UInt64) and the bytes
        raw = np.array([r[i] for r in rows], dtype=np.float64).tobytes()
        return base64.b64encode(np.array([len(raw)], dtype=np.uint64).tobytes() + raw).decode("ascii")
    doc = "\n".join([
        '<?xml version="1.0"?>',
        f'<VTKFile type="PolyData" version="1.0" byte_order="{sys.byteorder.capitalize()}Endian" '
        'header_type="UInt64">',
        "<PolyData>",
        f'<Piece NumberOfPoints="{n}" NumberOfVerts="{n}" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="0">',
        '<PointData Scalars="value_MPa">',
        f'<Array type="String" Name="name" format="ascii">{text(1)}</Array>',
        f'<Array type="String" Name="label" format="ascii">{text(2)}</Array>',
        f'<Array type="String" Name="feature" format="ascii">{text(3)}</Array>',
        f'<DataArray type="Float64" Name="value_MPa" format="binary">{numbers(4)}</DataArray>',
        f'<DataArray type="Float64" Name="band_MPa" format="binary">{numbers(5)}</DataArray>',
        f'<DataArray type="UInt8" Name="mirror_image" format="ascii">{" ".join(str(r[6]) for r in rows)}</DataArray>',
        "</PointData>",
        f'<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">{points}</DataArray></Points>',
        "<Verts>",
        f'<DataArray type="Int64" Name="connectivity" format="ascii">{" ".join(map(str, range(n)))}</DataArray>',
        f'<DataArray type="Int64" Name="offsets" format="ascii">{" ".join(map(str, range(1, n + 1)))}</DataArray>',
        "</Verts>",
        "</Piece>", "</PolyData>", "</VTKFile>", ""])
    (Path(folder) / PEAKS_FILE).write_text(doc, encoding="utf-8")
    return {"peaks": PEAKS_FILE}


def _images(location_mm, whole_part: bool) -> list[tuple[float, float, float]]:
    """The place (mm) and, with ``whole_part``, its distinct mirror images in x = 0 and y = 0
    (a place on a symmetry plane is its own image there; pipeline.output.mirror's COPIES order)."""
    x, y, z = (float(c) for c in location_mm)
    if not whole_part:
        return [(x, y, z)]
    out: list[tuple[float, float, float]] = []
    for sx, sy in COPIES:
        q = (sx * x + 0.0, sy * y + 0.0, z)
        if all(math.dist(q, o) > 1e-9 * max(1.0, abs(x), abs(y), abs(z)) for o in out):
            out.append(q)
    return out
