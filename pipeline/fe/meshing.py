"""Build and mesh the part with gmsh, hand the mesh to DOLFINx (units: mm).

gmsh runs on one rank per mesh (several meshes on several ranks at once); DOLFINx then
distributes each mesh. Physical group names are looked up where the mesh was made and
broadcast, so later stages ask for "seat", never for a number.
"""
from __future__ import annotations

import contextlib
import tempfile
import threading
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import gmsh
import numpy as np
from dolfinx import cpp as _cpp
from dolfinx.io import gmshio
from dolfinx.mesh import create_mesh, meshtags_from_entities
from mpi4py import MPI

from geometry.part import BuiltGeometry, build
from geometry.meshspec import MeshSpec
from geometry.sizing import mesh
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
    similarity law to round-off (tests/study/test_sizes.py). No. 05 itself has scale 1 and is
    meshed exactly as given.
    """
    return d.h3 / REFERENCE_H3_MM


def _unit(v: float, scale: float) -> float:
    """v / scale rounded to 12 significant digits.

    gmsh's mesh changes with the last bit of an input: No. 05 × 1e-3 divided back by its
    scale gives b1 = 45.00000000000001, which meshed differently from 45 (critical peak
    1 % off). Rounding gives the same inputs for every exact similarity copy."""
    return float(f"{v / scale:.12g}")


def normalised(d: Dimensions, spec: MeshSpec, scale: float) -> tuple[Dimensions, MeshSpec]:
    """Part and mesh sizes with every length divided by ``scale`` (gmsh's working units)."""
    if scale == 1.0:
        return d, spec
    dn = Dimensions(**{k: _unit(v, scale) for k, v in asdict(d).items()})
    sn = replace(spec, size_body=_unit(spec.size_body, scale), size_feature=_unit(spec.size_feature, scale),
                 size_fillet=_unit(spec.size_fillet, scale), grading=_unit(spec.grading, scale),
                 size_hotspot=_unit(spec.size_hotspot, scale), hotspot_radius=_unit(spec.hotspot_radius, scale),
                 size_edge_hotspot=_unit(spec.size_edge_hotspot, scale),
                 edge_hotspot_radius=_unit(spec.edge_hotspot_radius, scale),
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
    msh: bytes | None = None  # the gmsh file (mesh.msh, mm), on rank 0, when asked for


@dataclass
class MeshedPart:
    """A gmsh mesh as plain arrays, on the rank that made it (lengths in mm).

    What :func:`distribute` needs to build the DOLFINx mesh on every rank, so that meshing
    (serial, in gmsh) and distributing (collective) can happen at different times: several
    meshes are made at once on different ranks (:func:`make_meshes`).
    """

    x: np.ndarray                # node coordinates, mm (n × 3)
    cells: np.ndarray            # tets, gmsh node order
    cell_values: np.ndarray      # volume physical tags
    facets: np.ndarray           # boundary triangles in a physical group, gmsh node order
    facet_values: np.ndarray     # their surface physical tags
    cell_type: int               # gmsh element type of the tets (4 linear, 11 quadratic)
    names: dict[str, int]        # surface physical group name -> tag
    built: BuiltGeometry
    scale: float                 # mm per gmsh unit
    quality: float               # worst det J ratio of the curved tets
    timings: dict[str, float]
    msh: bytes | None = None     # the gmsh file (mm, MSH 4.1 binary with a note), when asked for


HEARTBEAT_S = 10.0


@contextlib.contextmanager
def heartbeat(progress: Callable[[str], None] | None, what: str, every_s: float = HEARTBEAT_S):
    """Say every ``every_s`` seconds that ``what`` is still running (gmsh's meshing call
    gives no progress of its own, and releases the interpreter while it works)."""
    if progress is None:
        yield
        return
    stop = threading.Event()
    t0 = time.perf_counter()

    def beat() -> None:
        while not stop.wait(every_s):
            progress(f"{what}: still working ({time.perf_counter() - t0:.0f} s so far)")
    thread = threading.Thread(target=beat, name="meshing-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


class Mesher:
    """Part d (``model``) built once in this process's gmsh session, then meshed for one
    spec after another: ``with Mesher(d, model) as m: part = m.generate(spec)``.

    Why: building the part (OpenCASCADE booleans) costs time in every mesh, and a
    run makes two or more meshes per process (the pilot's, then the requested or the
    error-bar ones). Each mesh starts from a cleared mesh and no size fields (the builder
    removes its own), so it is bit for bit the mesh a fresh session makes: the mesh
    depends only on its inputs, whichever rank makes it and whatever it made before
    (tests/geometry/test_geometry.py). gmsh has one session per process: if something else
    re-initialised it meanwhile, the part is built again.
    """

    def __init__(self, d: Dimensions, model: str, progress: Callable[[str], None] | None = None,
                 gmsh_options: dict[str, float] | None = None) -> None:
        self.d, self.model = d, model
        self.progress = progress  # told every HEARTBEAT_S while one mesh takes longer
        self.gmsh_options = gmsh_options  # gmsh options of every mesh, beside the builder's (geometry.sizing.mesh)
        self.scale = meshing_scale(d)
        self.name = f"crosshead-{id(self)}"
        self.built: BuiltGeometry | None = None

    def __enter__(self) -> "Mesher":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """End the gmsh session (if it is still this part's); generate() would start another."""
        if self._live():
            gmsh.finalize()
        self.built = None

    def _live(self) -> bool:
        """Is gmsh's current model still this Mesher's part?"""
        if self.built is None:
            return False
        try:
            return gmsh.model.getCurrent() == self.name
        except Exception:  # gmsh was finalised by someone else
            return False

    def _build(self, dn: Dimensions) -> None:
        # gmsh 4.8 cannot tell whether it is initialised; a fresh session either way.
        gmsh.initialize(readConfigFiles=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.add(self.name)
            self.built = build(dn, self.model)
        except BaseException:
            gmsh.finalize()
            self.built = None
            raise

    def generate(self, spec: MeshSpec, keep_msh: bool = False) -> MeshedPart:
        """Mesh the part for ``spec`` → arrays (mm); with ``keep_msh`` the gmsh file too
        (physical names, mm). gmsh works in units of :func:`meshing_scale`."""
        t0 = time.perf_counter()
        dn, spec_n = normalised(self.d, spec, self.scale)
        timings: dict[str, float] = {}
        if self._live():
            gmsh.model.mesh.clear()
        else:
            self._build(dn)
        timings["geometry"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        # Every curved tet leaves the builder with a det J ratio >= HO_TARGET (0.3).
        with heartbeat(self.progress, f"meshing ×{spec.factor:.3g}"):
            quality = (mesh(dn, spec_n) if self.gmsh_options is None else mesh(dn, spec_n, self.gmsh_options)).quality
        msh = msh_bytes(self.model, self.scale) if keep_msh else None
        names = {gmsh.model.getPhysicalName(dim, tag): tag for dim, tag in gmsh.model.getPhysicalGroups(2)}
        x = gmshio.extract_geometry(gmsh.model) * self.scale
        topo = gmshio.extract_topology_and_markers(gmsh.model)
        cell_type = max(topo, key=lambda t: gmsh.model.mesh.getElementProperties(t)[1])
        facet_types = [t for t in topo if gmsh.model.mesh.getElementProperties(t)[1] == 2]
        # Free gmsh's copy now: kept until the next mesh, it slows DOLFINx's import of this
        # one (docs/decisions/0006-error-bar-meshes-over-the-ranks.md).
        gmsh.model.mesh.clear()
        timings["mesh"] = time.perf_counter() - t0
        if len(facet_types) != 1:
            raise RuntimeError(f"mesh: expected one kind of boundary triangle, got gmsh types {facet_types}")
        return MeshedPart(x=x, cells=np.asarray(topo[cell_type]["topology"], dtype=np.int64),
                          cell_values=np.asarray(topo[cell_type]["cell_data"], dtype=np.int32),
                          facets=np.asarray(topo[facet_types[0]]["topology"], dtype=np.int64),
                          facet_values=np.asarray(topo[facet_types[0]]["cell_data"], dtype=np.int32),
                          cell_type=int(cell_type), names=names, built=self.built, scale=self.scale,
                          quality=quality, timings=timings, msh=msh)


# mesh.msh's note on what it holds: a section gmsh and meshio skip (the MSH 4.1 format
# ignores a section whose header it does not know), read by a person or a program.
MSH_PART = {"quarter": "quarter model x >= 0, y >= 0 of the crosshead; symmetry planes x = 0 and y = 0 "
                       "(the whole part is its mirror images in both planes); mm",
            "full": "the whole crosshead; mm"}


def msh_bytes(model: str, scale: float) -> bytes:
    """gmsh's current mesh as a file in mm (gmsh works in units of ``scale``, see
    :func:`meshing_scale`), MSH 4.1 binary, with a $Comments section after the format
    line saying which part it holds (MSH_PART of ``model``)."""
    gmsh.option.setNumber("Mesh.ScalingFactor", scale)  # write in mm
    gmsh.option.setNumber("Mesh.Binary", 1)
    try:
        with tempfile.TemporaryDirectory(prefix="crosshead-msh-") as tmp:
            path = Path(tmp) / "mesh.msh"
            gmsh.write(str(path))
            data = path.read_bytes()
    finally:
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.option.setNumber("Mesh.ScalingFactor", 1.0)
    end = data.index(b"$EndMeshFormat\n") + len(b"$EndMeshFormat\n")
    note = f"$Comments\ncrosshead mesh.msh: {MSH_PART[model]}\n$EndComments\n".encode("ascii")
    return data[:end] + note + data[end:]


def given_or_new(mesher: Mesher | None, d: Dimensions, model: str) -> contextlib.AbstractContextManager[Mesher]:
    """For a with-block: ``mesher`` itself, left open (its owner closes it), or a new
    Mesher of part d closed at the block's end. A given Mesher must be of part d."""
    if mesher is None:
        return Mesher(d, model)
    if (mesher.d, mesher.model) != (d, model):
        raise ValueError("the Mesher is of another part")
    return contextlib.nullcontext(mesher)


def generate(d: Dimensions, model: str, spec: MeshSpec, keep_msh: bool = False) -> MeshedPart:
    """Geometry → gmsh mesh → arrays, in this process only, in a gmsh session of its own
    (see :class:`Mesher` for several meshes of one part)."""
    with Mesher(d, model) as m:
        return m.generate(spec, keep_msh)


def distribute(part: MeshedPart | None, owner: int, model: str, comm: MPI.Comm = MPI.COMM_WORLD) -> ImportedMesh:
    """The DOLFINx mesh of ``part`` (held by rank ``owner``), shared over comm. Collective.

    What dolfinx.io.gmshio.model_to_mesh does from a live gmsh model, here from arrays.
    """
    t0 = time.perf_counter()
    meta = None
    if comm.rank == owner:
        meta = (part.cell_type, part.cells.shape[1], part.facets.shape[1], part.names, part.built,
                part.scale, part.quality, part.timings, part.msh is not None)
    cell_type, n_nodes, n_facet_nodes, names, built, scale, quality, timings, has_msh = comm.bcast(meta, root=owner)
    msh = part.msh if comm.rank == owner else None
    if has_msh and owner != 0:  # the gmsh file goes to the rank that writes the run's files
        if comm.rank == owner:
            comm.send(msh, dest=0, tag=7)
        elif comm.rank == 0:
            msh = comm.recv(source=owner, tag=7)
    if comm.rank == owner:
        x, cells, cell_values = part.x, part.cells, part.cell_values
        facets, facet_values = part.facets, part.facet_values
    else:
        x = np.empty((0, 3))
        cells = np.empty((0, n_nodes), dtype=np.int64)
        cell_values = np.empty((0,), dtype=np.int32)
        facets = np.empty((0, n_facet_nodes), dtype=np.int64)
        facet_values = np.empty((0,), dtype=np.int32)
    domain = gmshio.ufl_mesh(cell_type, 3)
    dcell = _cpp.mesh.to_type(str(domain.ufl_cell()))
    cells = cells[:, gmshio.cell_perm_array(dcell, n_nodes)]
    dmesh = create_mesh(comm, cells, x, domain)
    tdim = dmesh.topology.dim
    entities, values = _cpp.io.distribute_entity_data(dmesh._mesh, tdim, cells, cell_values)
    dmesh.topology.create_connectivity(tdim, 0)
    cell_tags = meshtags_from_entities(dmesh, tdim, _cpp.graph.AdjacencyList_int32(entities),
                                       values.astype(np.int32))
    facet_type = _cpp.mesh.cell_entity_type(dcell, tdim - 1, 0)
    facets = facets[:, gmshio.cell_perm_array(facet_type, n_facet_nodes)]
    entities, values = _cpp.io.distribute_entity_data(dmesh._mesh, tdim - 1, facets, facet_values)
    dmesh.topology.create_connectivity(tdim - 1, tdim)
    facet_tags = meshtags_from_entities(dmesh, tdim - 1, _cpp.graph.AdjacencyList_int32(entities),
                                        values.astype(np.int32))
    timings = dict(timings, **{"import": time.perf_counter() - t0})
    return ImportedMesh(mesh=dmesh, cell_tags=cell_tags, facet_tags=facet_tags,
                        facet_ids=names, constraint_points=np.array(built.constraint_points) * scale,
                        model=model, volume_cad=built.volume * scale ** 3,
                        jacobian_ratio=quality, timings=timings, msh=msh if comm.rank == 0 else None)


def make_mesh(d: Dimensions, model: str, spec: MeshSpec, comm: MPI.Comm = MPI.COMM_WORLD,
              keep_msh: bool = False, mesher: Mesher | None = None) -> ImportedMesh:
    """Geometry → gmsh mesh (on rank 0) → DOLFINx mesh. Times each of the three stages (s).

    ``mesher``: this process's :class:`Mesher` of part d, if it has one (else a new session)."""
    return make_meshes(d, model, [spec], comm, [keep_msh], mesher=mesher)[0]()


def owners(costs: Sequence[float], ranks: int) -> list[int]:
    """The rank that meshes each job: the largest job first, each to the least loaded rank."""
    load = [0.0] * ranks
    out = [0] * len(costs)
    for i in sorted(range(len(costs)), key=lambda i: (-costs[i], i)):
        r = min(range(ranks), key=lambda r: (load[r], r))
        out[i] = r
        load[r] += costs[i]
    return out


def make_meshes(d: Dimensions, model: str, specs: Sequence[MeshSpec], comm: MPI.Comm = MPI.COMM_WORLD,
                keep_msh: Sequence[bool] | None = None,
                solve_on: Sequence[int | None] | None = None,
                mesher: Mesher | None = None) -> list[Callable[[], ImportedMesh] | None]:
    """Mesh several specs at once, each on one rank; return a loader per mesh.

    Why: gmsh is serial, and meshing the three meshes of a run's error bar one after the
    other on rank 0 left the other ranks idle for seconds. The cost of a mesh is taken as
    factor⁻³ (its number of elements, roughly). ``solve_on[k]``: None (default) shares
    mesh k over comm, and every rank calls loader k, in the same order; a rank number
    gives mesh k to that rank alone (sent there if another rank made it), whose loader
    returns it on MPI.COMM_SELF; the other ranks get None. A mesh that failed raises its
    error on every rank, before anything is loaded, the first in spec order. ``mesher``:
    this process's :class:`Mesher` of part d, if it has one (else one for this call).
    """
    keep = list(keep_msh) if keep_msh is not None else [False] * len(specs)
    target = list(solve_on) if solve_on is not None else [None] * len(specs)
    who = owners([s.factor ** -3 for s in specs], comm.size)
    parts: dict[int, MeshedPart] = {}
    error: tuple[int, Exception] | None = None
    with given_or_new(mesher, d, model) as m:
        for k, spec in enumerate(specs):
            if who[k] == comm.rank and error is None:
                try:
                    parts[k] = m.generate(spec, keep[k])
                except Exception as exc:  # re-raised on every rank below
                    error = (k, exc)
    errors = [e for e in comm.allgather(error) if e is not None]
    if errors:
        raise min(errors, key=lambda e: e[0])[1]
    for k, rank in enumerate(target):  # every rank in the same order: no deadlock
        if rank is None or rank == who[k]:
            continue
        if comm.rank == who[k]:
            comm.send(parts.pop(k), dest=rank, tag=k)
        elif comm.rank == rank:
            parts[k] = comm.recv(source=who[k], tag=k)
    loaders: list[Callable[[], ImportedMesh] | None] = []
    for k, rank in enumerate(target):
        if rank is None:
            loaders.append(lambda k=k: distribute(parts.get(k), who[k], model, comm))
        elif rank == comm.rank:
            loaders.append(lambda k=k: distribute(parts[k], 0, model, MPI.COMM_SELF))
        else:
            loaders.append(None)
    return loaders
