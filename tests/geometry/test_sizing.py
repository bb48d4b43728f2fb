"""geometry.sizing.mesh meshes in timed stages: the same mesh as gmsh's own one-call
generate(3), every stage timed, gmsh's options left as they were."""
import hashlib
import math
from dataclasses import replace

import gmsh
import numpy as np
import pytest

from geometry import sizing
from geometry.meshspec import MeshSpec
from geometry.part import build
from geometry.table import lookup

D05 = lookup("05").dims
PLACES = ((0.0, 10.5, 0.0), (23.25, 8.0, 6.25))  # mm, as a pilot finds them on No. 05


def _digest() -> tuple[int, str]:
    """Number of nodes and a digest of their coordinates and of the tets' nodes."""
    _, xyz, _ = gmsh.model.mesh.getNodes()
    _, _, nodes = gmsh.model.mesh.getElements(3)
    h = hashlib.sha1(np.asarray(xyz).tobytes() + np.asarray(nodes[0]).tobytes()).hexdigest()
    return len(xyz) // 3, h


def _mesh(spec: MeshSpec, staged: bool, monkeypatch) -> tuple[tuple[int, str], dict]:
    """Mesh No. 05 in a new session, staged (sizing's path) or by one generate(3) (gmsh's
    own path, under the options sizing sets), both without the project's curved-tet repair
    (not gmsh's, so not part of the comparison); the mesh's digest and the stage times."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        build(D05, "quarter")
        with monkeypatch.context() as m:
            m.setattr(sizing, "ensure_curved_quality", lambda order: 1.0)
            if not staged:
                m.setattr(sizing, "_generate_by_stage", lambda order: (gmsh.model.mesh.generate(3) or {}, {}))
            done = sizing.mesh(D05, spec)
        return _digest(), done.stage_cpu_s
    finally:
        gmsh.finalize()


@pytest.mark.slow
def test_staged_mesh_is_gmshs_one_call_mesh(monkeypatch):
    """The stages (one linear generate(3), then gmsh's Optimize pass, then setOrder) give
    gmsh's one-call generate(3) mesh node for node, and every stage is timed."""
    spec = replace(MeshSpec.default_for(D05, 3.0), hotspots=PLACES, size_hotspot=0.5, hotspot_radius=0.6,
                   size_edge_hotspot=0.5, edge_hotspot_radius=0.6)
    staged, stage_cpu_s = _mesh(spec, True, monkeypatch)
    one_call, _ = _mesh(spec, False, monkeypatch)
    assert staged[0] > 1000
    assert staged == one_call
    assert set(stage_cpu_s) == set(sizing.STAGES) and all(t >= 0.0 for t in stage_cpu_s.values())


@pytest.mark.slow
def test_stages_leave_gmshs_options_as_set(gmsh_session):
    """The order, optimisation and high-order options are back at their values after a mesh."""
    build(D05, "quarter")
    sizing.mesh(D05, MeshSpec.default_for(D05, 4.0), {"Mesh.HighOrderOptimize": 0})
    assert gmsh.option.getNumber("Mesh.ElementOrder") == 2
    assert gmsh.option.getNumber("Mesh.Optimize") == 1   # gmsh's default, which the project keeps
    assert gmsh.option.getNumber("Mesh.HighOrderOptimize") == 0


def test_box_distance_is_the_euclidean_distance_to_the_box():
    box = (0.0, 0.0, 0.0, 35.0, 22.5, 25.0)
    assert sizing._box_distance((10.0, 5.0, 3.0), box) == 0.0          # inside
    assert sizing._box_distance((-3.0, 5.0, 3.0), box) == pytest.approx(3.0)
    assert sizing._box_distance((-3.0, -4.0, 30.0), box) == pytest.approx(math.sqrt(9 + 16 + 25))


@pytest.mark.slow
def test_balls_left_out_do_not_change_the_mesh(monkeypatch):
    """Leaving out the mirror images that cannot reach the part gives the mesh of every
    image kept (a distance of 0 to the part keeps them all), node for node."""
    spec = replace(MeshSpec.default_for(D05, 3.0), hotspots=PLACES, size_hotspot=0.5, hotspot_radius=0.6,
                   size_edge_hotspot=0.5, edge_hotspot_radius=0.6)
    counts, got = zip(*(_mesh_counting_balls(monkeypatch, "quarter", spec, keep_all) for keep_all in (False, True)))
    counts = list(counts)
    # (0, 10.5, 0) has 2 images, both within reach; (23.25, 8, 6.25) has 4, and those at
    # x = -23.25 lie 23.25 and 24.6 mm from the part, beyond radius + thickness =
    # 0.6 + (12 - 1.5) / 0.5 = 21.6 mm (sizes x 3: hmax 0.16 h3 x 3 = 12 mm, h_s 1.5 mm).
    assert counts == [4, 6]
    assert got[0] == got[1]


def _mesh_counting_balls(monkeypatch, model: str, spec: MeshSpec, keep_all: bool = False) -> tuple[int, tuple[int, str]]:
    """No. 05's ``model`` meshed to ``spec`` in a gmsh session of its own: the number of
    Ball fields made and the mesh's digest. ``keep_all``: every mirror image is taken to
    reach the part (a distance of 0), so none is left out."""
    gmsh.initialize(readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        build(D05, model)
        made: list[int] = []
        balls = sizing._balls

        def counted(*args) -> list[int]:
            tags = balls(*args)
            made.extend(tags)
            return tags
        with monkeypatch.context() as m:
            if keep_all:
                m.setattr(sizing, "_box_distance", lambda p, box: 0.0)
            m.setattr(sizing, "_balls", counted)
            sizing.mesh(D05, spec)
        return len(made), _digest()
    finally:
        gmsh.finalize()


@pytest.mark.slow
def test_a_place_and_its_mirror_image_make_one_set_of_balls(monkeypatch):
    """The full part's pilot finds a place and its mirror images: their Balls are made once,
    and the mesh is the one of the place alone (the Balls mirror every place anyway)."""
    p = PLACES[1]
    mirrored = (p, (-p[0], p[1], p[2]), (p[0], -p[1], p[2]))
    specs = [replace(MeshSpec.default_for(D05, 4.0), hotspots=places, size_hotspot=0.5, hotspot_radius=0.6,
                     size_edge_hotspot=0.5, edge_hotspot_radius=0.6) for places in ((p,), mirrored)]
    calls, got = zip(*(_mesh_counting_balls(monkeypatch, "full", spec) for spec in specs))
    calls = list(calls)
    assert calls == [4, 4]        # the four images of one place, in the full part all within reach
    assert got[0] == got[1]
