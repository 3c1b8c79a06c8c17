"""Which samples of a log derive identify uses: the ``valid`` column and the ``--exclude`` rules.

A real log holds samples that are not the joint torque of a moving arm. Each rule names
one kind; the report says how many samples (or torque values) each removed, per log:

=============  ===============================================================  ===============
rule           removes                                                          removes what
=============  ===============================================================  ===============
``valid``      the samples whose ``valid`` column is 0 (derive.identify.log)    whole samples
``ends=MS``    the first and the last MS milliseconds of each log (run)        whole samples
``brake``      the samples where every joint's torque is exactly 0 (brakes      whole samples
               holding the arm, a drive switched off)
``zeros``      a joint's torque that is exactly 0 (a dropout: 1.32, 0, 2.34     that torque
               N m; a joint whose drive is off while the others move)
``saturated``  a torque at the joint's limit, to SATURATION (clipped: the       that torque
               command, not what the joint felt): ``tau`` against gear ratio
               x ``torque_limit``, ``u`` against ``torque_limit`` or
               ``voltage_limit``
=============  ===============================================================  ===============

A removed sample splits its log: the motion is filtered and differentiated on each
stretch of kept samples on its own (a brake phase or a flagged sample may hold anything,
and the arm stops abruptly when the brakes close), a removed torque splits that joint's
torque alike (derive.identify.signals), so that no filter reaches across a gap. Rules apply in the
order of the table; each counts what the earlier ones left.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from derive.errors import DataError
from derive.identify.log import Log
from derive.model.actuators import Motor
from derive.model.chain import Actuation

RULES = ("brake", "zeros", "saturated", "ends")
SATURATION = 1e-3    # a torque within 0.1 % of the limit is at it


@dataclass(frozen=True)
class Exclusion:
    """The ``--exclude`` rules chosen (module docstring); ``ends_ms`` 0: not chosen."""

    brake: bool = False
    zeros: bool = False
    saturated: bool = False
    ends_ms: float = 0.0

    def text(self) -> str:
        """The rules as the command line gives them (``none`` when none)."""
        out = [r for r in ("brake", "zeros", "saturated") if getattr(self, r)]
        out += [f"ends={self.ends_ms:g}"] if self.ends_ms else []
        return ",".join(out) or "none"


@dataclass(frozen=True)
class Mask:
    """What of one log is used: ``sample`` (N, bool: motion and torque), ``torque`` (N x n,
    bool: that joint's torque, False wherever ``sample`` is); ``removed``: per rule (``valid``,
    ``ends``, ``brake``: samples; ``zeros``, ``saturated``: torque values) how many it removed,
    and per joint (``zeros_per_joint``, ``saturated_per_joint``); per joint the torque values
    kept (``kept_torques``) and how many of them are exactly 0 (``kept_zeros``)."""

    sample: np.ndarray
    torque: np.ndarray
    removed: dict

    @staticmethod
    def everything(log: Log) -> "Mask":
        """Every sample of ``log`` that its valid column keeps (no rules)."""
        sample = np.ones(log.samples, bool) if log.valid is None else log.valid.copy()
        return Mask(sample, np.repeat(sample[:, None], log.signal.shape[1], axis=1), {})


def parse_exclude(values: list[str] | None) -> Exclusion:
    """The rules of ``--exclude`` (repeated, or comma-separated): brake, zeros, saturated,
    ends=MS. DataError naming an unknown rule or a bad MS."""
    chosen: dict = {}
    for value in values or ():
        for raw in str(value).split(","):
            word = raw.strip()
            name, _, arg = word.partition("=")
            if name not in RULES:
                raise DataError(f"--exclude {word!r}: expected one of brake, zeros, saturated, ends=MS (milliseconds "
                                "at each end of every log), got an unknown rule")
            if name == "ends":
                try:
                    ms = float(arg.removesuffix("ms"))
                except ValueError:
                    ms = math.nan
                if not (math.isfinite(ms) and ms > 0):
                    raise DataError(f"--exclude {word!r}: expected ends=MS with MS > 0 milliseconds (e.g. ends=200), "
                                    f"got {arg!r}")
                chosen["ends_ms"] = ms
            elif arg:
                raise DataError(f"--exclude {word!r}: expected the rule {name} without a value")
            else:
                chosen[name] = True
    return Exclusion(**chosen)


def limits(log: Log, motors: Sequence[Motor]) -> np.ndarray:
    """Per joint the bound on |signal| at which it saturates (inf: none known): ``u`` the motor's
    input limit, ``tau`` gear ratio x torque_limit of a torque-actuated joint; none for currents."""
    out = np.full(len(motors), math.inf)
    for j, motor in enumerate(motors):
        torque = motor.actuation is Actuation.TORQUE
        if log.family == "u":
            limit = motor.input_limit
        elif log.family == "tau" and torque and motor.torque_limit is not None:
            limit = motor.gear_ratio * motor.torque_limit
        else:
            limit = None
        if limit is not None:
            out[j] = float(limit)
    return out


def mask(log: Log, rules: Exclusion, motors: Sequence[Motor]) -> Mask:
    """The samples and torques of ``log`` that ``rules`` (and its valid column) keep (``motors``:
    the arm's, derive.model.actuators.Motor, for their limits). DataError for ``saturated`` on
    a log none of whose joints has a known limit."""
    n = log.signal.shape[1]
    sample = np.ones(log.samples, bool) if log.valid is None else log.valid.copy()
    removed: dict = {}
    if log.valid is not None:
        removed["valid"] = int((~log.valid).sum())
    if rules.ends_ms:
        before = sample.copy()
        span = rules.ends_ms / 1000.0
        sample &= (log.t - log.t[0] >= span) & (log.t[-1] - log.t >= span)
        removed["ends"] = int((before & ~sample).sum())
    if rules.brake:
        still = (log.signal == 0).all(axis=1) & sample
        sample &= ~still
        removed["brake"] = int(still.sum())
    torque = np.repeat(sample[:, None], n, axis=1)
    if rules.zeros:
        hit = (log.signal == 0) & torque
        torque &= ~hit
        removed["zeros"] = int(hit.sum())
        removed["zeros_per_joint"] = [int(x) for x in hit.sum(axis=0)]
    if rules.saturated:
        bound = limits(log, motors)
        if not np.isfinite(bound).any():
            what = {"tau": "a torque-actuated motor's torque_limit", "u": "the motors' torque_limit or voltage_limit",
                    "current": "a current limit, which the arm file does not hold"}[log.family]
            raise DataError(f"--exclude saturated: expected a limit to compare the log's {log.family}1..{n} with "
                            f"({what}), got none in the arm file")
        hit = (np.abs(log.signal) >= bound * (1 - SATURATION)) & torque
        torque &= ~hit
        removed["saturated"] = int(hit.sum())
        removed["saturated_per_joint"] = [int(x) for x in hit.sum(axis=0)]
    removed["kept_torques"] = [int(x) for x in torque.sum(axis=0)]
    removed["kept_zeros"] = [int(x) for x in ((log.signal == 0) & torque).sum(axis=0)]
    return Mask(sample=sample, torque=torque, removed=removed)
