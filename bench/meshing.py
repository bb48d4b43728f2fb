"""gmsh's options against meshing time and peaks: each option set meshes No. 05 (×1, ×1.69)
and the full part (cases/05-full.toml at its own factor) on the pilot's refined places.

    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.meshing --repeats 5 --out /tmp/meshing.json
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.meshing --peaks --variants default,3d-hxt --factors 0.85,1
    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.meshing --volumes --repeats 3

Timing (the default): every mesh in a gmsh session of its own, the part built first and
not timed; the option sets interleaved (each repeat runs every set once, in an order
rotated by one each repeat) so that the other load on the machine falls on all alike.
Prints per set and mesh the median CPU time (s) of each of gmsh's stages
(geometry.sizing.STAGES), the sum's CPU and wall time, their ratios to the default set's
(the median of each round's pair), the P2 DOFs and whether the mesh is the default's node
for node. ``--peaks``: each set's No. 05 run
(pilot, the ×1 mesh and its error bar, one rank) with the set's options on every mesh:
global and critical peaks and bands (MPa) against the references 113.82 / 66.27 MPa.
``--volumes``: what meshing the part's 3-D volumes on several ranks could save, a bound:
every mesh meshed whole (geometry.sizing.mesh) and, in a session of its own, with its
volumes' 3-D meshes made one at a time after the whole surface mesh (the others hidden,
Mesh.MeshOnlyVisible), the rest of geometry.sizing.mesh unchanged; per volume its tets and
3-D CPU time, and the CPU time on 2 ranks if only the 3-D stage were split (the volumes
over the ranks longest first) as a ratio to the one-rank total.
Lengths in mm, times in s, stresses in MPa. Results go to stdout, progress to stderr.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import gmsh
import numpy as np
from mpi4py import MPI

# Option sets: gmsh options set after the project's own (geometry.sizing._set_mesh_options).
VARIANTS: dict[str, dict[str, float]] = {
    "default": {},
    "no-optimise": {"Mesh.Optimize": 0},
    "netgen": {"Mesh.OptimizeNetgen": 1},
    "2d-delaunay": {"Mesh.Algorithm": 5},
    "2d-meshadapt": {"Mesh.Algorithm": 1},
    "3d-hxt": {"Mesh.Algorithm3D": 10},
    "3d-hxt-2threads": {"Mesh.Algorithm3D": 10, "General.NumThreads": 2, "Mesh.MaxNumThreads3D": 2},
    "2threads": {"General.NumThreads": 2, "Mesh.MaxNumThreads1D": 2, "Mesh.MaxNumThreads2D": 2},
    "from-boundary": {"Mesh.MeshSizeExtendFromBoundary": 1},
    "ho-fastcurving": {"Mesh.HighOrderOptimize": 4},
    "order-straight": {"Mesh.SecondOrderLinear": 1},
    "2d-delaunay+3d-hxt": {"Mesh.Algorithm": 5, "Mesh.Algorithm3D": 10},
}
REFERENCES_MPA = {"peak": 113.82, "critical": 66.27}  # No. 05 at 10 kN (docs/accuracy.md)


def meshes(factors: list[float], full: bool) -> list[tuple[str, object, float]]:
    """(label, case, factor) of each mesh to time: No. 05 at ``factors``, and the full part
    at its case file's factor."""
    from pipeline.api import resolve_case as resolve
    out = [(f"05 ×{f:g}", resolve("05"), f) for f in factors]
    if full:
        case = resolve(case_file=Path(__file__).resolve().parent.parent / "cases" / "05-full.toml")
        out.append((f"05-full ×{case.mesh_factor:g}", case, case.mesh_factor))
    return out


def places(case) -> tuple[tuple[float, float, float], ...]:
    """The pilot's refined places of ``case`` (mm), as a run finds them (one rank)."""
    from pipeline.api import RunContext, pilot
    return pilot(case, RunContext(comm=MPI.COMM_SELF)).hotspots


