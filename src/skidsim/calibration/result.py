"""What a calibration returns: :class:`CalibrationResult` (law, history of evaluations, costs; JSON round trip),
and :class:`Evaluator`, the call of the simulator that times it and records one history row per evaluation.

Cost accounting: ``n_fe_runs``, ``n_steps`` and ``fe_wall_s`` of a result are the method's cost: every evaluation
the method asked for, at the cost of the FE run that produced it (also when it came from the
:class:`~skidsim.calibration.cache.FECache`). ``n_steps_run`` / ``n_cache_hits`` say what this run paid.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.atomic import write_bytes
from skidsim.calibration.cache import FEOutcome, Simulator
from skidsim.errors import InputError, SkidsimError
from skidsim.friction import ExponentialDecay


class CalibrationError(SkidsimError):
    """A calibration that cannot finish (iteration budget exhausted with on_max_iter='raise')."""


HISTORY_COLUMNS = [
    "method",
    "seq",
    "stage",
    "iteration",
    "speed_kmh",
    "mu_s",
    "mu_k",
    "alpha",
    "sn_sim",
    "sn_measured",
    "rel_err",
    "lo",
    "hi",
    "sn_pred",
    "sn_pred_whole",
    "cached",
    "n_steps_run",
    "n_steps",
    "wall_s_run",
    "fe_wall_s",
]


@dataclass
class CalibrationResult:
    """Outcome of one calibration of one site by one method.

    params: the calibrated law (mu_s, mu_k dimensionless, alpha in s/m).
    history: one row per evaluation the method asked for (columns ``HISTORY_COLUMNS``): stage (the
    parameter searched, or ``verify`` for ours), speed_kmh, the law, sn_sim, sn_measured, rel_err
    (sn_sim/sn_measured - 1), search interval lo/hi (study), sn_pred (our surrogate's prediction), sn_pred_whole
    (ours: the prediction of the surrogate as its latest correction would be as a whole step, see
    ``correction_relaxation``), cached,
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
        m = (
            np.isclose(h["mu_s"], p.mu_s, rtol=0, atol=1e-12)
            & np.isclose(h["mu_k"], p.mu_k, rtol=0, atol=1e-12)
            & np.isclose(h["alpha"], p.alpha, rtol=0, atol=1e-12)
        )
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
        return {
            "method": self.method,
            "mu_s": self.params.mu_s,
            "mu_k": self.params.mu_k,
            "alpha_s_per_m": self.params.alpha,
            "converged": bool(self.converged),
            "n_fe_runs": self.n_fe_runs,
            "n_steps": self.n_steps,
            "fe_wall_s": self.fe_wall_s,
            "overhead_s": float(self.overhead_s),
            "wall_s": self.wall_s,
            "n_cache_hits": self.n_cache_hits,
            "n_steps_run": self.n_steps_run,
            "fit_rmse": self.fit_rmse,
            "message": self.message,
        }

    def to_dict(self) -> dict:
        h = self.history.astype(object).where(self.history.notna(), None)
        return {
            "method": self.method,
            "params": self.params.as_dict(),
            "converged": bool(self.converged),
            "message": self.message,
            "measured_kmh": {str(k): v for k, v in self.measured_kmh.items()},
            "overhead_s": float(self.overhead_s),
            "settings": _jsonable(self.settings),
            "summary": _jsonable(self.summary()),
            "history": h.to_dict("records"),
        }

    def to_json(self, path: str | Path) -> None:
        """Write the result as JSON (temporary file + rename)."""
        text = json.dumps(_jsonable(self.to_dict()), indent=1, allow_nan=False)
        write_bytes(path, text.encode(), fsync=True)

    @classmethod
    def from_dict(cls, d: Mapping, *, source: str | Path | None = None) -> CalibrationResult:
        try:
            hist = pd.DataFrame(d["history"], columns=HISTORY_COLUMNS)
            for c in HISTORY_COLUMNS:
                if c in ("method", "stage"):
                    continue
                if c == "cached":
                    hist[c] = hist[c].astype(bool)
                else:
                    hist[c] = pd.to_numeric(hist[c], errors="coerce")
            return cls(
                method=str(d["method"]),
                params=ExponentialDecay(**d["params"]),
                history=hist,
                converged=bool(d["converged"]),
                message=str(d["message"]),
                measured_kmh={float(k): float(v) for k, v in d["measured_kmh"].items()},
                overhead_s=float(d.get("overhead_s", 0.0)),
                settings=dict(d.get("settings", {})),
            )
        except KeyError as exc:
            raise InputError(source, "a calibration result field", column=str(exc.args[0]), got="missing") from exc

    @classmethod
    def from_json(cls, path: str | Path) -> CalibrationResult:
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


class Evaluator:
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
        row = dict.fromkeys(HISTORY_COLUMNS)
        row.update(
            {
                "method": self.method,
                "seq": len(self.rows) + 1,
                "speed_kmh": float(speed_kmh),
                "mu_s": float(law.mu_s),
                "mu_k": float(law.mu_k),
                "alpha": float(law.alpha),
                "sn_sim": float(out.sn),
                "cached": bool(out.cached),
                "n_steps_run": int(out.n_steps),
                "n_steps": out.cost_steps,
                "wall_s_run": float(out.wall_s),
                "fe_wall_s": out.cost_wall_s,
            }
        )
        row.update(extra)
        if row.get("sn_measured") is not None:
            row["rel_err"] = row["sn_sim"] / row["sn_measured"] - 1.0
        self.rows.append(row)
        return out

    def overhead_s(self, t_start: float) -> float:
        """Wall time, s, since ``t_start`` (``time.perf_counter``) spent outside the simulator (>= 0)."""
        return max(time.perf_counter() - t_start - self.sim_wall, 0.0)

    def history(self) -> pd.DataFrame:
        df = pd.DataFrame(self.rows, columns=HISTORY_COLUMNS)
        for c in HISTORY_COLUMNS:
            if c in ("method", "stage"):
                df[c] = df[c].astype(object)
            elif c == "cached":
                df[c] = df[c].astype(bool)
            else:
                df[c] = pd.to_numeric(df[c], errors="coerce")
        return df
