"""Matplotlib plots (convergence, sections, peaks against DOFs); headless backend (units:
MPa, mm).

``python -m pipeline.output.plots FOLDER`` draws a run's plots in their own process, beside the
error-bar solves and the picture (pipeline/output/picture.py), from the files the run writes.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


NOT_ASKED = "not asked for (--want): not resolved"  # a peak's title when the run skipped its refinement


def load_matplotlib() -> bool:
    """Import matplotlib with its Agg backend now, and say whether it is installed.

    Why: the import takes a good part of a second; the drawing process does it while it
    waits for the run's results, so that the plots, the last thing a run waits for, start
    at once (docs/decisions/0039-speed-of-a-run.md)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
    except ImportError:
        return False
    return True


def convergence_plot(path: Path, conv: dict, case) -> bool:
    """Each peak (MPa) against the representative mesh size N^(-1/3) of the study's meshes:
    both nodal readings, the value reported, the finest mesh's error bar and, where the
    estimator extrapolated, the limit at h = 0."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig = convergence_figure(conv, case.size)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def convergence_figure(conv: dict, size: str):
    """The figure of :func:`convergence_plot` (matplotlib must be importable)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    levels = conv["levels"]  # finest first, as est["h"] and est["values"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.9))
    for ax, key, label in ((axes[0], "peak", "global peak"), (axes[1], "critical", "critical-region peak")):
        est = conv[key]
        asked = key not in conv.get("not_wanted", {})
        h = est["h"]
        ax.plot(h, [lv[f"{key}_unaveraged_MPa"] for lv in levels], "v:", color="C3",
                label="unaveraged (largest element-node value)")
        ax.plot(h, [lv[f"{key}_averaged_MPa"] for lv in levels], "^:", color="C0",
                label="averaged (nodal-averaged stress)")
        ax.plot(h, est["values"], "o-", color="k", label="reported value" if asked else "value (meshes not refined for it)")
        if est.get("band") is not None and asked:
            ax.errorbar([h[0]], [est["values"][0]], yerr=[est["band"]], fmt="none", ecolor="C1",
                        elinewidth=3, capsize=6, label=f"error bar ±{est['band']:.3g} MPa")
        # Only these two statuses extrapolate (pipeline/output/report.py words them alike); the
        # others' "extrapolated" is the finest value itself or absent.
        if est.get("extrapolated") is not None and est["status"] in ("converged", "scattered") and asked:
            name = "Richardson limit" if est["status"] == "converged" else "least-squares limit"
            ax.plot([0], [est["extrapolated"]], "*", color="C2", ms=12,
                    label=f"{name} {est['extrapolated']:.2f} MPa")
        ax.set_xlim(left=-0.03 * max(h))  # h = 0 (the limit) just inside the frame
        ax.set_xlabel("representative mesh size h = DOFs^(-1/3)")
        ax.set_ylabel("von Mises (MPa)")
        ax.set_title(f"No. {size}: {label}\ntrend over the meshes: {est['status'] if asked else NOT_ASKED}",
                     fontsize=11)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    fig.tight_layout()
    return fig