def time_one(case, spec, options: dict[str, float]) -> dict:
    """Build the part in a new gmsh session and mesh it under ``options``: stage wall and CPU times (s),
    P2 DOFs, a digest of the node coordinates and the worst det J ratio."""
    from geometry.part import build
    from geometry.sizing import mesh
    from pipeline.api import normalised, meshing_scale

    dn, spec_n = normalised(case.dims, spec, meshing_scale(case.dims))
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("bench")
        build(dn, case.model)
        done = mesh(dn, spec_n, options)
        _, xyz, _ = gmsh.model.mesh.getNodes()
        types, tags, _ = gmsh.model.mesh.getElements(3)
        tets = sum(len(t) for t in tags)
    finally:
        gmsh.finalize()
    xyz = np.round(np.asarray(xyz), 9)
    return {"stage_s": done.stage_s, "stage_cpu_s": done.stage_cpu_s, "total_s": sum(done.stage_s.values()),
            "total_cpu_s": sum(done.stage_cpu_s.values()), "dofs": 3 * (len(xyz) // 3),
            "tets": tets, "digest": hashlib.sha1(xyz.tobytes()).hexdigest()[:12], "quality": done.quality}


def timing(names: list[str], factors: list[float], full: bool, repeats: int) -> list[dict]:
    """Every option set on every mesh, ``repeats`` rounds, the sets' order rotated each round."""
    targets = []
    for label, case, f in meshes(factors, full):
        hot = places(case)
        targets.append((label, case, replace(case.mesh_spec(f), hotspots=hot)))
        print(f"{label}: {len(hot)} places", file=sys.stderr)
    runs: dict[tuple[str, str], list[dict]] = {}
    for r in range(repeats):
        order = names[r % len(names):] + names[:r % len(names)]
        for label, case, spec in targets:
            for name in order:
                try:
                    runs.setdefault((label, name), []).append(time_one(case, spec, VARIANTS[name]))
                except Exception as exc:  # a set gmsh cannot mesh with is a result, not a stop
                    runs.setdefault((label, name), []).append({"error": str(exc)})
                last = runs[(label, name)][-1]
                print(f"round {r + 1} {label} {name}: " + (last["error"] if "error" in last else
                      f"{last['total_s']:.2f} s wall, {last['total_cpu_s']:.2f} s CPU"), file=sys.stderr)
    rows = []
    for (label, name), got in runs.items():
        ok = [g for g in got if "error" not in g]
        if not ok:
            rows.append({"mesh": label, "variant": name, "error": got[0]["error"]})
            continue
        row = {"mesh": label, "variant": name, "runs": len(ok), "dofs": ok[0]["dofs"], "tets": ok[0]["tets"],
               "quality": ok[0]["quality"], "digests": sorted({g["digest"] for g in ok})}
        for key in ("stage_s", "stage_cpu_s"):
            row[key] = {k: statistics.median(g[key][k] for g in ok) for k in ok[0][key]}
        for key in ("total_s", "total_cpu_s"):
            row[key] = statistics.median(g[key] for g in ok)
            base = runs.get((label, "default"), [])
            # Ratios of the same round's pair (interleaved), then their median.
            pairs = [g[key] / b[key] for g, b in zip(got, base) if "error" not in g and "error" not in b]
            if pairs:
                row[key.replace("total", "ratio")] = statistics.median(pairs)
        if base and "error" not in base[0]:
            row["same_mesh"] = row["digests"] == sorted({b["digest"] for b in base if "error" not in b})
        rows.append(row)
    return rows


def _sorted_digest() -> str:
    """A digest of the current mesh's node coordinates (mm, to 1e-9) in sorted order: the
    same mesh, node for node, whatever order its nodes were made in."""
    _, xyz, _ = gmsh.model.mesh.getNodes()
    xyz = np.round(np.asarray(xyz).reshape(-1, 3), 9)
    return hashlib.sha1(xyz[np.lexsort(xyz.T[::-1])].tobytes()).hexdigest()[:12]


def _tet_keys() -> set[bytes]:
    """The current mesh's tets as the digests of their corner coordinates (mm, to 1e-9,
    sorted): the same set for the same tets, whatever their nodes' and elements' tags."""
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    xyz = np.round(np.asarray(xyz).reshape(-1, 3), 9)
    index = np.zeros(int(tags.max()) + 1, dtype=int)
    index[tags] = np.arange(len(tags))
    keys = set()
    for nodes in gmsh.model.mesh.getElements(3)[2]:
        corners = xyz[index[np.asarray(nodes).reshape(-1, 4)]]                # tets × 4 × 3
        corners = np.take_along_axis(corners, np.lexsort(corners.transpose(2, 0, 1)[::-1])[..., None], axis=1)
        keys.update(hashlib.sha1(c.tobytes()).digest() for c in corners)
    return keys


def _recording(per_volume: list[dict], linear: dict, split: bool):
    """A stand-in for gmsh.model.mesh.generate that records, after generate(3), each
    volume's tag and tets in ``per_volume`` and the linear mesh's tets, sorted digest and
    tet keys (:func:`_tet_keys`) in ``linear``. ``split``: generate(3) becomes the surface mesh once (generate(2)), then each
    volume's 3-D mesh alone, the others hidden (Mesh.MeshOnlyVisible), its CPU time (s)
    recorded too."""
    generate = gmsh.model.mesh.generate

    def tets(tag: int) -> int:
        return sum(len(t) for t in gmsh.model.mesh.getElements(3, tag)[1])

    def recorded(dim: int = 3) -> None:
        if dim < 3 or not split:
            generate(dim)
            if dim == 3:
                per_volume.extend({"volume": tag, "tets": tets(tag)} for _, tag in gmsh.model.getEntities(3))
        else:
            generate(2)
            volumes = gmsh.model.getEntities(3)
            gmsh.option.setNumber("Mesh.MeshOnlyVisible", 1)
            try:
                for _, tag in volumes:
                    gmsh.model.setVisibility(volumes, 0)
                    gmsh.model.setVisibility([(3, tag)], 1)
                    c0 = time.process_time()
                    generate(3)
                    per_volume.append({"volume": tag, "tets": tets(tag), "cpu_s": time.process_time() - c0})
            finally:
                gmsh.option.setNumber("Mesh.MeshOnlyVisible", 0)
                gmsh.model.setVisibility(volumes, 1)
        if dim == 3:
            linear.update(tets=tets(-1), digest=_sorted_digest(), keys=_tet_keys())
    return recorded


def volumes_one(case, spec, split: bool) -> dict:
    """Build the part in a new gmsh session and mesh it (geometry.sizing.mesh), whole or
    with its volumes' 3-D meshes made one at a time (``split``): stage CPU times (s), per
    volume its tets (and, split, its 3-D CPU time, s), the sorted node digest."""
    from geometry.part import build
    from geometry.sizing import mesh
    from pipeline.api import normalised, meshing_scale

    dn, spec_n = normalised(case.dims, spec, meshing_scale(case.dims))
    per_volume: list[dict] = []
    linear: dict = {}
    generate = gmsh.model.mesh.generate
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("bench")
        build(dn, case.model)
        gmsh.model.mesh.generate = _recording(per_volume, linear, split)
        try:
            done = mesh(dn, spec_n)
        finally:
            gmsh.model.mesh.generate = generate
        stage_cpu_s = dict(done.stage_cpu_s)
        if split:  # gmsh's log holds one 3-D time per volume: the stage is their sum
            stage_cpu_s["3d"] = sum(v["cpu_s"] for v in per_volume)
        digest = _sorted_digest()
    finally:
        gmsh.finalize()
    return {"stage_cpu_s": stage_cpu_s, "total_cpu_s": sum(stage_cpu_s.values()), "per_volume": per_volume,
            "linear": linear, "digest": digest}


def lpt(costs: dict[int, float], ranks: int) -> list[list[int]]:
    """The keys of ``costs`` over ``ranks`` ranks, longest first, each to the least loaded
    (pipeline.fe.meshing.owners, how a run hands out its meshes); each rank's in that order."""
    from pipeline.api import owners
    order = sorted(costs, key=lambda k: -costs[k])
    who = owners([costs[k] for k in order], ranks)
    return [[k for k, r in zip(order, who) if r == rank] for rank in range(ranks)]


def volumes(factors: list[float], full: bool, repeats: int, ranks: int = 2) -> list[dict]:
    """Every mesh whole and volume by volume, ``repeats`` rounds of the pair; per mesh the
    medians and the bound on ``ranks`` ranks: the stages but the 3-D one (made once on
    every rank) plus the largest rank's share of the volumes' 3-D CPU time, over the
    one-rank total of the same split session; and the same with optimise, order and repair
    split too, in proportion to the rank's tets (their ideal, not gmsh's: they are whole-
    mesh calls)."""
    rows = []
    for label, case, f in meshes(factors, full):
        spec = replace(case.mesh_spec(f), hotspots=places(case))
        runs: dict[bool, list[dict]] = {False: [], True: []}
        for r in range(repeats):
            for split in ((False, True) if r % 2 == 0 else (True, False)):
                runs[split].append(volumes_one(case, spec, split))
                last = runs[split][-1]
                print(f"round {r + 1} {label} {'by volume' if split else 'whole'}: {last['total_cpu_s']:.2f} s CPU, "
                      f"3-D {last['stage_cpu_s']['3d']:.2f} s", file=sys.stderr)
        whole, split = runs[False], runs[True]
        differ = len(whole[0]["linear"]["keys"] - split[0]["linear"]["keys"])
        for g in whole + split:
            del g["linear"]["keys"]
        med = statistics.median
        stage_whole = {k: med(g["stage_cpu_s"][k] for g in whole) for k in whole[0]["stage_cpu_s"]}
        stage_split = {k: med(g["stage_cpu_s"][k] for g in split) for k in split[0]["stage_cpu_s"]}
        vols = [{"volume": v["volume"], "tets": v["tets"],
                 "whole_tets": next(w["tets"] for w in whole[0]["per_volume"] if w["volume"] == v["volume"]),
                 "cpu_s": med(g["per_volume"][i]["cpu_s"] for g in split)}
                for i, v in enumerate(split[0]["per_volume"])]
        cost = {v["volume"]: v["cpu_s"] for v in vols}
        share = lpt(cost, ranks)
        total = sum(stage_split.values())
        sum_3d = sum(cost.values())
        largest = max(sum(cost[k] for k in keys) for keys in share)
        tets = {v["volume"]: v["tets"] for v in vols}
        most_tets = max(sum(tets[k] for k in keys) for keys in share) / sum(tets.values())
        rest = sum(stage_split[k] for k in ("optimise", "order", "repair"))
        bound = total - sum_3d + largest
        rows.append({"mesh": label, "volumes": vols, "ranks": share, "runs": repeats,
                     "stage_cpu_s_whole": stage_whole, "total_cpu_s_whole": med(g["total_cpu_s"] for g in whole),
                     "stage_cpu_s_split": stage_split, "total_cpu_s_split": total,
                     "bound_cpu_s": bound, "ratio": bound / total,
                     "ratio_rest_split": (bound - rest + most_tets * rest) / total,
                     "tets_whole": whole[0]["linear"]["tets"], "linear_tets_differing": differ,
                     "same_linear_mesh": {g["linear"]["digest"] for g in split} == {g["linear"]["digest"] for g in whole},
                     "same_mesh": {g["digest"] for g in split} == {g["digest"] for g in whole},
                     "digests": {"whole": sorted({g["digest"] for g in whole}),
                                 "split": sorted({g["digest"] for g in split}),
                                 "whole_linear": sorted({g["linear"]["digest"] for g in whole}),
                                 "split_linear": sorted({g["linear"]["digest"] for g in split})}})
    return rows


def volumes_table(rows: list[dict]) -> str:
    """The --volumes rows as a Markdown table (counts; CPU s, medians)."""
    out = ["| mesh | volumes | tets per volume | 3-D CPU per volume (s) | 3-D CPU whole (s) | meshing CPU whole (s)"
           " | on 2 ranks (s) | ratio | ratio, the rest split too | linear mesh against whole | final nodes |", "|---" * 11 + "|"]
    for r in rows:
        vols = r["volumes"]
        tets = " + ".join(str(v["tets"]) for v in vols)
        cpu = " + ".join(f"{v['cpu_s']:.2f}" for v in vols)
        out.append(f"| {r['mesh']} | {len(vols)} | {tets} | {cpu} | {r['stage_cpu_s_whole']['3d']:.2f} | "
                   f"{r['total_cpu_s_whole']:.2f} | {r['bound_cpu_s']:.2f} of {r['total_cpu_s_split']:.2f} | "
                   f"{r['ratio']:.2f} | {r['ratio_rest_split']:.2f} | "
                   f"{'same' if r['same_linear_mesh'] else 'other'} nodes, {r['linear_tets_differing']} tets differ | "
                   f"{'same' if r['same_mesh'] else 'other'} |")
    return "\n".join(out)


def peaks(names: list[str], factors: list[float]) -> list[dict]:
    """Each set's No. 05 run at each mesh factor (pilot, the factor's mesh and its error
    bar, this process alone, the run cache off): peaks and bands (MPa), finest DOFs, wall
    time (s)."""
    from pipeline.api import Mesher, RunContext, RunOptions, estimate_levels, resolve_case, run

    rows = []
    three = RunOptions(levels=3, to_tolerance=False, sensitivity=False)
    for factor, name in [(f, n) for f in factors for n in names]:
        case = resolve_case("05", overrides={"mesh_factor": factor})
        t0 = time.perf_counter()
        # Every mesh of the run (the pilot's included) made under the set's options.
        with Mesher(case.dims, case.model, gmsh_options=VARIANTS[name]) as mesher:
            result = run(case, three, RunContext(comm=MPI.COMM_SELF, mesher=mesher))
        levels = result.levels
        row = {"variant": name, "factor": factor, "dofs": levels[0].dofs, "places": len(result.places.hotspots),
               "wall_s": time.perf_counter() - t0}
        for key in ("peak", "critical"):
            est = estimate_levels(levels, case.order, key)
            value = getattr(levels[0], key).value_MPa
            row[key] = {"value_MPa": value, "band_MPa": est.band, "status": est.status,
                        "covers_reference": est.band is not None
                        and abs(value - REFERENCES_MPA[key]) <= est.band}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    return rows


def table(rows: list[dict]) -> str:
    """The timing rows as a Markdown table: CPU time of each stage (s, medians), the total's
    CPU and wall time (s, medians) and their ratios to the default set's (medians of the
    rounds' pairs)."""
    stages = ("1d", "2d", "3d", "optimise", "order", "repair")
    out = ["| mesh | options | DOFs | " + " | ".join(stages) + " | CPU (s) | × default | wall (s) | × default"
           " | same mesh |", "|---" * 14 + "|"]
    for r in rows:
        if "error" in r:
            out.append(f"| {r['mesh']} | {r['variant']} | failed: {r['error']} |" + " |" * 11)
            continue
        st = " | ".join(f"{r['stage_cpu_s'].get(s, 0.0):.2f}" for s in stages)
        out.append(f"| {r['mesh']} | {r['variant']} | {r['dofs']} | {st} | {r['total_cpu_s']:.2f} | "
                   f"{r.get('ratio_cpu_s', float('nan')):.2f} | {r['total_s']:.2f} | {r.get('ratio_s', float('nan')):.2f} | "
                   f"{'yes' if r.get('same_mesh') else 'no'} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.meshing", description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"option sets, comma-separated (default all: {', '.join(VARIANTS)})")
    ap.add_argument("--factors", help="No. 05's mesh factors (default 1,1.69; with --peaks 1)")
    ap.add_argument("--no-full", action="store_true", help="leave out the full part")
    ap.add_argument("--repeats", type=int, default=3, help="rounds of every set on every mesh (default 3)")
    ap.add_argument("--peaks", action="store_true", help="each set's No. 05 peaks and bands instead of timing")
    ap.add_argument("--volumes", action="store_true",
                    help="each mesh whole and volume by volume: the bound of meshing the volumes on 2 ranks")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = ap.parse_args(argv)
    names = [n.strip() for n in args.variants.split(",") if n.strip()]
    unknown = [n for n in names if n not in VARIANTS]
    if unknown or args.repeats < 1:
        print(f"--variants: unknown {', '.join(unknown)}" if unknown else "--repeats: at least 1", file=sys.stderr)
        return 2
    try:
        factors = [float(f) for f in (args.factors or ("1" if args.peaks else "1,1.69")).split(",")]
    except ValueError:
        print(f"--factors: not numbers: {args.factors}", file=sys.stderr)
        return 2
    if args.volumes:
        rows = volumes(factors, not args.no_full, args.repeats)
        print(volumes_table(rows))
    elif args.peaks:
        rows = peaks(names, factors)
        for r in rows:
            print(f"×{r['factor']:g} {r['variant']}: " + ", ".join(
                f"{k} {r[k]['value_MPa']:.2f} ± {r[k]['band_MPa'] if r[k]['band_MPa'] is not None else float('nan'):.2f}"
                f" MPa ({'covers' if r[k]['covers_reference'] else 'misses'} {REFERENCES_MPA[k]})"
                for k in ("peak", "critical")) + f"; {r['dofs']} DOFs, {r['places']} places, {r['wall_s']:.1f} s")
    else:
        rows = timing(names, factors, not args.no_full, args.repeats)
        print(table(rows))
    if args.out is not None:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
