"""Reading a logged run of the arm (derive identify's LOG.csv), every problem named.

A log is CSV text: a header row of column names, then one row of numbers per sample.
Columns (n joints): ``t`` [s]; ``theta1..n`` [rad or m]; exactly one of ``tau1..n``
(joint torque [N m or N]), ``current1..n`` (motor current [A]: joint torque gr Kt i)
or ``u1..n`` (the input u of eq. 12: voltage [V], or motor torque for torque-actuated
joints); optionally ``dtheta1..n`` [rad/s or m/s] (a tachometer: then the velocity is
not differentiated from theta); optionally ``valid`` (1: the sample is used, 0: it is not;
any other value is an error). Lines starting with ``#`` are comments. Times must
increase, uniformly to 1 % (the filter is designed for one sample rate), except at a
*join*: an interval of GAP median intervals or more (a gap between two runs), or a step of
an angle larger than JUMP and JUMP_RATIO times the steps around it (two runs appended: an
arm does not move 0.05 rad in one sample). Each stretch between joins is filtered on its
own (derive.identify.signals), and the report counts the joins.

:func:`log_paths` expands the LOG arguments of derive identify (a shell-style glob given as
one argument is expanded here, sorted); every run is read on its own (:func:`read_log`)
and filtered on its own (derive.identify.signals).
"""
from __future__ import annotations

import csv
import glob
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from derive.errors import DataError

FAMILIES = ("tau", "current", "u")
JITTER = 0.01          # the largest deviation of a sample interval from the median, relative
GAP = 1.5              # an interval this many median intervals long or longer is a join (a gap between runs)
JUMP = 0.05            # rad or m in one sample, and JUMP_RATIO x the neighbouring steps: a join (runs appended)
JUMP_RATIO = 20.0
MAX_BYTES = 4 << 30    # 4 GiB: a log is read whole
_NAME = re.compile(r"([a-z_]+?)(\d+)\Z")


@dataclass(frozen=True)
class Log:
    """A validated log: t (N,), theta (N x n), dtheta (N x n or None), the measured
    signal (N x n) of kind ``family`` (FAMILIES), the file it came from, and the ``valid``
    column (N, bool; None: the log has none, every sample is valid), the samples at which a
    new stretch starts after a join (module docstring) and how many joins were gaps in time."""

    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray | None
    signal: np.ndarray
    family: str
    source: str
    valid: np.ndarray | None = None
    joins: tuple[int, ...] = ()
    gaps: int = 0

    @property
    def samples(self) -> int:
        return len(self.t)

    @property
    def rate(self) -> float:
        """Sample rate [Hz] (the median interval's)."""
        return 1.0 / float(np.median(np.diff(self.t)))


def _columns(header: list[str], n: int, where: str) -> dict[str, list[int]]:
    """Column indices by family name (t, theta, dtheta, and one of FAMILIES); DataError for an
    unknown, repeated or missing column."""
    expected = (f"t, theta1..theta{n}, one of tau1..tau{n}, current1..current{n} or u1..u{n}, "
                f"optionally dtheta1..dtheta{n} and valid")
    found: dict[str, dict[int, int]] = {}
    for k, raw in enumerate(header):
        name = raw.strip()
        if name in ("t", "valid"):
            fam, joint = name, 0
        else:
            m = _NAME.match(name)
            fam, joint = (m[1], int(m[2])) if m else (name, -1)
            if fam not in ("theta", "dtheta") + FAMILIES or not 1 <= joint <= n:
                raise DataError(f"{where}: column {k + 1} {name!r}: expected one of the columns {expected} "
                                f"(the arm has {n} joint{'s' if n > 1 else ''}), got an unknown column")
        if joint in found.setdefault(fam, {}):
            raise DataError(f"{where}: column {k + 1} {name!r}: expected each column once, got it twice")
        found[fam][joint] = k
    families = [f for f in FAMILIES if f in found]
    if len(families) != 1:
        raise DataError(f"{where}: expected exactly one of the column families tau, current or u, got "
                        + (" and ".join(families) if families else "none"))
    need = {"t": [0], "theta": list(range(1, n + 1)), families[0]: list(range(1, n + 1))}
    if "dtheta" in found:
        need["dtheta"] = list(range(1, n + 1))
    if "valid" in found:
        need["valid"] = [0]
    for fam, joints in need.items():
        missing = [f"{fam}{j}" if fam != "t" else "t" for j in joints if j not in found.get(fam, {})]
        if missing:
            raise DataError(f"{where}: expected the columns {expected}, missing {', '.join(missing)}")
    return {fam: [found[fam][j] for j in joints] for fam, joints in need.items()}


