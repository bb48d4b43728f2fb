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
from pipeline.post.peaks import von_mises


def field(x: np.ndarray) -> np.ndarray:
    """A quadratic displacement (mm) on points x (3, n): P2 holds it exactly, and it obeys
    the quarter model's symmetry (u_x = 0 on x = 0, u_y = 0 on y = 0)."""
    return np.vstack([1e-3 * x[0] * (1 + x[1]), 2e-3 * x[1] * x[2], -1e-3 * (x[0] ** 2 + x[2] ** 2)])


@pytest.mark.parametrize("whole", [False, True])
def test_field_file_holds_the_p2_field(tmp_path, whole):
    mesh = create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([2.0, 1.0, 1.5])], [3, 2, 2], CellType.tetrahedron)
    u = fem.Function(fem.VectorFunctionSpace(mesh, ("CG", 2)))
    u.interpolate(field)
    files = write_fields(tmp_path, u, von_mises(u, Material()), Material(), whole_part=whole)
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
    cell_data = {"von_mises_unaveraged_MPa": rng.random((9, 4)).astype(np.float32)}
    path = tmp_path / "grid.vtu"
    write_vtu(path, points, cells, kind, data, cell_data)

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
    for name, a in cell_data.items():
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetCellData().GetArray(name)), a)
        np.testing.assert_array_equal(m.cell_data[name][0], a)
    assert b'compressor="vtkZLibDataCompressor"' in path.read_bytes()[:1000]
    assert b'type="Int32" Name="connectivity"' in path.read_bytes()[:2000]


def test_vtu_writer_refuses_a_mismatched_array(tmp_path):
    from pipeline.output.vtu import write_vtu
    with pytest.raises(ValueError, match="von_mises_MPa"):
        write_vtu(tmp_path / "bad.vtu", np.zeros((4, 3)), np.array([[0, 1, 2, 3]]), "tetra",
                  {"von_mises_MPa": np.zeros(3)})
