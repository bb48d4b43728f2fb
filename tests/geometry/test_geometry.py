"""Geometry: table row, validator, CAD volume against an independent volume, groups."""
import math
from dataclasses import replace

import gmsh
import pytest
from helpers.volumes import volume_by_quadrature

from geometry.part import build
from geometry.table import InputError, lookup, validate, with_overrides

D05 = lookup("05").dims


def test_no05_row_is_the_paper_table():
    row = lookup("05")
    d = row.dims
    assert (d.b1, d.b2, d.b6, d.d14, d.d2, d.h3) == (45, 12.5, 70, 31, 21, 25)
    assert (d.dj, d.rf, d.seat_inner, d.seat_outer) == (20, 1.5, 25, 37)   # docs/design.md §2 defaults
    assert row.load_N == 10_000 and "Imrak" in row.source


@pytest.mark.parametrize("model", ["quarter", "full"])
def test_cad_volume_matches_independent_volume(gmsh_session, model):
    build(D05, model)
    vol = sum(gmsh.model.occ.getMass(3, t) for _, t in gmsh.model.getEntities(3))
    assert vol == pytest.approx(volume_by_quadrature(D05, model), rel=1e-7)


@pytest.mark.parametrize("rf", [0.0, 0.5, 2.0])
def test_volume_with_other_fillets(gmsh_session, rf):
    d = validate(with_overrides(D05, rf=rf))
    build(d, "quarter")
    vol = sum(gmsh.model.occ.getMass(3, t) for _, t in gmsh.model.getEntities(3))
    assert vol == pytest.approx(volume_by_quadrature(d, "quarter"), rel=1e-7)


@pytest.mark.parametrize("model,names", [
    ("quarter", {"seat", "journal_bearing", "symmetry_x", "symmetry_y", "body", "constraint_points"}),
    ("full", {"seat", "journal_bearing", "body", "constraint_points"})])
