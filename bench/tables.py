"""The bench's rows: medians over repeats, errors against the reference, the time to 1 %,
and the table, CSV and plot made of them (mm, MPa, s)."""
from __future__ import annotations

import csv
import math
import statistics
from pathlib import Path

from bench.point import STAGES


def aggregate(spec: dict, ranks: int, threads: int, runs: list[dict], ref: dict) -> dict:
    """One row: medians of the stage times over the runs, errors against the reference."""
    row = {"kind": spec["kind"], "order": spec.get("order", 2),
           "solver": spec.get("solver") or f"ccx-{spec.get('ccx_solver', 'spooles')}",
           "factor": spec["factor"], "pilot": bool(spec.get("pilot")), "want": spec.get("want", "both"),
           "ranks": ranks, "threads": threads,
           "cores": ranks * threads}
    ok = [r for r in runs if "error" not in r]
    if not ok:
        row["error"] = runs[-1].get("error", "no run") if runs else "no run"
        return row
    first = ok[0]
    med = statistics.median
    for k in ("dofs", "cells", "iterations", "peak_MPa", "critical_MPa"):
        row[k] = first.get(k)
    row["peak_location_mm"] = first["peak_location_mm"]
    row["critical_location_mm"] = first["critical_location_mm"]
    for st in STAGES:
        vals = [r["stages_s"].get(st) for r in ok if r["stages_s"].get(st) is not None]
        row[f"t_{st}"] = med(vals) if vals else None
    row["t_total"] = med([r["total_s"] for r in ok])
    row["t_core"] = (med([r["stages_s"]["write"] + r["stages_s"]["ccx"] + r["stages_s"]["read"] for r in ok])
                     if spec["kind"] != "dolfinx" else row["t_total"])
    row["t_total_min"] = min(r["total_s"] for r in ok)
    row["t_total_max"] = max(r["total_s"] for r in ok)
    row["t_imports"] = med([r["imports_s"] for r in ok])
    row["t_interpreter"] = med([max(r["wall_s"] - r["process_s"], 0.0) for r in ok])
    row["mem_MiB"] = max(r["maxrss_MiB"] for r in ok)
    row["mem_sum_MiB"] = max(r["maxrss_sum_MiB"] for r in ok)
    if spec["kind"] != "dolfinx":
        row["ccx_mem_MiB"] = max(r.get("ccx_maxrss_MiB", 0.0) for r in ok)
    row["repeats"] = len(ok)
    row["peak_err"] = (row["peak_MPa"] - ref["peak"]) / ref["peak"]
    row["critical_err"] = (row["critical_MPa"] - ref["critical"]) / ref["critical"]
    spread = [abs(r["peak_MPa"] - first["peak_MPa"]) for r in ok]
    row["peak_repeat_spread_MPa"] = max(spread)
    return row


def time_to_error(rows: list[dict], kinds: set[str], keys: tuple[str, ...], tol: float = 0.01,
                  time_key: str = "t_total", cores: int = 1) -> dict | None:
    """Fastest row of the given kinds on ``cores`` cores whose |errors| (keys) are all <= tol."""
    ok = [r for r in rows if r["kind"] in kinds and r.get("cores") == cores and "error" not in r
          and all(abs(r[k]) <= tol for k in keys)]
    if not ok:
        return None
    best = min(ok, key=lambda r: r[time_key])
    return {"time_s": best[time_key], "config": label(best), "factor": best["factor"],
            "dofs": best["dofs"], "peak_err": best["peak_err"], "critical_err": best["critical_err"]}


def label(r: dict) -> str:
    places = (" +bore edges" if r.get("want") == "critical" else " +pilot") if r.get("pilot") else ""
    if r["kind"] == "peer":
        return f"CalculiX C3D10 {r['solver'][4:]} user mesh" + (", bore edges" if r.get("want") == "critical" else "")
    if r["kind"] == "calculix":
        s = f"CalculiX C3D10 {r['solver'][4:]}" + places
        return s + (f" {r['threads']}thr" if r.get("threads", 1) != 1 else "")
    s = f"P{r['order']} {r['solver']}" + places
    return s + (f" x{r['ranks']}ranks" if r.get("ranks", 1) != 1 else "")


