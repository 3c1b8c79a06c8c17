"""From a log to the samples of the regression: zero-phase filtering, differentiation,
the joint torque of eq. 12's left side, decimation (derive identify).

Theta (and theta' when the log has it) and the measured signal pass the same low-pass
filter forwards and backwards: a Butterworth filter of order 4 (scipy.signal.butter,
second-order sections, scipy.signal.sosfiltfilt), so motion and torque keep the same
attenuation and no delay. theta' and theta'' are central differences of fourth order of
the filtered signals (exact for polynomials of degree 4). The rows within 2 / f_c of
either end are dropped (the filter's transients), then every r-th row is kept,
r = floor(f_s / (2 f_c)): the filtered noise then lies below the new Nyquist frequency
and consecutive rows are close to uncorrelated, as the standard deviations of least
squares assume (parallel filtering and decimation: M. Gautier, "Dynamic identification
of robots with power model", ICRA 1997; J. Swevers et al. 1997).

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
from scipy.signal import butter, sosfiltfilt

from derive.errors import DataError
from derive.identify import CUTOFF
from derive.identify.log import Log
from derive.model.actuators import terms
from derive.model.chain import Actuation, Chain

ORDER = 4         # of the Butterworth filter (CUTOFF: derive.identify, the default cut-off)


@dataclass(frozen=True)
class Samples:
    """The rows of the regression: t (N), theta, dtheta, ddtheta, the torque y of
    J theta'' + G and sign(theta') through the same filter as the torque (the Coulomb
    columns, N x n each); how they were made (cut-off [Hz], the log's rate [Hz],
    decimation r, rows dropped at each end)."""

    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    ddtheta: np.ndarray
    y: np.ndarray
    sign: np.ndarray
    cutoff: float
    rate: float
    decimation: int
    edge: int


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


def prepare(log: Log, chain: Chain, cutoff: float = CUTOFF) -> Samples:
    """The regression's samples of ``log`` (module docstring). DataError for a cut-off that is
    not below the log's Nyquist frequency, or too few rows left."""
    check_drives(log, chain)
    fs = log.rate
    if not (math.isfinite(cutoff) and 0 < cutoff < 0.5 * fs):
        raise DataError(f"--cutoff {cutoff:g} Hz: expected a frequency > 0 below the log's Nyquist frequency "
                        f"{0.5 * fs:g} Hz (sample rate {fs:g} Hz)")
    h = 1.0 / fs
    sos = butter(ORDER, cutoff, fs=fs, output="sos")
    edge = max(3, math.ceil(2 * fs / cutoff))
    step = max(1, math.floor(fs / (2 * cutoff)))
    if log.samples <= 2 * edge + 1:
        raise DataError(f"{log.source}: {log.samples} samples: expected more than {2 * edge + 1} (the filter's "
                        f"transients, 2 / f_c = {2 / cutoff:g} s at either end, are dropped)")
    pad = min(edge * 3, log.samples - 1)    # odd extension, long enough for its own transient to decay
    theta = sosfiltfilt(sos, log.theta, axis=0, padlen=pad)
    signal = sosfiltfilt(sos, log.signal, axis=0, padlen=pad)
    if log.dtheta is not None:
        dtheta = sosfiltfilt(sos, log.dtheta, axis=0, padlen=pad)
        ddtheta = differentiate(dtheta, h)[0]
    else:
        dtheta, ddtheta = differentiate(theta, h)
    B, emf, kt = drive_constants(chain)
    if log.family == "u":
        y = signal * B
    else:
        y = (signal * kt if log.family == "current" else signal) + emf * dtheta
    sign = sosfiltfilt(sos, np.sign(dtheta), axis=0, padlen=pad)   # a step, smeared as the torque's is
    rows = slice(edge, log.samples - edge, step)
    return Samples(t=log.t[rows], theta=theta[rows], dtheta=dtheta[rows], ddtheta=ddtheta[rows], y=y[rows],
                   sign=sign[rows],
                   cutoff=cutoff, rate=fs, decimation=step, edge=edge)