def sections_plot(path: Path, sections: dict, analytic: dict, h_mm: float) -> bool:
    """σ_xx through the height at x = 0 (bore edge and mid-ligament): the FE profile, its
    linearisation, and the approximate formula's linear distribution (±σ at the faces)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    import numpy as np
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, label, colour in (("bore_edge_height", "bore edge", "tab:red"),
                               ("mid_ligament_height", "mid-ligament", "tab:blue")):
        line = sections["lines"][key]
        z = np.array(line["position_mm"])
        ax.plot(line["sigma_xx_MPa"], z, "-", color=colour, label=f"FE σ_xx, {label}")
        m, b = line["membrane_MPa"], line["bending_MPa"]
        ax.plot(m + b * (1 - 2 * z / z[-1]), z, "--", color=colour, label=f"linearised, {label}")
    s = analytic["approximate_MPa"]
    ax.plot([s, -s], [0, h_mm], ":", color="black", label=f"approximate formula (±{s:.1f} MPa)")
    cs = sections.get("critical_section")
    if cs:
        ax.plot([cs["nominal_MPa"], -cs["nominal_MPa"]], [0, h_mm], "-.", color="grey",
                label=f"FE nominal from N, M (±{cs['nominal_MPa']:.1f} MPa)")
    ax.axvline(0, color="lightgrey", lw=0.8)
    ax.set_xlabel("normal stress σ_xx on the section x = 0 (MPa)")
    ax.set_ylabel("height z (mm)")
    ax.set_title("Ligament beside the bore: FE against the beam formula")
    ax.legend(fontsize=8, loc="upper right")
    # Fixed margins, not tight_layout: its trial drawing was a third of the plots' time.
    # They leave room for four-digit ticks (tight_layout chose 0.088 for No. 05's).
    fig.subplots_adjust(left=0.11, right=0.965, bottom=0.13, top=0.915)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def peaks_plot(path: Path, res: dict) -> bool:
    """Each peak (MPa) against the DOFs of the run's meshes: both nodal readings, the value
    reported, and the error bar of the requested (finest) mesh; each panel's title says the
    peak's status and verdict in the run's words (results.json), and the legend sits below
    the panels, off the data."""
    if len(res["fe"]["levels"]) < 2:
        return False
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig = peaks_figure(res)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def peaks_figure(res: dict):
    """The figure of :func:`peaks_plot` (matplotlib must be importable)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipeline.output.texts import PEAK_KEYS, status_text, verdict_text
    levels = res["fe"]["levels"]
    dofs = [lv["dofs"] for lv in levels]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.7))
    for ax, key, prefix, value_key, label in ((axes[0], "peak", "peak", "peak_MPa", "global peak"),
                                              (axes[1], "critical", "critical", "critical_peak_MPa",
                                               "critical-region peak")):
        block = res["fe"][key]
        asked = not block.get("not_wanted")
        ax.plot(dofs, [lv[f"{prefix}_unaveraged_MPa"] for lv in levels], "v:", color="C3",
                label="unaveraged (largest element-node value)")
        ax.plot(dofs, [lv[f"{prefix}_averaged_MPa"] for lv in levels], "^:", color="C0",
                label="averaged (nodal-averaged stress)")
        ax.plot(dofs, [lv[value_key] for lv in levels], "o-",
                color="k", label="reported value" if asked else "value (meshes not refined for it)")
        est = block.get("error_estimate") or {}
        if est.get("band") is not None and asked:
            ax.errorbar([dofs[0]], [block["value_MPa"]], yerr=[est["band"]], fmt="none", ecolor="C1",
                        elinewidth=3, capsize=6, label=f"error bar ±{est['band']:.3g} MPa")
        ax.set_xscale("log")
        ax.set_xlabel("degrees of freedom")
        ax.set_ylabel("von Mises (MPa)")
        # The peak's status and verdict in the run's words (a results.json older than the
        # status names the trend instead).
        verdict = (res["fe"].get("verdict") or {}).get(PEAK_KEYS[key][0])
        status = status_text(block) if "status" in block else (est.get("status", "no estimate") if asked else NOT_ASKED)
        ax.set_title(f"No. {res['case']['size']}: {label}\n{status}"
                     + (f", {verdict_text(verdict)}" if verdict and verdict["verdict"] != "none" else ""), fontsize=11)
        ax.grid(alpha=0.3, which="both")
        # Below the panel: inside, it covered the coarser meshes' readings.
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    # Fixed margins for the reason given in sections_plot; the bottom one holds the legends.
    fig.subplots_adjust(left=0.075, right=0.985, bottom=0.27, top=0.885, wspace=0.22)
    return fig


def _tornado_limits(ax, base: float, allowable: float) -> tuple[float, float, bool]:
    """The x range of a tornado panel (MPa): the data's, at least ±5 % of the run's value
    ``base`` (a change of 1 % must not fill the panel), widened to take in the allowable
    when it lies within half the run's value of it; and whether the allowable is inside."""
    lo, hi = ax.get_xlim()
    lo, hi = min(lo, 0.95 * base), max(hi, 1.05 * base)
    if abs(allowable - base) <= 0.5 * base:
        pad = 0.03 * (max(hi, allowable) - min(lo, allowable))
        lo, hi = min(lo, allowable - pad), max(hi, allowable + pad)
    return lo, hi, lo <= allowable <= hi