def summary(rows: list[dict], cores: int = 1) -> dict:
    """Times to 1 % error (s) of the pipeline and of CalculiX on ``cores`` cores, their
    ratios, and the 1- against multi-rank times on the finest mesh."""
    out: dict = {"tolerance": 0.01, "cores": cores}
    for name, keys in (("both", ("peak_err", "critical_err")), ("critical", ("critical_err",))):
        pipe = time_to_error(rows, {"dolfinx"}, keys, cores=cores)
        ccx_total = time_to_error(rows, {"calculix"}, keys, cores=cores)
        ccx_core = time_to_error(rows, {"calculix"}, keys, time_key="t_core", cores=cores)
        block = {"pipeline": pipe, "calculix_total": ccx_total, "calculix_core": ccx_core}
        if pipe and ccx_total:
            block["ratio_total"] = ccx_total["time_s"] / pipe["time_s"]
        if pipe and ccx_core:
            block["ratio_core"] = ccx_core["time_s"] / pipe["time_s"]
        out[name] = block
    # Scaling: the same finest-mesh point on more ranks (pipeline) or threads (CalculiX).
    good = [r for r in rows if "error" not in r]
    scaling = []
    for r in good:
        if r["cores"] == cores:
            continue
        base = next((b for b in good if b["cores"] == cores and b["kind"] == r["kind"]
                     and b["order"] == r["order"] and b["solver"] == r["solver"]
                     and b["factor"] == r["factor"] and b.get("pilot") == r.get("pilot")), None)
        if base is None:
            continue
        scaling.append({"config": label(r), "factor": r["factor"], "dofs": r["dofs"],
                        "same_mesh": r["dofs"] == base["dofs"],
                        "cores": r["cores"], "time_s": r["t_total"], "base_time_s": base["t_total"],
                        "speedup": base["t_total"] / r["t_total"],
                        "solve_speedup": (base["t_ccx"] / r["t_ccx"] if r["kind"] == "calculix"
                                          else base["t_solve"] / r["t_solve"]),
                        "peak_rel_diff": (r["peak_MPa"] - base["peak_MPa"]) / base["peak_MPa"],
                        "critical_rel_diff": (r["critical_MPa"] - base["critical_MPa"]) / base["critical_MPa"]})
    out["scaling"] = scaling
    return out


COLUMNS = [("config", 22), ("factor", 6), ("DOFs", 8), ("its", 4), ("geom", 6), ("mesh", 6),
           ("import", 6), ("asm|wr", 6), ("solve|ccx", 9), ("post", 6), ("total", 7),
           ("MiB", 6), ("peak", 7), ("err%", 7), ("crit", 7), ("err%", 7)]


def table(rows: list[dict]) -> str:
    def f(v, w, fmt="{:.2f}"):
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return "-".rjust(w)
        return (fmt.format(v) if not isinstance(v, str) else v).rjust(w)

    head = " ".join(n.rjust(w) for n, w in COLUMNS)
    lines = [head, "-" * len(head)]
    for r in rows:
        if "error" in r:
            lines.append(f"{label(r):>22} {r['factor']:6.2f}  FAILED: {r['error']}")
            continue
        ccx = r["kind"] == "calculix"
        asm = (r["t_loads"] or 0) + (r["t_write"] or 0) if ccx else r["t_assemble"]
        sol = r["t_ccx"] if ccx else r["t_solve"]
        mem = max(r["mem_MiB"], r.get("ccx_mem_MiB") or 0.0)
        cells = [label(r), f"{r['factor']:.2f}", str(r["dofs"]), f(r["iterations"], 4, "{:d}"),
                 f(r["t_geometry"], 6), f(r["t_mesh"], 6), f(r["t_import"], 6), f(asm, 6),
                 f(sol, 9), f(r["t_post"], 6), f(r["t_total"], 7), f(mem, 6, "{:.0f}"),
                 f(r["peak_MPa"], 7), f(100 * r["peak_err"], 7, "{:+.2f}"),
                 f(r["critical_MPa"], 7), f(100 * r["critical_err"], 7, "{:+.2f}")]
        lines.append(" ".join(c.rjust(w) for c, (_, w) in zip(cells, COLUMNS)))
    return "\n".join(lines)


CSV_KEYS = ["kind", "order", "solver", "factor", "ranks", "threads", "dofs", "cells", "iterations",
            "repeats"] + [f"t_{s}" for s in STAGES] + [
            "t_total", "t_core", "t_total_min", "t_total_max", "t_imports", "t_interpreter",
            "mem_MiB", "mem_sum_MiB", "ccx_mem_MiB", "peak_MPa", "peak_err", "critical_MPa",
            "critical_err", "error"]


def write_csv(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_KEYS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in CSV_KEYS})


