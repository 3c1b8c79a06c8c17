"""PNG figures of simulation traces, laid out like the paper's Figures 5-8.

matplotlib with the Agg backend, fixed size and dpi, no metadata timestamps.
"""
from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from derive.sim.simulate import Trace  # noqa: E402

STYLE = {"mpc": ("tab:red", "-"), "dobc": ("tab:blue", "--"), "npid": ("tab:green", "-"),
         "npid_unprotected": ("tab:orange", ":"), "mom": ("tab:purple", "-.")}
LABEL = {"mpc": "MPC (eq. 15)", "dobc": "DOBC (eq. 27)", "npid": "NPID (eq. 34)",
         "npid_unprotected": "PID without anti-windup", "mom": "MOM (momentum observer)"}


POINTS = 4000   # a line of more samples is drawn through each bucket's smallest and largest value


def _thin(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) of a line as drawn: unchanged up to 2 POINTS samples, else the smallest and the largest
    sample of each of POINTS buckets in time order (min-max decimation: every extreme stays, and the
    figure, 720 pixels wide, cannot show more; matplotlib kept every sample of a 0.1 ms run, 1.5 GB)."""
    count = len(t)
    if count <= 2 * POINTS:
        return t, y
    size = -(-count // POINTS)
    pad = size * POINTS - count
    padded = np.concatenate([y, np.full(pad, y[-1])]).reshape(POINTS, size)
    base = np.arange(POINTS) * size
    pick = np.sort(np.stack([base + padded.argmin(axis=1), base + padded.argmax(axis=1)], axis=1), axis=1).ravel()
    pick = np.minimum(pick, count - 1)
    return t[pick], y[pick]


def _line(ax, t: np.ndarray, y: np.ndarray, **style) -> None:
    ax.plot(*_thin(np.asarray(t), np.asarray(y)), **style)


def _label(tr: Trace) -> str:
    """The legend entry; a failed run says where it stopped."""
    label = LABEL.get(tr.name, tr.name)
    return label if tr.failure is None else f"{label}: FAILED at t = {tr.failure.time:.3g} s"


def _mark_failure(ax, tr: Trace, values: np.ndarray, color: str) -> None:
    """A cross at the last sample of a failed run."""
    if tr.failure is not None and len(tr.t):
        ax.plot([tr.t[-1]], [values[-1]], marker="x", ms=10, mew=2, color=color, ls="none")


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def link_figure(traces: list[Trace], i: int, unit: str = "V") -> bytes:
    """Link i: u [V, or ``unit``: N m in torque mode], theta-dot [deg/s], theta and y_d [deg] (Figures 5-6)."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for tr in traces:
        color, ls = STYLE.get(tr.name, ("k", "-"))
        _line(axes[0], tr.t, tr.u[:, i], color=color, ls=ls, lw=1, label=_label(tr))
        _line(axes[1], tr.t, np.degrees(tr.dtheta[:, i]), color=color, ls=ls, lw=1)
        _line(axes[2], tr.t, np.degrees(tr.theta[:, i]), color=color, ls=ls, lw=1)
        for ax, values in zip(axes, (tr.u[:, i], np.degrees(tr.dtheta[:, i]), np.degrees(tr.theta[:, i]))):
            _mark_failure(ax, tr, values, color)
    _line(axes[2], traces[0].t, np.degrees(traces[0].yd[:, i]), color="k", lw=0.8, ls="-.", label="y_d")
    for ax, label in zip(axes, (f"u [{unit}]", "velocity [deg/s]", "position [deg]")):
        ax.set_ylabel(label)
        ax.grid(True, lw=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[2].legend(loc="upper right", fontsize=8)
    axes[2].set_xlabel("t [s]")
    fig.suptitle(f"link {i + 1}")
    fig.tight_layout()
    return _png(fig)


def error_figure(traces: list[Trace]) -> bytes:
    """Tracking error y_d - C theta of every controller, per output (Figures 7-8; a continuous joint's
    wrapped to (-pi, pi], as the controllers take it)."""
    n = traces[0].theta.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n), sharex=True, squeeze=False)
    for i in range(n):
        ax = axes[i, 0]
        for tr in traces:
            color, ls = STYLE.get(tr.name, ("k", "-"))
            e = np.degrees(tr.error[:, i])
            _line(ax, tr.t, e, color=color, ls=ls, lw=1, label=_label(tr))
            _mark_failure(ax, tr, e, color)
        ax.set_ylabel(f"e{i + 1} [deg]")
        ax.grid(True, lw=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle("tracking error")
    fig.tight_layout()
    return _png(fig)


def difference_figure(traces: list[Trace], others: list[Trace], name: str, other: str) -> bytes:
    """theta of plant ``name`` minus theta of plant ``other`` [rad], per link, for every
    controller both ran (derive simulate --compare)."""
    by_name = {tr.name: tr for tr in others}
    n = traces[0].theta.shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.6 * n), sharex=True, squeeze=False)
    for i in range(n):
        ax = axes[i, 0]
        for tr in traces:
            o = by_name.get(tr.name)
            if o is None:
                continue
            k = min(len(tr.t), len(o.t))
            color, ls = STYLE.get(tr.name, ("k", "-"))
            _line(ax, tr.t[:k], tr.theta[:k, i] - o.theta[:k, i], color=color, ls=ls, lw=1, label=_label(tr))
        ax.set_ylabel(f"dtheta{i + 1} [rad]")
        ax.grid(True, lw=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"theta on the {name} plant minus theta on the {other} plant")
    fig.tight_layout()
    return _png(fig)
