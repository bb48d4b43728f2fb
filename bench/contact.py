"""The journal seated in a side-plate bore, solved with CalculiX's contact (mm, N, MPa).

An independent check of the pipeline's bearing load model (docs/design.md §3: a pressure
p0·cos θ on the lower half of each journal, uniform along it). Here nothing is assumed
about the pressure: the crosshead (the pipeline's own quarter mesh, C3D10, loaded by the
seat pressure and held by its symmetry planes) rests in the bore of a side plate (its own
gmsh mesh, C3D10), and CalculiX finds where and how hard they touch.

The side plate (quarter, y ≥ 0): a block x ∈ [b1/2 + rf, that + thickness] (default: the
journal's bearing length, flush with the fillet's run-out at one end and with the tip at the
other), y ∈ [0, width/2], from ``below`` under the bore to ``above`` over the journal axis,
with a bore of diameter dj + clearance whose lowest line touches the journal's lowest line
(the journal rests at the bottom of its bore). Its top face is held (u = 0): the plate hangs
from there, as a hook block's side plates hang from the sheave axle, and carries Q/2 per
journal upwards. Its face y = 0 is a symmetry plane (u_y = 0).

Contact: the lower half of the journal's bearing surface (the faces the pipeline's
``journal_bearing`` group holds) is the slave, the whole bore the master (its mesh does
not end at θ = 90°, and a larger master costs nothing),
``TYPE=SURFACE TO SURFACE`` with a linear penalty ``*SURFACE BEHAVIOR`` and no friction
(or Coulomb friction μ). The crosshead's only rigid motion left, its vertical translation,
is carried by the contact; a soft spring (1 N/mm) on one node keeps the first iteration's
matrix regular and takes a force the study reports (about 0.02 N, under 1e-5 of Q/4).

Read-back: the displacement of the crosshead's nodes goes into the DOLFINx P2 space of its
mesh (as bench/calculix.py does) so its peaks are read exactly as the pipeline reads its
own. The contact is read from the crosshead's side: its nodal contact forces (the
out-of-balance forces under that displacement) and the normal pressure of its own surface
stress. CalculiX's nodal CPRESS (.frd) is kept in the solution for inspection only: on
quadratic faces it integrated to about twice the load (docs/load-reference.md).
"""
from __future__ import annotations

import math
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bench.calculix import C3D10_FLIP, CcxModel, build_model, fmt, inp_text, read_dat_displacements, run_job
from geometry.table import Dimensions
from pipeline.api import NumericalError

# The four faces of a C3D10 element (CalculiX/Abaqus numbering S1..S4): corner nodes, then
# the mid-side nodes of edges (c0,c1), (c1,c2), (c2,c0); 0-based local node numbers.
C3D10_FACES = np.array([[0, 1, 2, 4, 5, 6],
                        [0, 3, 1, 7, 8, 4],
                        [1, 3, 2, 8, 9, 5],
                        [2, 3, 0, 9, 7, 6]])
# gmsh's tetra10 order → C3D10 order: the last two nodes swapped (docs/stack.md).
GMSH_TO_C3D10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])
SPRING_N_PER_MM = 1.0  # the soft vertical spring that keeps the crosshead's matrix regular


@dataclass(frozen=True)
class PlateSpec:
    """The side plate and its contact (mm; penalty MPa/mm).

    ``clearance_mm`` is diametral (bore − journal diameter). ``thickness_mm`` None: the
    journal's bearing length b6/2 − b1/2 − rf. The width, the ligament under the bore and
    the height over the axis are multiples of dj by default (a plate of usual proportions;
    the paper gives none). ``offset_mm``: the plate's inner face stands this far off the
    fillet's run-out (0: flush, its bore edge on the fillet's end). ``held``: the face held
    fixed, "top" (the plate hangs from it, as from a sheave axle) or "bottom" (the plate
    stands on it: the ligament under the bore in compression instead). ``size_mm``: element
    size on the bore; it grows to 3× that
    away from it. ``penalty_MPa_per_mm``: the slope of the linear pressure-overclosure law,
    None for 20·E/size (penetration at 100 MPa then about 1e-5 mm, a thousandth of the
    elastic approach of journal and bore). ``friction``: Coulomb μ (0: frictionless).
    """

    clearance_mm: float = 0.0
    thickness_mm: float | None = None
    width_per_dj: float = 2.5
    below_per_dj: float = 0.75
    above_per_dj: float = 2.0
    size_mm: float = 1.5
    penalty_MPa_per_mm: float | None = None
    friction: float = 0.0
    offset_mm: float = 0.0
    held: str = "top"

    def x_range(self, d: Dimensions) -> tuple[float, float]:
        """The plate's faces along the journal axis (mm): from ``offset_mm`` beyond the
        fillet's run-out outwards (default thickness: to the tip)."""
        x0 = d.b1 / 2 + d.rf + self.offset_mm
        t = self.thickness_mm if self.thickness_mm is not None else d.b6 / 2 - x0
        return x0, x0 + t