def pareto_plot(path: Path, rows: list[dict], ref: dict) -> bool:
    """Two log-log panels (global, critical): |error| against time, one series per config."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    good = [r for r in rows if "error" not in r]
    series: dict[str, list[dict]] = {}
    for r in good:
        series.setdefault(label(r), []).append(r)
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.8))
    markers = {1: "v", 2: "o", 3: "s"}
    floor = 1e-5
    for ax, key, title in ((axes[0], "peak_err", "global peak"), (axes[1], "critical_err", "critical-region peak")):
        for k, (name, rs) in enumerate(sorted(series.items())):
            rs = sorted(rs, key=lambda r: r["t_total"])
            err = [max(abs(r[key]), floor) for r in rs]
            if rs[0]["kind"] == "calculix":
                # Black for the iterative solver, grey for spooles; dashed on more threads;
                # CalculiX's own part (write + ccx + read) dotted, on one thread only.
                colour = "k" if rs[0]["solver"] == "ccx-iterative" else "0.55"
                one = rs[0].get("threads", 1) == 1
                ax.plot([r["t_total"] for r in rs], err, "-" if one else "--", marker="*", color=colour,
                        ms=9, label=f"{name} (geometry→peak)")
                if one:
                    ax.plot([r["t_core"] for r in rs], err, ":", marker="*", color=colour, ms=7, mfc="none",
                            label=f"{name} (write+ccx+read only)")
            else:
                ax.plot([r["t_total"] for r in rs], err, "-" if rs[0]["ranks"] == 1 else "--",
                        marker=markers.get(rs[0]["order"], "o"), color=f"C{k % 10}", label=name)
        pipe = sorted((r for r in good if r["kind"] == "dolfinx"), key=lambda r: r["t_total"])
        front, best = [], math.inf
        for r in pipe:
            e = max(abs(r[key]), floor)
            if e < best * (1 - 1e-6):
                front.append((r["t_total"], e))
                best = e
        if front:
            ax.step(*zip(*front), where="post", color="grey", lw=4, alpha=0.25, label="pipeline Pareto front")
        ax.axhline(0.01, color="r", ls="--", lw=1, label="1 %")
        ax.set_xscale("log")
        ax.set_yscale("log")
        errs = [max(abs(r[key]), floor) for r in good] or [0.01]
        ax.set_ylim(min(0.5 * min(errs), 1e-3), max(1.5 * max(errs), 0.02))
        ax.set_xlabel("wall time, geometry → peaks (s; median of repeats)")
        ax.set_ylabel("|relative error| vs the reference")
        ax.set_title(f"No. 05 {title} (reference {ref['peak' if key == 'peak_err' else 'critical']:.2f} MPa)")
        ax.grid(alpha=0.3, which="both")
    # One legend for both panels (the same series), below them: inside, it covered data.
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def summary_text(s: dict, scaling: bool = True) -> str:
    lines = []
    for name, title in (("both", "both peaks"), ("critical", "critical peak")):
        b = s[name]
        p, ct, cc = b["pipeline"], b["calculix_total"], b["calculix_core"]

        def one(x):
            return "not reached" if x is None else \
                f"{x['time_s']:.2f} s ({x['config']}, factor {x['factor']}, {x['dofs']} DOFs)"
        lines.append(f"time to 1 % ({title}): pipeline {one(p)}")
        lines.append(f"    CalculiX geometry→peaks {one(ct)}; write+ccx+read only {one(cc)}")
        if "ratio_total" in b or "ratio_core" in b:
            r1 = b.get("ratio_total")
            r2 = b.get("ratio_core")
            lines.append(f"    CalculiX / pipeline: {r1:.2f}× (geometry→peaks), {r2:.2f}× (ccx core only)"
                         if r1 and r2 else f"    CalculiX / pipeline: {r1 or r2}")
    for sc in s.get("scaling", []) if scaling else []:
        lines.append(f"{sc['config']} on {sc['cores']} cores, factor {sc['factor']} ({sc['dofs']} DOFs): "
                     f"{sc['time_s']:.2f} s vs {sc['base_time_s']:.2f} s (speed-up {sc['speedup']:.2f}, "
                     f"solve {sc['solve_speedup']:.2f}); peaks differ by {sc['peak_rel_diff']:.1e} / "
                     f"{sc['critical_rel_diff']:.1e} relative"
                     + ("" if sc["same_mesh"] else " -- NOT THE SAME MESH (DOFs differ)"))
    return "\n".join(lines)


def csv_list(conv):
    """An argparse type: a comma-separated list, each item converted by ``conv``."""
    return lambda s: [conv(x) for x in s.split(",") if x.strip()]
