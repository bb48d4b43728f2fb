"""The ParaView file (pipeline/output/fields.py) read back against the solution it was
written from (mm, MPa): its 10-node tets, their node order, the mirrored whole part with its
symmetry-plane nodes shared, and the compressed VTK XML layout."""
from __future__ import annotations

import meshio
import numpy as np
import pytest
from dolfinx import fem
from dolfinx.mesh import CellType, create_box
from mpi4py import MPI

from pipeline.fe.elasticity import Material
from pipeline.output.fields import write_fields
from pipeline.post.peaks import node_readings


def field(x: np.ndarray) -> np.ndarray:
    """A quadratic displacement (mm) on points x (3, n): P2 holds it exactly, and it obeys
    the quarter model's symmetry (u_x = 0 on x = 0, u_y = 0 on y = 0)."""
    return np.vstack([1e-3 * x[0] * (1 + x[1]), 2e-3 * x[1] * x[2], -1e-3 * (x[0] ** 2 + x[2] ** 2)])


@pytest.mark.parametrize("whole", [False, True])
def test_field_file_holds_the_p2_field(tmp_path, whole):
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.5])], [3, 2, 2], CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 2)))
    u.interpolate(field)
    files = write_fields(tmp_path, u, node_readings(u, Material(), None), Material(), whole_part=whole)
    n_nodes = u.function_space.dofmap.index_map.size_global
    n_cells = mesh.topology.index_map(3).size_global
    x0 = u.function_space.tabulate_dof_coordinates()
    if MPI.COMM_WORLD.rank != 0:    # rank 0 writes the files
        return
    m = meshio.read(tmp_path / files["fields"])
    cells = m.cells_dict["tetra10"]
    assert len(cells) == (4 if whole else 1) * n_cells
    x, d = m.points.astype(float), m.point_data["displacement_mm"].astype(float)
    # Every mid-edge node sits halfway along its VTK edge (the box's tets are straight),
    # and every cell is positively oriented, also the reflected ones.
    for a, b, k in ((0, 1, 4), (1, 2, 5), (2, 0, 6), (0, 3, 7), (1, 3, 8), (2, 3, 9)):
        np.testing.assert_allclose(x[cells[:, k]], 0.5 * (x[cells[:, a]] + x[cells[:, b]]), atol=1e-6)
    e = x[cells[:, 1:4]] - x[cells[:, [0]]]
    assert np.all(np.linalg.det(e) > 0)
    # The field at every node: the closed form, reflected where the quarter was (u_x
    # changes sign in x = 0, u_y in y = 0); Float32 values.
    sign = np.where(x < -1e-9, -1.0, 1.0)      # which copy a node belongs to (z is never mirrored)
    expected = field((x * sign).T).T * sign
    np.testing.assert_allclose(d, expected, atol=1e-6 * np.abs(expected).max())
    # Nodes on the planes x = 0 and y = 0 are shared by the copies: counted from the box's
    # own nodes, not from the file.
    on_x, on_y = np.isclose(x0[:, 0], 0.0), np.isclose(x0[:, 1], 0.0)
    shared = 4 * n_nodes - 2 * on_x.sum() - 2 * on_y.sum() + (on_x & on_y).sum()
    assert len(x) == (shared if whole else n_nodes)
    assert len(np.unique(np.round(x, 5), axis=0)) == len(x)   # no node written twice