@dataclass
class PlateMesh:
    """The side plate's C3D10 mesh (nodes mm, elements 0-based) and the node and face sets
    its supports and contact use."""

    nodes: np.ndarray
    elements: np.ndarray
    top: np.ndarray          # 0-based nodes of the held face (top or bottom: PlateSpec.held)
    sym_y: np.ndarray        # 0-based nodes on y = 0
    bore_faces: np.ndarray   # (F, 2): element (0-based), face (1..4) on the bore
    volume_mm3: float
    flipped: int = 0


def plate_mesh(d: Dimensions, spec: PlateSpec) -> PlateMesh:
    """Build and mesh the quarter side plate in a gmsh session of its own (second order).

    Raises NumericalError if OpenCASCADE's volume differs from the closed form (a silent
    boolean failure, docs/stack.md)."""
    import gmsh

    if spec.held not in ("top", "bottom"):
        raise ValueError(f"side plate: held must be 'top' or 'bottom', got {spec.held!r}")
    x0, x1 = spec.x_range(d)
    rj, c = d.dj / 2, spec.clearance_mm
    rb, zb = rj + c / 2, d.h3 / 2 + c / 2          # bore radius and axis height
    zlo, ztop = d.h3 / 2 - rj - spec.below_per_dj * d.dj, d.h3 / 2 + spec.above_per_dj * d.dj
    half_w = spec.width_per_dj * d.dj / 2
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("side-plate")
        occ = gmsh.model.occ
        box = occ.addBox(x0, 0.0, zlo, x1 - x0, half_w, ztop - zlo)
        cyl = occ.addCylinder(x0 - 1.0, 0.0, zb, x1 - x0 + 2.0, 0.0, 0.0, rb)
        out, _ = occ.cut([(3, box)], [(3, cyl)])
        occ.synchronize()
        vol = sum(occ.getMass(3, t) for _, t in out)
        expected = (x1 - x0) * (half_w * (ztop - zlo) - math.pi * rb ** 2 / 2)
        if abs(vol - expected) > 1e-6 * expected:
            raise NumericalError(f"side plate: CAD volume {vol:.6g} mm³, closed form {expected:.6g} mm³")
        bore = [t for _, t in gmsh.model.getEntities(2) if gmsh.model.getType(2, t) == "Cylinder"]
        field = gmsh.model.mesh.field
        dist = field.add("Distance")
        field.setNumbers(dist, "FacesList", bore)
        thr = field.add("Threshold")
        for name, value in (("IField", dist), ("LcMin", spec.size_mm), ("LcMax", 3 * spec.size_mm),
                            ("DistMin", 0.5 * rj), ("DistMax", 2.5 * rj)):
            field.setNumber(thr, name, value)
        field.setAsBackgroundMesh(thr)
        for name, value in (("Mesh.MeshSizeExtendFromBoundary", 0), ("Mesh.MeshSizeFromPoints", 0),
                            ("Mesh.MeshSizeFromCurvature", 0), ("Mesh.ElementOrder", 2),
                            ("Mesh.HighOrderOptimize", 0), ("General.NumThreads", 1)):
            gmsh.option.setNumber(name, value)
        gmsh.model.mesh.generate(3)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(11)
    finally:
        gmsh.finalize()
    tags = np.asarray(tags, dtype=np.int64)
    index = np.full(tags.max() + 1, -1, dtype=np.int64)
    index[tags] = np.arange(tags.size)
    x = np.asarray(xyz, dtype=float).reshape(-1, 3)
    gm = index[np.asarray(enodes, dtype=np.int64).reshape(-1, 10)]
    used = np.unique(gm)                      # drop nodes no element uses (docs/stack.md)
    renum = np.full(x.shape[0], -1, dtype=np.int64)
    renum[used] = np.arange(used.size)
    nodes, elems = x[used], renum[gm][:, GMSH_TO_C3D10]
    elems, flipped = _positive(elems, nodes)
    tol = 1e-6 * d.b6
    on_bore = np.abs(np.hypot(nodes[:, 1], nodes[:, 2] - zb) - rb) < 1e-4 * rb
    faces = surface_faces(elems, on_bore)
    held = nodes[:, 2] > ztop - tol if spec.held == "top" else nodes[:, 2] < zlo + tol
    return PlateMesh(nodes=nodes, elements=elems, top=np.flatnonzero(held),
                     sym_y=np.flatnonzero(nodes[:, 1] < tol), bore_faces=faces, volume_mm3=vol,
                     flipped=flipped)


