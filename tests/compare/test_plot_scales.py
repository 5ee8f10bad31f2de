"""The differences plot (``loopcheck run``'s differences.png, and the sweep's worst variant) is
scaled to its data: each axis encloses its differences and spans little more than them; the
gate's tolerance is a band only when it is within a decade of the largest difference, and
otherwise the legend says how far off scale it is.

The seed's engines differ by at most 5.85e-6 rad and 1.25e-3 rad/s (measured) against the
default tolerances 1e-3 rad and 0.1 rad/s: both off scale (171× and 80×).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from loopcheck.compare.plots import DATA_MARGIN, plot_differences, tolerance_band
from loopcheck.compare.run import judge


def drawn(c, monkeypatch, tmp_path):
    """The figure plot_differences saves for ``c``."""
    import loopcheck.compare.plots

    kept = []
    monkeypatch.setattr(loopcheck.compare.plots, "_save", lambda fig, path: kept.append(fig))
    plot_differences(c, tmp_path / "d.png")
    (fig,) = kept
    fig.canvas.draw()
    return fig


def bands(ax) -> list[tuple[float, float]]:
    """The y extent (data coordinates) of every filled area of ``ax`` spanning its width."""
    out = []
    for patch in ax.patches:
        y = patch.get_path().transformed(patch.get_transform() - ax.transData).vertices[:, 1]
        out.append((float(y.min()), float(y.max())))
    return out


def legend_texts(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_the_tolerance_band_is_drawn_within_a_decade_only():
    assert tolerance_band(1.25e-3, 0.1, "rad/s") == (
        False, "gate tolerance ±0.1 rad/s: off scale, 80× the largest difference")
    assert tolerance_band(1e-3, 1e-2, "rad") == (True, "gate tolerance ±0.01 rad")  # a decade exactly
    assert tolerance_band(1e-3, 1.1e-2, "rad")[0] is False
    assert tolerance_band(1e-3, 1e-4, "rad") == (True, "gate tolerance ±0.0001 rad")
    assert tolerance_band(1e-3, 9e-5, "rad") == (
        False, "gate tolerance ±9e-05 rad: too narrow to show, 0.09× the largest difference")
    assert tolerance_band(0.0, 1e-3, "rad") == (False, "gate tolerance ±0.001 rad: off scale, every difference is 0")


def test_the_seed_s_differences_fill_their_axes_and_the_tolerances_are_named(seed_comparison, monkeypatch, tmp_path):
    """Each axis spans its data plus DATA_MARGIN (8 %) of their range at each end, so the data
    fill at least 1/(1 + 2·0.08) of it; no band is drawn and the legend names the tolerance off
    scale. (The old axes were ±tolerance: the data filled 0.3 % and 0.6 % of them.)"""
    fig = drawn(seed_comparison, monkeypatch, tmp_path)
    d = seed_comparison.diff
    for ax, values, ratio in zip(fig.axes, (d.dq, d.domega), ("171×", "80×")):
        low, high = ax.get_ylim()
        assert low <= values.min() and values.max() <= high
        assert (high - low) <= (1 + 2 * DATA_MARGIN) * np.ptp(values) * (1 + 1e-9)
        assert bands(ax) == []
        assert any(f"off scale, {ratio} the largest difference" in text for text in legend_texts(ax))


def test_a_tolerance_within_a_decade_is_a_band_on_the_scale_of_the_data(seed_comparison, monkeypatch, tmp_path):
    """Tolerances set to 3.4× and 2.4× the seed's largest differences: each is a band from
    −tol to +tol, inside the axis, which spans the band plus its margin."""
    d = seed_comparison.diff
    tol = replace(seed_comparison.gate.tolerances, q_atol=2e-5, omega_atol=3e-3)
    c = judge(seed_comparison.scene, seed_comparison.reference, seed_comparison.other, tol)
    fig = drawn(c, monkeypatch, tmp_path)
    for ax, values, limit in zip(fig.axes, (d.dq, d.domega), (2e-5, 3e-3)):
        assert np.max(np.abs(values)) * 10 >= limit  # within a decade: drawn
        (band,) = bands(ax)
        assert band == pytest.approx((-limit, limit), rel=1e-12)
        low, high = ax.get_ylim()
        assert low <= -limit and limit <= high and (high - low) <= 2 * limit * (1 + 2 * DATA_MARGIN) * (1 + 1e-9)
        assert any(text.startswith("gate tolerance ±") and "off scale" not in text for text in legend_texts(ax))