@pytest.mark.parametrize("kind, k", [("tetra", 4), ("tetra10", 10)])
def test_vtu_file_reads_back_in_vtk_and_meshio(tmp_path, kind, k):
    """The zlib-compressed appended .vtu (pipeline/output/vtu.py) read by two independent
    readers, VTK's own (what ParaView and the picture use) and meshio's, gives back every
    array bit for bit, in the dtype it was written in (Int32 connectivity where it fits)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    from pipeline.output.vtu import VTK_CELL_TYPES, write_vtu
    rng = np.random.default_rng(7)
    n = 60_000    # arrays of more than one compressed chunk (1 MiB)
    points = rng.normal(size=(n, 3)) * 25.0
    cells = rng.integers(0, n, size=(9, k))
    data = {"von_mises_MPa": rng.random(n) * 100.0, "displacement_mm": rng.normal(size=(n, 3)).astype(np.float32)}
    path = tmp_path / "grid.vtu"
    write_vtu(path, points, cells, kind, data)

    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, points)
    np.testing.assert_array_equal(m.cells_dict[kind], cells)
    for name, a in data.items():
        np.testing.assert_array_equal(m.point_data[name], a)

    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetPoints().GetData()), points)
    np.testing.assert_array_equal(vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, k), cells)
    assert {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())} == {VTK_CELL_TYPES[kind][0]}
    assert vtk_to_numpy(grid.GetCells().GetConnectivityArray()).dtype == np.int32 or \
        grid.GetCells().IsStorage64Bit() is False
    for name, a in data.items():
        got = vtk_to_numpy(grid.GetPointData().GetArray(name))
        assert got.dtype == a.dtype
        np.testing.assert_array_equal(got, a)
    assert b'compressor="vtkZLibDataCompressor"' in path.read_bytes()[:1000]
    assert b'type="Int32" Name="connectivity"' in path.read_bytes()[:2000]


def test_vtu_writer_refuses_a_mismatched_array(tmp_path):
    from pipeline.output.vtu import write_vtu
    with pytest.raises(ValueError, match="von_mises_MPa"):
        write_vtu(tmp_path / "bad.vtu", np.zeros((4, 3)), np.array([[0, 1, 2, 3]]), "tetra",
                  {"von_mises_MPa": np.zeros(3)})


# A stress state with known principal stresses: diag(120, 30, −45) MPa turned by 30° about z
# then 40° about x. Its principal stresses are those three (largest first), its von Mises
# √(½((s1 − s2)² + (s2 − s3)² + (s3 − s1)²)), and its six VTK components xx, yy, zz, xy, yz, xz
# are the entries of R·diag·Rᵀ, worked out with the rotation below.
PRINCIPAL = np.array([120.0, 30.0, -45.0])


def _rotation() -> np.ndarray:
    a, b = np.radians(30.0), np.radians(40.0)
    rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(b), -np.sin(b)], [0.0, np.sin(b), np.cos(b)]])
    return rx @ rz


def test_the_derived_arrays_are_the_tensor_s_components_von_mises_and_principal_stresses():
    from pipeline.output.fields import _with_invariants
    R = _rotation()
    s = R @ np.diag(PRINCIPAL) @ R.T
    n = 3
    out = _with_invariants({"displacement_mm": np.tile([0.1, -0.2, 0.3], (n, 1)),
                            "stress_MPa": np.tile(s.ravel(), (n, 1))})
    s1, s2, s3 = PRINCIPAL
    vm = np.sqrt(0.5 * ((s1 - s2) ** 2 + (s2 - s3) ** 2 + (s3 - s1) ** 2))
    tol = 1e-6 * np.abs(PRINCIPAL).max()  # Float32 arrays: 7 digits
    for k, i, j in ((0, 0, 0), (1, 1, 1), (2, 2, 2), (3, 0, 1), (4, 1, 2), (5, 0, 2)):  # VTK's order
        np.testing.assert_allclose(out["stress_MPa"][:, k], s[i, j], atol=tol)
    np.testing.assert_allclose(out["von_mises_averaged_MPa"], vm, atol=tol)
    for i, value in enumerate(PRINCIPAL, start=1):
        np.testing.assert_allclose(out[f"principal_stress_{i}_MPa"], value, atol=tol)
    np.testing.assert_allclose(out["displacement_mm"], [[0.1, -0.2, 0.3]] * n, atol=1e-7)
    assert all(a.dtype == np.float32 for a in out.values())


def test_the_field_file_holds_a_uniform_stress_at_every_node(tmp_path):
    """u = ε·x with a constant strain ε: the stress σ = 2μ ε + λ tr(ε) I (Hooke, the Lamé
    constants of E = 210 000 MPa, ν = 0.3 written out here) at every node of the file, with its
    von Mises and principal stresses (those of σ, by numpy's eigvalsh of the closed form)."""
    E, nu = 210_000.0, 0.3
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = np.array([[4e-4, 1e-4, -2e-4], [1e-4, -1e-4, 3e-4], [-2e-4, 3e-4, 2e-4]])
    sigma = 2 * mu * eps + lam * np.trace(eps) * np.eye(3)
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.5])], [2, 2, 2], CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 2)))
    u.interpolate(lambda x: eps @ x)
    files = write_fields(tmp_path, u, node_readings(u, Material(E, nu), lambda x: x[:, 0] > 1.0), Material(E, nu))
    if MPI.COMM_WORLD.rank != 0:
        return
    m = meshio.read(tmp_path / files["fields"])
    pd = {k: v.astype(float) for k, v in m.point_data.items()}
    tol = 1e-6 * np.abs(sigma).max()  # Float32
    vtk = [sigma[0, 0], sigma[1, 1], sigma[2, 2], sigma[0, 1], sigma[1, 2], sigma[0, 2]]
    np.testing.assert_allclose(pd["stress_MPa"], np.tile(vtk, (len(m.points), 1)), atol=tol)
    dev = sigma - np.trace(sigma) / 3 * np.eye(3)
    np.testing.assert_allclose(pd["von_mises_averaged_MPa"], np.sqrt(1.5 * np.sum(dev * dev)), atol=tol)
    principal = np.linalg.eigvalsh(sigma)[::-1]
    for i in range(3):
        np.testing.assert_allclose(pd[f"principal_stress_{i + 1}_MPa"], principal[i], atol=tol)
    # The readings at the nodes, unaveraged and reported (the midpoint on half the box): the
    # same uniform value; one component each, the reported one the active scalars.
    for name in ("von_mises_unaveraged_MPa", "von_mises_reported_MPa"):
        assert pd[name].ndim == 1
        np.testing.assert_allclose(pd[name], np.sqrt(1.5 * np.sum(dev * dev)), rtol=1e-6)
    assert not m.cell_data
    assert b'<PointData Scalars="von_mises_reported_MPa">' in (tmp_path / files["fields"]).read_bytes()[:4000]


