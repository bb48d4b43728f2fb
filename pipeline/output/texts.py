"""How results.json's values read for a person, in one place: the report, the terminal's
closing lines and a study's tables write a value, a peak, its error bar and where it sits
alike (mm, N, MPa). The words themselves (statuses, verdicts) are the analysis's
(pipeline.analysis.words); these only format them."""
from __future__ import annotations

from pipeline.analysis.words import verdict_word
from pipeline.post.errorbar import SETTLED, SETTLED_BAND

# The checked stresses in the words of the report's and the terminal's verdict lines, by
# results.json's verdict names.
VERDICT_NAMES = {"global_peak": "global peak (whole part)", "critical_peak": "critical-region peak",
                 "critical_section_nominal": "critical section, nominal (N, M)",
                 "journal_root_nominal": "journal root, nominal bending"}
# Each peak block of results.json's fe, its verdict name and its safety-factor key.
PEAK_KEYS = {"peak": ("global_peak", "safety_factor"), "critical": ("critical_peak", "critical_safety_factor")}


def num(x: float | None, nd: int = 2) -> str:
    """A number for a person: thousands separated by a thin space's stand-in (a space),
    ``nd`` decimals; '—' for none."""
    return "—" if x is None else f"{x:,.{nd}f}".replace(",", " ")


def pm(value: float | None, band: float | None) -> str:
    """A peak (MPa) with its error bar when it has one: '114.28 ± 2.37' (the report's, the
    terminal's and a study's tables write it alike)."""
    return num(value) + ("" if band is None or value is None else f" ± {num(band)}")


def location(xyz) -> str:
    """A location (mm): '(23.14, 7.01, 4.99) mm'; '-0.00' written as '0.00'."""
    return "(" + ", ".join(f"{v + 0.0:.2f}".replace("-0.00", "0.00") for v in xyz) + ") mm"


def feature_text(block: dict) -> str:
    """Where a peak sits, in words; a singular one says at which singular feature (the
    location's name alone, e.g. the fillet, would hide that the peak is not finite)."""
    where = block.get("singular_feature")
    return f"{block['feature']} (singular: {where})" if where else block["feature"]


def band_pct(block: dict) -> float | None:
    """A peak block's band as a share of its value (%), or None without a band."""
    est = block.get("error_estimate") or {}
    band = est.get("band")
    if band is None or block.get("not_wanted") or not block.get("value_MPa"):
        return None
    return 100.0 * band / abs(block["value_MPa"])


def status_text(block: dict) -> str:
    """A peak's status in the run's words, with its band's share of the value when it has
    one: 'within tolerance (0.64 %)'."""
    pct = band_pct(block)
    return block["status"] + ("" if pct is None else f" ({pct:.2f} %)")


def verdict_text(verdict: dict | None) -> str:
    """A checked stress's verdict in the run's words (PASS, FAIL, UNDECIDED, no verdict)."""
    return verdict_word("none" if verdict is None else verdict["verdict"])


def safety_text(value: float | None) -> str:
    """A safety factor, or 'none' (a peak with no verdict)."""
    return "none" if value is None else f"{value:.2f}"


def accuracy_text(acc: dict) -> str:
    """One line on the error bars (results.json's fe.accuracy): each wanted peak's band (%)
    against the tolerance, the meshes of the error bar and, when a band stays above the
    tolerance, why; each peak's status says the same in its own words."""
    bands = ", ".join(f"{p} {'no band' if b is None else f'{b:.2f} %'}" for p, b in acc["bands_pct"].items())
    meshes = f"meshes ×{', ×'.join(f'{f:.4g}' for f in acc['mesh_factors'])}"
    extra = len(acc["meshes_solved"]) - len(acc["mesh_factors"])
    solved = f" ({len(acc['meshes_solved'])} solved in all)" if extra > 0 else ""
    head = f"{bands} of the value; tolerance {acc['tolerance_pct']:g} %; {meshes}{solved}"
    if acc["met"]:
        return head
    if all(b is None for b in acc["bands_pct"].values()):
        return f"tolerance {acc['tolerance_pct']:g} %: not checked, {acc['note']}"
    return f"{head}: {acc['note']}"


def error_bar_text(block: dict) -> str:
    """One line saying how sure we are of a peak, from its error_estimate."""
    if block.get("not_wanted"):
        return f"not resolved ({block['not_wanted']})"
    est = block.get("error_estimate")
    if est is None:
        return "no error estimate (fewer than three meshes)"
    bracket, trend = est.get("bracket"), est.get("band_trend")
    if bracket is not None and trend is not None and bracket > trend:
        of_trend = dict(est, band=trend, gci_fine=trend / max(abs(est["values"][0]), 1e-300))
        return (f"± {num(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), half the gap between the unaveraged "
                f"and averaged nodal values; the meshes' trend alone: {trend_text(of_trend)}")
    return trend_text(est)


def trend_text(est: dict) -> str:
    """error_bar_text of an estimate's band from the meshes' trend."""
    st = est["status"]
    if st == "converged":
        if est["order_used"] < est["order_observed"] - 1e-9:
            return (f"± {num(est['band'])} MPa (GCI {100 * est['gci_fine']:.2f} %), extrapolated "
                    f"{num(est['extrapolated'])} MPa with the element's formal order {est['order_used']:g}: the "
                    f"observed order {est['order_observed']:.2f} is above it (a coarse mesh off the trend), "
                    "so neither the limit nor the band uses it")
        return (f"± {num(est['band'])} MPa (GCI {100 * est['gci_fine']:.2f} %), extrapolated "
                f"{num(est['extrapolated'])} MPa, observed order {est['order_observed']:.2f}")
    if st == "exact":
        return "unchanged across meshes"
    if st == "settled":
        return (f"± {num(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), the same on every mesh to within "
                f"{100 * SETTLED:g} %; band = {100 * SETTLED_BAND:g} %, what such nodal readings are still off by, "
                "not their smaller spread")
    if st == "scattered":
        return (f"± {num(est['band'])} MPa ({100 * est['gci_fine']:.1f} %), values scatter between meshes "
                f"(unstructured meshes move nodal peaks by ~1 %); least-squares limit {num(est['extrapolated'])} MPa, "
                "band with safety factor 3")
    if st == "unsettled":
        return (f"± {num(est['band'])} MPa ({100 * est['gci_fine']:.1f} %), values still changing between "
                "meshes (not in the asymptotic range); band = largest change, no extrapolation")
    if st == "oscillatory":
        return (f"± {num(est['band'])} MPa ({100 * est['gci_fine']:.2f} %), values oscillate "
                "between meshes; band = largest change")
    if st == "singular":
        return (f"NOT CONVERGED: grows with refinement (observed order "
                f"{est['order_observed']:.2f}); the peak sits at a singular feature and has no finite value")
    return f"NOT CONVERGED (status {st}, observed order {est['order_observed']:.2f})"
