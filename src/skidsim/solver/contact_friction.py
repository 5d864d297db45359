"""Penalty friction with a return mapping, and Rayleigh damping fitted to a rubber loss factor.

**Penalty friction** (``SolverConfig.friction_model = "penalty"``; Wriggers, *Computational Contact Mechanics*,
2nd ed. 2006, sections 5.2 and 10.3; Simo & Hughes, *Computational Inelasticity* 1998, ch. 1-3 for the return
mapping; Laursen, *Computational Contact and Impact Mechanics* 2002, ch. 5). Each contact node carries a
tangential force ``f_t`` (N). Per step

1. the old force is projected onto the current tangent plane (the surface normal moves with the node);
2. elastic predictor: ``f_trial = P_t f_old - k_t du_t`` with ``du_t`` the node's tangential displacement
   increment over the step and ``k_t = c_t A`` (``c_t`` the tangential stiffness per unit contact area in Pa/m,
   ``A`` the node's tributary area in m^2);
3. return mapping onto the slip surface ``|f_t| <= mu(s) N``: if ``|f_trial| > mu(s) N`` the force is scaled back
   to ``mu(s) N f_trial / |f_trial|`` (the closest point of the disc; exact for isotropic Coulomb friction).

The traction ``f_t / A`` is then a function of the tangential displacement history and the pressure only: the
element size does not enter (with the stick limit ``m |v_t| / dt`` it does, through the nodal mass).

**Rayleigh damping** (``slide_damping_model = "rayleigh"``): ``C = alpha M + beta K`` with the damping ratio
``zeta(omega) = alpha / (2 omega) + beta omega / 2``; a loss factor ``eta = tan delta`` means ``zeta = eta / 2``,
fitted at two circular frequencies (Chopra, *Dynamics of Structures*, section 11.4). The explicit step with
stiffness-proportional damping is ``dt = (2 / omega_max) (sqrt(1 + xi^2) - xi)``, ``xi`` the damping ratio at
``omega_max`` (Belytschko, Liu & Moran, *Nonlinear Finite Elements*, 2000, section 6.3).
"""

from __future__ import annotations

import math

import numpy as np

_TINY = np.finfo(float).tiny  # smallest normal double (looked up once: np.finfo costs a call per step)


def return_map(
    f_trial_n: np.ndarray, limit_n: np.ndarray, out: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Project trial tangential forces ``(3, n)`` (N) onto the discs ``|f| <= limit_n`` (N).

    Returns ``(f, stick)``: the admissible forces (in ``out`` if given) and a boolean mask of the nodes that stayed
    elastic (stick).
    """
    mag = np.add.reduce(f_trial_n * f_trial_n, 0)
    np.sqrt(mag, out=mag)
    stick = mag <= limit_n
    # min(1, limit / |f|): 1 inside the disc (also at |f| = 0), the radial scale-back outside
    np.maximum(mag, _TINY, out=mag)
    scale = np.divide(limit_n, mag, out=mag)
    np.minimum(1.0, scale, out=scale)
    return np.multiply(f_trial_n, scale, out=out), stick


def tangential_part(a: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The part of vectors ``a`` (3, n) in the plane normal to the unit normals ``normal`` (3, n) (new array):
    ``a - (a_x n_x + a_y n_y + a_z n_z) n``."""
    p = a * normal
    an = np.add(p[0], p[1])
    an += p[2]
    np.multiply(an, normal, out=p)
    return np.subtract(a, p, out=p)


def penalty_friction(
    f_old_n: np.ndarray,
    du_t_m: np.ndarray,
    k_t_n_per_m: np.ndarray,
    limit_n: np.ndarray,
    normal,
    out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One step of the penalty friction law (see the module docstring).

    f_old_n: (3, n) tangential forces (N) of the previous step (0 for nodes that just came into contact).
    du_t_m: (3, n) displacement increments (m) of the nodes over the step (projected here); only the product
    ``k_t_n_per_m * du_t_m`` enters, so the solver passes the velocities (m/s) with ``k_t dt`` (N s/m).
    k_t_n_per_m: (n,) tangential penalty stiffness (N/m) = stiffness per area x tributary area.
    limit_n: (n,) slip limit mu(s) N (N). normal: unit surface normals (nx, ny, nz), (3, n) (or a tuple of rows).
    Returns ``(f, stick)`` as :func:`return_map` (``f`` in ``out`` if given).
    """
    # P_t f_old - k_t P_t du = P_t (f_old - k_t du): the projection is linear, one projection for two
    trial = np.multiply(k_t_n_per_m, du_t_m)
    np.subtract(f_old_n, trial, out=trial)
    return return_map(tangential_part(trial, np.asarray(normal)), limit_n, out)


def rayleigh_coefficients(loss_factor: float, band_hz: tuple[float, float]) -> tuple[float, float]:
    """``(alpha in 1/s, beta in s)`` of the Rayleigh damping whose loss factor is ``loss_factor`` at both band ends.

    ``zeta = eta / 2`` at ``omega_1 = 2 pi f_1`` and ``omega_2 = 2 pi f_2``: ``alpha = eta w1 w2 / (w1 + w2)``,
    ``beta = eta / (w1 + w2)``; between them the loss factor is lower (minimum ``2 sqrt(alpha beta)`` at
    ``sqrt(w1 w2)``), outside higher.
    """
    w1, w2 = (2.0 * math.pi * f for f in band_hz)
    return loss_factor * w1 * w2 / (w1 + w2), loss_factor / (w1 + w2)


def loss_factor_at(frequency_hz, alpha_per_s: float, beta_s: float):
    """Loss factor ``2 zeta = alpha / omega + beta omega`` of Rayleigh damping at ``frequency_hz`` (Hz)."""
    w = 2.0 * math.pi * np.asarray(frequency_hz, dtype=float)
    return alpha_per_s / w + beta_s * w


def damped_step_factor(omega_max_rad_s: float, alpha_per_s: float, beta_s: float) -> float:
    """Factor ``sqrt(1 + xi^2) - xi`` on the undamped stable step ``2 / omega_max``, ``xi`` the damping ratio at
    ``omega_max`` (rad/s) (Belytschko, Liu & Moran 2000, eq. 6.3.29)."""
    xi = 0.5 * (alpha_per_s / omega_max_rad_s + beta_s * omega_max_rad_s)
    return math.sqrt(1.0 + xi * xi) - xi