def test_the_reported_array_is_the_reading_rule_at_every_node(tmp_path):
    """u_x = a·max(x − 1, 0) on a box with a layer of vertices at x = 1, read with the midpoint
    on x ≥ 1: every tet's stress is exact, zero left of x = 1 and uniaxial strain right of it
    (von Mises |σ_xx − σ_yy| = 2μ·a). At each vertex the unaveraged reading is that value
    where a tet of the right side has the vertex (x ≥ 1) and zero elsewhere; the reported one
    is the midpoint of it and the file's averaged von Mises where x ≥ 1, the unaveraged one
    elsewhere; at a mid-edge node the mean of its edge's two vertices (linear, as the
    averaged stress). The array's largest value is the peak read from the same readings."""
    from pipeline.post.peaks import node_peak
    a = 1e-3
    mat = Material(210_000.0, 0.3)
    mu = mat.E / (2 * (1 + mat.nu))
    right = 2 * mu * a
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [4, 2, 2], CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 2)))
    u.interpolate(lambda x: np.vstack([a * np.maximum(x[0] - 1.0, 0.0), 0 * x[0], 0 * x[0]]))
    readings = node_readings(u, mat, lambda xyz: xyz[:, 0] >= 1.0 - 1e-9)
    files = write_fields(tmp_path, u, readings, mat)
    peak = node_peak(readings)
    if MPI.COMM_WORLD.rank != 0:
        return
    m = meshio.read(tmp_path / files["fields"])
    x, cells = m.points.astype(float), m.cells_dict["tetra10"]
    pd = {k: v.astype(float) for k, v in m.point_data.items()}
    vertices = np.unique(cells[:, :4])
    xv = x[vertices, 0]
    unaveraged = np.where(xv >= 1.0 - 1e-6, right, 0.0)
    np.testing.assert_allclose(pd["von_mises_unaveraged_MPa"][vertices], unaveraged, atol=1e-6 * right)
    expected = np.where(xv >= 1.0 - 1e-6, 0.5 * (unaveraged + pd["von_mises_averaged_MPa"][vertices]), unaveraged)
    np.testing.assert_allclose(pd["von_mises_reported_MPa"][vertices], expected, atol=1e-6 * right)
    on = np.abs(xv - 1.0) < 1e-6
    assert np.all(pd["von_mises_reported_MPa"][vertices][on] < 0.99 * right)   # the midpoint differs there
    reported = pd["von_mises_reported_MPa"]
    for k, (i, j) in zip(range(4, 10), ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))):   # VTK's tet10 edges
        np.testing.assert_allclose(reported[cells[:, k]], 0.5 * (reported[cells[:, i]] + reported[cells[:, j]]),
                                   atol=1e-6 * right)
    assert reported.max() == pytest.approx(peak.value_MPa, rel=1e-6) and peak.value_MPa == pytest.approx(right)


