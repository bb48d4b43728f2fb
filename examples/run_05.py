"""Hook No. 05 under 10 kN, through crosshead's public API (mm, N, MPa).

This is what `make run` computes, written as your own script would: a case, its run, the
two peaks with their error bars, the verdicts, and one field file for ParaView. Run it
from the repository's root:

    .venv/bin/python examples/run_05.py [--mesh-factor 1.0] [--out results/example-05]

`tests/test_examples.py` runs it and checks its numbers against independent references.
"""
# %% [markdown]
# ## The case
#
# A case is everything the analysis needs: the size's dimensions from
# geometry/sizes.csv (No. 05 is the paper's Table 1), the hook load (its rated load,
# 10 000 N), the material (steel, E = 210 000 MPa, nu = 0.3) and the mesh. Any field can be
# overridden by the names a case file uses: `{"mesh_factor": 1.3}` makes every element
# 1.3 times larger, `{"dims.rf": 2.0}` sets the shoulder fillet's radius to 2 mm.

from __future__ import annotations

import argparse
from pathlib import Path

from pipeline.api import Material, RunOptions, resolve_case, run, write_fields


def main(argv: list[str] | None = None) -> dict:
    """Run No. 05 and return its two peaks, bands and verdicts (MPa)."""
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--mesh-factor", type=float, default=1.0, help="every element size × this (default 1)")
    args.add_argument("--out", type=Path, default=Path("results/example-05"), help="where fields.vtu goes")
    a = args.parse_args(argv)
    case = resolve_case("05", overrides={"mesh_factor": a.mesh_factor})

    # %% [markdown]
    # ## The run
    #
    # `run` finds where the peaks sit (a coarse pilot solve), solves the requested mesh and
    # two coarser ones for the error bar, and decides each peak's status and verdict. It
    # writes nothing. The sensitivity section (what the verdict rests on: the assumed
    # journal diameter, fillet and seat varied) is left out here to keep the example quick.
    result = run(case, RunOptions(sensitivity=False))

    # %% [markdown]
    # ## The peaks and their error bars
    #
    # The global peak sits on the journal's shoulder fillet, the critical one at the bore
    # edge beside the ligament the hand formulas describe. Each value comes with a band:
    # an estimate of the discretisation error from the meshes, with its status
    # (docs/design.md §5).
    answer = {}
    for key, name in (("peak", "global"), ("critical", "critical")):
        p = result.peaks[key]
        verdict = result.verdicts[f"{name}_peak"]
        print(f"{name:8s} peak {p.value_MPa:7.2f} ± {p.band_MPa:.2f} MPa ({p.estimate.status}) at {p.feature}; "
              f"{verdict.verdict} against {case.allowable_MPa:g} MPa, capacity {verdict.capacity_N:.0f} N")
        answer[name] = {"value_MPa": p.value_MPa, "band_MPa": p.band_MPa, "verdict": verdict.verdict}

    # %% [markdown]
    # ## Beside the hand formulas
    #
    # The paper's approximate (beam) and exact (curved bar) formulas give a nominal stress
    # of the ligament: the FE peaks hold the stress concentration they average out.
    print(f"formulas: approximate {result.hand.approximate.sigma_MPa:.2f} MPa, "
          f"exact {result.hand.exact.sigma_MPa:.2f} MPa")

    # %% [markdown]
    # ## A field file for ParaView
    #
    # The requested mesh keeps its displacement and its von Mises readings at the nodes;
    # `write_fields` puts them, mirrored to the whole part, into fields.vtu, where each peak
    # is the reported array's value at its place (docs/design.md §7).
    a.out.mkdir(parents=True, exist_ok=True)
    u, _ = result.requested.fields
    write_fields(a.out, u, result.requested.readings, Material(E=case.E_MPa, nu=case.nu), whole_part=True)
    print(f"fields: {a.out / 'fields.vtu'}")
    return answer


if __name__ == "__main__":
    main()
