"""Measured DFT values as the calibrations use them: a curve's (speed, mu) arrays and its value at given speeds.

A measured curve is a DataFrame (speed_kmh [km/h], mu), a mapping ``{speed_kmh: mu}`` or a
:class:`skidsim.dft.DftTrace`. Values at a speed: linear interpolation of the trace (as ``DftTrace.at``), or the
local linear regression within ``+-window_kmh`` when a window is given. A mapping is used as is.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.errors import InputError


def site_trace(traces: pd.DataFrame, site: str) -> pd.DataFrame:
    """One site's DFT trace (speed_kmh [km/h], mu; sorted by speed) from the ingest's trace table (columns site,
    speed_kmh, mu; ``dft_traces.parquet``)."""
    return traces[traces["site"] == site][["speed_kmh", "mu"]].sort_values("speed_kmh")


def measured_arrays(curve, *, source: str | Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(speeds km/h ascending, mu) of a measured curve; duplicate speeds are averaged.

    ``curve``: DataFrame with columns ``speed_kmh`` and ``mu``, a mapping ``{speed_kmh: mu}``, or an object
    with ``speeds_kmh`` and ``mu`` arrays (``skidsim.dft.DftTrace``). ``source`` names the file in errors.
    """
    src = source if source is not None else getattr(curve, "path", None)
    if isinstance(curve, pd.DataFrame):
        for col in ("speed_kmh", "mu"):
            if col not in curve.columns:
                raise InputError(
                    src,
                    "a column of the measured curve",
                    column=col,
                    got="missing",
                    hint=f"columns are {list(curve.columns)}",
                )
        v = pd.to_numeric(curve["speed_kmh"], errors="coerce").to_numpy(float)
        mu = pd.to_numeric(curve["mu"], errors="coerce").to_numpy(float)
    elif isinstance(curve, Mapping):
        try:
            v = np.array([float(k) for k in curve.keys()], dtype=float)
            mu = np.array([float(x) for x in curve.values()], dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(src, "a mapping speed_kmh -> mu of numbers", got=dict(curve)) from exc
    elif hasattr(curve, "speeds_kmh") and hasattr(curve, "mu"):
        v = np.asarray(curve.speeds_kmh, dtype=float)
        mu = np.asarray(curve.mu, dtype=float)
    else:
        raise InputError(
            src, "a DataFrame (speed_kmh, mu), a dict {speed_kmh: mu} or a DftTrace", got=type(curve).__name__
        )
    if v.size == 0:
        raise InputError(src, "at least one measured point", column="mu", got="empty")
    bad = ~(np.isfinite(v) & np.isfinite(mu))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(src, "finite numbers", row=i, column="speed_kmh/mu", got=(v[i], mu[i]))
    if (mu <= 0).any() or (mu > 2).any():
        i = int(np.flatnonzero((mu <= 0) | (mu > 2))[0])
        raise InputError(src, "a friction coefficient in (0, 2]", row=i, column="mu", got=float(mu[i]))
    if (v < 0).any():
        i = int(np.flatnonzero(v < 0)[0])
        raise InputError(src, "a speed >= 0 km/h", row=i, column="speed_kmh", got=float(v[i]))
    uv, inv = np.unique(v, return_inverse=True)
    umu = np.bincount(inv, weights=mu) / np.bincount(inv)
    return uv, umu


def measured_at(curve, speeds_kmh, *, window_kmh: float | None = None, source: str | Path | None = None) -> np.ndarray:
    """Measured mu at ``speeds_kmh`` (km/h).

    A mapping ``{speed_kmh: mu}`` must hold every requested speed (used as is). Otherwise linear interpolation of
    the trace (``window_kmh`` None, the convention of ``DftTrace.at``) or the local least-squares line through the
    samples within ``+-window_kmh`` km/h (needs two distinct speeds in the window). Speeds outside the trace raise
    :class:`InputError`.
    """
    v, mu = measured_arrays(curve, source=source)
    src = source if source is not None else getattr(curve, "path", None)
    out = []
    for s in np.atleast_1d(np.asarray(speeds_kmh, dtype=float)):
        hit = np.flatnonzero(np.abs(v - s) < 1e-9)
        if hit.size:
            out.append(float(mu[hit[0]]))
            continue
        if isinstance(curve, Mapping):
            raise InputError(
                src,
                f"a measured value at {s:g} km/h (a mapping is used as is, never interpolated)",
                column="speed_kmh",
                got=sorted(float(k) for k in curve),
            )
        if s < v[0] - 1e-9 or s > v[-1] + 1e-9:
            raise InputError(
                src, f"a measured curve covering {s:g} km/h", column="speed_kmh", got=f"{v[0]:g}..{v[-1]:g} km/h"
            )
        if window_kmh is None:
            out.append(float(np.interp(s, v, mu)))
        else:
            sel = np.abs(v - s) <= window_kmh
            if np.unique(v[sel]).size < 2:
                raise InputError(
                    src,
                    f"samples at 2 or more speeds within +-{window_kmh:g} km/h of {s:g} km/h",
                    column="speed_kmh",
                    got=int(sel.sum()),
                    hint="widen window_kmh",
                )
            b1, b0 = np.polyfit(v[sel] - s, mu[sel], 1)
            out.append(float(b0))
    return np.asarray(out)


def measured_dict(measured, speeds_kmh, window_kmh: float | None, source) -> dict[float, float]:
    """``{speed_kmh: mu}`` of ``measured`` at ``speeds_kmh`` (km/h; see :func:`measured_at`)."""
    vals = measured_at(measured, speeds_kmh, window_kmh=window_kmh, source=source)
    return {float(s): float(x) for s, x in zip(speeds_kmh, vals)}
