"""The fillet's midpoint read node by node against the midpoint of the fillet's two maxima
(docs/decisions/0035-reported-value-node-by-node.md), on the same meshes (mm, MPa):

    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.reading_rule --size 05 --mesh-factors 0.8,0.9,1.0,1.1,1.2,1.3
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.reading_rule --others

For each part and mesh factor F: the pilot's places as a run finds them, then the meshes a
run with ``--mesh-factor F --no-sensitivity`` solves for its error bar (F, F·1.3, F·1.69,
and the smaller step's F·√1.3 where a rule's first band is above the tolerance), each
solved once and read both ways:

- *maxima* (``old``): the fillet's value is the midpoint of its largest element-node value
  and its largest averaged value, wherever each sits; elsewhere the largest element-node
  value; the global peak is the larger;
- *node by node* (``new``): at every node the midpoint of that node's largest element-node
  value and its averaged value on the fillet, the element-node value elsewhere; the peak is
  the largest over the nodes (pipeline.post.peaks.node_peak).

Each rule's error bar is the run's (pipeline.post.errorbar.estimate_levels, a midpoint's
band at least its half gap), its meshes chosen by the run's tolerance steps for a pinned
mesh. ``--others``: the parts of tests/verification/test_regression.py's OTHER_PARTS on the
default path's three meshes ×1, ×1.3, ×1.69 (as that test solves them). Prints a table and
the references each band covers; ``--out FILE`` keeps the rows as JSON. One rank.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

RATIO = 1.3
TOLERANCE_PCT = 1.0
# Independent references (MPa): docs/fillet-reference.md (make reference) and docs/accuracy.md (P3).
REFERENCES = {("05", ()): (113.82, 66.27)}
OTHER_PARTS = [   # tests/verification/test_regression.py: (size, dimension overrides, global reference MPa)
    ("1.6", {}, 114.30),
    ("05", {"dims.rf": 0.5, "dims.dj": 16.0}, 275.86),
    ("05", {"dims.rf": 0.3}, 228.12),
]


def old_rule(r, fillet_mask: np.ndarray, region: np.ndarray | None = None):
    """The fillet read by the midpoint of its two maxima, every other place by its largest
    element-node value, the larger of the two (within ``region``, a mask of r's nodes)."""
    from pipeline.api import MIDPOINT, UNAVERAGED, NodalPeak, Peak
    inside = np.ones(len(r.xyz), dtype=bool) if region is None else region

    def reading(mask: np.ndarray, rule: str):
        if not mask.any():
            return None
        iu, ia = (int(np.flatnonzero(mask)[np.argmax(v[mask])]) for v in (r.unaveraged, r.averaged))
        return NodalPeak(Peak(float(r.unaveraged[iu]), tuple(r.xyz[iu])), Peak(float(r.averaged[ia]), tuple(r.xyz[ia])),
                         rule)
    found = [p for p in (reading(inside & fillet_mask, MIDPOINT), reading(inside & ~fillet_mask, UNAVERAGED)) if p]
    return max(found, key=lambda p: p.value_MPa)


def read_level(case, lv, mat) -> dict:
    """One solved mesh read both ways: {rule: SimpleNamespace(dofs, peak, critical)}."""
    from pipeline.api import critical_region, fillet_region, node_peak, node_readings
    u, vm = lv.fields
    fillet = fillet_region(case)
    r = node_readings(u, mat, fillet, vm)
    crit = critical_region(case)(r.xyz)
    return {"old": SimpleNamespace(factor=lv.factor, dofs=lv.dofs, peak=old_rule(r, r.midpoint),
                                   critical=old_rule(r, r.midpoint, crit)),
            "new": SimpleNamespace(factor=lv.factor, dofs=lv.dofs, peak=node_peak(r),
                                   critical=node_peak(r, critical_region(case)))}


def band_pct(case, levels, attr: str) -> float | None:
    from pipeline.api import estimate_levels
    est = estimate_levels(levels, case.order, attr)
    return None if est.band is None else 100.0 * est.band / abs(getattr(levels[0], attr).value_MPa)


def half_gap_pct(level) -> float:
    from pipeline.api import MIDPOINT
    return max([100.0 * p.half_width_MPa / abs(p.value_MPa) for p in (level.peak, level.critical)
                if p.rule == MIDPOINT], default=0.0)


def chosen(case, read, factor: float, rule: str, steps: bool) -> list:
    """The error bar's levels under ``rule``: the first set F, F·r, F·r², then (``steps``,
    a pinned mesh) the smaller step F, F·√r, F·r where a band is above the tolerance and the
    requested mesh's half gap is not (pipeline/analysis/tolerance.py)."""
    first = [read(factor * RATIO ** k)[rule] for k in range(3)]
    within = all(b is not None and b <= TOLERANCE_PCT for b in (band_pct(case, first, a) for a in ("peak", "critical")))
    if not steps or within or half_gap_pct(first[0]) > TOLERANCE_PCT:
        return first
    return [first[0], read(factor * math.sqrt(RATIO))[rule], first[1]]


def estimate_row(case, levels, references: tuple[float | None, float | None]) -> dict:
    """Both peaks' values, bands and statuses over ``levels`` and whether each band covers its reference."""
    from pipeline.api import estimate_levels
    row = {"factors": [lv.factor for lv in levels], "dofs": [lv.dofs for lv in levels]}
    for attr, ref in zip(("peak", "critical"), references):
        p = getattr(levels[0], attr)
        est = estimate_levels(levels, case.order, attr)
        row[attr] = {"value_MPa": p.value_MPa, "location_mm": list(p.location_mm), "rule": p.rule,
                     "unaveraged_MPa": p.unaveraged.value_MPa, "averaged_MPa": p.averaged.value_MPa,
                     "readings_apart_mm": math.dist(p.unaveraged.location_mm, p.averaged.location_mm),
                     "band_MPa": est.band, "status": est.status, "reference_MPa": ref,
                     "covers": None if ref is None or est.band is None else abs(p.value_MPa - ref) <= est.band,
                     "levels_MPa": [getattr(lv, attr).value_MPa for lv in levels]}
    return row


def measure(size: str, dims: dict, factor: float | None, references, steps: bool) -> dict:
    """Both rules on one part at mesh ``factor`` (None: the default path's ×1, not pinned)."""
    from pipeline.api import LevelTask, Material, pilot, resolve_case, solve_level
    overrides = dict(dims, **({} if factor is None else {"mesh_factor": factor}))
    case = resolve_case(size, overrides=overrides)
    places = pilot(case)
    mat = Material(E=case.E_MPa, nu=case.nu)
    solved: dict[float, dict] = {}

    def read(f: float) -> dict:
        key = round(f, 9)
        if key not in solved:
            lv = solve_level(case, LevelTask(f, hotspots=places.hotspots, keep_fields=True))
            solved[key] = read_level(case, lv, mat)
        return solved[key]
    row = {"size": size, "dims": dims, "mesh_factor": case.mesh_factor, "places": len(places.hotspots)}
    for rule in ("old", "new"):
        row[rule] = estimate_row(case, chosen(case, read, case.mesh_factor, rule, steps), references)
    row["meshes_solved"] = sorted(solved)
    return row


def line(row: dict) -> str:
    def pk(side: dict, key: str) -> str:
        p = side[key]
        band = "none" if p["band_MPa"] is None else f"{p['band_MPa']:.2f}"
        cover = "" if p["covers"] is None else (" covers" if p["covers"] else " MISSES")
        return f"{p['value_MPa']:.3f} ± {band} ({p['status']}{cover})"
    o, n = row["old"], row["new"]
    return (f"{row['size']} {row['dims'] or ''} ×{row['mesh_factor']:g}: meshes "
            f"{'/'.join(f'{f:.4g}' for f in n['factors'])}; global old {pk(o, 'peak')} new {pk(n, 'peak')} "
            f"[{100 * (n['peak']['value_MPa'] / o['peak']['value_MPa'] - 1):+.3f} %, readings "
            f"{o['peak']['readings_apart_mm']:.2f} mm apart]; critical old {pk(o, 'critical')} new {pk(n, 'critical')}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.reading_rule", description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="05")
    ap.add_argument("--mesh-factors", default="", help="pinned mesh factors, e.g. 0.8,0.9,1.0")
    ap.add_argument("--others", action="store_true", help="OTHER_PARTS of the regression tests, default path")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = ap.parse_args(argv)
    rows = []
    for f in (float(x) for x in args.mesh_factors.split(",") if x.strip()):
        rows.append(measure(args.size, {}, f, REFERENCES.get((args.size, ()), (None, None)), steps=True))
        print(line(rows[-1]), flush=True)
    for size, dims, ref in OTHER_PARTS if args.others else ():
        rows.append(measure(size, dims, None, (ref, None), steps=False))
        print(line(rows[-1]), flush=True)
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