def tornado_plot(path: Path, res: dict) -> bool:
    """The tornado chart of the sensitivity analysis: for each varied input, the global and
    the critical peak (MPa) at the low and the high end of its range as bars from the run's
    value, the inputs ordered by the global peak's swing; the allowable drawn in each panel
    (its axis widened to take it in) or, when it lies far off, named in the panel's title;
    the single-mesh noise beside the bars; one legend below both panels. False (nothing
    drawn) without a sensitivity list."""
    if not res.get("sensitivity"):
        return False
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig = tornado_figure(res)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def tornado_figure(res: dict):
    """The figure of :func:`tornado_plot` (matplotlib must be importable; ``res`` has a
    sensitivity list)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pipeline.analysis.words import range_text
    entries = res["sensitivity"]
    fe, summ = res["fe"], res.get("sensitivity_summary") or {}
    noise = summ.get("noise_MPa") or {}
    allowable = float(res["case"]["allowable_MPa"])

    def swing(e: dict) -> float:
        return max((abs(v - fe["peak_MPa"]) for v in e["peak_MPa"] if v is not None), default=0.0)
    order = sorted(entries, key=swing)  # the largest swing on top
    height = 2.6 + 0.38 * len(order)
    fig, axes = plt.subplots(1, 2, figsize=(11, height))
    handles: dict[str, object] = {}
    for ax, key, label, nkey in ((axes[0], "peak_MPa", "global peak", "global_peak"),
                                 (axes[1], "critical_peak_MPa", "critical-region peak", "critical_peak")):
        base = fe[key]
        for i, e in enumerate(order):
            for v, colour, end in ((e[key][0], "C0", "low"), (e[key][1], "C3", "high")):
                if v is None:
                    ax.text(base, i, "  invalid" if end == "high" else "invalid  ", va="center",
                            ha="left" if end == "high" else "right", fontsize=8, color="0.4")
                    continue
                bar = ax.barh(i, v - base, left=base, height=0.6, color=colour, alpha=0.8)
                handles.setdefault(f"{end} end of the range", bar)
        handles.setdefault("this run's value", ax.axvline(base, color="k", lw=1))
        title = f"No. {res['case']['size']}: {label}\nthis run {base:.1f} MPa"
        if noise.get(nkey):
            title += f", noise ±{noise[nkey]:.2g} MPa"
            handles.setdefault("single-mesh noise",
                               ax.axvspan(base - noise[nkey], base + noise[nkey], color="0.85", zorder=0))
        lo, hi, inside = _tornado_limits(ax, base, allowable)
        ax.set_xlim(lo, hi)
        if inside:
            handles.setdefault(f"allowable {allowable:g} MPa",
                               ax.axvline(allowable, color="C1", ls="--", lw=1.5))
        else:
            title += f"\nallowable {allowable:g} MPa: off the axis, {'left' if allowable < lo else 'right'}"
        ax.set_yticks(range(len(order)))
        ax.set_yticklabels([f"{e['input']} {range_text(e['range'], e['unit'])}" for e in order], fontsize=9)
        ax.set_xlabel("von Mises (MPa)")
        ax.set_title(title, fontsize=9.5)
        ax.grid(alpha=0.3, axis="x")
    # One legend for both panels, below them: inside a panel it hid the bars of the widest
    # swing, and one under each panel ran off the figure's right edge.
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=len(handles), fontsize=8,
               frameon=False)
    fig.tight_layout(rect=(0, 0.4 / height, 1, 1))
    return fig


def draw_plots(folder: Path, res: dict) -> None:
    """A run's plots from its results ``res`` (results.json's content) into ``folder``:
    sections.png when the results carry section stresses, peaks.png and, with a
    sensitivity section, sensitivity.png."""
    folder = Path(folder)
    sections = res["fe"].get("sections")
    if sections:
        sections_plot(folder / "sections.png", sections, res["analytic"], float(res["case"]["dims"]["h3"]))
    peaks_plot(folder / "peaks.png", res)
    tornado_plot(folder / "sensitivity.png", res)


if __name__ == "__main__":  # a finished run's folder, drawn again from its results.json
    draw_plots(Path(sys.argv[1]), json.loads((Path(sys.argv[1]) / "results.json").read_text(encoding="utf-8")))
