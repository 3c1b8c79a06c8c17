"""Figures of a sweep: the tracking-error envelope over time and metric histograms.

matplotlib with the Agg backend (as derive.sim.plots), fixed size and dpi, no
metadata timestamps.
"""
from __future__ import annotations

import numpy as np

from derive.sim.plots import LABEL, STYLE, _png, plt
from derive.sim.sweep import SampleResult


def envelope_figure(results: list[SampleResult], names: tuple[str, ...], n: int, worst: dict) -> bytes:
    """Per link (rows) and controller (columns, each its own scale): the median
    tracking error, its 5-95 % band over the samples, and the worst sample's error."""
    cols = len(names)
    fig, axes = plt.subplots(n, cols, figsize=(3.6 * cols, 2.6 * n), sharex=True, squeeze=False)
    t = results[0].t
    for c, name in enumerate(names):
        color, _ = STYLE.get(name, ("k", "-"))
        runs = [r.errors[name] for r in results if r.errors.get(name) is not None]
        axes[0, c].set_title(LABEL.get(name, name), fontsize=9)
        if not runs:
            continue
        e = np.degrees(np.stack(runs))   # samples x points x n
        lo, mid, hi = np.percentile(e, [5, 50, 95], axis=0)
        w = next((r for r in results if r.index == worst[name]), None)
        for i in range(n):
            ax = axes[i, c]
            ax.fill_between(t, lo[:, i], hi[:, i], color=color, alpha=0.25, lw=0, label="5-95 %")
            ax.plot(t, mid[:, i], color=color, lw=1, label="median")
            if w is not None and w.errors.get(name) is not None:
                ax.plot(t, np.degrees(w.errors[name][:, i]), color="k", lw=0.6, ls=":",
                        label=f"worst (sample {w.index})")
    for i in range(n):
        axes[i, 0].set_ylabel(f"e{i + 1} [deg]")
        for c in range(cols):
            axes[i, c].grid(True, lw=0.3)
            axes[i, c].tick_params(labelsize=8)
    for c in range(cols):
        axes[-1, c].set_xlabel("t [s]")
    axes[0, 0].legend(loc="upper right", fontsize=7)
    fig.suptitle(f"tracking error over {len(results)} samples")
    fig.tight_layout()
    return _png(fig)


def histogram_figure(results: list[SampleResult], names: tuple[str, ...], n: int,
                     metric: str = "steady_state_error") -> bytes:
    """Histograms of ``metric`` per link (log-spaced bins), one colour per controller."""
    fig, axes = plt.subplots(1, n, figsize=(4 * n, 3.2), squeeze=False)
    for i in range(n):
        ax = axes[0, i]
        series = {name: np.array([r.metrics[name][i][metric] for r in results if name in r.metrics])
                  for name in names}
        values = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in series.values()] or [np.ones(1)])
        lo, hi = (values.min(), values.max()) if values.size else (1e-6, 1.0)
        bins = np.logspace(np.log10(lo) - 0.05, np.log10(hi) + 0.05, 30)
        for name, v in series.items():
            v = v[np.isfinite(v) & (v > 0)]
            color, _ = STYLE.get(name, ("k", "-"))
            ax.hist(v, bins=bins, color=color, alpha=0.5, label=LABEL.get(name, name))
        ax.set_xscale("log")
        ax.set_xlabel(f"{metric} [rad], link {i + 1}")
        ax.set_ylabel("samples")
        ax.grid(True, lw=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return _png(fig)
