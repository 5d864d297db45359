"""The FE evaluation: the simulator callback the calibrations drive, and the per-site cache of its runs.

A calibration calls ``simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome``; :func:`fe_simulator` wraps
:func:`skidsim.solver.simulate` into one, :meth:`FECache.wrap` puts a per-site parquet cache in front of any, so a
rerun or a resumed run never repeats a simulation.

**Batches.** Runs that do not depend on each other (the speeds of a verification batch, the validation speeds of
every method) are announced with :func:`prefetch` ``(simulate, [(speed_kmh, law), ...])``: the simulators of this
module then run the cache misses together (:func:`skidsim.solver.simulate_batch`, the same SN as single runs bit for
bit), store them, and answer the following ``simulate(speed_kmh, law)`` calls with those outcomes as if each had
run then (``cached`` False, its steps, its share of the batch's wall time). Cache keys are those of single runs.
Announced runs that will not be asked for (a look-ahead's unused points) are taken back with :func:`withdraw`,
which returns what they cost (the cache keeps them: a rerun finds them as hits).

Cost accounting: ``n_steps`` / ``wall_s`` of an :class:`FEOutcome` are what this call paid (0 for a cache hit);
``cost_steps`` / ``cost_wall_s`` are the cost of the FE run behind the value, cached or not (the method's cost).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from skidsim.atomic import write_parquet
from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay

_KEY_DECIMALS = 12  # parameters and speeds are rounded to this many decimals in cache keys


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
Request = tuple[float, ExponentialDecay]  # (speed km/h, law) of one FE run


def prefetch(simulate: Simulator, requests) -> None:
    """Announce the FE runs ``requests`` (``(speed_kmh, law)`` pairs) to ``simulate``: a simulator that can batch
    (:func:`fe_simulator`, :meth:`FECache.wrap` around one) runs them together now and answers the following calls
    with their outcomes; any other simulator ignores it (its calls then run one by one, the same numbers)."""
    fn = getattr(simulate, "prefetch", None)
    if fn is not None:
        fn([(float(v), law) for v, law in requests])


def withdraw(simulate: Simulator, requests) -> list[FEOutcome]:
    """Withdraw announced runs ``requests`` (``(speed_kmh, law)`` pairs) that will not be asked for (a look-ahead's
    points the caller did not need). Returns the outcomes behind those that were run by a :func:`prefetch` and not
    yet answered (``cached`` False, the steps run) or that the cache holds (``cached``, 0 steps now, the run's
    cost), in the order of ``requests``; a request that was never run, or a simulator that does not batch, gives
    nothing. The cache keeps the runs it stored; a withdrawn run is no longer answered as a new evaluation."""
    fn = getattr(simulate, "withdraw", None)
    return [] if fn is None else fn([(float(v), law) for v, law in requests])


def fe_simulator(pavement, config=None, **simulate_kwargs) -> Simulator:
    """The simulator callback around :func:`skidsim.solver.simulate` for one pavement and solver config.

    ``pavement``: a heightfield with ``evaluate`` and ``extent_m`` (``skidsim.reconstruct``); ``config``: a
    ``skidsim.solver.SolverConfig`` (None: the solver's reference preset); extra keyword arguments go to
    ``simulate`` (e.g. ``y_offset_mm``). Returns ``simulate(speed_kmh, law) -> FEOutcome`` with the run's SN,
    time steps and wall time (s). Its ``run_batch(requests)`` runs several ``(speed_kmh, law)`` together
    (:func:`skidsim.solver.simulate_batch`; wall time shared by steps) and ``prefetch(requests)`` keeps those
    outcomes for the next calls (see :func:`prefetch`); not with per-run outputs (``trace_path``, ``vtu_dir``).
    """
    from skidsim.solver import simulate as fe_simulate  # lazy: the solver is heavy and optional here
    from skidsim.solver import simulate_batch

    pending: dict[tuple, FEOutcome] = {}

    def simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome:
        out = pending.pop((float(speed_kmh), law), None)
        if out is not None:
            return out
        r = fe_simulate(pavement, float(speed_kmh), law, config, **simulate_kwargs)
        return FEOutcome(sn=float(r.sn), n_steps=int(r.n_steps), wall_s=float(r.wall_s))

    def run_batch(requests: list[Request]) -> list[FEOutcome]:
        rs = simulate_batch(pavement, [v for v, _ in requests], [law for _, law in requests], config, **simulate_kwargs)
        return [FEOutcome(sn=float(r.sn), n_steps=int(r.n_steps), wall_s=float(r.wall_s)) for r in rs]

    def prefetch_runs(requests: list[Request]) -> None:
        todo = list(dict.fromkeys((float(v), law) for v, law in requests if (float(v), law) not in pending))
        if len(todo) > 1:
            pending.update(zip(todo, run_batch(todo)))

    def withdraw_runs(requests: list[Request]) -> list[FEOutcome]:
        return [out for out in (pending.pop((float(v), law), None) for v, law in requests) if out is not None]

    if not {"trace_path", "vtu_dir"} & set(simulate_kwargs):
        simulate.run_batch = run_batch  # type: ignore[attr-defined]
        simulate.prefetch = prefetch_runs  # type: ignore[attr-defined]
        simulate.withdraw = withdraw_runs  # type: ignore[attr-defined]
    return simulate


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
        self._fresh: dict[tuple, FEOutcome] = {}  # prefetched runs, answered once as new evaluations
        self._extra_columns: list[str] = []
        self._load()

    # -- keys
    def _key_from(self, site, speed_kmh, mu_s, mu_k, alpha, keyvals: Mapping[str, str]) -> tuple:
        r = _KEY_DECIMALS
        return (
            str(site),
            round(float(speed_kmh), r),
            round(float(mu_s), r),
            round(float(mu_k), r),
            round(float(alpha), r),
        ) + tuple((k, str(keyvals.get(k, ""))) for k in sorted(keyvals))

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
            raise InputError(
                self.path,
                "a parquet FE cache table",
                got=type(exc).__name__,
                hint="delete the file to start a fresh cache",
            ) from exc
        for col in self.BASE_COLUMNS + ("sn", "n_steps", "wall_s"):
            if col not in df.columns:
                raise InputError(
                    self.path, "an FE cache column", column=col, got="missing", hint=f"columns are {list(df.columns)}"
                )
        return df

    def _ingest(self, df: pd.DataFrame) -> None:
        keycols = [c for c in df.columns if c.startswith("key_")]
        for c in keycols:
            if c not in self._extra_columns:
                self._extra_columns.append(c)
        records = df.to_dict("records")
        for rec in records:
            keyvals = {
                c[4:]: (
                    "" if rec.get(c) is None or (isinstance(rec.get(c), float) and math.isnan(rec[c])) else str(rec[c])
                )
                for c in keycols
            }
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
                write_parquet(self.path, self.table)
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
            return pd.DataFrame(
                {c: pd.Series(dtype="float64" if c not in ("site", *keycols) else "object") for c in cols}
            )
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
        return FEOutcome(
            sn=float(rec["sn"]),
            n_steps=0,
            wall_s=0.0,
            cached=True,
            fe_steps=int(rec["n_steps"]),
            fe_wall_s=float(rec["wall_s"]),
        )

    def store(self, speed_kmh: float, law: ExponentialDecay, outcome: FEOutcome) -> None:
        """Add one evaluation and write the table atomically."""
        self.store_many([(speed_kmh, law, outcome)])

    def store_many(self, evaluations) -> None:
        """Add evaluations ``(speed_kmh, law, outcome)`` (in that order) and write the table once, atomically."""
        for speed_kmh, law, outcome in evaluations:
            self._add(speed_kmh, law, outcome)
        self._write()

    def _add(self, speed_kmh: float, law: ExponentialDecay, outcome: FEOutcome) -> None:
        k = self.key(speed_kmh, law)
        seq = 1 + max((int(r.get("seq") or 0) for r in self._rows.values()), default=0)
        rec = {
            "site": self.site,
            "speed_kmh": float(speed_kmh),
            "mu_s": float(law.mu_s),
            "mu_k": float(law.mu_k),
            "alpha": float(law.alpha),
        }
        rec.update({f"key_{n}": v for n, v in self.key_fields.items()})
        rec.update(
            {
                "sn": float(outcome.sn),
                "n_steps": int(outcome.cost_steps),
                "wall_s": float(outcome.cost_wall_s),
                "seq": seq,
            }
        )
        self._rows[k] = rec

    def wrap(self, simulate: Simulator) -> Simulator:
        """A simulator that answers from the cache when it can and records every new evaluation.

        Its ``prefetch(requests)`` (see :func:`prefetch`) leaves the cache hits and, when ``simulate`` can batch
        (``simulate.run_batch``) and there are several misses, runs the misses together, stores them at once and
        answers the next call of each as a new evaluation; otherwise the calls run one by one as without it.
        """

        def prefetch_runs(requests: list[Request]) -> None:
            misses: dict[tuple, Request] = {}
            for v, law in requests:
                k = self.key(v, law)
                if k not in self._rows and k not in self._fresh:
                    misses.setdefault(k, (v, law))
            run_batch = getattr(simulate, "run_batch", None)
            if run_batch is None or len(misses) < 2:  # the calls run one by one, each stored at once, as before
                return
            todo = list(misses.values())
            outs = run_batch(todo)
            for k, out in zip(misses, outs):
                if not isinstance(out, FEOutcome):
                    raise TypeError(f"simulate must return FEOutcome, got {type(out).__name__}")
                self._fresh[k] = out
            self.store_many([(v, law, out) for (v, law), out in zip(todo, outs)])

        def cached_simulate(speed_kmh: float, law: ExponentialDecay) -> FEOutcome:
            fresh = self._fresh.pop(self.key(speed_kmh, law), None)
            if fresh is not None:
                self.n_new += 1
                return fresh
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

        def withdraw_runs(requests: list[Request]) -> list[FEOutcome]:
            outs = []
            for v, law in requests:
                out = self._fresh.pop(self.key(v, law), None) or self.lookup(v, law)
                if out is not None:
                    outs.append(out)
            return outs

        cached_simulate.cache = self  # type: ignore[attr-defined]
        cached_simulate.prefetch = prefetch_runs  # type: ignore[attr-defined]
        cached_simulate.withdraw = withdraw_runs  # type: ignore[attr-defined]
        return cached_simulate
