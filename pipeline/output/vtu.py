"""Writing VTK XML unstructured grids (.vtu) with raw appended binary data.

Raw appended data is the layout VTK and ParaView read fastest: every array is one block of
bytes after the XML header, read without decoding. The base64 encoding that meshio writes
is a third larger and costs the reader a decoding pass over the whole file
(docs/performance.md). Arrays are written in this machine's byte order, which the header
names.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

VTK_CELL_TYPES = {"tetra": (10, 4), "tetra10": (24, 10)}  # name -> (VTK type id, nodes per cell)
_VTK_DTYPES = {np.dtype(np.float64): "Float64", np.dtype(np.int64): "Int64", np.dtype(np.uint8): "UInt8"}


def _data_array(name: str, array: np.ndarray, offset: int) -> str:
    components = f' NumberOfComponents="{array.shape[1]}"' if array.ndim == 2 else ""
    return (f'<DataArray type="{_VTK_DTYPES[array.dtype]}" Name="{name}"{components} '
            f'format="appended" offset="{offset}"/>')


def write_vtu(path: Path, points: np.ndarray, cells: np.ndarray, cell_type: str,
              point_data: dict[str, np.ndarray]) -> None:
    """Write one cell type's grid: points (n, 3, mm), cells (m, k) indexing them in VTK's node
    order, and point arrays (n,) or (n, c) named with their units."""
    vtk_type, k = VTK_CELL_TYPES[cell_type]
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    if cells.ndim != 2 or cells.shape[1] != k:
        raise ValueError(f"{cell_type} cells need {k} nodes each, got shape {cells.shape}")
    n, m = len(points), len(cells)
    blocks = [("Points", np.ascontiguousarray(points, dtype=np.float64)),
              ("connectivity", cells.ravel()),
              ("offsets", np.arange(k, k * m + 1, k, dtype=np.int64)),
              ("types", np.full(m, vtk_type, dtype=np.uint8))]
    blocks += [(name, np.ascontiguousarray(a, dtype=np.float64)) for name, a in point_data.items()]
    for name, a in blocks[4:]:
        if len(a) != n:
            raise ValueError(f"point array {name!r} has {len(a)} rows for {n} points")
    offsets, at = [], 0
    for _, a in blocks:
        offsets.append(at)
        at += 8 + a.nbytes  # each block: its size in bytes (UInt64), then the data
    tags = [_data_array(name, a, off) for (name, a), off in zip(blocks, offsets)]
    order = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
    header = "\n".join([
        '<?xml version="1.0"?>',
        f'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="{order}" header_type="UInt64">',
        "<UnstructuredGrid>",
        f'<Piece NumberOfPoints="{n}" NumberOfCells="{m}">',
        "<Points>", tags[0], "</Points>",
        "<Cells>", *tags[1:4], "</Cells>",
        "<PointData>", *tags[4:], "</PointData>",
        "</Piece>", "</UnstructuredGrid>",
        '<AppendedData encoding="raw">',
        "_"])
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for _, a in blocks:
            f.write(np.uint64(a.nbytes).tobytes())
            a.tofile(f)
        f.write(b"\n</AppendedData>\n</VTKFile>\n")
