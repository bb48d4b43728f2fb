"""Matplotlib plots (convergence); headless backend (units: MPa, mm)."""
from __future__ import annotations

from pathlib import Path


def convergence_plot(path: Path, conv: dict, case) -> bool:
    """Peak against representative mesh size N^(-1/3), with extrapolated value and GCI band."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, label in ((axes[0], "peak", "global peak"), (axes[1], "critical", "critical-region peak")):
        est = conv[key]
        h = est["h"]
        ax.plot(h, est["values"], "o-", label=f"FE {label}")
        if est.get("extrapolated") is not None and est["status"] == "converged":
            ext, band = est["extrapolated"], est["band"]
            ax.axhline(ext, color="k", ls="--", label=f"Richardson {ext:.2f} MPa")
            ax.axhspan(est["values"][0] - band, est["values"][0] + band, color="C1", alpha=0.2,
                       label=f"GCI band finest ±{band:.2f} MPa")
            ax.plot([0], [ext], "k*", ms=10)
        ax.set_xlim(left=0)
        ax.set_xlabel("representative mesh size h = DOFs^(-1/3)")
        ax.set_ylabel("von Mises (MPa)")
        ax.set_title(f"No. {case.size}: {label} [{est['status']}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
