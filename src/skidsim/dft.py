"""Dynamic Friction Tester (ASTM E1911) traces: friction coefficient mu versus slider speed in km/h.

File format (see ``docs/data-contract.md``): a CSV file whose header (row 1) contains the columns
``speed_kmh`` (slider speed, km/h, >= 0) and ``mu`` (friction coefficient, dimensionless, 0 < mu < 1.5); other
columns are ignored. Rows may come in any order (a spin-down trace is recorded from high to low speed); rows
with the same speed are averaged. Blank lines are skipped; row numbers in messages are the file's line numbers
(header = row 1).

Conventions that change numbers:

* :meth:`DftTrace.at` interpolates linearly between the (sorted, de-duplicated) samples; it never
  extrapolates.
* :meth:`DftTrace.smooth_at` fits an ordinary least-squares straight line (uniform weights) to all samples
  with ``|speed - v| <= window_kmh`` and evaluates it at ``v`` (local linear regression, the window is
  clipped by the trace ends, so near an end it is one-sided).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from skidsim.errors import DftError

SPEED_COLUMN = "speed_kmh"
MU_COLUMN = "mu"
MU_RANGE = (0.0, 1.5)
"""Open interval of plausible friction coefficients."""


@dataclass(frozen=True, eq=False)
class DftTrace:
    """A DFT friction trace: ``mu`` (dimensionless) at strictly increasing ``speeds_kmh`` (km/h).

    ``path`` names the source file in messages.
    """

    speeds_kmh: np.ndarray
    mu: np.ndarray
    path: str = "<dft>"

    def __post_init__(self) -> None:
        s = np.asarray(self.speeds_kmh, dtype=float)
        m = np.asarray(self.mu, dtype=float)
        if s.ndim != 1 or s.shape != m.shape or s.size < 2:
            raise DftError(self.path, "at least 2 samples with one mu per speed", got=f"shapes {s.shape}, {m.shape}")
        if not np.all(np.diff(s) > 0):
            raise DftError(self.path, "strictly increasing speeds_kmh (use read_dft or from_samples)")
        object.__setattr__(self, "speeds_kmh", s)
        object.__setattr__(self, "mu", m)

    @classmethod
    def from_samples(cls, speeds_kmh, mu, path: str = "<dft>") -> DftTrace:
        """Sort samples by speed and average the mu of equal speeds."""
        s = np.asarray(speeds_kmh, dtype=float)
        m = np.asarray(mu, dtype=float)
        uniq, inverse = np.unique(s, return_inverse=True)
        mean = np.bincount(inverse, weights=m, minlength=uniq.size) / np.bincount(inverse, minlength=uniq.size)
        if uniq.size < 2:
            raise DftError(path, "samples at 2 or more distinct speeds", got=f"{uniq.size} distinct speed(s)")
        return cls(uniq, mean, path)

    @property
    def range_kmh(self) -> tuple[float, float]:
        """Lowest and highest speed of the trace in km/h."""
        return float(self.speeds_kmh[0]), float(self.speeds_kmh[-1])

    def covers(self, speeds_kmh) -> bool:
        """True when every speed (km/h) lies within :attr:`range_kmh`."""
        v = np.atleast_1d(np.asarray(speeds_kmh, dtype=float))
        lo, hi = self.range_kmh
        return bool(np.all((v >= lo) & (v <= hi)))

    def _check(self, speeds_kmh) -> np.ndarray:
        v = np.asarray(speeds_kmh, dtype=float)
        lo, hi = self.range_kmh
        bad = v[~((v >= lo) & (v <= hi))]
        if bad.size:
            raise DftError(
                self.path,
                f"speeds within the trace's covered range {lo:g}-{hi:g} km/h",
                column=SPEED_COLUMN,
                got=float(bad.ravel()[0]),
                hint="the trace does not reach this speed; no extrapolation",
            )
        return v

    def at(self, speeds_kmh) -> np.ndarray:
        """mu at ``speeds_kmh`` (km/h) by linear interpolation; :class:`DftError` outside the trace."""
        v = self._check(speeds_kmh)
        return np.interp(v, self.speeds_kmh, self.mu)

    def smooth_at(self, speeds_kmh, window_kmh: float = 5.0) -> np.ndarray:
        """mu at ``speeds_kmh`` (km/h) by local linear regression within +-``window_kmh`` (km/h).

        Uniform-weight least-squares line through every sample with ``|speed - v| <= window_kmh``, evaluated
        at ``v``. Needs samples at 2 distinct speeds in the window, else :class:`DftError`. A straight-line
        trace is reproduced exactly; on a curved trace the bias is about ``curvature * window**2 / 6``.
        """
        if not (window_kmh > 0):
            raise ValueError(f"window_kmh must be positive km/h, got {window_kmh!r}")
        v = self._check(speeds_kmh)
        out = np.empty(v.shape)
        s, m = self.speeds_kmh, self.mu
        for idx, vi in np.ndenumerate(v):
            lo = np.searchsorted(s, vi - window_kmh, side="left")
            hi = np.searchsorted(s, vi + window_kmh, side="right")
            ss, mm = s[lo:hi], m[lo:hi]
            if ss.size < 2:
                raise DftError(
                    self.path,
                    f"samples at 2 or more speeds within +-{window_kmh:g} km/h of {vi:g} km/h",
                    column=SPEED_COLUMN,
                    got=f"{ss.size} sample(s)",
                    hint="widen window_kmh",
                )
            sc = ss - vi
            sbar, mbar = sc.mean(), mm.mean()
            sxx = np.sum((sc - sbar) ** 2)
            slope = np.sum((sc - sbar) * (mm - mbar)) / sxx
            out[idx] = mbar - slope * sbar
        return out


def _number(text: str, path, row: int, column: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise DftError(path, "a number", row=row, column=column, got=text) from None
    if not math.isfinite(x):
        raise DftError(path, "a finite number", row=row, column=column, got=text)
    return x


def read_dft(path) -> DftTrace:
    """Read a DFT CSV trace (columns ``speed_kmh`` in km/h and ``mu``) into a :class:`DftTrace`.

    Raises :class:`DftError` naming the file, the row (header = row 1) and the column for: a missing file,
    missing columns, a non-numeric or non-finite value, mu outside (0, 1.5), a negative speed, fewer than 2
    data rows, or fewer than 2 distinct speeds.
    """
    path = Path(path)
    if not path.is_file():
        raise DftError(path, "an existing DFT csv file", got="no such file")
    speeds, mus = [], []
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = None
        for fields in reader:
            row = reader.line_num
            if header is None:
                header = [f.strip() for f in fields]
                missing = [c for c in (SPEED_COLUMN, MU_COLUMN) if c not in header]
                if missing:
                    raise DftError(
                        path,
                        f"a header with columns {SPEED_COLUMN} and {MU_COLUMN}",
                        row=1,
                        got=",".join(header),
                        hint=f"missing {', '.join(missing)}",
                    )
                i_s, i_m = header.index(SPEED_COLUMN), header.index(MU_COLUMN)
                continue
            if not any(f.strip() for f in fields):
                continue  # blank line
            if len(fields) <= max(i_s, i_m):
                raise DftError(path, f"{len(header)} fields as in the header", row=row, got=f"{len(fields)} fields")
            s = _number(fields[i_s].strip(), path, row, SPEED_COLUMN)
            m = _number(fields[i_m].strip(), path, row, MU_COLUMN)
            if s < 0:
                raise DftError(path, "a speed >= 0 km/h", row=row, column=SPEED_COLUMN, got=s)
            if not (MU_RANGE[0] < m < MU_RANGE[1]):
                raise DftError(
                    path,
                    f"a friction coefficient between {MU_RANGE[0]:g} and {MU_RANGE[1]:g} (exclusive)",
                    row=row,
                    column=MU_COLUMN,
                    got=m,
                )
            speeds.append(s)
            mus.append(m)
    if header is None:
        raise DftError(path, f"a header with columns {SPEED_COLUMN} and {MU_COLUMN}", row=1, got="an empty file")
    if len(speeds) < 2:
        raise DftError(path, "at least 2 data rows", got=f"{len(speeds)} row(s)")
    return DftTrace.from_samples(speeds, mus, str(path))
