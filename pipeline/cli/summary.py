"""The closing lines of a run or a convergence study, from the results.json it wrote: each
peak with its error bar and where it sits, the accuracy reached, the formulas and safety
factors, the loads asked, the sensitivity sentence and the files (mm, N, MPa)."""
from __future__ import annotations

import json
import time
from pathlib import Path

from pipeline.cli.terminal import T_START, show
from pipeline.output.report import accuracy_text, error_bar_text, feature_text, no_safety_factor_reason, pm

LOADS_SHOWN = 3  # loads shown at each end of a long load sweep's terminal line


def run_summary(out: Path) -> None:
    """The run's closing lines, from the results.json it wrote (the lines say what the file
    says)."""
    res = json.loads((out / "results.json").read_text(encoding="utf-8"))
    fe = res["fe"]
    for name, key in (("global peak  ", "peak"), ("critical peak", "critical")):
        show(f"{name} {fe[key]['value_MPa']:8.2f} MPa  {error_bar_text(fe[key])}  [{feature_text(fe[key])}]")
    if fe.get("accuracy"):
        show(accuracy_text(fe["accuracy"]))
    an = res["analytic"]

    def sf(key: str) -> str:
        return f"{fe[key]:.2f}" if fe[key] is not None else f"none ({no_safety_factor_reason(fe, key)})"
    show(f"formulas: approximate {an['approximate_MPa']:.2f} MPa, exact {an['exact_MPa']:.2f} MPa; "
         f"safety factor {sf('safety_factor')} (global), {sf('critical_safety_factor')} (critical)")
    if res.get("load_sweep"):
        rows = res["load_sweep"]
        texts = [f"{r['load_N']:g} N {pm(r['peak_MPa'], r.get('peak_band_MPa'))} / "
                 f"{pm(r['critical_peak_MPa'], r.get('critical_band_MPa'))}" for r in rows]
        long = len(rows) > 2 * LOADS_SHOWN  # a line a person can read: the ends, the rest in the files
        if long:
            texts = texts[:LOADS_SHOWN] + [f"… {len(rows) - 2 * LOADS_SHOWN} more in results.json …"] + texts[-LOADS_SHOWN:]
        show(f"the lines above are at Q = {res['case']['load_N']:g} N; {f'{len(rows)} loads' if long else 'every load'} "
             "(global / critical peak, MPa): " + "; ".join(texts))
        if res.get("load_sweep_verdict"):
            show(res["load_sweep_verdict"])
    summ = res.get("sensitivity_summary")
    if summ:
        show(f"sensitivity: {summ['sentence']}")
    named = res.get("files") or {"results": "results.json"}
    files = [named[k] for k in ("report", "results") if k in named] + \
        [f for k, f in named.items() if k not in ("report", "results")]
    # The seconds since the program started, as the progress lines count them (the run's own
    # total in results.json starts after the imports).
    show(f"written to {out}/ ({', '.join(files[:4])}{', ...' if len(files) > 4 else ''}) "
         f"in {time.perf_counter() - T_START:.1f} s")
