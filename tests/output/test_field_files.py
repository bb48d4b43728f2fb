"""The ParaView files a run writes (fields.vtu, peaks.vtp), read with VTK alone as ParaView
would: one connected whole part whose outer surface is the CAD's; a reported array whose
value at each reported place is the reported value and whose largest value is the global
peak; the reported places with their values and bands (docs/design.md §7). ParaView's own
reader is VTK's; pvpython is not needed."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


ROOT = Path(__file__).resolve().parents[2]


def _run(out: Path, *extra: str) -> Path:
    """A coarse run of No. 05 with its three error-bar meshes (the places have bands)."""
    p = subprocess.run([sys.executable, "-m", "pipeline", "run", "--size", "05", "--mesh-factor", "3",
                        "--no-sensitivity", "--out", str(out), "--quiet", *extra],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return out


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    return _run(tmp_path_factory.mktemp("fields") / "05")


def _grid(path: Path):
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def _surface(grid):
    """The outer surface of a grid of 10-node tets, each quadratic face split into triangles
    that follow its curvature (VTK's nonlinear subdivision)."""
    from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter
    f = vtkDataSetSurfaceFilter()
    f.SetInputData(grid)
    f.SetNonlinearSubdivisionLevel(3)
    f.Update()
    return f.GetOutput()


def _area(poly) -> float:
    from vtkmodules.vtkFiltersCore import vtkMassProperties, vtkTriangleFilter
    tri = vtkTriangleFilter()
    tri.SetInputData(poly)
    mp = vtkMassProperties()
    mp.SetInputConnection(tri.GetOutputPort())
    mp.Update()
    return mp.GetSurfaceArea()


def _cad_area(dims: dict) -> float:
    """The whole part's outer surface area (mm²) from the OpenCASCADE model itself."""
    import gmsh

    from geometry.part import build
    from geometry.table import Dimensions
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("area")
        build(Dimensions(**dims), "full")
        outer = gmsh.model.getBoundary(gmsh.model.getEntities(3), combined=True, oriented=False)
        return sum(gmsh.model.occ.getMass(2, abs(tag)) for _, tag in outer)
    finally:
        gmsh.finalize()


@pytest.mark.slow
def test_the_whole_part_is_one_connected_mesh_with_the_cad_s_surface(whole):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersCore import vtkConnectivityFilter
    grid = _grid(whole / "fields.vtu")
    conn = vtkConnectivityFilter()
    conn.SetInputData(grid)
    conn.SetExtractionModeToAllRegions()
    conn.Update()
    assert conn.GetNumberOfExtractedRegions() == 1
    surface = _surface(grid)
    dims = json.loads((whole / "results.json").read_text())["case"]["dims"]
    assert _area(surface) == pytest.approx(_cad_area(dims), rel=1e-3)
    # No face of the symmetry planes is left inside the part as a surface.
    x = vtk_to_numpy(surface.GetPoints().GetData())
    scale = np.abs(x).max()
    on_plane = (np.abs(x[:, 0]) < 1e-6 * scale) | (np.abs(x[:, 1]) < 1e-6 * scale)
    assert on_plane.mean() < 0.01   # only the planes' traces on the outer surface


def _probe(grid, point) -> dict[str, float]:
    """Point arrays interpolated at ``point`` (mm) by VTK's probe filter (ParaView's Probe)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkPolyData
    from vtkmodules.vtkFiltersCore import vtkProbeFilter
    pts = vtkPoints()
    pts.InsertNextPoint(*point)
    src = vtkPolyData()
    src.SetPoints(pts)
    probe = vtkProbeFilter()
    probe.SetInputData(src)
    probe.SetSourceData(grid)
    probe.Update()
    out = probe.GetOutput().GetPointData()
    assert vtk_to_numpy(out.GetArray("vtkValidPointMask"))[0] == 1, f"{point} is outside the part"
    return {out.GetArrayName(i): vtk_to_numpy(out.GetArray(i))[0] for i in range(out.GetNumberOfArrays())}


def _node(grid, point) -> int:
    """The grid's point nearest ``point`` (mm)."""
    from vtkmodules.vtkCommonDataModel import vtkStaticPointLocator
    locator = vtkStaticPointLocator()
    locator.SetDataSet(grid)
    locator.BuildLocator()
    return locator.FindClosestPoint(point)


REPORTED = "von_mises_reported_MPa"


def _images(place, mirrored: bool) -> list[tuple[float, float, float]]:
    """A place (mm) and, for a quarter drawn whole, its images in x = 0 and y = 0."""
    x, y, z = place
    return [(sx * x, sy * y, z) for sx in (1, -1) for sy in (1, -1)] if mirrored else [(x, y, z)]


@pytest.mark.slow
def test_the_reported_array_holds_each_reported_value_at_its_place(whole):
    """The contract of docs/design.md §7: at each reported place (and its mirror images) the
    node of fields.vtu there holds the reported value in von_mises_reported_MPa, and
    von_mises_unaveraged_MPa / von_mises_averaged_MPa hold the two readings it was made of,
    to 1e-6 (Float32 keeps 7 digits); the array's largest value is the global peak. VTK's
    probe (ParaView's Probe Location) reads the same values to 1e-5: it interpolates in the
    curved tet at parametric coordinates that its Newton iteration finds to ~1e-5."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    grid = _grid(whole / "fields.vtu")
    pd = grid.GetPointData()
    arrays = {name: vtk_to_numpy(pd.GetArray(name)).astype(float)
              for name in (REPORTED, "von_mises_unaveraged_MPa", "von_mises_averaged_MPa")}
    points = vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    fe = json.loads((whole / "results.json").read_text())["fe"]
    assert arrays[REPORTED].max() == pytest.approx(fe["peak_MPa"], rel=1e-6)
    for key in ("peak", "critical"):
        p = fe[key]
        assert p["averaged_location_mm"] == p["location_mm"]   # both readings at one node
        for place in _images(p["location_mm"], mirrored=True):
            node = _node(grid, place)
            assert np.linalg.norm(points[node] - place) <= 1e-5, (key, place)
            assert arrays[REPORTED][node] == pytest.approx(p["value_MPa"], rel=1e-6), (key, place)
            assert arrays["von_mises_unaveraged_MPa"][node] == pytest.approx(p["unaveraged_MPa"], rel=1e-6)
            assert arrays["von_mises_averaged_MPa"][node] == pytest.approx(p["averaged_MPa"], rel=1e-6)
            assert float(_probe(grid, place)[REPORTED]) == pytest.approx(p["value_MPa"], rel=1e-5), (key, place)
    assert fe["peak_MPa"] == fe["peak"]["value_MPa"] and fe["critical_peak_MPa"] == fe["critical"]["value_MPa"]


@pytest.mark.slow
def test_no_von_mises_array_has_more_than_one_component(whole):
    """One value per node for every von Mises array (ParaView would colour a several-component
    array by its magnitude), the reported one the active scalars; no cell arrays."""
    grid = _grid(whole / "fields.vtu")
    pd = grid.GetPointData()
    names = [pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())]
    von_mises = [n for n in names if "von_mises" in n]
    assert set(von_mises) == {REPORTED, "von_mises_unaveraged_MPa", "von_mises_averaged_MPa"}
    assert all(pd.GetArray(n).GetNumberOfComponents() == 1 for n in von_mises)
    assert pd.GetScalars().GetName() == REPORTED
    assert grid.GetCellData().GetNumberOfArrays() == 0


def _polydata(path: Path):
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    assert reader.GetErrorCode() == 0
    return reader.GetOutput()


def _strings(pd, name: str) -> list[str]:
    a = pd.GetAbstractArray(name)
    return [a.GetValue(i) for i in range(a.GetNumberOfValues())]


def _peak_places(folder: Path) -> tuple[np.ndarray, dict]:
    """peaks.vtp's points (mm) and point data by name (numbers as arrays, names as strings)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    poly = _polydata(folder / "peaks.vtp")
    pd = poly.GetPointData()
    data = {n: _strings(pd, n) for n in ("name", "label", "feature")}
    data.update({n: vtk_to_numpy(pd.GetArray(n)) for n in ("value_MPa", "band_MPa", "mirror_image")})
    assert poly.GetNumberOfVerts() == poly.GetNumberOfPoints()   # drawn as points
    return vtk_to_numpy(poly.GetPoints().GetData()).astype(float), data


@pytest.mark.slow
def test_peaks_vtp_holds_the_reported_places_with_names_values_and_bands(whole):
    """peaks.vtp: each reported place and its distinct mirror images (the critical peak lies
    in x = 0: two images), named, with results.json's value and band (MPa); its label says
    them; listed in results.json's files; a probe of fields.vtu at each of its points reads
    its value."""
    res = json.loads((whole / "results.json").read_text())
    assert res["files"]["peaks"] == "peaks.vtp"
    points, data = _peak_places(whole)
    grid = _grid(whole / "fields.vtu")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    reported = vtk_to_numpy(grid.GetPointData().GetArray(REPORTED)).astype(float)
    for key, name, images in (("peak", "global peak", 4), ("critical", "critical peak", 2)):
        p = res["fe"][key]
        mine = np.array([n == name for n in data["name"]])
        assert mine.sum() == images
        expected = np.unique(np.round(_images(p["location_mm"], True), 9) + 0.0, axis=0)
        np.testing.assert_allclose(np.unique(np.round(points[mine], 9) + 0.0, axis=0), expected, atol=1e-9)
        np.testing.assert_allclose(data["value_MPa"][mine], p["value_MPa"], rtol=1e-15)
        np.testing.assert_allclose(data["band_MPa"][mine], p["error_estimate"]["band"], rtol=1e-15)
        assert sorted(data["mirror_image"][mine]) == [0] + [1] * (images - 1)
        assert {data["feature"][i] for i in np.flatnonzero(mine)} == {p["feature"]}
        label = f"{name} {p['value_MPa']:.2f} ± {p['error_estimate']['band']:.2f} MPa"
        assert {data["label"][i] for i in np.flatnonzero(mine)} == {label}
        for place in points[mine]:
            assert reported[_node(grid, place)] == pytest.approx(p["value_MPa"], rel=1e-6)


@pytest.mark.slow
def test_the_stress_tensor_s_invariants_are_consistent(whole):
    """von Mises and principal stresses written beside the tensor are the tensor's (checked
    at every node by an independent formula: von Mises from the principal stresses)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    pd = _grid(whole / "fields.vtu").GetPointData()
    s1, s2, s3 = (vtk_to_numpy(pd.GetArray(f"principal_stress_{i}_MPa")).astype(float) for i in (1, 2, 3))
    vm = vtk_to_numpy(pd.GetArray("von_mises_averaged_MPa")).astype(float)
    assert np.all(s1 >= s2) and np.all(s2 >= s3)
    from_principal = np.sqrt(0.5 * ((s1 - s2) ** 2 + (s2 - s3) ** 2 + (s3 - s1) ** 2))
    np.testing.assert_allclose(vm, from_principal, rtol=1e-4, atol=1e-4 * vm.max())
    t = vtk_to_numpy(pd.GetArray("stress_MPa")).astype(float)
    np.testing.assert_allclose(t[:, 0] + t[:, 1] + t[:, 2], s1 + s2 + s3, rtol=1e-4, atol=1e-4 * vm.max())


@pytest.mark.slow
def test_the_quarter_fields_hold_the_quarter(tmp_path):
    out = _run(tmp_path / "q", "--quarter-fields")
    x = _grid(out / "fields.vtu").GetPoints()
    from vtkmodules.util.numpy_support import vtk_to_numpy
    xyz = vtk_to_numpy(x.GetData())
    assert xyz[:, 0].min() > -1e-6 and xyz[:, 1].min() > -1e-6
    # peaks.vtp: the places alone, no mirror images.
    points, data = _peak_places(out)
    assert data["name"] == ["global peak", "critical peak"] and list(data["mirror_image"]) == [0, 0]
    fe = json.loads((out / "results.json").read_text())["fe"]
    np.testing.assert_allclose(points, [fe["peak"]["location_mm"], fe["critical"]["location_mm"]], atol=1e-12)
