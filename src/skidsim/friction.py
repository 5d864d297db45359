"""Friction laws used at the slider-pavement interface.

The study's law (Oden & Martins 1985, ABAQUS ``*FRICTION, EXPONENTIAL DECAY``)::

    mu(s) = mu_k + (mu_s - mu_k) * exp(-alpha * s)

with ``s`` the slip speed. **Units**: inside skidsim ``s`` is in **m/s** and ``alpha`` in **s/m**, as in the
ABAQUS form (decay coefficient ``d_c`` multiplies the slip rate in model units; our solver is SI).
DFT speeds are quoted in km/h; convert with :func:`kmh_to_ms`. The study's search interval for alpha,
[0, 1], is therefore [0, 1] s/m: at 20 km/h (5.56 m/s) and alpha = 0.2 s/m the static share is
exp(-1.11) = 0.33, at 60 km/h exp(-3.33) = 0.036.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

KMH_PER_MS = 3.6


def kmh_to_ms(v_kmh):
    """Speed in km/h to m/s."""
    return np.asarray(v_kmh, dtype=float) / KMH_PER_MS if np.ndim(v_kmh) else float(v_kmh) / KMH_PER_MS


def ms_to_kmh(v_ms):
    """Speed in m/s to km/h."""
    return np.asarray(v_ms, dtype=float) * KMH_PER_MS if np.ndim(v_ms) else float(v_ms) * KMH_PER_MS


@dataclass(frozen=True)
class ExponentialDecay:
    """mu(s) = mu_k + (mu_s - mu_k) exp(-alpha s); s slip speed in m/s, alpha in s/m (dimensionless mus)."""

    mu_s: float
    mu_k: float
    alpha: float  # s/m

    def mu(self, slip_speed_ms):
        """Friction coefficient at slip speed(s) in m/s."""
        s = np.abs(np.asarray(slip_speed_ms, dtype=float))
        return self.mu_k + (self.mu_s - self.mu_k) * np.exp(-self.alpha * s)

    def mu_kmh(self, speed_kmh):
        """Friction coefficient at speed(s) given in km/h."""
        return self.mu(np.asarray(speed_kmh, dtype=float) / KMH_PER_MS)

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class ConstantFriction:
    """Coulomb friction with a constant coefficient (verification runs)."""

    mu_c: float

    def mu(self, slip_speed_ms):
        return np.full(np.shape(slip_speed_ms), self.mu_c, dtype=float) if np.ndim(slip_speed_ms) else float(self.mu_c)

    def mu_kmh(self, speed_kmh):
        return self.mu(speed_kmh)
