"""The run's plots as a reader meets them (pipeline/output/plots.py): no legend covers a
panel's data or runs off the figure, no title is cut, the allowable is drawn inside each
tornado panel or named in its title, and each peaks panel's title says the peak's status
and verdict in results.json's words. Measured on the drawn figures (matplotlib's window
extents, pixels), for made-up results of No. 05's shape (MPa)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from pipeline.output.plots import peaks_figure, tornado_figure  # noqa: E402


def _res(allowable: float = 80.0) -> dict:
    """results.json's keys the plots read: three meshes, both peaks, seven varied inputs."""
    levels = [{"dofs": d, "peak_MPa": p, "peak_unaveraged_MPa": p + 0.7, "peak_averaged_MPa": p - 0.7,
               "critical_peak_MPa": c, "critical_unaveraged_MPa": c, "critical_averaged_MPa": c - 0.03}
              for d, p, c in ((197862, 113.77, 66.22), (118302, 113.84, 66.23), (72303, 113.91, 66.23))]
    ranges = {"dj": ([18.0, 21.0], [136.4, 106.1], [66.6, 65.9]), "rf": ([1.2, 1.8], [124.3, 106.1], [65.7, 66.6]),
              "seat_inner": ([23.14, 26.86], [114.1, 113.4], [67.6, 65.6]),
              "seat_outer": ([35.14, 38.86], [114.2, 113.3], [67.0, 65.4]),
              "bearing_shape": (["cosine", "uniform"], [113.77, 116.4], [66.22, 66.23]),
              "bearing_centre_mm": ([27.05, 29.5], [100.6, 113.77], [57.4, 66.22]),
              "bearing_length_mm": ([4.4, 11.0], [108.1, 113.77], [66.3, 66.22])}
    return {"case": {"size": "05", "allowable_MPa": allowable},
            "fe": {"levels": levels, "peak_MPa": 113.77, "critical_peak_MPa": 66.22,
                   "peak": {"value_MPa": 113.77, "status": "within tolerance", "error_estimate": {"band": 0.73}},
                   "critical": {"value_MPa": 66.22, "status": "within tolerance", "error_estimate": {"band": 0.1}},
                   "verdict": {"global_peak": {"verdict": "fail"}, "critical_peak": {"verdict": "pass"}}},
            "sensitivity": [{"input": k, "range": r, "unit": "" if isinstance(r[0], str) else "mm",
                             "peak_MPa": g, "critical_peak_MPa": c} for k, (r, g, c) in ranges.items()],
            "sensitivity_summary": {"noise_MPa": {"global_peak": 0.85, "critical_peak": 0.045}}}


def _laid_out(fig):
    """The figure drawn, its renderer, and its box (pixels)."""
    fig.canvas.draw()
    return fig.canvas.get_renderer(), fig.bbox


def _inside(box, outer, tol: float = 0.5) -> bool:
    return (box.x0 >= outer.x0 - tol and box.x1 <= outer.x1 + tol and box.y0 >= outer.y0 - tol
            and box.y1 <= outer.y1 + tol)


def _legends(fig) -> list:
    return [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]


@pytest.mark.parametrize("allowable", [80.0, 60.0, 300.0, 10.0])
def test_no_legend_covers_data_or_runs_off_and_the_allowable_is_seen_or_named(allowable):
    """The tornado chart at No. 05's allowable, 80 MPa (inside both panels' reach), and at
    allowables far off one or both (then named in the title, left or right)."""
    fig = tornado_figure(_res(allowable))
    try:
        renderer, box = _laid_out(fig)
        for legend in _legends(fig):
            extent = legend.get_window_extent(renderer)
            assert _inside(extent, box)
            assert not any(extent.overlaps(ax.bbox) for ax in fig.axes)
        for ax in fig.axes:
            assert _inside(ax.title.get_window_extent(renderer), box), ax.get_title()
            lo, hi = ax.get_xlim()
            drawn = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--" and ln.get_xdata()[0] == allowable]
            if lo <= allowable <= hi:
                assert drawn, ax.get_title()
            else:
                side = "left" if allowable < lo else "right"
                assert f"allowable {allowable:g} MPa: off the axis, {side}" in ax.get_title()
        labels = [t.get_text() for lg in _legends(fig) for t in lg.get_texts()]
        assert (f"allowable {allowable:g} MPa" in labels) == any(
            ax.get_xlim()[0] <= allowable <= ax.get_xlim()[1] for ax in fig.axes)
    finally:
        plt.close(fig)
    # No. 05's own allowable lies within half of each peak's value of it: drawn in both panels.
    fig = tornado_figure(_res(80.0))
    try:
        assert all(ax.get_xlim()[0] <= 80.0 <= ax.get_xlim()[1] for ax in fig.axes)
    finally:
        plt.close(fig)


def test_the_peaks_legends_sit_below_the_data_and_the_titles_say_the_status():
    """peaks.png: each panel's legend below its axes (inside, it covered the coarser meshes'
    readings), inside the figure; each title the peak's status and verdict in results.json's
    words, not the trend's."""
    res = _res()
    fig = peaks_figure(res)
    try:
        renderer, box = _laid_out(fig)
        for legend in _legends(fig):
            extent = legend.get_window_extent(renderer)
            assert _inside(extent, box) and not any(extent.overlaps(ax.bbox) for ax in fig.axes)
        titles = [ax.get_title() for ax in fig.axes]
        assert "within tolerance (0.64 %), FAIL" in titles[0] and "within tolerance (0.15 %), PASS" in titles[1]
        assert all(_inside(ax.title.get_window_extent(renderer), box) for ax in fig.axes)
    finally:
        plt.close(fig)


def test_matplotlib_is_loaded_ahead_with_the_backend_the_plots_use():
    from pipeline.output.plots import load_matplotlib
    assert load_matplotlib()
    import matplotlib
    assert matplotlib.get_backend().lower() == "agg"
