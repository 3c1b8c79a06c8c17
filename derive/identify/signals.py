"""From a log to the samples of the regression: zero-phase filtering, differentiation,
the joint torque of eq. 12's left side, decimation (derive identify).

Theta (and theta' when the log has it) and the measured signal pass the same low-pass
filter forwards and backwards: a Butterworth filter of order 4 (scipy.signal.butter,
second-order sections, scipy.signal.sosfiltfilt), so motion and torque keep the same
attenuation and no delay. theta' and theta'' are central differences of fourth order of
the filtered signals (exact for polynomials of degree 4). The rows within 2 / f_c of
either end are dropped (the filter's transients; its odd extension is smooth where a run
starts or ends at rest), within CUT / f_c of an end that an excluded sample made (a cut
mid-motion, where the odd extension's kink in the second derivative leaves a transient of
about 1e-5 of the signal at 2 / f_c and 1e-6 at 3 / f_c), then every r-th row is kept,
r = floor(f_s / (2 f_c)): the filtered noise then lies below the new Nyquist frequency
and consecutive rows are close to uncorrelated, as the standard deviations of least
squares assume (parallel filtering and decimation: M. Gautier, "Dynamic identification
of robots with power model", ICRA 1997; J. Swevers et al. 1997).

A log is cut into stretches at its joins (derive.identify.log) and at the samples the
exclusion rules remove whole (derive.identify.exclude); each stretch is filtered and
differentiated on its own, its ends dropped as above. Within a stretch, a joint's torque
that a rule removed (a dropout, a saturated value) splits that joint's torque alike,
unless the gap is short (at most f_s / (FILL f_c) samples, a tenth of the cut-off's
period): then the filter runs across it, the gap bridged by a cubic spline through the
kept torques (for a signal below the cut-off, a far smaller error than the noise), and
only the gap's own rows are not used.

The measured signal becomes the torque J theta'' + G of eq. 12, which includes the
motors' back-EMF damping gr^2 Kt Kv / Ra theta' of voltage-driven joints:
tau1..n (joint torque): tau + gr^2 Kt Kv / Ra theta'; current1..n: gr Kt i + the same;
u1..n: B u (eq. 12 with d = 0). The Coulomb columns sign(theta') of derive identify
--coulomb are a step at every reversal: they pass the torque's filter too (parallel
filtering), so that the step is smeared alike on both sides of the regression; the other
columns are smooth functions of the motion, whose band lies below the cut-off.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp
from scipy.interpolate import CubicSpline
from scipy.signal import butter, sosfiltfilt

from derive.errors import DataError
from derive.identify import CUTOFF
from derive.identify.exclude import Mask
from derive.identify.log import Log
from derive.model.actuators import terms
from derive.model.chain import Actuation, Chain

ORDER = 4         # of the Butterworth filter (CUTOFF: derive.identify, the default cut-off)
CUT = 3.0         # x 1 / f_c dropped at an end made by an excluded sample (2 / f_c at a log's ends and joins)
FILL = 10         # a torque gap of at most f_s / (FILL f_c) samples (a tenth of the cut-off's period) is bridged


@dataclass(frozen=True)
class Run:
    """How one log became rows: its file, sample rate [Hz], samples, decimation r, rows dropped
    at each end of every stretch (the filter's transients), the stretches filtered on their
    own, the rows and torque equations it gives, what each exclusion rule removed
    (derive.identify.exclude.Mask.removed), the joins found in it (derive.identify.log) and
    how many of them were gaps in time."""

    source: str
    rate: float
    samples: int
    decimation: int
    edge: int
    stretches: int
    rows: int
    equations: int
    removed: dict
    joins: int = 0
    gaps: int = 0


@dataclass(frozen=True)
class Samples:
    """The rows of the regression, over every log: t (N, each log's own time), theta, dtheta,
    ddtheta, the torque y of J theta'' + G and sign(theta') through the same filter as the
    torque (the Coulomb columns), N x n each; ``use`` (N x n, bool): the torque equations
    used (False where a torque was excluded or lies within a filter transient of a gap:
    y is 0 there); ``run`` (N): the index of the log a row comes from; ``runs``: how each
    log was made into rows; the cut-off [Hz]."""

    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    ddtheta: np.ndarray
    y: np.ndarray
    sign: np.ndarray
    use: np.ndarray
    run: np.ndarray
    runs: tuple[Run, ...]
    cutoff: float

    @property
    def equations(self) -> int:
        return int(self.use.sum())

    @staticmethod
    def stack(parts: list["Samples"]) -> "Samples":
        """The rows of several logs, one after the other (each prepared on its own)."""
        cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in
               ("t", "theta", "dtheta", "ddtheta", "y", "sign", "use")}
        run = np.concatenate([np.full(len(p.t), k) for k, p in enumerate(parts)])
        return Samples(**cat, run=run, runs=tuple(r for p in parts for r in p.runs), cutoff=parts[0].cutoff)


def drive_constants(chain: Chain) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(B_ii, back-EMF damping gr^2 Kt Kv / Ra (0 for a torque-driven joint), torque per
    ampere gr Kt) per joint; the last None unless every joint is voltage-driven."""
    values = chain.values()
    volt = [a.actuation is Actuation.VOLTAGE for a in chain.actuators]
    B = np.array([float(sp.sympify(terms(a)[0]).xreplace(values)) for a in chain.actuators])
    emf = np.array([float((a.gear_ratio ** 2 * a.torque_constant * a.voltage_constant / a.resistance).xreplace(values))
                    if v else 0.0 for a, v in zip(chain.actuators, volt)])
    kt = np.array([float((a.gear_ratio * a.torque_constant).xreplace(values)) for a in chain.actuators]) \
        if all(volt) else None
    return B, emf, kt


def check_drives(log: Log, chain: Chain) -> None:
    """DataError when a current log meets an arm without motor constants."""
    if log.family == "current" and drive_constants(chain)[2] is None:
        torque = [i for i, a in enumerate(chain.actuators, 1) if a.actuation is not Actuation.VOLTAGE]
        raise DataError(f"{log.source}: a current log (current1..{chain.n}) needs each joint's motor constants "
                        f"(tau = gear_ratio torque_constant i), but motor[{torque[0]}] of the arm is torque-actuated "
                        "(no torque_constant); log tau1..n instead, or give the motors' constants")


def differentiate(x: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(x', x'') by fourth-order central differences along axis 0; the first and last two rows
    are not defined (zero)."""
    d1, d2 = np.zeros_like(x), np.zeros_like(x)
    d1[2:-2] = (x[:-4] - 8 * x[1:-3] + 8 * x[3:-1] - x[4:]) / (12 * h)
    d2[2:-2] = (-x[:-4] + 16 * x[1:-3] - 30 * x[2:-2] + 16 * x[3:-1] - x[4:]) / (12 * h * h)
    return d1, d2


def stretches(keep: np.ndarray, minimum: int) -> list[tuple[int, int]]:
    """The maximal runs [a, b) of True in ``keep`` (1-D) that are at least ``minimum`` long."""
    edges = np.diff(np.concatenate([[0], keep.astype(np.int8), [0]]))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    return [(int(a), int(b)) for a, b in zip(starts, ends) if b - a >= minimum]


def short_gaps(keep: np.ndarray, longest: int) -> np.ndarray:
    """The samples of the runs of False in ``keep`` (1-D) at most ``longest`` long with True on
    both sides (a dropout inside a stretch)."""
    out = np.zeros(len(keep), bool)
    for a, b in stretches(~keep, 1):
        if b - a <= longest and a > 0 and b < len(keep):
            out[a:b] = True
    return out


def _split(N: int, joins: tuple[int, ...]) -> list[tuple[int, int]]:
    """[a, b) between consecutive joins (the log's runs)."""
    cuts = [0, *joins, N]
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def _filter(sos: np.ndarray, x: np.ndarray, edge: int) -> np.ndarray:
    """x filtered forwards and backwards along axis 0, oddly extended (long enough for its own
    transient to decay)."""
    return sosfiltfilt(sos, x, axis=0, padlen=min(edge * 3, len(x) - 1))


def prepare(log: Log, chain: Chain, cutoff: float = CUTOFF, mask: Mask | None = None) -> Samples:
    """The regression's samples of ``log`` (module docstring), only from what ``mask`` keeps
    (derive.identify.exclude; default: every sample): each stretch of kept samples is
    filtered and differentiated on its own, each joint's torque on each stretch of its kept
    torques, and rows within 2 / f_c of a stretch's ends are not used. DataError for a
    cut-off that is not below the log's Nyquist frequency."""
    check_drives(log, chain)
    fs = log.rate
    if not (math.isfinite(cutoff) and 0 < cutoff < 0.5 * fs):
        hint = (f"; the sample interval is {1 / fs:.4g} s: a time column t in milliseconds? (t is in seconds)"
                if 1 / fs >= 0.05 else "")
        raise DataError(f"--cutoff {cutoff:g} Hz: expected a frequency > 0 below the log's Nyquist frequency "
                        f"{0.5 * fs:g} Hz (sample rate {fs:g} Hz){hint}")
    mask = mask if mask is not None else Mask.everything(log)
    h = 1.0 / fs
    sos = butter(ORDER, cutoff, fs=fs, output="sos")
    edge = max(3, math.ceil(2 * fs / cutoff))
    step = max(1, math.floor(fs / (2 * cutoff)))
    fill = max(1, math.floor(fs / (FILL * cutoff)))
    if log.samples <= 2 * edge + 1:
        raise DataError(f"{log.source}: {log.samples} samples: expected more than {2 * edge + 1} (the filter's "
                        f"transients, 2 / f_c = {2 / cutoff:g} s at either end, are dropped)")
    B, emf, kt = drive_constants(chain)
    N, n = log.signal.shape
    theta, dtheta, ddtheta = (np.zeros((N, n)) for _ in range(3))
    y, sign = np.zeros((N, n)), np.zeros((N, n))
    use = np.zeros((N, n), bool)
    rows = np.zeros(N, bool)
    cut = max(edge, math.ceil(CUT * fs / cutoff))
    runs = _split(N, log.joins)
    natural = {a for a, _ in runs} | {b for _, b in runs}           # a log's ends and its joins
    parts = [(a + c, a + d) for a, b in runs for c, d in stretches(mask.sample[a:b], 2 * edge + 2)]

    def used(lo: int, hi: int) -> slice:
        return slice(lo + (edge if lo in natural else cut), hi - (edge if hi in natural else cut))

    for a, b in parts:
        theta[a:b] = _filter(sos, log.theta[a:b], edge)
        if log.dtheta is not None:
            dtheta[a:b] = _filter(sos, log.dtheta[a:b], edge)
            ddtheta[a:b] = differentiate(dtheta[a:b], h)[0]
        else:
            dtheta[a:b], ddtheta[a:b] = differentiate(theta[a:b], h)
        rows[used(a, b)] = True
        for j in range(n):
            kept, raw = mask.torque[a:b, j], log.signal[a:b, j]
            filled = short_gaps(kept, fill)
            if filled.any():                     # a dropout: bridged for the filter, its own rows not used
                at = np.arange(b - a)
                raw = raw.copy()
                raw[filled] = CubicSpline(at[kept], raw[kept])(at[filled])
            for c, d in stretches(kept | filled, 2 * edge + 2):
                c, d = a + c, a + d
                signal = _filter(sos, raw[c - a:d - a], edge)
                if log.family == "u":
                    y[c:d, j] = signal * B[j]
                else:
                    y[c:d, j] = (signal * kt[j] if log.family == "current" else signal) + emf[j] * dtheta[c:d, j]
                sign[c:d, j] = _filter(sos, np.sign(dtheta[c:d, j]), edge)   # a step, smeared as the torque's
                use[used(c, d), j] = True
            use[a:b, j] &= ~filled
    keep = np.zeros(N, bool)
    for a, b in parts:                       # every r-th row of each stretch, after its transients
        span = used(a, b)
        keep[span.start:span.stop:step] = True
    keep &= rows
    use &= keep[:, None]
    keep &= use.any(axis=1)
    run = Run(source=log.source, rate=fs, samples=N, decimation=step, edge=edge, stretches=len(parts),
              rows=int(keep.sum()), equations=int(use.sum()), removed=dict(mask.removed), joins=len(log.joins),
              gaps=log.gaps)
    return Samples(t=log.t[keep], theta=theta[keep], dtheta=dtheta[keep], ddtheta=ddtheta[keep], y=y[keep],
                   sign=sign[keep], use=use[keep], run=np.zeros(int(keep.sum()), int), runs=(run,), cutoff=cutoff)
