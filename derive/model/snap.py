"""How close to a multiple of pi/2 an angle of an arm file must be to be that multiple (derive.model.rigid.exact_angle).

By default ``SNAP_TOLERANCE`` (1e-8 rad, 10 nm at a metre: ROS files' 1.57079632679). A URDF arm's ``[arm]
snap_angles`` or a DH arm's ``[dh] snap_angles`` (from SNAP_TOLERANCE to NEAR_MISS) widens it while the file is
read (:func:`snapping`): the 1.5708 of CAD exporters (3.7e-6 rad from pi/2) is then pi/2, whose rotation has exact
0 and +-1 entries; kept as written its rotation is dense with 120-bit rationals, and the exact proofs of
``derive check`` (derive.proofs.torus) cost 3 to 8 times more.
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

from derive.model.fields import show

SNAP_TOLERANCE = 1e-8    # rad: an angle this close to k pi/2 is k pi/2 exactly
NEAR_MISS = 1e-3         # rad: an angle this close to k pi/2 but not snapped is reported
# the tolerance in force while a file is read: SNAP_TOLERANCE, or the file's snap_angles (:func:`snapping`)
_SNAP: ContextVar[float] = ContextVar("snap_tolerance", default=SNAP_TOLERANCE)


def snap_tolerance() -> float:
    """The snapping tolerance in force [rad]: ``SNAP_TOLERANCE``, or the one :func:`snapping` set."""
    return _SNAP.get()


@contextmanager
def snapping(tolerance: float | None) -> Iterator[None]:
    """Inside the block, derive.model.rigid.exact_angle snaps angles within ``tolerance`` rad of a multiple of
    pi/2 (None: ``SNAP_TOLERANCE``); the file readers (derive.model.urdf, derive.model.dh) open it."""
    token = _SNAP.set(SNAP_TOLERANCE if tolerance is None else float(tolerance))
    try:
        yield
    finally:
        _SNAP.reset(token)


def snap_choice(r, value, field: str) -> float | None | bool:
    """A snapping tolerance of an arm file (``[arm] snap_angles`` of a URDF arm, ``[dh] snap_angles``) read
    with the derive.model.fields.Reader ``r``: None when absent (SNAP_TOLERANCE), the tolerance [rad], or
    False after adding the problem: a number from SNAP_TOLERANCE to NEAR_MISS (:func:`snapping`)."""
    if value is None:
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) \
            and SNAP_TOLERANCE <= value <= NEAR_MISS:
        return float(value)
    r.add(field, f"a number of radians from {SNAP_TOLERANCE:g} to {NEAR_MISS:g}: angles that close to a multiple "
          "of pi/2 are taken as that multiple (1e-05 takes the 1.5708 of CAD exporters as pi/2)", show(value))
    return False