def _positive(elems: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, int]:
    """C3D10 elements each turned to a positive corner volume (CalculiX stops on a
    negative Jacobian), and how many had to be turned."""
    p = nodes[elems[:, :4]]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    neg = vol < 0
    elems = elems.copy()
    elems[neg] = elems[neg][:, C3D10_FLIP]
    return elems, int(neg.sum())


def surface_faces(elems: np.ndarray, on: np.ndarray) -> np.ndarray:
    """The element faces (element 0-based, face 1..4) whose three corner nodes all have
    ``on`` true and that lie on the boundary (no other element shares them).

    Corners only: a mid-side node of a curved face may have been pulled straight by the
    curved-tet repair (geometry/curved.py) and lie slightly off the surface."""
    corners = elems[:, C3D10_FACES[:, :3]]                 # (E, 4, 3)
    keys = np.sort(corners, axis=2).reshape(-1, 3)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    boundary = counts[inverse.ravel()] == 1
    all_on = on[corners].all(axis=2).ravel()
    pick = np.flatnonzero(boundary & all_on)
    return np.column_stack([pick // 4, pick % 4 + 1])


@dataclass
class ContactModel:
    """Crosshead and plate as one CalculiX model (1-based ids in ``model``), with the
    contact surfaces and the numbers the read-back needs."""

    model: CcxModel                # both bodies; dof_node and V are the crosshead's
    n_cross_nodes: int             # nodes 1..n_cross_nodes are the crosshead's
    n_cross_elements: int
    slave_faces: np.ndarray        # (F, 2) element (1-based), face 1..4: the journal
    master_faces: np.ndarray       # (F, 2) element (1-based), face 1..4: the bore
    plate_top: np.ndarray          # 1-based nodes with u = 0 (the plate's reaction)
    spring_node: int               # 1-based
    spec: PlateSpec
    plate: PlateMesh
    facet_tags: object = None      # the crosshead mesh's boundary tags (the seat's marker)


def seat_only(lc):
    """The pipeline's load case without its bearing pressure and point constraint: the
    seat pressure and the symmetry planes only (the plate supports the journal)."""
    if lc.point_constraint_index is None:
        raise ValueError("the contact model replaces the bearing support: use support = 'bearing'")
    constraints = [c for k, c in enumerate(lc.constraints) if k != lc.point_constraint_index]
    return replace(lc, tractions=lc.tractions[:1], constraints=constraints, support_force_z_N=float("nan"),
                   point_constraint_index=None)


def contact_model(mesh, facet_tags, lc, d: Dimensions, spec: PlateSpec) -> ContactModel:
    """The crosshead of ``mesh`` (quarter; loaded by the seat pressure of ``lc``, held by
    its symmetry planes) and a side plate of ``spec`` under its journal, as one model."""
    cross = build_model(mesh, facet_tags, seat_only(lc))
    plate = plate_mesh(d, spec)
    nc, ec = cross.nodes.shape[0], cross.elements.shape[0]
    zc, rj, tol = d.h3 / 2, d.dj / 2, 1e-6 * d.b6
    x0, _ = spec.x_range(d)
    xyz = cross.nodes
    on_journal = ((np.abs(np.hypot(xyz[:, 1], xyz[:, 2] - zc) - rj) < 1e-4 * rj)
                  & (xyz[:, 0] >= d.b1 / 2 + d.rf - tol) & (xyz[:, 2] <= zc + tol))
    slave = surface_faces(cross.elements - 1, on_journal)
    if slave.size == 0 or plate.bore_faces.size == 0:
        raise NumericalError("contact model: no journal or no bore faces found")
    fixed = {k: v.copy() for k, v in cross.fixed.items()}
    top = plate.top + nc + 1
    for comp in range(3):
        extra = top if comp != 1 else np.union1d(top, plate.sym_y + nc + 1)
        fixed[comp] = np.union1d(fixed.get(comp, np.array([], dtype=np.int64)), extra)
    both = CcxModel(nodes=np.vstack([cross.nodes, plate.nodes]),
                    elements=np.vstack([cross.elements, plate.elements + nc + 1]),
                    fixed=fixed, loads=np.vstack([cross.loads, np.zeros_like(plate.nodes)]),
                    dof_node=cross.dof_node, V=cross.V, flipped=cross.flipped + plate.flipped)
    # The spring sits on the crosshead's lowest node on x = 0, far from journal and fillet.
    on_sym = np.flatnonzero(np.abs(xyz[:, 0]) < tol)
    spring = int(on_sym[np.argmin(xyz[on_sym, 2] - 1e-3 * xyz[on_sym, 1])]) + 1
    return ContactModel(model=both, n_cross_nodes=nc, n_cross_elements=ec,
                        slave_faces=slave + [1, 0], master_faces=plate.bore_faces + [ec + 1, 0],
                        plate_top=top, spring_node=spring, spec=spec, plate=plate, facet_tags=facet_tags)


def _face_lines(faces: np.ndarray) -> list[str]:
    return [f"{e},S{s}" for e, s in faces.tolist()]


def penalty(spec: PlateSpec, E_MPa: float) -> float:
    """The penalty slope (MPa/mm) of ``spec``: its own, or 20·E / the bore's element size."""
    return spec.penalty_MPa_per_mm or 20.0 * E_MPa / spec.size_mm


def deck(cm: ContactModel, mat, increments: int = 4) -> str:
    """The CalculiX input deck of the contact model: bench.calculix's deck of both bodies
    with the contact surfaces, the spring and a nonlinear static step (``increments``
    equal increments: the load is applied gradually, the contact state found within each)."""
    ne = cm.model.elements.shape[0]
    spring_el = ne + 1
    k = penalty(cm.spec, mat.E)
    model_lines = ["*SURFACE, NAME=SJOURNAL, TYPE=ELEMENT", *_face_lines(cm.slave_faces),
                   "*SURFACE, NAME=SBORE, TYPE=ELEMENT", *_face_lines(cm.master_faces),
                   "*ELEMENT, TYPE=SPRING1, ELSET=ESPRING", f"{spring_el},{cm.spring_node}",
                   "*SPRING, ELSET=ESPRING", "3", f"{SPRING_N_PER_MM:.6f}",  # ccx needs the point
                   "*NSET, NSET=NPLATETOP", *[", ".join(map(str, cm.plate_top[i:i + 10].tolist()))
                                              for i in range(0, cm.plate_top.size, 10)],
                   "*SURFACE INTERACTION, NAME=SI",
                   "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", fmt(k)]
    if cm.spec.friction > 0:
        # Stick slope: the penalty's order (CalculiX's default would be used otherwise).
        model_lines += ["*FRICTION", f"{fmt(cm.spec.friction)},{fmt(k)}"]
    model_lines += ["*CONTACT PAIR, INTERACTION=SI, TYPE=SURFACE TO SURFACE", "SJOURNAL,SBORE"]
    dt = 1.0 / increments
    step = ["*STEP, INC=1000", "*STATIC", f"{fmt(dt)},1.0,{fmt(dt / 100)},{fmt(dt)}"]
    output = ["*NODE PRINT, NSET=NPLATETOP, TOTALS=ONLY", "RF",
              "*CONTACT FILE", "CSTR, CDIS"]
    return inp_text(cm.model, mat, title="crosshead in side-plate bores (contact)",
                    model_lines=model_lines, step_lines=step, output_lines=output)


def read_frd_contact(path: Path) -> dict[int, np.ndarray]:
    """The last CONTACT block of a CalculiX .frd file: node id (1-based) → (COPEN, CSLIP1,
    CSLIP2, CPRESS, CSHEAR1, CSHEAR2) (mm, MPa)."""
    lines = Path(path).read_text().splitlines()
    heads = [k for k, s in enumerate(lines) if s.startswith(" -4") and s.split()[1] == "CONTACT"]
    if not heads:
        raise NumericalError(f"no CONTACT block in {path}")
    out: dict[int, np.ndarray] = {}
    for s in lines[heads[-1] + 1:]:
        if s.startswith(" -3"):
            break
        if s.startswith(" -1"):
            # Fixed columns: " -1", the node id in 10, then values in 12 each.
            node = int(s[3:13])
            vals = [float(s[13 + 12 * i: 25 + 12 * i]) for i in range((len(s) - 13) // 12)]
            out[node] = np.array(vals)
    return out


def read_dat_totals(path: Path, title: str) -> list[np.ndarray]:
    """Each 'total' line after a header starting with ``title`` in a CalculiX .dat file
    (one per increment printed), as arrays of its numbers."""
    lines = Path(path).read_text().splitlines()
    out = []
    for k, s in enumerate(lines):
        if s.strip().startswith(title):
            for t in lines[k + 1:k + 6]:
                if t.strip():
                    out.append(np.array([float(v) for v in t.split()]))
                    break
    return out


@dataclass
class ContactSolution:
    """What the contact solve gives: the crosshead's displacement (DOLFINx P2, mm), the
    slave nodes' contact pressure (MPa), reactions (N) and times (s)."""

    u: object
    pressure: dict[int, float]           # crosshead node (1-based) → CPRESS, MPa
    gap: dict[int, float]                # crosshead node (1-based) → COPEN, mm
    plate_reaction_N: np.ndarray         # (3,) sum over the held top face
    spring_force_N: float
    attempts: int                        # increments CalculiX tried (a cut-back counts again)
    iterations: int                      # contact/equilibrium iterations over all of them
    timings: dict[str, float] = field(default_factory=dict)
    inp_path: Path | None = None


def solve_contact(cm: ContactModel, mat, threads: int = 1, workdir: Path | None = None,
                  increments: int = 4, ccx: str = "ccx") -> ContactSolution:
    """Write the deck, run CalculiX, read U (crosshead into DOLFINx), CPRESS and reactions."""
    from dolfinx import fem

    if shutil.which(ccx) is None:
        raise FileNotFoundError(f"{ccx}: CalculiX not found (Debian package calculix-ccx; tools/setup.sh installs it)")
    own = workdir is None
    wd = Path(tempfile.mkdtemp(prefix="ccx-contact-")) if own else Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    try:
        t0 = time.perf_counter()
        (wd / "job.inp").write_text(deck(cm, mat, increments))
        timings["write"] = time.perf_counter() - t0
        log, timings["ccx"], _ = run_job(wd, threads, ccx)
        t0 = time.perf_counter()
        n_all = cm.model.nodes.shape[0]
        U = read_dat_displacements(wd / "job.dat", n_all)
        u = fem.Function(cm.model.V, name="displacement_mm")
        u.x.array[:] = U[:cm.n_cross_nodes][cm.model.dof_node].ravel()
        u.x.scatter_forward()
        contact = read_frd_contact(wd / "job.frd")
        rf = read_dat_totals(wd / "job.dat", "total force (fx,fy,fz) for set NPLATETOP")
        timings["read"] = time.perf_counter() - t0
        uz_spring = U[cm.spring_node - 1, 2]
    finally:
        if own:
            shutil.rmtree(wd, ignore_errors=True)
    if not rf:
        raise NumericalError("contact model: no plate reaction in the .dat file")
    slave_nodes = set(np.unique(cm.model.elements[cm.slave_faces[:, 0] - 1][
        np.arange(len(cm.slave_faces))[:, None], C3D10_FACES[cm.slave_faces[:, 1] - 1]]).tolist())
    pressure = {n: float(v[3]) for n, v in contact.items() if n in slave_nodes}
    gap = {n: float(v[0]) for n, v in contact.items() if n in slave_nodes}
    return ContactSolution(u=u, pressure=pressure, gap=gap, plate_reaction_N=rf[-1][:3],
                           spring_force_N=float(-SPRING_N_PER_MM * uz_spring),
                           attempts=len(re.findall(r"^ *increment \d+ attempt \d+", log, re.M)),
                           iterations=len(re.findall(r"^ *iteration \d+", log, re.M)), timings=timings,
                           inp_path=None if own else wd / "job.inp")



# Degree-5 rule on the triangle (7 points, Dunavant): barycentric (a, b, c) and weights
# summing to 1/2, the reference triangle's area.
_A1, _B1 = 0.059715871789770, 0.470142064105115
_A2, _B2 = 0.797426985353087, 0.101286507323456
TRI7 = np.array([[1 / 3, 1 / 3, 1 / 3], [_A1, _B1, _B1], [_B1, _A1, _B1], [_B1, _B1, _A1],
                 [_A2, _B2, _B2], [_B2, _A2, _B2], [_B2, _B2, _A2]])
TRI7_W = np.array([0.225, *[0.132394152788506] * 3, *[0.125939180544827] * 3]) / 2


def _p2_triangle(l: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions of the 6-node triangle (corners, then mid-sides (0,1) (1,2) (2,0))
    at barycentric points ``l`` (n × 3), and their derivatives in (l1, l2) with l0 = 1 − l1 − l2."""
    a, b, c = l[:, 0], l[:, 1], l[:, 2]
    N = np.column_stack([a * (2 * a - 1), b * (2 * b - 1), c * (2 * c - 1), 4 * a * b, 4 * b * c, 4 * c * a])
    dN1 = np.column_stack([-(4 * a - 1), 4 * b - 1, 0 * a, 4 * (a - b), 4 * c, -4 * c])
    dN2 = np.column_stack([-(4 * a - 1), 0 * a, 4 * c - 1, -4 * b, 4 * b, 4 * (a - c)])
    return N, np.stack([dN1, dN2], axis=1)


@dataclass
class PressureSamples:
    """The contact pressure at the quadrature points of the journal's contact faces:
    position (mm), angle θ from straight down about the journal axis (degrees), pressure
    (MPa) and the area each point stands for (mm²)."""

    xyz: np.ndarray
    theta_deg: np.ndarray
    p_MPa: np.ndarray
    area_mm2: np.ndarray


def _face_points(cm: ContactModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The slave faces' quadrature points on their curved geometry (F × 7 × 3, mm), the
    area each stands for (F × 7, mm²), the shape-function values there (7 × 6) and the
    faces' nodes (F × 6, 1-based)."""
    els = cm.model.elements[cm.slave_faces[:, 0] - 1]
    fn = els[np.arange(len(els))[:, None], C3D10_FACES[cm.slave_faces[:, 1] - 1]]
    X = cm.model.nodes[fn - 1]
    N, dN = _p2_triangle(TRI7)
    pts = np.einsum("qk,fkj->fqj", N, X)
    t1 = np.einsum("qk,fkj->fqj", dN[:, 0], X)
    t2 = np.einsum("qk,fkj->fqj", dN[:, 1], X)
    area = np.linalg.norm(np.cross(t1, t2), axis=2) * TRI7_W
    return pts, area, N, fn


def _samples(pts: np.ndarray, area: np.ndarray, p: np.ndarray, d: Dimensions) -> PressureSamples:
    xyz = pts.reshape(-1, 3)
    theta = np.degrees(np.arctan2(xyz[:, 1], d.h3 / 2 - xyz[:, 2]))
    return PressureSamples(xyz=xyz, theta_deg=theta, p_MPa=p.ravel(), area_mm2=area.ravel())


def cpress_samples(cm: ContactModel, pressure: dict[int, float], d: Dimensions) -> PressureSamples:
    """CalculiX's nodal contact pressure (CPRESS) interpolated (quadratic, as the faces'
    geometry) to the 7 quadrature points of each slave face."""
    pts, area, N, fn = _face_points(cm)
    pv = np.array([[pressure.get(int(n), 0.0) for n in row] for row in fn])
    return _samples(pts, area, np.einsum("qk,fk->fq", N, pv), d)


def stress_samples(cm: ContactModel, u, mat, d: Dimensions) -> PressureSamples:
    """The normal pressure −n·σ·n of the crosshead's own stress (from its displacement
    ``u``, DG1 per element, unaveraged) at the slave faces' quadrature points, n the
    journal's outward radial direction: the pressure as the journal's material feels it,
    read by the pipeline's stress definition rather than CalculiX's contact output."""
    from dolfinx import fem

    from pipeline.api import stress

    mesh = u.function_space.mesh
    W = fem.TensorFunctionSpace(mesh, ("DG", 1))
    sig = fem.Function(W)
    sig.interpolate(fem.Expression(stress(u, mat), W.element.interpolation_points()))
    pts, area, _, _ = _face_points(cm)
    cells = np.repeat(cm.slave_faces[:, 0] - 1, pts.shape[1]).astype(np.int32)
    flat = pts.reshape(-1, 3)
    S = sig.eval(flat, cells).reshape(-1, 3, 3)
    n = np.column_stack([np.zeros(len(flat)), flat[:, 1], flat[:, 2] - d.h3 / 2])
    n /= np.linalg.norm(n, axis=1)[:, None]
    p = -np.einsum("ni,nij,nj->n", n, S, n)
    return _samples(pts, area, p.reshape(area.shape), d)


def nodal_contact_forces(cm: ContactModel, u, lc, mat) -> tuple[np.ndarray, np.ndarray]:
    """The forces (N) the plate puts on the crosshead's slave nodes, and those nodes (mm):
    the crosshead's out-of-balance nodal forces K·u − f_seat under CalculiX's displacement,
    assembled with CalculiX's C3D10 stiffness quadrature (degree 2), so that they vanish
    at every free node but the contact's. Their first moments are exact: the consistent
    nodal forces of any traction have the traction's resultant and moment."""
    import ufl
    from dolfinx import fem
    from dolfinx.fem.petsc import assemble_vector
    from petsc4py import PETSc

    from pipeline.api import strain, stress

    V = u.function_space
    mesh = V.mesh
    v = ufl.TestFunction(V)
    seat = seat_only(lc).tractions[0]
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=cm.facet_tags)
    dx = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 2})
    residual = ufl.inner(stress(u, mat), strain(v)) * dx - ufl.inner(seat.value, v) * ds(seat.marker)
    r = assemble_vector(fem.form(residual))
    r.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    R = r.array_r.reshape(-1, 3).copy()
    r.destroy()
    block_of = np.full(cm.n_cross_nodes, -1, dtype=np.int64)
    block_of[cm.model.dof_node] = np.arange(cm.model.dof_node.size)
    slave = np.unique(cm.model.elements[cm.slave_faces[:, 0] - 1][
        np.arange(len(cm.slave_faces))[:, None], C3D10_FACES[cm.slave_faces[:, 1] - 1]]) - 1
    return cm.model.nodes[slave], R[block_of[slave]]


def pressure_summary(s: PressureSamples, d: Dimensions, spec: PlateSpec, load_N: float,
                     n_theta: int = 10, n_x: int = 8) -> dict:
    """The pressure's resultant, centre, angular and axial distribution beside the cos θ
    model's (docs/design.md §3), for one journal of the quarter model (mm, N, MPa).

    - ``force_z_N``: the upward force of the pressure on the quarter's journal (Q/4 if
      the read-back is complete);
    - ``centre_x_mm`` and ``lever_mm``: the centre of the upward force along the journal,
      and its distance from the shoulder (the body's end face x = b1/2), which sets the
      journal's root bending moment; the cos θ model's are the middle of the bearing length;
    - ``theta``: per angle band (degrees from straight down) the mean pressure and the
      share of the upward force, beside the cos θ model's p0·cos θ and share;
    - ``axial``: per band along the journal the upward force per unit length (N/mm),
      beside the cos θ model's uniform Q/(2·Lj)·(1/2 in the quarter);
    - ``extent_deg``: the angle within which 99 % of the upward force acts;
    - ``p_max_MPa``: the largest pressure at a sample point; ``p0_MPa`` the cos θ model's.
    """
    x0, x1 = spec.x_range(d)
    xj0, xj1 = d.b1 / 2 + d.rf, d.b6 / 2
    rj, lj = d.dj / 2, xj1 - xj0
    q_quarter = load_N / 4
    cos_t = np.cos(np.radians(s.theta_deg))
    fz = s.p_MPa * cos_t * s.area_mm2                 # upward force of each sample, N
    total = float(fz.sum())
    centre = float((fz * s.xyz[:, 0]).sum() / total)
    p0 = load_N / (math.pi * rj * lj)
    edges = np.linspace(0.0, 90.0, n_theta + 1)
    theta_rows = []
    for a, b in zip(edges[:-1], edges[1:]):
        m = (s.theta_deg >= a) & (s.theta_deg < b) if b < 90 else (s.theta_deg >= a)
        area = s.area_mm2[m].sum()
        ra, rb = math.radians(a), math.radians(b)
        # The cos θ model over the band: mean pressure p0·(sin b − sin a)/(b − a) and the
        # share of the upward force ∫cos²θ dθ / (π/4) over the quarter's 0..90°.
        cos_share = ((rb - ra) / 2 + (math.sin(2 * rb) - math.sin(2 * ra)) / 4) / (math.pi / 4)
        theta_rows.append({"from_deg": float(a), "to_deg": float(b),
                           "p_mean_MPa": float((s.p_MPa[m] * s.area_mm2[m]).sum() / area) if area > 0 else 0.0,
                           "cos_model_p_mean_MPa": p0 * (math.sin(rb) - math.sin(ra)) / (rb - ra),
                           "force_share": float(fz[m].sum() / total),
                           "cos_model_force_share": cos_share})
    xs = np.linspace(xj0, xj1, n_x + 1)
    axial_rows = []
    for a, b in zip(xs[:-1], xs[1:]):
        m = (s.xyz[:, 0] >= a) & (s.xyz[:, 0] < b) if b < xs[-1] else (s.xyz[:, 0] >= a)
        axial_rows.append({"from_mm": float(a), "to_mm": float(b),
                           "force_per_mm_N": float(fz[m].sum() / (b - a)),
                           "cos_model_force_per_mm_N": q_quarter / lj})
    order = np.argsort(s.theta_deg)
    cum = np.cumsum(fz[order]) / total
    extent = float(s.theta_deg[order][np.searchsorted(cum, 0.99)])
    return {"force_z_N": total, "force_z_over_quarter_load": total / q_quarter,
            "centre_x_mm": centre, "lever_mm": centre - d.b1 / 2,
            "cos_model_centre_x_mm": (xj0 + xj1) / 2, "cos_model_lever_mm": (xj0 + xj1) / 2 - d.b1 / 2,
            "plate_x_mm": [x0, x1], "extent_deg": extent,
            "p_max_MPa": float(s.p_MPa.max()), "p0_MPa": p0,
            "theta": theta_rows, "axial": axial_rows}


def force_summary(xyz: np.ndarray, F: np.ndarray, d: Dimensions, load_N: float,
                  theta_edges_deg: tuple[float, ...] = (0, 15, 30, 45, 60, 75, 90.001)) -> dict:
    """The contact's resultant and centre from the slave nodes' forces (N, mm), beside the
    cos θ model's: ``force_z_N`` (Q/4 on the quarter's journal if equilibrium holds),
    ``centre_x_mm`` (exact: the first moment of consistent nodal forces is the traction's),
    ``lever_mm`` from the shoulder x = b1/2, and the share of the upward force in bands of
    θ (a band holds several elements, so the corner/mid-side split of a quadratic face's
    nodal forces averages out)."""
    fz = F[:, 2]
    total = float(fz.sum())
    centre = float((fz * xyz[:, 0]).sum() / total)
    theta = np.degrees(np.arctan2(xyz[:, 1], d.h3 / 2 - xyz[:, 2]))
    xj0, xj1 = d.b1 / 2 + d.rf, d.b6 / 2
    bands = []
    for a, b in zip(theta_edges_deg[:-1], theta_edges_deg[1:]):
        m = (theta >= a) & (theta < b)
        ra, rb = math.radians(a), math.radians(min(b, 90.0))
        cos_share = ((rb - ra) / 2 + (math.sin(2 * rb) - math.sin(2 * ra)) / 4) / (math.pi / 4)
        bands.append({"from_deg": float(a), "to_deg": float(min(b, 90.0)),
                      "force_share": float(fz[m].sum() / total), "cos_model_force_share": cos_share})
    return {"force_z_N": total, "force_z_over_quarter_load": total / (load_N / 4),
            "force_x_N": float(F[:, 0].sum()), "centre_x_mm": centre, "lever_mm": centre - d.b1 / 2,
            "cos_model_centre_x_mm": (xj0 + xj1) / 2, "cos_model_lever_mm": (xj0 + xj1) / 2 - d.b1 / 2,
            "theta": bands}
