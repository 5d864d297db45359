"""The FE mapping the calibration fitted the law through: :class:`SurrogateMap` ``SN(v) = a(v) + b(v) mu(v + d(v))``
(the identity for the study's bisection) and the sum of squares of a law through it (:func:`sse_of`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skidsim.calibration.result import CalibrationResult
from skidsim.errors import InputError
from skidsim.friction import KMH_PER_MS, ExponentialDecay


@dataclass(frozen=True)
class SurrogateMap:
    """The calibration's FE mapping ``SN(v) = a(v) + b(v) mu(v + d(v))`` (v, d in km/h); linear interpolation
    between ``speeds_kmh``, constant beyond (as :func:`skidsim.calibration.calibrate_fast`)."""

    speeds_kmh: tuple[float, ...]
    a: tuple[float, ...]
    b: tuple[float, ...]
    d_kmh: tuple[float, ...]

    @classmethod
    def identity(cls) -> SurrogateMap:
        return cls((40.0,), (0.0,), (1.0,), (0.0,))

    @classmethod
    def from_result(cls, result: CalibrationResult) -> SurrogateMap:
        """The final surrogate of an ``ours`` result; the identity for a result without one (the study)."""
        s = result.settings or {}
        if not all(k in s for k in ("speeds_kmh", "b")):
            return cls.identity()
        v = tuple(float(x) for x in s["speeds_kmh"])
        n = len(v)
        a = tuple(float(x) for x in (s.get("a") or [0.0] * n))
        d = (
            tuple(float(x) for x in (s.get("slip_offsets_kmh") or [0.0] * n))
            if s.get("model", "slip") == "slip"
            else (0.0,) * n
        )
        b = tuple(float(x) for x in s["b"])
        if not (len(a) == len(b) == len(d) == n):
            raise InputError(
                None,
                "surrogate settings a, b, slip_offsets_kmh of one length per calibration speed",
                got={"speeds_kmh": v, "a": a, "b": b, "d": d},
            )
        return cls(v, a, b, d)

    def terms(self, v_kmh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(a, b, effective slip speed in m/s) at ``v_kmh``."""
        v = np.asarray(v_kmh, dtype=float)
        sv = np.asarray(self.speeds_kmh)
        a = np.interp(v, sv, self.a)
        b = np.interp(v, sv, self.b)
        s = (v + np.interp(v, sv, self.d_kmh)) / KMH_PER_MS
        return a, b, s

    def predict(self, law: ExponentialDecay, v_kmh) -> np.ndarray:
        """Surrogate SN of ``law`` at ``v_kmh``."""
        a, b, s = self.terms(v_kmh)
        return a + b * law.mu(s)

    def jacobian(self, law: ExponentialDecay, v_kmh) -> np.ndarray:
        """d SN / d (mu_s, mu_k, alpha[s/m]) at ``v_kmh``: shape (n, 3)."""
        _, b, s = self.terms(v_kmh)
        e = np.exp(-law.alpha * s)
        return np.column_stack([b * e, b * (1.0 - e), -b * (law.mu_s - law.mu_k) * s * e])


def sse_of(mapping: SurrogateMap, law: ExponentialDecay, v_kmh, y) -> float:
    """Sum of squared differences between the surrogate curve of ``law`` and ``y`` at ``v_kmh``."""
    r = mapping.predict(law, v_kmh) - np.asarray(y, dtype=float)
    return float(r @ r)
