"""Writing VTK XML unstructured grids (.vtu) with zlib-compressed appended binary data.

Each array is one appended block, split into compressed chunks as VTK's
``vtkZLibDataCompressor`` writes them (a UInt64 header: chunk count, chunk size, last chunk's
size, each chunk's compressed size), so VTK, ParaView and meshio read it without a
decoding pass. Connectivity and offsets are Int32 when the indices fit, Int64 otherwise;
arrays are written in this machine's byte order, which the header names.
"""
from __future__ import annotations

import contextlib
import os
import sys
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterator
from xml.sax.saxutils import quoteattr

import numpy as np

from pipeline.runtime.cores import unbound

VTK_CELL_TYPES = {"tetra": (10, 4), "tetra10": (24, 10)}  # name -> (VTK type id, nodes per cell)
_VTK_DTYPES = {np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32", np.dtype(np.int64): "Int64",
               np.dtype(np.int32): "Int32", np.dtype(np.uint8): "UInt8"}
CHUNK_BYTES = 1 << 20  # uncompressed bytes per zlib chunk
ZLIB_LEVEL = 1  # the fastest: Float32 data compress little at any level (docs/decisions/0007-drawing-and-field-files.md)


def _index_dtype(largest: int) -> np.dtype:
    """Int32 for indices that fit, else Int64."""
    return np.dtype(np.int32) if largest < 2 ** 31 - 1 else np.dtype(np.int64)


@contextlib.contextmanager
def _machine_wide_pool() -> Iterator[ThreadPoolExecutor]:
    """A pool of one thread per core of the machine (at most 4), whatever core this
    thread is bound to (pipeline.runtime.cores: a rank's own pool would share its one core)."""
    with unbound(), ThreadPoolExecutor(max_workers=min(os.cpu_count() or 1, 4)) as pool:
        yield pool


def _deflate(chunk: bytes) -> bytes:
    """One chunk compressed as VTK's zlib compressor writes it."""
    return zlib.compress(chunk, ZLIB_LEVEL)


def _compressed(data: bytes, pool: ThreadPoolExecutor | None = None) -> bytes:
    """``data`` as one appended block in VTK's zlib layout (UInt64 header), its chunks
    compressed by ``pool``'s threads when given (zlib lets go of the interpreter lock while
    it compresses, so the chunks compress side by side on the cores that are free)."""
    chunks = [data[i:i + CHUNK_BYTES] for i in range(0, len(data), CHUNK_BYTES)] or [b""]
    packed = list(pool.map(_deflate, chunks)) if pool is not None else [_deflate(c) for c in chunks]
    header = np.array([len(chunks), CHUNK_BYTES if len(chunks) > 1 else len(chunks[0]), len(chunks[-1]),
                       *(len(p) for p in packed)], dtype=np.uint64)
    return header.tobytes() + b"".join(packed)


def _data_array(name: str, array: np.ndarray, offset: int) -> str:
    components = f' NumberOfComponents="{array.shape[1]}"' if array.ndim == 2 else ""
    return (f'<DataArray type="{_VTK_DTYPES[array.dtype]}" Name={quoteattr(name)}{components} '
            f'format="appended" offset="{offset}"/>')


def write_vtu(path: Path, points: np.ndarray, cells: np.ndarray, cell_type: str,
              point_data: dict[str, np.ndarray], points_dtype: type = np.float64,
              scalars: str | None = None) -> None:
    """Write one cell type's grid: points (n, 3, mm, stored as ``points_dtype``), cells (m, k)
    indexing them in VTK's node order, and point arrays (n,) or (n, c), named with their
    units, each kept in its own dtype (float64, float32, int32 ...). ``scalars``: the point
    array that is the active scalars (what ParaView colours by)."""
    vtk_type, k = VTK_CELL_TYPES[cell_type]
    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] != k:
        raise ValueError(f"{cell_type} cells need {k} nodes each, got shape {cells.shape}")
    if scalars is not None and scalars not in point_data:
        raise ValueError(f"the active scalars {scalars!r} are not a point array")
    n, m = len(points), len(cells)
    index = _index_dtype(max(n, k * m))
    blocks = [("Points", np.ascontiguousarray(points, dtype=points_dtype)),
              ("connectivity", np.ascontiguousarray(cells, dtype=index).ravel()),
              ("offsets", np.arange(k, k * m + 1, k, dtype=index)),
              ("types", np.full(m, vtk_type, dtype=np.uint8))]
    for name, a in point_data.items():
        a = np.ascontiguousarray(a)
        if a.dtype not in _VTK_DTYPES:
            a = a.astype(np.float64)
        if len(a) != n:
            raise ValueError(f"point array {name!r} has {len(a)} rows for {n} points")
        blocks.append((name, a))
    n_point = 4 + len(point_data)
    with _machine_wide_pool() as pool:
        payloads = [_compressed(a.tobytes(), pool) for _, a in blocks]
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in payloads])[:-1]]).astype(int)
    tags = [_data_array(name, a, off) for (name, a), off in zip(blocks, offsets)]
    order = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
    header = "\n".join([
        '<?xml version="1.0"?>',
        f'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="{order}" header_type="UInt64" '
        'compressor="vtkZLibDataCompressor">',
        "<UnstructuredGrid>",
        f'<Piece NumberOfPoints="{n}" NumberOfCells="{m}">',
        "<Points>", tags[0], "</Points>",
        "<Cells>", *tags[1:4], "</Cells>",
        f"<PointData Scalars={quoteattr(scalars)}>" if scalars else "<PointData>", *tags[4:n_point], "</PointData>",
        "</Piece>", "</UnstructuredGrid>",
        '<AppendedData encoding="raw">',
        "_"])
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for p in payloads:
            f.write(p)
        f.write(b"\n</AppendedData>\n</VTKFile>\n")
