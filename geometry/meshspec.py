"""What a mesh should be: element sizes (mm), order and refined places. No gmsh here:
case validation reads it without starting the mesher."""
from __future__ import annotations

from dataclasses import dataclass

from .table import RF_PER_H, Dimensions

HOTSPOT_SIZE = 0.4  # × the smaller of the feature and fillet sizes, at a pilot's stress peak
HOTSPOT_RADIUS = 0.024  # × h3 at rf = RF_PER_H·h3: how far that size holds around the peak (not scaled by factor)
FILLET_PER_RF = 0.25  # the fillet's element size, × rf


@dataclass(frozen=True)
class MeshSpec:
    """Mesh size controls, mm. ``factor`` scales every size together (refinement studies).

    size_body: size far from features; size_feature: size on the bore edges and the seat
    band edges; size_fillet: size on the shoulder fillets (the journal-root stress peak
    sits there); grading: distance over which sizes grow to size_body; order: geometric
    order of the elements (1 or 2).
    """

    size_body: float
    size_feature: float
    size_fillet: float
    grading: float
    factor: float = 1.0
    order: int = 2
    # Stress peaks found on a pilot mesh (mm, any quadrant: mirrored into all four):
    # size_hotspot within hotspot_radius of a place on the journal root
    # (geometry.places.at_journal_root), size_edge_hotspot within edge_hotspot_radius of
    # one elsewhere (the bore and seat edges), then growing like near the fillets.
    hotspots: tuple[tuple[float, float, float], ...] = ()
    size_hotspot: float = 0.0
    hotspot_radius: float = 0.0
    size_edge_hotspot: float = 0.0
    edge_hotspot_radius: float = 0.0

    @staticmethod
    def default_for(d: Dimensions, factor: float = 1.0, order: int = 2) -> "MeshSpec":
        """Sizes proportional to the part so every row meshes alike.

        The ratios were chosen for No. 05 by the convergence study (`make converge`). A
        refined place on the journal root takes its size from the fillet's (rf/10 with the
        default sizes); one elsewhere (the bore edges, where the critical peak sits) the
        size it has on the table's parts, where rf = RF_PER_H·h3, whatever this part's rf:
        the stress at the bore edge does not depend on the fillet, and tying its size to a
        small rf made it needlessly fine (rf = 0.5 mm on No. 05: 0.05 mm, 27 times the
        elements in each ball; docs/sweeps.md). The radius of a place on the journal root
        follows rf like its size (:func:`fillet_scale`): near the fillet the stress varies
        over lengths of rf, so a part with another rf is refined like a table row seen
        through a magnifying glass; the bore edges' radius stays HOTSPOT_RADIUS·h3.
        """
        fillet = FILLET_PER_RF * d.rf if d.rf > 0 else 0.02 * d.h3
        feature = 0.05 * d.h3
        return MeshSpec(size_body=0.16 * d.h3, size_feature=feature, size_fillet=fillet,
                        grading=0.4 * d.h3, factor=factor, order=order,
                        size_hotspot=HOTSPOT_SIZE * min(feature, fillet),
                        hotspot_radius=HOTSPOT_RADIUS * d.h3 * fillet_scale(d),
                        edge_hotspot_radius=HOTSPOT_RADIUS * d.h3,
                        size_edge_hotspot=HOTSPOT_SIZE * min(feature, FILLET_PER_RF * (RF_PER_H * d.h3)))


def fillet_scale(d: Dimensions) -> float:
    """rf over the fillet radius the refinement's lengths were chosen for, RF_PER_H·h3
    (1 on the table's rows whose rf is that, exactly; 1 for a sharp corner, rf = 0).

    The refined places on the journal root (their ball radius here, their spacing and
    rounding in pipeline.analysis.pilot) are those lengths × this ratio."""
    return d.rf / (RF_PER_H * d.h3) if d.rf > 0 else 1.0
