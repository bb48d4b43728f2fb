"""The closing lines of a run or a convergence study, from the results.json it wrote, for
a person to scan: one line per peak with its value ± error bar, its status, PASS or FAIL,
safety factor and where it sits; the error bars against the tolerance, the formulas, the
loads asked, the sensitivity sentence, the notes and the files (mm, N, MPa). Every line
is at most terminal.WIDTH characters (a longer text goes on indented lines of its own),
and every word for a status or a verdict is the one results.json and the report use."""
from __future__ import annotations

import json
import time
from pathlib import Path

from pipeline.analysis.words import NOT_ASKED, SINGULAR
from pipeline.cli.terminal import T_START, say
from pipeline.output.texts import (PEAK_KEYS, accuracy_text, feature_text, pm, safety_text, status_text,
                                   verdict_text)

LOADS_SHOWN = 3  # loads shown at each end of a long load sweep's list
PEAK_NAMES = {"peak": "global peak", "critical": "critical peak"}


def peak_line(res: dict, key: str) -> str:
    """One peak: '<name>  113.77 ± 0.73 MPa  within tolerance (0.64 %)  FAIL  SF 0.70  <where>'."""
    fe = res["fe"]
    block = fe[key]
    verdict_key, sf_key = PEAK_KEYS[key]
    band = None if block["status"] in (NOT_ASKED, SINGULAR) else (block.get("error_estimate") or {}).get("band")
    return (f"{PEAK_NAMES[key]:<13} {pm(block['value_MPa'], band):>15} MPa  {status_text(block)}  "
            f"{verdict_text((fe.get('verdict') or {}).get(verdict_key))}  SF {safety_text(fe.get(sf_key))}  "
            f"{feature_text(block)}")


def run_summary(out: Path) -> None:
    """The run's closing lines, from the results.json it wrote (the lines say what the file
    says)."""
    res = json.loads((out / "results.json").read_text(encoding="utf-8"))
    fe, an, c = res["fe"], res["analytic"], res["case"]
    say(f"hook No. {c['size']} at Q = {c['load_N']:g} N against the allowable {c['allowable_MPa']:g} MPa:")
    for key in ("peak", "critical"):
        say(peak_line(res, key))
    if fe.get("accuracy"):
        say(f"error bars: {accuracy_text(fe['accuracy'])}")
    say(f"hand formulas (nominal): approximate {an['approximate_MPa']:.2f} MPa, exact {an['exact_MPa']:.2f} MPa")
    if res.get("load_sweep"):
        rows = res["load_sweep"]
        texts = [f"{r['load_N']:g} N {pm(r['peak_MPa'], r.get('peak_band_MPa'))} / "
                 f"{pm(r['critical_peak_MPa'], r.get('critical_band_MPa'))}" for r in rows]
        long = len(rows) > 2 * LOADS_SHOWN  # lines a person can read: the ends, the rest in the files
        if long:
            texts = texts[:LOADS_SHOWN] + [f"… {len(rows) - 2 * LOADS_SHOWN} more in results.json …"] + texts[-LOADS_SHOWN:]
        say(f"the lines above are at Q = {res['case']['load_N']:g} N; {f'{len(rows)} loads' if long else 'every load'} "
            "(global / critical peak, MPa): " + "; ".join(texts))
        if res.get("load_sweep_verdict"):
            say(res["load_sweep_verdict"])
    summ = res.get("sensitivity_summary")
    if summ:
        say(f"sensitivity: {summ['sentence']}")
    for note in res.get("notes") or []:
        say(f"note: {note}")
    named = res.get("files") or {"results": "results.json"}
    first = [named[k] for k in ("report_pdf", "report_html", "results") if k in named]
    files = first + [f for k, f in named.items() if f not in first]
    # The seconds since the program started, as the progress lines count them (the run's own
    # total in results.json starts after the imports).
    say(f"written to {out}/ ({', '.join(files[:4])}{', ...' if len(files) > 4 else ''}) "
        f"in {time.perf_counter() - T_START:.1f} s")