def test_peaks_vtp_reads_back_in_vtk(tmp_path):
    """write_peaks: each place with its distinct mirror images (a place in x = 0 is its own
    image there), names, labels, values and bands as given (NaN where there is no band),
    read back by VTK's own reader (ParaView's)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    from pipeline.output.fields import write_peaks
    fe = {"peak": {"value_MPa": 113.642, "location_mm": [23.16, 6.86, 4.87], "feature": "journal shoulder fillet",
                   "error_estimate": {"band": 0.6}},
          "critical": {"value_MPa": 66.224, "location_mm": [0.0, 10.5, 0.0], "feature": "bore edge (bottom face)",
                       "error_estimate": None}}
    assert write_peaks(tmp_path, fe, whole_part=True) == {"peaks": "peaks.vtp"}
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(tmp_path / "peaks.vtp"))
    reader.Update()
    poly = reader.GetOutput()
    pd = poly.GetPointData()

    def strings(name):
        a = pd.GetAbstractArray(name)
        return [a.GetValue(i) for i in range(a.GetNumberOfValues())]
    xyz = vtk_to_numpy(poly.GetPoints().GetData())
    np.testing.assert_array_equal(xyz, [[23.16, 6.86, 4.87], [-23.16, 6.86, 4.87], [23.16, -6.86, 4.87],
                                        [-23.16, -6.86, 4.87], [0.0, 10.5, 0.0], [0.0, -10.5, 0.0]])
    assert strings("name") == ["global peak"] * 4 + ["critical peak"] * 2
    assert strings("label") == ["global peak 113.64 ± 0.60 MPa"] * 4 + ["critical peak 66.22 MPa"] * 2
    assert strings("feature") == ["journal shoulder fillet"] * 4 + ["bore edge (bottom face)"] * 2
    np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray("value_MPa")), [113.642] * 4 + [66.224] * 2)
    band = vtk_to_numpy(pd.GetArray("band_MPa"))
    assert list(band[:4]) == [0.6] * 4 and np.isnan(band[4:]).all()
    assert list(vtk_to_numpy(pd.GetArray("mirror_image"))) == [0, 1, 1, 1, 0, 1]
    assert poly.GetNumberOfVerts() == 6
    write_peaks(tmp_path, fe, whole_part=False)
    reader.Modified()
    reader.Update()
    assert reader.GetOutput().GetNumberOfPoints() == 2
