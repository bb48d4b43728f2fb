"""Build and mesh the part with gmsh, hand the mesh to DOLFINx (units: mm).

gmsh runs on rank 0 only; DOLFINx distributes the mesh. Physical group names are looked
up on rank 0 and broadcast, so later stages ask for "seat", never for a number.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import gmsh
import numpy as np
from dolfinx.io import gmshio
from mpi4py import MPI

from geometry.builder import BuiltGeometry, MeshSpec, build, jacobian_ratio, mesh
from geometry.table import Dimensions


REFERENCE_H3_MM = 25.0  # No. 05's body height: every part is built and meshed at this size


def meshing_scale(d: Dimensions) -> float:
    """The length (mm) that gmsh's unit stands for when it builds and meshes part d: h3 / 25 mm.

    gmsh's meshers are not scale-invariant (absolute tolerances inside the 2-D and 3-D
    algorithms): No. 05 at twice its size, every mesh size doubled, got another mesh
    (3717 vs 3702 tets at mesh factor 2), a global peak of 147 instead of 124 MPa and, from
    one badly curved tet on the bore wall, a critical peak of 104-116 MPa (varying from run
    to run) instead of 67 MPa. So the part is built and meshed at No. 05's size (lengths
    divided by this scale) and the node coordinates are multiplied by it afterwards:
    geometrically similar parts get similar meshes and their FE stresses obey the
    similarity law to round-off (tests/test_sizes.py). No. 05 itself has scale 1 and is
    meshed exactly as given.
    """
    return d.h3 / REFERENCE_H3_MM


def _unit(v: float, scale: float) -> float:
    """v / scale rounded to 12 significant digits.

    gmsh's mesh changes with the last bit of an input: No. 05 × 1e-3 divided back by its
    scale gives b1 = 45.00000000000001, which meshed differently from 45 (critical peak
    1 % off). Rounding gives the same inputs for every exact similarity copy."""
    return float(f"{v / scale:.12g}")


def _normalised(d: Dimensions, spec: MeshSpec, scale: float) -> tuple[Dimensions, MeshSpec]:
    """Part and mesh sizes with every length divided by ``scale`` (gmsh's working units)."""
    if scale == 1.0:
        return d, spec
    dn = Dimensions(**{k: _unit(v, scale) for k, v in asdict(d).items()})
    sn = replace(spec, size_body=_unit(spec.size_body, scale), size_feature=_unit(spec.size_feature, scale),
                 size_fillet=_unit(spec.size_fillet, scale), grading=_unit(spec.grading, scale),
                 size_hotspot=_unit(spec.size_hotspot, scale), hotspot_radius=_unit(spec.hotspot_radius, scale),
                 hotspots=tuple(tuple(_unit(c, scale) for c in p) for p in spec.hotspots))
    return dn, sn


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

    If ``msh_path`` is given the gmsh mesh (with physical names) is written there too, in mm.
    gmsh works in units of :func:`meshing_scale` (the part at No. 05's size); the returned
    mesh, constraint points and volume are in mm.
    """
    scale = meshing_scale(d)
    dn, spec_n = _normalised(d, spec, scale)
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
            built = build(dn, model)
            timings["geometry"] = time.perf_counter() - t0
            t0 = time.perf_counter()
            # Every curved tet leaves the builder with a det J ratio >= HO_TARGET (0.3).
            mesh(dn, spec_n)
            quality = jacobian_ratio()
            if msh_path is not None:
                gmsh.option.setNumber("Mesh.ScalingFactor", scale)  # write in mm
                gmsh.write(str(msh_path))
                gmsh.option.setNumber("Mesh.ScalingFactor", 1.0)
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
    if scale != 1.0:
        dmesh.geometry.x[:] *= scale  # gmsh units → mm
    timings["import"] = time.perf_counter() - t0
    return ImportedMesh(mesh=dmesh, cell_tags=cell_tags, facet_tags=facet_tags,
                        facet_ids=names, constraint_points=np.array(built.constraint_points) * scale,
                        model=model, volume_cad=built.volume * scale ** 3,
                        jacobian_ratio=quality, timings=timings)