def read_log(path: str | Path, n: int) -> Log:
    """The log at ``path`` for an n-joint arm. DataError (its message naming the line and
    column) for an unreadable file, an unknown, missing or repeated column, a row of
    another length, a value that is not a finite number, times that do not increase
    or are not uniform to 1 %."""
    where = str(path)
    try:
        with open(path, "rb") as stream:
            raw = stream.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DataError(f"{where}: cannot read the log ({exc.strerror or exc})") from None
    if len(raw) > MAX_BYTES:
        raise DataError(f"{where}: expected a log of at most {MAX_BYTES >> 30} GiB")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"{where}: expected UTF-8 text, got byte 0x{raw[exc.start]:02x} at offset {exc.start}") from None
    lines = text.splitlines()
    head = next((k for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")), None)
    if head is None:
        raise DataError(f"{where}: expected a header row of column names, got no rows")
    header = next(csv.reader([lines[head]]))
    cols = _columns(header, n, where)
    try:
        data = np.loadtxt(io.StringIO(text), delimiter=",", comments="#", skiprows=head + 1, ndmin=2, dtype=float)
    except ValueError:
        _first_bad_row(lines, head, header, where)
        raise
    if data.size == 0:
        raise DataError(f"{where}: expected rows of samples after the header, got none")
    if data.shape[1] != len(header):
        _first_bad_row(lines, head, header, where)
    rows = _LazyLines(lines, head)
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = map(int, np.argwhere(bad)[0])
        raise DataError(f"{where}: line {rows[r]}, column {header[c].strip()!r}: expected a finite number, "
                        f"got {float(data[r, c])!r} ({int(bad.sum())} non-finite value{'s' if bad.sum() > 1 else ''})")
    t = data[:, cols["t"][0]]
    step = np.diff(t)
    if (step <= 0).any():
        r = int(np.argmax(step <= 0)) + 1
        what = "repeated" if step[r - 1] == 0 else "unsorted"
        back = float(t[r - 1] - t[r]) > 2 * float(np.median(np.abs(step)))
        raise DataError(f"{where}: line {rows[r]}: expected times that increase, got t = {float(t[r])!r} after "
                        f"t = {float(t[r - 1])!r} on line {rows[r - 1]} ({what} times)"
                        + ("; a run appended with its own times? give each run as its own LOG" if back else ""))
    gaps = np.zeros(len(step), bool)
    if len(t) > 2:
        median = float(np.median(step))
        gaps = step >= GAP * median
        off = np.where(gaps, 0.0, np.abs(step - median))
        worst = int(np.argmax(off))
        if off[worst] > JITTER * median:
            raise DataError(f"{where}: line {rows[worst + 1]}: expected uniform sample times (within 1 % of the "
                            f"median interval {median:.6g} s), got an interval of {step[worst]:.6g} s; resample "
                            "the log onto a uniform grid")
    valid = None
    if "valid" in cols:
        flag = data[:, cols["valid"][0]]
        bad = (flag != 0) & (flag != 1)
        if bad.any():
            r = int(np.argmax(bad))
            raise DataError(f"{where}: line {rows[r]}, column 'valid': expected 0 or 1 (1: the sample is used, 0: it "
                            f"is left out), got {float(flag[r])!r} ({int(bad.sum())} such value"
                            f"{'s' if bad.sum() > 1 else ''})")
        valid = flag == 1
    family = next(f for f in FAMILIES if f in cols)
    theta = data[:, cols["theta"]]
    jumped = jumps(theta)
    if valid is not None:                   # a flagged sample may hold anything
        jumped &= valid[:-1] & valid[1:]
    joins = np.flatnonzero(gaps | jumped) + 1
    return Log(t=t, theta=theta, dtheta=data[:, cols["dtheta"]] if "dtheta" in cols else None,
               signal=data[:, cols[family]], family=family, source=where, valid=valid,
               joins=tuple(int(k) for k in joins), gaps=int(gaps.sum()))


def jumps(theta: np.ndarray) -> np.ndarray:
    """(N - 1,) bool: the steps theta[k] -> theta[k + 1] at which some joint jumps (module docstring)."""
    d = np.abs(np.diff(theta, axis=0))
    if len(d) < 3:
        return np.zeros(len(d), bool)
    pad = np.pad(d, ((2, 2), (0, 0)))
    around = np.maximum.reduce([pad[0:-4], pad[1:-3], pad[3:-1], pad[4:]])
    return ((d > JUMP) & (d > JUMP_RATIO * around)).any(axis=1)


def log_paths(arguments: list[str | Path]) -> list[Path]:
    """The LOG arguments as files: each one that holds a glob character (``*``, ``?``, ``[``) and
    is not itself an existing file is expanded (sorted); the rest kept as given. DataError for a
    glob that matches no file, and for a file named twice."""
    out: list[Path] = []
    for arg in arguments:
        text = str(arg)
        if any(c in text for c in "*?[") and not Path(text).exists():
            found = sorted(glob.glob(text))
            if not found:
                raise DataError(f"{text}: expected the glob to match at least one log file, got no match")
            out += [Path(f) for f in found]
        else:
            out.append(Path(text))
    seen: dict[Path, str] = {}
    for path in out:
        key = Path(path).resolve()
        if key in seen:
            raise DataError(f"{path}: expected each log once, got it twice (also as {seen[key]})")
        seen[key] = str(path)
    return out


class _LazyLines:
    """rows[r]: the line number of data row r, counted only when a message needs one."""

    def __init__(self, lines: list[str], head: int):
        self.lines, self.head, self.numbers = lines, head, None

    def __getitem__(self, r: int) -> int:
        if self.numbers is None:
            self.numbers = _line_numbers(self.lines, self.head)
        return self.numbers[r]


def _line_numbers(lines: list[str], head: int) -> list[int]:
    """The 1-based line number of each data row (comments and blank lines skipped)."""
    return [k + 1 for k in range(head + 1, len(lines)) if lines[k].strip() and not lines[k].lstrip().startswith("#")]


def _first_bad_row(lines: list[str], head: int, header: list[str], where: str) -> None:
    """Raise the DataError of the first row that has the wrong number of values or a value
    that is not a number."""
    for number in _line_numbers(lines, head):
        values = next(csv.reader([lines[number - 1]]))
        if len(values) != len(header):
            raise DataError(f"{where}: line {number}: expected {len(header)} comma-separated values (the "
                            f"header's columns), got {len(values)}")
        for name, value in zip(header, values):
            try:
                float(value)
            except ValueError:
                raise DataError(f"{where}: line {number}, column {name.strip()!r}: expected a number, got "
                                f"{value.strip()[:40]!r}") from None
    raise DataError(f"{where}: expected rows of comma-separated numbers")


def minimum_samples(log: Log, p: int, n: int) -> None:
    """DataError when the log has fewer equations (samples x joints) than base parameters."""
    if log.samples * n < p:
        raise DataError(f"{log.source}: {log.samples} samples x {n} joints = {log.samples * n} equations, fewer "
                        f"than the {p} base parameters to identify: expected at least {math.ceil(p / n)} samples")
