"""Back-calculation of the exponential-decay friction law from DFT measurements (issue 6).

Two methods, side by side, both driven by a simulator callback (the workflow wraps
:func:`skidsim.solver.simulate` into one)::

    simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome

* :func:`calibrate_study` -- the study's nested bisection (section 6.2): ``mu_k`` at 60 km/h, then
  ``mu_s`` at 20 km/h holding ``mu_k``, then ``alpha`` at 40 km/h holding both; each search stops when
  ``|SN_sim - SN_measured| / SN_measured < tol`` (10 %).
* :func:`calibrate_fast` -- ours: the simulated skid number is close to ``g * mu(v + d(v))`` with a site
  geometric factor ``g`` and, in the real solver, an effective slip-speed excess ``d`` (default
  ``model="slip"``; ``model="ratio"`` is the field notes' ``g(v) * mu(v)``). The three parameters are fitted
  to the whole measured curve by bounded least squares *without* FE, then verified with one FE run per
  calibration speed (after one cheap pilot run); the surrogate is corrected from the FE runs until they agree
  with it within ``tol`` (0.01, below the DFT's repeatability).

Conventions that change numbers (also in ``docs/calibration.md``):

* **Units.** Speeds in km/h at the interface, slip speed in m/s inside the law (``v_ms = v_kmh / 3.6``),
  ``alpha`` in s/m. ``SN`` is the ratio tangential / normal force (dimensionless, the same scale as the
  DFT's ``mu``; *not* multiplied by 100).
* **Search intervals (study).** ``mu_s`` in [0, 0.85], ``mu_k`` in [0, 0.7], ``alpha`` in [0, 1] s/m:
  the ranges the study lists in its text ("[0, 0.85], [0, 0.7], and [0, 1]"). Its worked example uses
  [0, 0.85] for ``mu_k``; we keep [0, 0.7] (the listed range for ``mu_k``) by default, configurable.
* **Start values (study).** Parameters not yet searched are held at ``start = (mu_s, mu_k, alpha) =
  (0.4, 0.35, 0.6)``, the values of the study's mesh study. The first evaluation of each search is the
  midpoint of its interval (study step 1), never the start value.
* **Direction (study).** SN grows with ``mu_k`` and ``mu_s``; with ``alpha`` it falls when
  ``mu_s > mu_k`` and grows when ``mu_s < mu_k`` (the sign of d mu / d alpha). A positive error
  (simulation too high) keeps the half-interval on the side that lowers SN.
* **Max iterations (study).** ``max_iter`` FE evaluations per parameter. When a search exhausts it,
  ``on_max_iter="flag"`` keeps the evaluated value with the smallest ``|error|``, records a message naming
  the parameter, speed, interval and last error, marks the result not converged and goes on;
  ``"raise"`` raises :class:`CalibrationError` with the same message.
* **Measured values at a speed.** Linear interpolation of the trace (as ``DftTrace.at``), or local linear
  regression within ``+-window_kmh`` when a window is given. A dict ``{speed_kmh: mu}`` is used as is.
* **Cost accounting.** ``n_fe_runs``, ``n_steps`` and ``fe_wall_s`` of a :class:`CalibrationResult` are the
  method's cost: every evaluation the method asked for, at the cost of the FE run that produced it (also
  when it came from the :class:`FECache`). ``n_steps_run`` / ``n_cache_hits`` say what this run paid.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

from skidsim.errors import InputError, SkidsimError
from skidsim.friction import KMH_PER_MS, ExponentialDecay
from skidsim.runlog import atomic_path

#: Parameter bounds (mu_s, mu_k, alpha[s/m]) of the study (section 6.2).
DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {"mu_s": (0.0, 0.85), "mu_k": (0.0, 0.7), "alpha": (0.0, 1.0)}
#: Start values (mu_s, mu_k, alpha[s/m]) of the study's mesh study.
STUDY_START: tuple[float, float, float] = (0.4, 0.35, 0.6)
#: Calibration speeds (km/h) and validation speeds (km/h) of the study.
CALIBRATION_SPEEDS_KMH: tuple[float, ...] = (20.0, 40.0, 60.0)
VALIDATION_SPEEDS_KMH: tuple[float, ...] = (30.0, 50.0, 70.0)
#: The study's search order: (parameter, speed km/h).
STUDY_ORDER: tuple[tuple[str, float], ...] = (("mu_k", 60.0), ("mu_s", 20.0), ("alpha", 40.0))
_PARAMS = ("mu_s", "mu_k", "alpha")
_KEY_DECIMALS = 12  # parameters and speeds are rounded to this many decimals in cache keys


class CalibrationError(SkidsimError):
    """A calibration that cannot finish (iteration budget exhausted with on_max_iter='raise')."""


@dataclass(frozen=True)
class FEOutcome:
    """Result of one FE skid simulation as the calibration sees it.

    sn: simulated skid number, tangential / normal force (dimensionless, DFT mu scale).
    n_steps: explicit time steps run *by this call* (0 for a cache hit).
    wall_s: wall time of this call, s (0 for a cache hit).
    cached: True when the outcome came from an :class:`FECache`.
    fe_steps, fe_wall_s: cost of the FE run that produced ``sn`` (steps, s); default to n_steps, wall_s.
    """

    sn: float
    n_steps: int
    wall_s: float
    cached: bool = False
    fe_steps: int | None = None
    fe_wall_s: float | None = None

    @property
    def cost_steps(self) -> int:
        """Time steps of the FE run behind this outcome (the method's cost, cached or not)."""
        return int(self.n_steps if self.fe_steps is None else self.fe_steps)

    @property
    def cost_wall_s(self) -> float:
        """Wall time, s, of the FE run behind this outcome."""
        return float(self.wall_s if self.fe_wall_s is None else self.fe_wall_s)


Simulator = Callable[[float, ExponentialDecay], FEOutcome]


def fe_simulator(pavement, config=None, **simulate_kwargs) -> Simulator:
    """The simulator callback around :func:`skidsim.solver.simulate` for one pavement and solver config.

    ``pavement``: a heightfield with ``evaluate`` and ``extent_m`` (``skidsim.reconstruct``); ``config``: a
    ``skidsim.solver.SolverConfig`` (None: the solver's reference preset); extra keyword arguments go to
    ``simulate`` (e.g. ``y_offset_mm``). Returns ``simulate(speed_kmh, law) -> FEOutcome`` with the run's SN,
    time steps and wall time (s).
    """
    from skidsim.solver import simulate as fe_simulate  # lazy: the solver is heavy and optional here

    def simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome:
        r = fe_simulate(pavement, float(speed_kmh), law, config, **simulate_kwargs)
        return FEOutcome(sn=float(r.sn), n_steps=int(r.n_steps), wall_s=float(r.wall_s))

    return simulate


# ----------------------------------------------------------------------------------------------------
# atomic writes


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def _atomic_write_parquet(path: Path, df: pd.DataFrame) -> None:
    with atomic_path(path) as tmp:
        df.to_parquet(tmp, index=False)


# ----------------------------------------------------------------------------------------------------
# FE evaluation cache


class FECache:
    """Per-site parquet table of FE evaluations; a rerun or a resumed run never repeats a simulation.

    Key: ``(site, speed_kmh, mu_s, mu_k, alpha, **key_fields)``. Speeds (km/h) and parameters are rounded
    to 12 decimals; ``key_fields`` (mesh / solver identity, e.g. ``mesh="0.5mm", solver="a1b2c3"``) are
    compared by ``str(value)`` and stored as string columns ``key_<name>``. Rows written under other key
    fields stay in the table and simply do not match. Stored per row: ``sn``, ``n_steps`` (time steps of
    the FE run), ``wall_s`` (s), ``seq`` (order of insertion).

    After every new evaluation the whole table is re-read, merged and written to a temporary file that is
    renamed over the table (under an ``fcntl`` lock file ``<path>.lock``), so a killed run loses at most
    the evaluation in flight and two processes sharing the table do not drop each other's rows.
    """

    BASE_COLUMNS = ("site", "speed_kmh", "mu_s", "mu_k", "alpha")
    VALUE_COLUMNS = ("sn", "n_steps", "wall_s", "seq")

    def __init__(self, path: str | Path, site: str, **key_fields: Any):
        self.path = Path(path)
        self.site = str(site)
        self.key_fields = {str(k): str(v) for k, v in sorted(key_fields.items())}
        self.n_hits = 0
        self.n_new = 0
        self._rows: dict[tuple, dict] = {}
        self._extra_columns: list[str] = []
        self._load()

    # -- keys
    def _key_from(self, site, speed_kmh, mu_s, mu_k, alpha, keyvals: Mapping[str, str]) -> tuple:
        r = _KEY_DECIMALS
        return (str(site), round(float(speed_kmh), r), round(float(mu_s), r), round(float(mu_k), r),
                round(float(alpha), r)) + tuple((k, str(keyvals.get(k, ""))) for k in sorted(keyvals))

    def key(self, speed_kmh: float, law: ExponentialDecay) -> tuple:
        """Cache key of an evaluation of ``law`` at ``speed_kmh`` (km/h) for this site and key fields."""
        return self._key_from(self.site, speed_kmh, law.mu_s, law.mu_k, law.alpha, self.key_fields)

    # -- disk
    def _read_disk(self) -> pd.DataFrame | None:
        if not self.path.exists():
            return None
        try:
            df = pd.read_parquet(self.path)
        except Exception as exc:  # pyarrow raises several types
            raise InputError(self.path, "a parquet FE cache table", got=type(exc).__name__,
                             hint="delete the file to start a fresh cache") from exc
        for col in self.BASE_COLUMNS + ("sn", "n_steps", "wall_s"):
            if col not in df.columns:
                raise InputError(self.path, "an FE cache column", column=col, got="missing",
                                 hint=f"columns are {list(df.columns)}")
        return df

    def _ingest(self, df: pd.DataFrame) -> None:
        keycols = [c for c in df.columns if c.startswith("key_")]
        for c in keycols:
            if c not in self._extra_columns:
                self._extra_columns.append(c)
        records = df.to_dict("records")
        for rec in records:
            keyvals = {c[4:]: ("" if rec.get(c) is None or (isinstance(rec.get(c), float) and math.isnan(rec[c]))
                               else str(rec[c])) for c in keycols}
            # a row written without some of our key fields has "" for them: it never matches a real value
            allkeys = {k: keyvals.get(k, "") for k in set(keyvals) | set(self.key_fields)}
            k = self._key_from(rec["site"], rec["speed_kmh"], rec["mu_s"], rec["mu_k"], rec["alpha"], allkeys)
            if k not in self._rows:
                self._rows[k] = {c: rec.get(c) for c in df.columns}

    def _load(self) -> None:
        df = self._read_disk()
        if df is not None:
            self._ingest(df)

    def _write(self) -> None:
        lock_path = self.path.with_name(self.path.name + ".lock")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            import fcntl
        except ImportError:  # pragma: no cover - non-POSIX
            fcntl = None
        with open(lock_path, "a+") as lock:
            if fcntl is not None:
                fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
            try:
                disk = self._read_disk()
                if disk is not None:
                    self._ingest(disk)  # keep rows another process added meanwhile
                _atomic_write_parquet(self.path, self.table)
            finally:
                if fcntl is not None:
                    fcntl.flock(lock.fileno(), fcntl.LOCK_UN)

    # -- public
    @property
    def table(self) -> pd.DataFrame:
        """All cached evaluations as a DataFrame (one row per evaluation, sorted by ``seq``)."""
        keycols = sorted(set(self._extra_columns) | {f"key_{k}" for k in self.key_fields})
        cols = list(self.BASE_COLUMNS) + keycols + list(self.VALUE_COLUMNS)
        if not self._rows:
            return pd.DataFrame({c: pd.Series(dtype="float64" if c not in ("site", *keycols) else "object")
                                 for c in cols})
        df = pd.DataFrame(list(self._rows.values()))
        for c in cols:
            if c not in df.columns:
                df[c] = "" if c.startswith("key_") else np.nan
        df = df[cols]
        for c in keycols:
            df[c] = df[c].fillna("").astype(str)
        df["n_steps"] = df["n_steps"].astype("int64")
        return df.sort_values("seq", kind="stable").reset_index(drop=True)

    def __len__(self) -> int:
        return len(self._rows)

    def lookup(self, speed_kmh: float, law: ExponentialDecay) -> FEOutcome | None:
        """The cached outcome (marked ``cached``, 0 steps, 0 s now) or None."""
        rec = self._rows.get(self.key(speed_kmh, law))
        if rec is None:
            return None
        return FEOutcome(sn=float(rec["sn"]), n_steps=0, wall_s=0.0, cached=True,
                         fe_steps=int(rec["n_steps"]), fe_wall_s=float(rec["wall_s"]))

    def store(self, speed_kmh: float, law: ExponentialDecay, outcome: FEOutcome) -> None:
        """Add one evaluation and write the table atomically."""
        k = self.key(speed_kmh, law)
        seq = 1 + max((int(r.get("seq") or 0) for r in self._rows.values()), default=0)
        rec = {"site": self.site, "speed_kmh": float(speed_kmh), "mu_s": float(law.mu_s),
               "mu_k": float(law.mu_k), "alpha": float(law.alpha)}
        rec.update({f"key_{n}": v for n, v in self.key_fields.items()})
        rec.update({"sn": float(outcome.sn), "n_steps": int(outcome.cost_steps),
                    "wall_s": float(outcome.cost_wall_s), "seq": seq})
        self._rows[k] = rec
        self._write()

    def wrap(self, simulate: Simulator) -> Simulator:
        """A simulator that answers from the cache when it can and records every new evaluation."""

        def cached_simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome:
            hit = self.lookup(speed_kmh, law)
            if hit is not None:
                self.n_hits += 1
                return hit
            out = simulate(speed_kmh, law)
            if not isinstance(out, FEOutcome):
                raise TypeError(f"simulate must return FEOutcome, got {type(out).__name__}")
            self.store(speed_kmh, law, out)
            self.n_new += 1
            return out

        cached_simulate.cache = self  # type: ignore[attr-defined]
        return cached_simulate


# ----------------------------------------------------------------------------------------------------
# measured data


def measured_arrays(curve, *, source: str | Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(speeds km/h ascending, mu) of a measured curve; duplicate speeds are averaged.

    ``curve``: DataFrame with columns ``speed_kmh`` and ``mu``, a mapping ``{speed_kmh: mu}``, or an object
    with ``speeds_kmh`` and ``mu`` arrays (``skidsim.dft.DftTrace``). ``source`` names the file in errors.
    """
    src = source if source is not None else getattr(curve, "path", None)
    if isinstance(curve, pd.DataFrame):
        for col in ("speed_kmh", "mu"):
            if col not in curve.columns:
                raise InputError(src, "a column of the measured curve", column=col, got="missing",
                                 hint=f"columns are {list(curve.columns)}")
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
        raise InputError(src, "a DataFrame (speed_kmh, mu), a dict {speed_kmh: mu} or a DftTrace",
                         got=type(curve).__name__)
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


def measured_at(curve, speeds_kmh, *, window_kmh: float | None = None,
                source: str | Path | None = None) -> np.ndarray:
    """Measured mu at ``speeds_kmh`` (km/h).

    A mapping ``{speed_kmh: mu}`` must hold every requested speed (used as is). Otherwise linear interpolation of the trace (``window_kmh``
    None, the convention of ``DftTrace.at``) or the local least-squares line through the samples within
    ``+-window_kmh`` km/h (needs two distinct speeds in the window). Speeds outside the trace raise
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
            raise InputError(src, f"a measured value at {s:g} km/h (a mapping is used as is, never interpolated)",
                             column="speed_kmh", got=sorted(float(k) for k in curve))
        if s < v[0] - 1e-9 or s > v[-1] + 1e-9:
            raise InputError(src, f"a measured curve covering {s:g} km/h", column="speed_kmh",
                             got=f"{v[0]:g}..{v[-1]:g} km/h")
        if window_kmh is None:
            out.append(float(np.interp(s, v, mu)))
        else:
            sel = np.abs(v - s) <= window_kmh
            if np.unique(v[sel]).size < 2:
                raise InputError(src, f"samples at 2 or more speeds within +-{window_kmh:g} km/h of {s:g} km/h",
                                 column="speed_kmh", got=int(sel.sum()), hint="widen window_kmh")
            b1, b0 = np.polyfit(v[sel] - s, mu[sel], 1)
            out.append(float(b0))
    return np.asarray(out)


def _measured_dict(measured, speeds, window_kmh, source) -> dict[float, float]:
    vals = measured_at(measured, speeds, window_kmh=window_kmh, source=source)
    return {float(s): float(x) for s, x in zip(speeds, vals)}


# ----------------------------------------------------------------------------------------------------
# closed forms and the bounded least-squares fit (no FE)


def aitken_three_point(speeds_kmh: Sequence[float], y: Sequence[float]) -> ExponentialDecay | None:
    """Exponential ``mu_k + (mu_s - mu_k) exp(-alpha s)`` through three equally spaced points (Aitken).

    ``r = (y2 - y3)/(y1 - y2)``, ``alpha = -ln(r)/dv`` (dv in m/s, alpha in s/m),
    ``mu_k = (y1 y3 - y2^2)/(y1 + y3 - 2 y2)``, ``mu_s = mu_k + (y1 - mu_k) exp(alpha s1)``.
    Needs ``y1 > y2 > y3`` and convexity (0 < r < 1); returns None otherwise. No bounds are applied.
    """
    v = np.asarray(speeds_kmh, dtype=float)
    y1, y2, y3 = (float(t) for t in y)
    if v.shape != (3,) or not np.isclose(v[1] - v[0], v[2] - v[1]) or v[1] <= v[0]:
        raise ValueError(f"aitken_three_point needs three increasing, equally spaced speeds (km/h), got {v}")
    if not (y1 > y2 > y3):
        return None
    r = (y2 - y3) / (y1 - y2)
    if not (0.0 < r < 1.0):
        return None
    dv_ms = float(v[1] - v[0]) / KMH_PER_MS
    alpha = -math.log(r) / dv_ms
    mu_k = (y1 * y3 - y2 * y2) / (y1 + y3 - 2.0 * y2)
    mu_s = mu_k + (y1 - mu_k) * math.exp(alpha * float(v[0]) / KMH_PER_MS)
    return ExponentialDecay(mu_s=mu_s, mu_k=mu_k, alpha=alpha)


def _box_ls2_many(c1: np.ndarray, c2: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Exact min ||c1 p1 + c2 p2 - z||^2 over the box lo <= p <= hi, for a batch of G problems.

    c1, c2: columns, shape (G, n); z: (n,). KKT enumeration (the interior solution when feasible, the four
    edges with the free unknown clipped); the problem is convex, so the best candidate is the optimum.
    Returns (p (G, 2), sse (G,)).
    """
    g11 = np.einsum("gn,gn->g", c1, c1)
    g22 = np.einsum("gn,gn->g", c2, c2)
    g12 = np.einsum("gn,gn->g", c1, c2)
    r1 = c1 @ z
    r2 = c2 @ z
    zz = float(z @ z)

    def sse_of(p1, p2):
        return zz - 2 * (p1 * r1 + p2 * r2) + p1 * p1 * g11 + 2 * p1 * p2 * g12 + p2 * p2 * g22

    G = c1.shape[0]
    best_sse = np.full(G, np.inf)
    best = np.zeros((G, 2))

    def consider(p1, p2, ok):
        val = np.where(ok, sse_of(p1, p2), np.inf)
        better = val < best_sse - 1e-18
        best_sse[better] = val[better]
        best[better, 0] = p1[better]
        best[better, 1] = p2[better]

    det = g11 * g22 - g12 * g12
    with np.errstate(divide="ignore", invalid="ignore"):
        u1 = (g22 * r1 - g12 * r2) / det
        u2 = (g11 * r2 - g12 * r1) / det
    ok = (np.abs(det) > 1e-14 * np.maximum(g11 * g22, 1e-300)) & np.isfinite(u1) & np.isfinite(u2)
    ok &= (u1 >= lo[0] - 1e-15) & (u1 <= hi[0] + 1e-15) & (u2 >= lo[1] - 1e-15) & (u2 <= hi[1] + 1e-15)
    consider(np.clip(np.nan_to_num(u1), lo[0], hi[0]), np.clip(np.nan_to_num(u2), lo[1], hi[1]), ok)
    every = np.ones(G, dtype=bool)
    for bnd1 in (lo[0], hi[0]):  # p1 at a bound, p2 free then clipped
        with np.errstate(divide="ignore", invalid="ignore"):
            p2 = np.where(g22 > 0, (r2 - bnd1 * g12) / g22, lo[1])
        consider(np.full(G, bnd1), np.clip(p2, lo[1], hi[1]), every)
    for bnd2 in (lo[1], hi[1]):
        with np.errstate(divide="ignore", invalid="ignore"):
            p1 = np.where(g11 > 0, (r1 - bnd2 * g12) / g11, lo[0])
        consider(np.clip(p1, lo[0], hi[0]), np.full(G, bnd2), every)
    return best, np.maximum(best_sse, 0.0)


def fit_exponential_decay(speeds_kmh, y, *, a=None, b=None, bounds: Mapping[str, tuple[float, float]] | None = None,
                          n_alpha_grid: int = 401) -> tuple[ExponentialDecay, float]:
    """Bounded least squares of ``y_j ~ a_j + b_j mu(v_j)`` over (mu_s, mu_k, alpha); returns (law, SSE).

    speeds_kmh: km/h; ``a`` (default 0) and ``b`` (default 1) per point model the FE response
    ``SN = a + b mu``. Variable projection: for fixed alpha the model is linear in (mu_k, mu_s) and the
    box-constrained 2-unknown problem is solved exactly (KKT enumeration: interior, four edges); alpha (s/m)
    is searched on a grid of ``n_alpha_grid`` values over its bounds and refined with bounded Brent between
    the neighbours of the best grid value. Handles non-convex or non-monotone data (the best law within the
    bounds). Where the data do not identify all three parameters (a flat curve), the first best grid value
    wins: the fitted curve is unique, the parameters are not.
    """
    bnd = dict(DEFAULT_BOUNDS if bounds is None else bounds)
    v = np.asarray(speeds_kmh, dtype=float)
    y = np.asarray(y, dtype=float)
    a = np.zeros_like(y) if a is None else np.broadcast_to(np.asarray(a, dtype=float), y.shape)
    b = np.ones_like(y) if b is None else np.broadcast_to(np.asarray(b, dtype=float), y.shape)
    if v.shape != y.shape or v.ndim != 1 or v.size < 3:
        raise ValueError(f"need >= 3 points with matching speeds and values, got {v.shape} and {y.shape}")
    for name in _PARAMS:
        lo_, hi_ = bnd[name]
        if not (hi_ >= lo_):
            raise ValueError(f"bounds for {name} must satisfy lo <= hi, got {bnd[name]}")
    s = v / KMH_PER_MS
    z = y - a
    lo = np.array([bnd["mu_k"][0], bnd["mu_s"][0]], dtype=float)
    hi = np.array([bnd["mu_k"][1], bnd["mu_s"][1]], dtype=float)

    def solve(alphas):
        e = np.exp(-np.outer(np.atleast_1d(alphas), s))
        return _box_ls2_many(b * (1.0 - e), b * e, z, lo, hi)

    alo, ahi = (float(x) for x in bnd["alpha"])
    grid = np.linspace(alo, ahi, max(int(n_alpha_grid), 2))
    _, sse = solve(grid)
    i = int(np.argmin(sse))
    best_alpha, best_sse = float(grid[i]), float(sse[i])
    left, right = float(grid[max(i - 1, 0)]), float(grid[min(i + 1, len(grid) - 1)])
    if right > left:
        res = minimize_scalar(lambda al: float(solve(al)[1][0]), bounds=(left, right), method="bounded",
                              options={"xatol": 1e-12, "maxiter": 200})
        if res.success and float(res.fun) < best_sse:
            best_alpha, best_sse = float(res.x), float(res.fun)
    p, sse1 = solve(best_alpha)
    return ExponentialDecay(mu_s=float(p[0, 1]), mu_k=float(p[0, 0]), alpha=best_alpha), float(sse1[0])


# ----------------------------------------------------------------------------------------------------
# results


_HISTORY_COLUMNS = ["method", "seq", "stage", "iteration", "speed_kmh", "mu_s", "mu_k", "alpha",
                    "sn_sim", "sn_measured", "rel_err", "lo", "hi", "sn_pred", "cached",
                    "n_steps_run", "n_steps", "wall_s_run", "fe_wall_s"]


@dataclass
class CalibrationResult:
    """Outcome of one calibration of one site by one method.

    params: the calibrated law (mu_s, mu_k dimensionless, alpha in s/m).
    history: one row per evaluation the method asked for (columns ``_HISTORY_COLUMNS``): stage (the
    parameter searched, or ``verify`` for ours), speed_kmh, the law, sn_sim, sn_measured, rel_err
    (sn_sim/sn_measured - 1), search interval lo/hi (study), sn_pred (our surrogate's prediction), cached,
    n_steps_run / wall_s_run (paid now), n_steps / fe_wall_s (cost of the FE run behind it, s).
    overhead_s: wall time, s, the calibration spent outside the simulator in this run.
    """

    method: str
    params: ExponentialDecay
    history: pd.DataFrame
    converged: bool
    message: str
    measured_kmh: dict[float, float]
    overhead_s: float = 0.0
    settings: dict = field(default_factory=dict)

    @property
    def law(self) -> ExponentialDecay:
        return self.params

    @property
    def n_fe_runs(self) -> int:
        """FE evaluations the method needed (cache hits included)."""
        return int(len(self.history))

    @property
    def n_steps(self) -> int:
        """FE time steps the method needed (cost of the runs behind cache hits included)."""
        return int(self.history["n_steps"].sum()) if len(self.history) else 0

    @property
    def fe_wall_s(self) -> float:
        """FE wall time, s, the method needed (original runs)."""
        return float(self.history["fe_wall_s"].sum()) if len(self.history) else 0.0

    @property
    def wall_s(self) -> float:
        """fe_wall_s + overhead_s, s."""
        return self.fe_wall_s + float(self.overhead_s)

    @property
    def n_cache_hits(self) -> int:
        return int(self.history["cached"].sum()) if len(self.history) else 0

    @property
    def n_steps_run(self) -> int:
        """Time steps actually run in this call (0 when everything came from the cache)."""
        return int(self.history["n_steps_run"].sum()) if len(self.history) else 0

    def final_sn(self) -> dict[float, float]:
        """SN simulated with the final params at each speed where the history has it (km/h -> SN)."""
        h = self.history
        if not len(h):
            return {}
        p = self.params
        m = (np.isclose(h["mu_s"], p.mu_s, rtol=0, atol=1e-12) & np.isclose(h["mu_k"], p.mu_k, rtol=0, atol=1e-12)
             & np.isclose(h["alpha"], p.alpha, rtol=0, atol=1e-12))
        return {float(r.speed_kmh): float(r.sn_sim) for r in h[m].itertuples()}

    @property
    def fit_rmse(self) -> float:
        """RMSE of final-param SN vs measured at the calibration speeds; NaN if not all were simulated."""
        fs = self.final_sn()
        if not all(any(abs(s - t) < 1e-9 for t in fs) for s in self.measured_kmh):
            return float("nan")
        d = [fs[next(t for t in fs if abs(s - t) < 1e-9)] - m for s, m in self.measured_kmh.items()]
        return float(np.sqrt(np.mean(np.square(d))))

    def summary(self) -> dict:
        """Flat dict of the parameters and costs (for tables)."""
        return {"method": self.method, "mu_s": self.params.mu_s, "mu_k": self.params.mu_k,
                "alpha_s_per_m": self.params.alpha, "converged": bool(self.converged),
                "n_fe_runs": self.n_fe_runs, "n_steps": self.n_steps, "fe_wall_s": self.fe_wall_s,
                "overhead_s": float(self.overhead_s), "wall_s": self.wall_s, "n_cache_hits": self.n_cache_hits,
                "n_steps_run": self.n_steps_run, "fit_rmse": self.fit_rmse, "message": self.message}

    def to_dict(self) -> dict:
        h = self.history.astype(object).where(self.history.notna(), None)
        return {"method": self.method, "params": self.params.as_dict(), "converged": bool(self.converged),
                "message": self.message, "measured_kmh": {str(k): v for k, v in self.measured_kmh.items()},
                "overhead_s": float(self.overhead_s), "settings": _jsonable(self.settings),
                "summary": _jsonable(self.summary()), "history": h.to_dict("records")}

    def to_json(self, path: str | Path) -> None:
        """Write the result as JSON (temporary file + rename)."""
        text = json.dumps(_jsonable(self.to_dict()), indent=1, allow_nan=False)
        _atomic_write_bytes(Path(path), text.encode())

    @classmethod
    def from_dict(cls, d: Mapping, *, source: str | Path | None = None) -> "CalibrationResult":
        try:
            hist = pd.DataFrame(d["history"], columns=_HISTORY_COLUMNS)
            for c in _HISTORY_COLUMNS:
                if c in ("method", "stage"):
                    continue
                if c == "cached":
                    hist[c] = hist[c].astype(bool)
                else:
                    hist[c] = pd.to_numeric(hist[c], errors="coerce")
            return cls(method=str(d["method"]), params=ExponentialDecay(**d["params"]), history=hist,
                       converged=bool(d["converged"]), message=str(d["message"]),
                       measured_kmh={float(k): float(v) for k, v in d["measured_kmh"].items()},
                       overhead_s=float(d.get("overhead_s", 0.0)), settings=dict(d.get("settings", {})))
        except KeyError as exc:
            raise InputError(source, "a calibration result field", column=str(exc.args[0]), got="missing") from exc

    @classmethod
    def from_json(cls, path: str | Path) -> "CalibrationResult":
        return cls.from_dict(json.loads(Path(path).read_text()), source=path)


def _jsonable(x):
    if isinstance(x, Mapping):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return None if not math.isfinite(float(x)) else float(x)  # strict JSON: NaN/inf become null
    return x


class _Evaluator:
    """Calls the simulator, times it, and records one history row per call."""

    def __init__(self, simulate: Simulator, method: str):
        self.simulate = simulate
        self.method = method
        self.rows: list[dict] = []
        self.sim_wall = 0.0

    def __call__(self, speed_kmh: float, law: ExponentialDecay, **extra) -> FEOutcome:
        t0 = time.perf_counter()
        out = self.simulate(float(speed_kmh), law)
        self.sim_wall += time.perf_counter() - t0
        if not isinstance(out, FEOutcome):
            raise TypeError(f"simulate must return FEOutcome, got {type(out).__name__}")
        if not math.isfinite(out.sn):
            raise CalibrationError(f"simulate returned a non-finite SN at {speed_kmh:g} km/h for {law}")
        row = {c: None for c in _HISTORY_COLUMNS}
        row.update({"method": self.method, "seq": len(self.rows) + 1, "speed_kmh": float(speed_kmh),
                    "mu_s": float(law.mu_s), "mu_k": float(law.mu_k), "alpha": float(law.alpha),
                    "sn_sim": float(out.sn), "cached": bool(out.cached), "n_steps_run": int(out.n_steps),
                    "n_steps": out.cost_steps, "wall_s_run": float(out.wall_s), "fe_wall_s": out.cost_wall_s})
        row.update(extra)
        if row.get("sn_measured") is not None:
            row["rel_err"] = row["sn_sim"] / row["sn_measured"] - 1.0
        self.rows.append(row)
        return out

    def history(self) -> pd.DataFrame:
        df = pd.DataFrame(self.rows, columns=_HISTORY_COLUMNS)
        for c in _HISTORY_COLUMNS:
            if c in ("method", "stage"):
                df[c] = df[c].astype(object)
            elif c == "cached":
                df[c] = df[c].astype(bool)
            else:
                df[c] = pd.to_numeric(df[c], errors="coerce")
        return df


# ----------------------------------------------------------------------------------------------------
# the study's nested bisection


def calibrate_study(simulate: Simulator, measured, *,
                    intervals: Mapping[str, tuple[float, float]] | None = None,
                    start: tuple[float, float, float] = STUDY_START, tol: float = 0.10, max_iter: int = 15,
                    order: Sequence[tuple[str, float]] = STUDY_ORDER, on_max_iter: str = "flag",
                    window_kmh: float | None = None, source: str | Path | None = None) -> CalibrationResult:
    """The study's binary-search back-calculation (section 6.2), exactly.

    measured: ``{speed_kmh: mu}`` with the speeds of ``order`` (20, 40, 60 km/h), or a measured curve
    (see :func:`measured_at`). intervals: search interval per parameter (default :data:`DEFAULT_BOUNDS`,
    alpha in s/m). start: (mu_s, mu_k, alpha) held for the parameters not yet searched. tol: relative error
    |SN_sim - SN_measured| / SN_measured below which a search stops (strict <). max_iter: FE evaluations per
    parameter. on_max_iter: ``"flag"`` (keep the best evaluated value, converged=False, go on) or
    ``"raise"`` (:class:`CalibrationError`).
    """
    t_start = time.perf_counter()
    if on_max_iter not in ("flag", "raise"):
        raise ValueError(f"on_max_iter must be 'flag' or 'raise', got {on_max_iter!r}")
    if not (tol > 0):
        raise ValueError(f"tol must be a positive relative error, got {tol!r}")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1, got {max_iter!r}")
    iv = dict(DEFAULT_BOUNDS if intervals is None else intervals)
    for name, _ in order:
        if name not in _PARAMS:
            raise ValueError(f"unknown parameter {name!r} in order; expected one of {_PARAMS}")
        lo, hi = iv[name]
        if not (hi > lo):
            raise ValueError(f"interval for {name} must have hi > lo, got {iv[name]}")
    speeds = [float(v) for _, v in order]
    meas = _measured_dict(measured, speeds, window_kmh, source)
    current = dict(zip(_PARAMS, (float(x) for x in start)))
    ev = _Evaluator(simulate, "study")
    messages: list[str] = []
    converged = True
    for name, speed in order:
        lo, hi = (float(x) for x in iv[name])
        target = meas[float(speed)]
        tried: list[tuple[float, float]] = []  # (value, rel_err)
        done = False
        for it in range(1, int(max_iter) + 1):
            mid = 0.5 * (lo + hi)
            trial = dict(current, **{name: mid})
            law = ExponentialDecay(**trial)
            out = ev(speed, law, stage=name, iteration=it, sn_measured=target, lo=lo, hi=hi)
            err = out.sn / target - 1.0
            tried.append((mid, err))
            if abs(err) < tol:
                current[name] = mid
                done = True
                break
            increasing = True if name != "alpha" else (trial["mu_s"] < trial["mu_k"])
            too_high = err > 0
            if too_high == increasing:
                hi = mid
            else:
                lo = mid
        if not done:
            best_val, best_err = min(tried, key=lambda t: abs(t[1]))
            msg = (f"study bisection: {name} at {speed:g} km/h did not reach |SN_sim - SN_measured|/SN_measured "
                   f"< {tol:g} within max_iter={max_iter} FE evaluations (last interval [{lo:.6g}, {hi:.6g}], "
                   f"last error {tried[-1][1]:+.3%}, measured {target:.4g}); kept the best evaluated "
                   f"{name}={best_val:.6g} (error {best_err:+.3%})")
            if on_max_iter == "raise":
                raise CalibrationError(msg)
            current[name] = best_val
            messages.append(msg)
            converged = False
    params = ExponentialDecay(**current)
    overhead = time.perf_counter() - t_start - ev.sim_wall
    msg = "converged: every search met the tolerance" if converged else "; ".join(messages)
    return CalibrationResult(method="study", params=params, history=ev.history(), converged=converged,
                             message=msg, measured_kmh=meas, overhead_s=max(overhead, 0.0),
                             settings={"intervals": {k: list(v) for k, v in iv.items()}, "start": list(start),
                                       "tol": tol, "max_iter": int(max_iter),
                                       "order": [[n, float(v)] for n, v in order], "on_max_iter": on_max_iter,
                                       "window_kmh": window_kmh})


# ----------------------------------------------------------------------------------------------------
# our method


def calibrate_fast(simulate: Simulator, measured_curve, *, speeds_kmh: Sequence[float] = CALIBRATION_SPEEDS_KMH,
                   tol: float = 0.01, max_fe_runs: int = 15, fit_on: str = "trace",
                   fit_range_kmh: tuple[float, float] | None = None, bounds: Mapping | None = None,
                   g_prior: float = 1.0, pilot_speed_kmh: float | str | None = "fastest", model: str = "slip",
                   secant_min_dmu: float = 0.01, window_kmh: float | None = None, source: str | Path | None = None,
                   prior: Mapping[str, Sequence[float]] | None = None) -> CalibrationResult:
    """Fit all three parameters to the measured curve with few FE runs (ours).

    Model: ``SN_FE(v) ~ a(v) + b(v) mu(v)``, per calibration speed ``v_i`` (km/h); between them a and b
    are interpolated linearly in speed (constant beyond). Start ``a = 0, b = g_prior``.
    Pilot (``pilot_speed_kmh``, default ``"fastest"`` = the highest calibration speed, the FE run with the
    fewest time steps; None = no pilot): one FE run of the first fit at that speed sets the level
    ``b = SN / mu`` at every speed before the first full batch (g is close to speed independent), which
    saves a whole batch when g differs from ``g_prior`` by more than the tolerance.
    Loop: (1) fit (mu_s, mu_k, alpha) to the measured data by bounded least squares under the model (no FE,
    :func:`fit_exponential_decay`); (2) one FE run per calibration speed with that law; (3) the largest
    ``|SN_FE - SN_model|`` over the speeds is the model error: stop when it is <= ``tol``; else update the
    model per speed: ratio ``b = SN/mu, a = 0`` (fixed point on the geometric factor g) or, once two
    runs at that speed differ in mu by >= ``secant_min_dmu``, the secant line through them.

    ``model="slip"``: the FE samples the law at an *effective slip speed* ``v_i + d_i`` (the slider's nodes
    slip faster than the holder when it vibrates): ``SN ~ g mu(v_i + d_i)``. The pilot then runs a constant
    law (mu_s = mu_k = mean measured / g_prior, alpha 0) to get ``g = SN / mu``; each batch updates ``d_i``
    by inverting the law, ``mu(v_i + d_i) = SN_i / g`` (where not invertible - flat law, value outside
    [mu_k, mu_s] - the ratio update of ``b_i`` is used instead). Offsets are interpolated linearly between
    the calibration speeds.

    measured_curve: DataFrame (speed_kmh, mu), DftTrace or ``{speed_kmh: mu}``. fit_on: ``"trace"`` (every
    measured point within ``fit_range_kmh``, default the calibration speed range) or ``"speeds"`` (the
    measured values at the calibration speeds, see :func:`measured_at`). A dict is always ``"speeds"``.
    max_fe_runs: FE evaluation budget; when the next batch would exceed it the best verified law is kept
    (smallest RMSE vs measured at the calibration speeds), converged=False with a message.

    prior: the surrogate's starting state learned on other sites of the campaign (see :func:`surrogate_prior`):
    ``{"speeds_kmh": [...], "b": [...], "slip_offsets_kmh": [...]}`` (the geometric factor g and the slip
    offsets d in km/h at those speeds, interpolated linearly to ``speeds_kmh``, constant beyond). With a prior the
    pilot run is skipped: the first batch is usually already within ``tol`` (docs/calibration.md). Only for
    ``model="slip"``.
    """
    t_start = time.perf_counter()
    if fit_on not in ("trace", "speeds"):
        raise ValueError(f"fit_on must be 'trace' or 'speeds', got {fit_on!r}")
    if model not in ("ratio", "slip"):
        raise ValueError(f"model must be 'ratio' or 'slip', got {model!r}")
    if not (tol > 0):
        raise ValueError(f"tol must be positive (SN units), got {tol!r}")
    spd = np.array(sorted(float(v) for v in speeds_kmh))
    if spd.size < 1 or len(set(spd)) != spd.size:
        raise ValueError(f"speeds_kmh must be distinct speeds in km/h, got {speeds_kmh!r}")
    if max_fe_runs < spd.size:
        raise ValueError(f"max_fe_runs={max_fe_runs} is below one run per calibration speed ({spd.size})")
    bnd = dict(DEFAULT_BOUNDS if bounds is None else bounds)
    meas = _measured_dict(measured_curve, spd, window_kmh, source)
    m_cal = np.array([meas[float(v)] for v in spd])
    if fit_on == "trace" and not isinstance(measured_curve, Mapping):
        v_all, mu_all = measured_arrays(measured_curve, source=source)
        lo_v, hi_v = (spd[0], spd[-1]) if fit_range_kmh is None else fit_range_kmh
        sel = (v_all >= lo_v - 1e-9) & (v_all <= hi_v + 1e-9)
        v_fit, y_fit = v_all[sel], mu_all[sel]
        if np.unique(v_fit).size < 3:
            raise InputError(source, f"at least 3 measured speeds within {lo_v:g}..{hi_v:g} km/h",
                             column="speed_kmh", got=int(np.unique(v_fit).size))
        mode = "trace"
    else:
        v_fit, y_fit = spd, m_cal
        mode = "speeds"
        if spd.size < 3:
            raise ValueError("fit_on='speeds' needs >= 3 calibration speeds for three parameters")

    a_i = np.zeros(spd.size)
    b_i = np.full(spd.size, float(g_prior))
    d_i = np.zeros(spd.size)  # effective slip-speed offsets, km/h (model="slip")
    last: list[tuple[float, float] | None] = [None] * spd.size  # (mu, SN) of the latest run per speed
    ev = _Evaluator(simulate, "ours")
    if prior is not None:
        if model != "slip":
            raise ValueError("a surrogate prior is only defined for model='slip'")
        try:
            pv = np.asarray(prior["speeds_kmh"], dtype=float)
            pb = np.asarray(prior["b"], dtype=float)
            pd_ = np.asarray(prior["slip_offsets_kmh"], dtype=float)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"prior must map speeds_kmh, b and slip_offsets_kmh to number lists, got {prior!r}") from exc
        if not (pv.ndim == 1 and pv.size >= 1 and pb.shape == pv.shape and pd_.shape == pv.shape
                and np.all(np.isfinite(pb)) and np.all(pb > 0) and np.all(np.isfinite(pd_))
                and np.all(np.diff(pv) > 0)):
            raise ValueError(f"prior needs increasing speeds_kmh and finite b > 0 and slip_offsets_kmh of the same "
                             f"length, got {prior!r}")
        b_i = np.interp(spd, pv, pb)
        d_i = np.interp(spd, pv, pd_)
        pilot_speed_kmh = None
    if pilot_speed_kmh == "fastest":
        pilot_speed_kmh = float(spd[-1])
    if pilot_speed_kmh is not None:
        pilot_speed_kmh = float(pilot_speed_kmh)
        if max_fe_runs < spd.size + 1:
            raise ValueError(f"max_fe_runs={max_fe_runs} leaves no room for the pilot run and one batch")
        if model == "slip":
            mu_c = float(np.mean(m_cal)) / float(g_prior)
            mu_c = min(max(mu_c, max(bnd["mu_s"][0], bnd["mu_k"][0])), min(bnd["mu_s"][1], bnd["mu_k"][1]))
            law0 = ExponentialDecay(mu_s=mu_c, mu_k=mu_c, alpha=0.0)
        else:
            law0, _ = fit_exponential_decay(v_fit, y_fit, a=np.interp(v_fit, spd, a_i),
                                            b=np.interp(v_fit, spd, b_i), bounds=bnd)
        mu0 = float(law0.mu_kmh(pilot_speed_kmh))
        try:
            pm = float(measured_at(measured_curve, [pilot_speed_kmh], window_kmh=window_kmh, source=source)[0])
        except InputError:  # a pilot speed the data do not cover: no measured value to report, still usable
            pm = float("nan")
        out = ev(pilot_speed_kmh, law0, stage="pilot", iteration=0, sn_measured=pm,
                 sn_pred=float(np.interp(pilot_speed_kmh, spd, a_i) + np.interp(pilot_speed_kmh, spd, b_i) * mu0))
        if mu0 > 0:
            b_i[:] = out.sn / mu0
            a_i[:] = 0.0
        jp = np.flatnonzero(np.abs(spd - pilot_speed_kmh) < 1e-9)
        if jp.size:
            last[int(jp[0])] = (mu0, float(out.sn))
    verified: list[tuple[ExponentialDecay, float, float]] = []  # (law, rmse vs measured, model error)
    converged = False
    message = ""
    prev_law = None
    it = 0
    while True:
        it += 1
        a_fit = np.interp(v_fit, spd, a_i)
        b_fit = np.interp(v_fit, spd, b_i)
        v_eff_fit = v_fit + np.interp(v_fit, spd, d_i)
        law, _ = fit_exponential_decay(v_eff_fit, y_fit, a=a_fit, b=b_fit, bounds=bnd)
        if prev_law is not None and all(abs(getattr(law, p) - getattr(prev_law, p)) < 1e-12 for p in _PARAMS):
            message = (f"fast calibration stalled: the model update did not change the law after iteration "
                       f"{it - 1} (model error above tol={tol:g})")
            break
        if len(ev.rows) + spd.size > max_fe_runs:
            message = (f"fast calibration: FE budget max_fe_runs={max_fe_runs} reached after {len(ev.rows)} runs "
                       f"without the FE runs agreeing with the surrogate within tol={tol:g}")
            break
        mu_i = law.mu_kmh(spd + d_i)
        pred = a_i + b_i * mu_i
        sn = np.empty(spd.size)
        for j, v in enumerate(spd):
            out = ev(v, law, stage="verify", iteration=it, sn_measured=float(m_cal[j]), sn_pred=float(pred[j]))
            sn[j] = out.sn
        model_err = float(np.max(np.abs(sn - pred)))
        rmse = float(np.sqrt(np.mean((sn - m_cal) ** 2)))
        verified.append((law, rmse, model_err))
        if model_err <= tol:
            converged = True
            message = (f"converged after {it} iteration(s): FE agrees with the surrogate within {model_err:.2g} "
                       f"<= tol={tol:g}; RMSE vs measured at calibration speeds {rmse:.4g}")
            break
        for j in range(spd.size):
            mu_j, sn_j = float(mu_i[j]), float(sn[j])
            prev = last[j]
            if model == "slip":
                d_new = _invert_slip_kmh(law, (sn_j - a_i[j]) / b_i[j])
                if d_new is not None and 0.25 * spd[j] <= d_new <= 4.0 * spd[j]:
                    d_i[j] = d_new - spd[j]
                else:
                    b_i[j] = sn_j / mu_j if mu_j > 0 else b_i[j]
                continue
            if prev is not None and abs(mu_j - prev[0]) >= secant_min_dmu:
                bj = (sn_j - prev[1]) / (mu_j - prev[0])
                if 0.2 <= bj <= 5.0:
                    a_i[j], b_i[j] = sn_j - bj * mu_j, bj
                else:
                    a_i[j], b_i[j] = 0.0, sn_j / mu_j if mu_j > 0 else b_i[j]
            else:
                a_i[j], b_i[j] = 0.0, (sn_j / mu_j if mu_j > 0 else b_i[j])
            last[j] = (mu_j, sn_j)
        prev_law = law
    if converged:
        params = verified[-1][0]
    elif verified:
        params = min(verified, key=lambda t: t[1])[0]
        message += f"; kept the verified law with the smallest RMSE vs measured ({params})"
    else:  # pragma: no cover - max_fe_runs >= speeds guarantees one batch
        params = law
    overhead = time.perf_counter() - t_start - ev.sim_wall
    return CalibrationResult(method="ours", params=params, history=ev.history(), converged=converged,
                             message=message, measured_kmh=meas, overhead_s=max(overhead, 0.0),
                             settings={"speeds_kmh": spd.tolist(), "tol": tol, "max_fe_runs": int(max_fe_runs),
                                       "fit_on": mode, "fit_range_kmh": None if fit_range_kmh is None
                                       else list(fit_range_kmh), "bounds": {k: list(v) for k, v in bnd.items()},
                                       "g_prior": g_prior, "pilot_speed_kmh": pilot_speed_kmh, "model": model,
                                       "slip_offsets_kmh": d_i.tolist(), "b": b_i.tolist(), "a": a_i.tolist(),
                                       "secant_min_dmu": secant_min_dmu,
                                       "window_kmh": window_kmh,
                                       "prior": None if prior is None else {k: [float(x) for x in prior[k]] for k in
                                                                            ("speeds_kmh", "b", "slip_offsets_kmh")}})


def surrogate_prior(results: Sequence[CalibrationResult]) -> dict:
    """The campaign prior of our method: the median, over reference sites calibrated without a prior, of the
    surrogate's final geometric factor ``b`` and slip offsets ``d`` (km/h) at each calibration speed.

    Both are properties of the FE slider's dynamics (how much faster its contact nodes slip than the holder
    moves, and the ratio of SN to mu at the effective slip speed) and vary little between sites of one campaign
    (default campaign: d = 6.9 +- 1.3, 5.3 +- 1.0, 2.9 +- 0.8 km/h at 20, 40, 60 km/h; b = 1.045 +- 0.013).
    Raises ValueError when no result is usable (converged, model "slip", same calibration speeds).
    """
    usable = [r for r in results if r.method == "ours" and r.converged and r.settings.get("model") == "slip"
              and r.settings.get("prior") is None]
    if not usable:
        raise ValueError("surrogate_prior: no converged prior-free 'ours' calibration with model 'slip' to learn from")
    speeds = [tuple(float(v) for v in r.settings["speeds_kmh"]) for r in usable]
    if len(set(speeds)) != 1:
        raise ValueError(f"surrogate_prior: reference calibrations used different speeds {sorted(set(speeds))}")
    b = np.median(np.array([r.settings["b"] for r in usable], dtype=float), axis=0)
    d = np.median(np.array([r.settings["slip_offsets_kmh"] for r in usable], dtype=float), axis=0)
    return {"speeds_kmh": list(speeds[0]), "b": b.tolist(), "slip_offsets_kmh": d.tolist(), "n_sites": len(usable)}


def prior_reference_sites(sites: Sequence[str], n: int) -> list[str]:
    """The ``n`` reference sites whose prior-free calibrations make the prior: evenly spread over the site
    table's order (indices ``round(linspace(0, len - 1, n))``), all sites when ``n >= len(sites)``, none for 0."""
    sites = list(sites)
    if n <= 0 or not sites:
        return []
    if n >= len(sites):
        return sites
    idx = sorted(set(int(round(x)) for x in np.linspace(0, len(sites) - 1, n)))
    return [sites[i] for i in idx]


def _invert_slip_kmh(law: ExponentialDecay, mu_target: float) -> float | None:
    """Speed (km/h) at which ``law`` gives ``mu_target``; None when the law is flat or the value is out of range."""
    span = law.mu_s - law.mu_k
    if not (law.alpha > 1e-9 and abs(span) > 1e-9 and math.isfinite(mu_target)):
        return None
    r = (mu_target - law.mu_k) / span
    if not (0.0 < r <= 1.0):
        return None
    return -math.log(r) / law.alpha * KMH_PER_MS


# ----------------------------------------------------------------------------------------------------
# validation and tables


def simulate_speeds(simulate: Simulator, law: ExponentialDecay,
                    speeds_kmh: Sequence[float] = VALIDATION_SPEEDS_KMH) -> pd.DataFrame:
    """FE runs of ``law`` at ``speeds_kmh`` (km/h): DataFrame speed_kmh, sn_sim, n_steps, wall_s (s), cached.

    ``n_steps``/``wall_s`` are the cost of the FE run behind each value (also for cache hits).
    """
    rows = []
    for v in speeds_kmh:
        out = simulate(float(v), law)
        rows.append({"speed_kmh": float(v), "sn_sim": float(out.sn), "n_steps": out.cost_steps,
                     "wall_s": out.cost_wall_s, "cached": bool(out.cached)})
    return pd.DataFrame(rows, columns=["speed_kmh", "sn_sim", "n_steps", "wall_s", "cached"])


def fit_statistics(sim, meas) -> dict:
    """Agreement of simulated with measured values (both dimensionless SN / mu).

    r2: coefficient of determination about the 1:1 line, ``1 - sum (sim - meas)^2 / sum (meas - mean)^2``
    (can be negative); r2_pearson: squared Pearson correlation (the R^2 of a fitted trend line, as in
    spreadsheet plots); rmse, mae; max_rel_err: max |sim/meas - 1|; n.
    """
    s = np.asarray(sim, dtype=float).ravel()
    m = np.asarray(meas, dtype=float).ravel()
    if s.shape != m.shape:
        raise ValueError(f"sim and meas must have the same length, got {s.size} and {m.size}")
    ok = np.isfinite(s) & np.isfinite(m)
    s, m = s[ok], m[ok]
    n = int(s.size)
    if n == 0:
        return {"n": 0, "r2": float("nan"), "r2_pearson": float("nan"), "rmse": float("nan"),
                "mae": float("nan"), "max_rel_err": float("nan")}
    d = s - m
    sst = float(np.sum((m - m.mean()) ** 2))
    r2 = 1.0 - float(d @ d) / sst if sst > 0 else float("nan")
    if n >= 2 and s.std() > 0 and m.std() > 0:
        r2p = float(np.corrcoef(s, m)[0, 1] ** 2)
    else:
        r2p = float("nan")
    return {"n": n, "r2": r2, "r2_pearson": r2p, "rmse": float(np.sqrt(np.mean(d * d))),
            "mae": float(np.mean(np.abs(d))), "max_rel_err": float(np.max(np.abs(d / m)))}


def validation_table(runs: Mapping[str, Mapping[str, pd.DataFrame]], measured: Mapping[str, Any], *,
                     calibration_speeds_kmh: Sequence[float] = CALIBRATION_SPEEDS_KMH,
                     validation_speeds_kmh: Sequence[float] = VALIDATION_SPEEDS_KMH,
                     window_kmh: float | None = None) -> pd.DataFrame:
    """Long table of simulated vs measured per site, method and speed.

    runs: ``{site: {method: DataFrame(speed_kmh, sn_sim, ...)}}`` as returned by :func:`simulate_speeds`
    for the final params (calibration and validation speeds). measured: ``{site: curve}``. Columns: site,
    method, speed_kmh, kind (``calibration`` / ``validation`` / ``other``), sn_sim, mu_measured, err
    (sn_sim - mu_measured), rel_err, n_steps, wall_s (s).
    """
    cal = {float(v) for v in calibration_speeds_kmh}
    val = {float(v) for v in validation_speeds_kmh}
    rows = []
    for site, per_method in runs.items():
        if site not in measured:
            raise InputError(None, f"a measured curve for site {site!r}", column="site", got=sorted(measured))
        for method, df in per_method.items():
            for col in ("speed_kmh", "sn_sim"):
                if col not in df.columns:
                    raise InputError(None, f"column in the runs of {site}/{method}", column=col, got="missing")
            mu = measured_at(measured[site], df["speed_kmh"].to_numpy(float), window_kmh=window_kmh,
                             source=getattr(measured[site], "path", site))
            for r, m in zip(df.itertuples(index=False), mu):
                v = float(r.speed_kmh)
                kind = "calibration" if v in cal else ("validation" if v in val else "other")
                rows.append({"site": site, "method": method, "speed_kmh": v, "kind": kind,
                             "sn_sim": float(r.sn_sim), "mu_measured": float(m), "err": float(r.sn_sim) - float(m),
                             "rel_err": float(r.sn_sim) / float(m) - 1.0,
                             "n_steps": int(getattr(r, "n_steps", 0) or 0),
                             "wall_s": float(getattr(r, "wall_s", 0.0) or 0.0)})
    return pd.DataFrame(rows, columns=["site", "method", "speed_kmh", "kind", "sn_sim", "mu_measured", "err",
                                       "rel_err", "n_steps", "wall_s"])


def figure10_statistics(vtable: pd.DataFrame) -> pd.DataFrame:
    """R^2, RMSE, MAE, max relative error per method and kind (calibration / validation) over all sites."""
    rows = []
    for (method, kind), g in vtable.groupby(["method", "kind"], sort=True):
        rows.append({"method": method, "kind": kind, **fit_statistics(g["sn_sim"], g["mu_measured"])})
    return pd.DataFrame(rows, columns=["method", "kind", "n", "r2", "r2_pearson", "rmse", "mae", "max_rel_err"])


def _rmse_by(vtable: pd.DataFrame | None, site: str, method: str, kind: str) -> float:
    if vtable is None or not len(vtable):
        return float("nan")
    g = vtable[(vtable["site"] == site) & (vtable["method"] == method) & (vtable["kind"] == kind)]
    return float(np.sqrt(np.mean(g["err"] ** 2))) if len(g) else float("nan")


def comparison_table(results: Mapping[str, Mapping[str, CalibrationResult]], vtable: pd.DataFrame | None = None,
                     *, methods: Sequence[str] = ("study", "ours")) -> pd.DataFrame:
    """One row per site plus ``TOTAL``: FE runs, FE time steps, wall time (s), fit error, per method.

    Columns ``<method>_fe_runs, _steps, _wall_s, _converged, _rmse_cal, _rmse_val`` (RMSE of SN vs measured
    at calibration / validation speeds from ``vtable``; without it ``_rmse_cal`` is the result's own
    ``fit_rmse``), and ``steps_ratio`` = steps of the second method / steps of the first. ``_converged`` is
    1/0 per site. In ``TOTAL`` counts and times are sums, ``_converged`` the number of converged sites, the
    RMSEs are over all points. Plain int/float/str columns (parquet- and CSV-safe).
    """
    rows = []
    for site in sorted(results):
        row: dict[str, Any] = {"site": site}
        for m in methods:
            r = results[site].get(m)
            if r is None:
                continue
            row[f"{m}_fe_runs"] = r.n_fe_runs
            row[f"{m}_steps"] = r.n_steps
            row[f"{m}_wall_s"] = r.wall_s
            row[f"{m}_converged"] = int(bool(r.converged))
            row[f"{m}_rmse_cal"] = _rmse_by(vtable, site, m, "calibration") if vtable is not None else r.fit_rmse
            row[f"{m}_rmse_val"] = _rmse_by(vtable, site, m, "validation")
        rows.append(row)
    df = pd.DataFrame(rows)
    if df.empty:
        return df
    tot: dict[str, Any] = {"site": "TOTAL"}
    for m in methods:
        if f"{m}_steps" not in df:
            continue
        for c in ("fe_runs", "steps", "wall_s"):
            tot[f"{m}_{c}"] = df[f"{m}_{c}"].sum()
        tot[f"{m}_converged"] = int(df[f"{m}_converged"].sum())
        for kind, c in (("calibration", "rmse_cal"), ("validation", "rmse_val")):
            if vtable is not None and len(vtable):
                g = vtable[(vtable["method"] == m) & (vtable["kind"] == kind)]
                tot[f"{m}_{c}"] = float(np.sqrt(np.mean(g["err"] ** 2))) if len(g) else float("nan")
            else:
                tot[f"{m}_{c}"] = float(np.sqrt(np.nanmean(df[f"{m}_{c}"] ** 2)))
    df = pd.concat([df, pd.DataFrame([tot])], ignore_index=True)
    if len(methods) >= 2 and f"{methods[0]}_steps" in df and f"{methods[1]}_steps" in df:
        df["steps_ratio"] = df[f"{methods[1]}_steps"] / df[f"{methods[0]}_steps"]
    for m in methods:
        if f"{m}_converged" in df:
            df[f"{m}_converged"] = df[f"{m}_converged"].astype("int64")
    return df


def table2(results: Mapping[str, Mapping[str, CalibrationResult]], *,
           methods: Sequence[str] = ("study", "ours")) -> pd.DataFrame:
    """Parameters per site (like the study's Table 2): ``<method>_mu_s, _mu_k, _alpha_s_per_m, _converged``."""
    rows = []
    for site in sorted(results):
        row: dict[str, Any] = {"site": site}
        for m in methods:
            r = results[site].get(m)
            if r is None:
                continue
            row[f"{m}_mu_s"] = r.params.mu_s
            row[f"{m}_mu_k"] = r.params.mu_k
            row[f"{m}_alpha_s_per_m"] = r.params.alpha
            row[f"{m}_converged"] = bool(r.converged)
        rows.append(row)
    return pd.DataFrame(rows)
