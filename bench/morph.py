"""The sensitivity section two ways: its variants on the nominal mesh with the nodes moved
(the product's way) and each on a fresh mesh of its own (the way before), on one process,
side by side (docs/decisions/0036-sensitivity-variants-by-morphing.md).

    CROSSHEAD_NO_CACHE=1 .venv/bin/python -m bench.morph [--size 05] [--factors 1.0] [--repeats 3]

For every assumed dimension's range end it prints variant / nominal of both peaks both
ways, their difference against the section's noise (the nominal case on a second mesh,
as results.json's sensitivity_summary states it), and the section's wall and CPU time both
ways (medians of ``--repeats`` interleaved rounds). Writes nothing.
"""
from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

from pipeline.api import RunContext, analyse_sensitivity, analyse_variant, resolve_case


def one_way(case, moved: bool) -> tuple[object, float, float]:
    """The section's analysis of ``case`` on this process (no load-model ranges: they need
    a run's own mesh), and its wall and CPU time (s)."""
    t, c = time.perf_counter(), time.process_time()
    sens = analyse_sensitivity(case, RunContext(), analyse_one=None if moved else analyse_variant)
    return sens, time.perf_counter() - t, time.process_time() - c


def ratios(sens) -> dict[str, tuple[float | None, float | None]]:
    """Per range end, 'input=value': variant / nominal of the global and the critical peak."""
    out = {}
    for r, (lo, hi) in zip(sens.ranges, sens.ends):
        for v, rd in ((r.low, lo), (r.high, hi)):
            out[f"{r.input}={v:g}"] = tuple(None if not rd.ok else getattr(rd, a) / getattr(sens.baseline, a)
                                            for a in ("peak_MPa", "critical_MPa"))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="05")
    ap.add_argument("--factors", default="1.0", help="the run's mesh factors (the variants' are × 2.2)")
    ap.add_argument("--repeats", type=int, default=1)
    a = ap.parse_args(argv)
    for f in (float(x) for x in a.factors.split(",")):
        case = replace(resolve_case(a.size, overrides={"mesh_factor": f}), support="bearing")
        times: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
        got = {}
        for _ in range(a.repeats):
            for moved in (True, False):
                sens, wall, cpu = one_way(case, moved)
                times[moved].append((wall, cpu))
                got[moved] = sens
        base = got[False].baseline
        noise_g = abs(base.peak_MPa - got[False].second.peak_MPa) / base.peak_MPa
        noise_c = abs(base.critical_MPa - got[False].second.critical_MPa)
        print(f"No. {a.size} at mesh factor {f:g}: noise of one variant mesh {100 * noise_g:.2f} % (global), "
              f"{noise_c:.3f} MPa (critical)")
        print(f"{'end':>20} | {'global moved':>12} {'fresh':>8} {'Δ %':>6} | {'critical moved':>14} {'fresh':>8} "
              f"{'Δ MPa':>7}")
        fresh, moved = ratios(got[False]), ratios(got[True])
        for k in fresh:
            (gf, cf), (gm, cm) = fresh[k], moved[k]
            if None in (gf, cf, gm, cm):
                print(f"{k:>20} | not analysed")
                continue
            print(f"{k:>20} | {gm:12.4f} {gf:8.4f} {100 * (gm - gf):+6.2f} | {cm:14.4f} {cf:8.4f} "
                  f"{(cm - cf) * base.critical_MPa:+7.3f}")
        for moved_way in (True, False):
            w = statistics.median(t[0] for t in times[moved_way])
            c = statistics.median(t[1] for t in times[moved_way])
            print(f"section {'moved' if moved_way else 'fresh'}: wall {w:.2f} s, CPU {c:.2f} s "
                  f"(medians of {a.repeats})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