def test_physical_groups_present_and_non_empty(gmsh_session, model, names):
    build(D05, model)
    found = {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        found[gmsh.model.getPhysicalName(dim, tag)] = gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
    assert set(found) == names
    assert all(len(v) > 0 for v in found.values())
    share = 0.25 if model == "quarter" else 1.0
    seat_area = sum(gmsh.model.occ.getMass(2, t) for t in found["seat"])
    assert seat_area == pytest.approx(share * math.pi / 4 * (37 ** 2 - 25 ** 2), rel=1e-9)
    # Lower half of each journal bearing cylinder: half the lateral area π·dj·(b2 − rf).
    bearing_area = sum(gmsh.model.occ.getMass(2, t) for t in found["journal_bearing"])
    assert bearing_area == pytest.approx(share * 2 * 0.5 * math.pi * 20 * 11, rel=1e-9)


@pytest.mark.parametrize("field,over", [
    ("d2", {"d2": 45.0}), ("d2", {"d2": 50.0}), ("seat_inner", {"seat_inner": 20.0}),
    ("seat_outer", {"seat_outer": 46.0}), ("dj, rf", {"dj": 24.0}), ("dj, rf", {"rf": 3.0, "dj": 19.0}),
    ("b6", {"b6": 71.0}), ("b1", {"b1": -45.0}), ("h3", {"h3": float("nan")}),
    ("b2", {"b2": float("inf")}), ("rf", {"rf": -1.0}), ("h3", {"h3": 0.0}),
])
def test_unbuildable_rows_name_the_field(field, over):
    d = with_overrides(D05, **over)
    with pytest.raises(InputError, match=rf"^{field}:"):
        validate(d)


@pytest.mark.slow
@pytest.mark.parametrize("factor", [2.0, 1.3])
def test_mesh_quality_agrees_with_gmsh(gmsh_session, factor):
    """builder.mesh's worst det J ratio (numpy, from the node positions after the curved-tet
    repair) is gmsh's own (getJacobians at the same sample points)."""
    from geometry.meshspec import MeshSpec
    from geometry.sizing import mesh
    from geometry.curved import jacobian_ratio
    d = lookup("05").dims
    build(d, "quarter")
    quality = mesh(d, MeshSpec.default_for(d, factor)).quality
    measured = jacobian_ratio()                        # gmsh's own getJacobians
    assert quality == pytest.approx(measured, abs=1e-9)
    assert 0.3 - 1e-9 <= measured < 1.0                # curved tets, repaired to the target


@pytest.mark.slow
def test_mesher_meshes_like_a_new_session():
    """meshing.Mesher builds the part once and meshes it for spec after spec (the pilot's
    mesh, then the refined ones). Each mesh must be, bit for bit, the one a new gmsh session
    makes (meshing.generate: build, mesh, finalise), whatever was meshed before it: the
    1- and 2-rank runs make their meshes in different orders on different ranks."""
    import numpy as np

    from geometry.meshspec import MeshSpec
    from pipeline.fe.meshing import Mesher, generate
    d = lookup("05").dims
    places = ((0.0, 10.5, 0.0), (23.25, 8.0, 6.25))           # as a pilot finds them (mm)
    specs = [MeshSpec.default_for(d, 4.0), replace(MeshSpec.default_for(d, 4.0), hotspots=places),
             MeshSpec.default_for(d, 6.0)]
    with Mesher(d, "quarter") as m:
        reused = [m.generate(s) for s in specs]
    assert len({len(r.cells) for r in reused}) == 3          # three different meshes
    for spec, r in zip(specs, reused, strict=True):
        new = generate(d, "quarter", spec)
        for key in ("x", "cells", "cell_values", "facets", "facet_values"):
            assert np.array_equal(getattr(new, key), getattr(r, key)), (spec.factor, spec.hotspots, key)
        assert new.quality == r.quality and new.names == r.names


def _tets_near_places(rf: float):
    """No. 05 with fillet radius ``rf`` (mm) meshed at factor 2 with a refined place at the
    bore edge and one on the journal root (45° into the fillet, at its lowest, as a pilot
    finds them): (dims, spec, the two places, each tet's centroid (mm),
    each tet's six edge lengths (mm))."""
    import numpy as np

    from geometry.meshspec import MeshSpec
    from pipeline.fe.meshing import generate
    d = with_overrides(lookup("05").dims, rf=rf)
    s = rf * (1 - math.sqrt(0.5))
    bore, fillet = (0.0, d.d2 / 2, 0.0), (d.b1 / 2 + s, 0.0, d.h3 / 2 - d.dj / 2 - s)
    spec = replace(MeshSpec.default_for(d, 2.0), hotspots=(bore, fillet))
    part = generate(d, "quarter", spec)
    corners = part.x[part.cells[:, :4]]                       # (tets, 4, 3), mm
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    edges = np.stack([np.linalg.norm(corners[:, i] - corners[:, j], axis=1) for i, j in pairs], axis=1)
    return d, spec, bore, fillet, corners.mean(axis=1), edges


def _median_edge(centroid, edges, place, r_min: float, r_max: float) -> float:
    """The median tet edge (mm) of the tets whose centroid lies r_min..r_max mm from ``place``."""
    import numpy as np
    dist = np.linalg.norm(centroid - np.asarray(place), axis=1)
    near = (dist >= r_min) & (dist < r_max)
    assert near.sum() >= 20, (place, r_min, r_max)
    return float(np.median(edges[near]))


@pytest.mark.slow
@pytest.mark.parametrize("rf, expected_ratio", [(1.5, 1.0), (0.5, 3.0)])
def test_refined_place_takes_the_size_of_its_feature(rf, expected_ratio):
    """A refined place on the journal root is meshed at the fillet's hot-spot size (rf/10),
    one at the bore edge at the size it has on the table's parts (0.006·h3), whatever rf
    is: with rf = 0.5 mm on No. 05 the bore's tets are three times the fillet's, with No.
    05's own rf = 1.5 mm both are 0.15 mm. Measured on the mesh gmsh makes: the median
    length of the tet edges within 0.8 of each place's ball radius."""
    d, spec, bore, fillet, centroid, edges = _tets_near_places(rf)
    h_bore = _median_edge(centroid, edges, bore, 0.0, 0.8 * spec.edge_hotspot_radius)
    h_fillet = _median_edge(centroid, edges, fillet, 0.0, 0.8 * spec.hotspot_radius)
    assert h_bore / h_fillet == pytest.approx(expected_ratio, rel=0.25)
    assert h_bore == pytest.approx(2.0 * 0.006 * d.h3, rel=0.35)   # × the factor 2


@pytest.mark.slow
def test_refinement_on_the_journal_root_scales_with_rf():
    """Around a refined place on the journal root the mesh at rf = 0.5 mm is the mesh at
    rf = 1.5 mm (No. 05's own) shrunk by 3: the tets 1.5–2.5 rf from the place, outside
    its ball (0.4 rf), are as many times larger than those inside it at both radii (3.6
    and 3.4 when written). With a ball of fixed radius (0.6 mm, 0.024·h3) the ratio at
    rf = 0.5 mm was 2.3: part of that shell lay inside the ball. The bore edge's ball
    keeps 0.6 mm at both."""
    ratios = []
    for rf in (0.5, 1.5):
        _, spec, _, fillet, centroid, edges = _tets_near_places(rf)
        assert spec.hotspot_radius == pytest.approx(0.4 * rf)
        assert spec.edge_hotspot_radius == pytest.approx(0.6)
        inside = _median_edge(centroid, edges, fillet, 0.0, 0.8 * spec.hotspot_radius)
        shell = _median_edge(centroid, edges, fillet, 1.5 * rf, 2.5 * rf)
        ratios.append(shell / inside)
    assert ratios[0] == pytest.approx(ratios[1], rel=0.15)
    assert min(ratios) > 2.8, ratios
