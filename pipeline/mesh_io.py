"""Build and mesh the part with gmsh, hand the mesh to DOLFINx (units: mm).

gmsh runs on rank 0 only; DOLFINx distributes the mesh. Physical group names are looked
up on rank 0 and broadcast, so later stages ask for "seat", never for a number.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import gmsh
import numpy as np
from dolfinx.io import gmshio
from mpi4py import MPI

from geometry.builder import BuiltGeometry, MeshSpec, build, jacobian_ratio, mesh
from geometry.table import Dimensions


@dataclass
class ImportedMesh:
    """A DOLFINx mesh with its boundary tags and the names of the physical groups.

    facet_ids maps a surface group name to its marker in facet_tags; points maps
    "constraint_points" to their coordinates (mm).
    """

    mesh: object
    cell_tags: object
    facet_tags: object
    facet_ids: dict[str, int]
    constraint_points: np.ndarray
    model: str
    volume_cad: float
    jacobian_ratio: float  # worst min/max det J over the tets; <= 0 is an inverted element
    timings: dict[str, float] = field(default_factory=dict)


def make_mesh(d: Dimensions, model: str, spec: MeshSpec, comm=MPI.COMM_WORLD,
              msh_path: Path | None = None) -> ImportedMesh:
    """Geometry → gmsh mesh → DOLFINx mesh. Times each of the three stages (s).

    If ``msh_path`` is given the gmsh mesh (with physical names) is written there too.
    """
    timings: dict[str, float] = {}
    rank = comm.rank
    names: dict[str, int] = {}
    built: BuiltGeometry | None = None
    # gmsh 4.8 cannot tell whether it is initialised; own it for the length of this call.
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    error = None
    quality = float("nan")
    if rank == 0:
        try:
            t0 = time.perf_counter()
            gmsh.model.add("crosshead")
            built = build(d, model)
            timings["geometry"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            mesh(d, spec)
            quality = jacobian_ratio()
            if msh_path is not None:
                gmsh.write(str(msh_path))
            timings["mesh"] = time.perf_counter() - t0
            for dim, tag in gmsh.model.getPhysicalGroups(2):
                names[gmsh.model.getPhysicalName(dim, tag)] = tag
        except Exception as exc:  # re-raised on every rank below
            error = exc
    error = comm.bcast(error, root=0)
    if error is not None:
        gmsh.finalize()
        raise error
    names, built, timings, quality = comm.bcast((names, built, timings, quality), root=0)
    t0 = time.perf_counter()
    try:
        dmesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    finally:
        gmsh.finalize()
    timings["import"] = time.perf_counter() - t0
    return ImportedMesh(mesh=dmesh, cell_tags=cell_tags, facet_tags=facet_tags,
                        facet_ids=names, constraint_points=np.array(built.constraint_points),
                        model=model, volume_cad=built.volume,
                        jacobian_ratio=quality, timings=timings)
