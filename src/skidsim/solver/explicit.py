"""Explicit central-difference simulation of the DFT rubber slider on a rigid pavement.

Model (details and conventions in docs/solver.md):

* **Slider**: :class:`skidsim.slidermesh.SliderMesh` box, small-strain SRI hexahedra
  (:mod:`skidsim.solver.material`), one 24 x 24 element matrix, slicing kernel (:mod:`skidsim.solver.kernel`),
  row-sum lumped mass (optionally scaled by ``mass_scaling``). Small strain is exact for the rigid translation
  (it is in the null space of K); the slider barely deforms (nominal strain ~4e-4).
* **Time integration**: central difference (leapfrog): ``v(n+1/2) = v(n-1/2) + dt M^-1 f(n)``,
  ``u(n+1) = u(n) + dt v(n+1/2)``. ``dt = dt_safety * 2 / omega_max``, ``omega_max^2 = lambda_max(M^-1 K)``
  (power iteration on the assembled slider) + ``max_i k_i (1 + |grad z|^2_max) / m_i`` (contact penalty bound,
  Weyl's inequality; the slope bound is sampled over the swept strip).
* **Contact**: bottom-face nodes against the rigid heightfield, penalty on the vertical penetration
  ``d = z_surface(x, y) - z_node`` with potential ``k d^2 / 2`` (exactly conservative),
  ``k = penalty_scale E A_node / h`` with ``h`` the element height or ``penalty_length_mm``; the force is
  ``k d (-dz/dx, -dz/dy, 1)``, i.e. along the surface normal (``contact_gap = "normal"``: ``k`` divided by
  ``1 + |grad z|^2``, i.e. ``k d_n`` on the normal gap, normal stiffness ``k`` on any slope; the time-step bound
  then drops the slope factor). On a :class:`skidsim.reconstruct.Heightfield` only the *candidate* nodes are
  evaluated: those below the per-cell Bernstein upper bound of the bicubic surface
  (:class:`skidsim.solver.surfaces.SurfaceBound`); the others cannot touch, so the result is unchanged.
* **Friction**: ``mu(s)`` of the node's own slip speed ``s`` (magnitude of its tangential velocity; the pavement
  is at rest), Coulomb bound ``mu(s) N``, regularised near ``s = 0`` by the *stick limit*: the friction force never
  exceeds the force that stops the node's predicted tangential velocity within the step (``m |v_t,trial| / dt``).
  No viscous regularisation, so no extra stiffness and no time-step penalty; sticking is exact.
  Option ``friction_model = "penalty"``: elastic stick with a tangential penalty per unit contact area and a return
  mapping onto ``mu(s) N`` (:mod:`skidsim.solver.contact_friction`); its stiffness enters the time-step bound.
  Option ``slide_damping_model = "rayleigh"``: ``alpha M + beta K`` fitted to a rubber loss factor.
* **Loading**: the top face is bonded to a rigid holder: its x/y velocities are prescribed (0 during the preload,
  the test speed in x while sliding) and all top nodes share one vertical velocity (a single vertical degree of
  freedom carrying the dead load ``load_n``; the holder's mass is that of the top-face nodes). The holder takes the
  friction moment (no pitch or roll of the top face), as a slider glued to the DFT's rigid slider plate. Gravity
  is neglected (0.03 N against 11.8 N).
* **Phases**: quasi-static preload by dynamic relaxation (smooth load ramp over ``preload_ramp_s``, then hold,
  with mass-proportional damping of the absolute velocity), ended as soon as the total contact force is within
  ``preload_tolerance`` of the load at two checks ``preload_check_s`` apart (at most ``preload_time_s``), then
  every node receives the test speed in x and the holder slides
  ``slide_length_mm``.
* **Output**: SN = mean tangential / mean normal pavement force over the steady window; energy balance of the
  sliding phase; trace (parquet), optional VTU series.
* **Code**: one module per idea. :mod:`skidsim.solver.model` builds what the members share (the slider placed on
  the pavement, masses, stiffness, contact constants, time step); :mod:`skidsim.solver.batch` holds the state of the
  members stepped together; :mod:`skidsim.solver.stepping` is one step (internal force, damping, the contact laws
  of :mod:`skidsim.solver.contact`, the update, on preallocated buffers) and the preload and slide loops around it;
  :mod:`skidsim.solver.output` is what each member reports. This module runs them. **Batches**
  (:func:`simulate_batch`): runs on the same pavement with the same config share the mesh and the time step and
  are stepped together, nodal arrays ``(3, nz+1, B, ny+1, nx+1)`` (the kernel's batched layout); each member gets
  the SN of its single run bit for bit. :func:`simulate` is the batch of one.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from skidsim.errors import ConfigError
from skidsim.solver.batch import Batch
from skidsim.solver.config import SolverConfig
from skidsim.solver.model import build_kernel, build_model, material_from_config, max_frequency_power_iteration
from skidsim.solver.output import MemberOutput
from skidsim.solver.results import SimulationResult
from skidsim.solver.stepping import PHASES, Clock, preload_shared, slide

__all__ = [
    "PHASES",
    "build_kernel",
    "material_from_config",
    "max_frequency_power_iteration",
    "simulate",
    "simulate_batch",
]

log = logging.getLogger("skidsim.solver")


def simulate(
    pavement,
    speed_kmh: float,
    law,
    config: SolverConfig | None = None,
    *,
    y_offset_mm: float = 0.0,
    progress=None,
    trace_path: str | Path | None = None,
    vtu_dir: str | Path | None = None,
    slope_bound: float | None = None,
) -> SimulationResult:
    """Simulate one DFT slide of the rubber slider over ``pavement`` at ``speed_kmh`` (km/h).

    Parameters
    ----------
    pavement: object with ``evaluate(x_m, y_m) -> (z_m, dzdx, dzdy)`` and ``extent_m`` (see
        :mod:`skidsim.solver.surfaces`). The slider starts ``edge_margin_mm`` after ``x_min`` and slides in +x.
    speed_kmh: sliding speed in km/h (> 0).
    law: friction law with ``mu(slip_speed_ms)`` (e.g. :class:`skidsim.friction.ExponentialDecay`).
    config: :class:`SolverConfig` (default: the reference preset).
    y_offset_mm: lateral offset (mm) of the slider centre from the centre line of the strip.
    progress: optional callable ``progress(step, n_steps, elapsed_s, eta_s)``, called about every
        ``config.progress_every_s`` wall seconds (progress is also logged on logger ``skidsim.solver``).
    trace_path: if given, the trace is written there as parquet (atomically).
    vtu_dir: if given, ``config.vtu_frames`` VTU frames of the slide (+ ``slider.pvd``) are written there.
    slope_bound: optional bound on ``|grad z|^2`` of the pavement for the time step (default: sampled).
    """
    return _with_blas_limit(
        config,
        lambda cfg: _run(
            pavement, [speed_kmh], [law], cfg, y_offset_mm, progress, [trace_path], [vtu_dir], slope_bound
        ),
    )[0]


def simulate_batch(
    pavement,
    speeds_kmh,
    laws,
    config: SolverConfig | None = None,
    *,
    y_offset_mm: float = 0.0,
    progress=None,
    trace_paths=None,
    slope_bound: float | None = None,
) -> list[SimulationResult]:
    """Simulate several slides over the same ``pavement`` with the same ``config`` at once (one result per member).

    ``speeds_kmh`` (km/h) and ``laws`` (one law for all, or one per speed) define the members; they share the
    mesh, the placement and the time step (which depend only on the pavement and the config) and are stepped
    together: one kernel product, one contact evaluation and one set of NumPy calls per step for the whole batch
    (leading member axis, :class:`skidsim.solver.kernel.StructuredKernel`). A member whose preload has converged
    waits for the others; a member that has finished its slide leaves the batch. Each result equals
    :func:`simulate` of that member bit for bit (SN, trace, step counts; energies to rounding, ~1e-15 relative),
    except ``wall_s``: the batch's wall time shared in proportion to the members' steps. ``trace_paths``: one
    path (or None) per member. Other parameters as :func:`simulate`.
    """
    speeds = [float(s) for s in np.atleast_1d(np.asarray(speeds_kmh, dtype=float))]
    laws = list(laws) if isinstance(laws, list | tuple) else [laws] * len(speeds)
    if len(laws) != len(speeds):
        raise ConfigError(f"simulate_batch: {len(laws)} laws for {len(speeds)} speeds")
    if not speeds:
        return []
    paths = [None] * len(speeds) if trace_paths is None else list(trace_paths)
    return _with_blas_limit(
        config,
        lambda cfg: _run(pavement, speeds, laws, cfg, y_offset_mm, progress, paths, [None] * len(speeds), slope_bound),
    )


def _with_blas_limit(config, fn):
    config = SolverConfig.reference() if config is None else config
    limiter = None
    if config.blas_threads is not None:
        try:
            from threadpoolctl import threadpool_limits

            limiter = threadpool_limits(limits=int(config.blas_threads), user_api="blas")
        except ImportError:  # pragma: no cover - optional
            limiter = None
    try:
        return fn(config)
    finally:
        if limiter is not None:
            limiter.restore_original_limits()


def _run(pavement, speeds_kmh, laws, config, y_offset_mm, progress, trace_paths, vtu_dirs, slope_bound):
    """Preload and slide the members (one speed and law each) together; one result per member."""
    t_wall0 = time.perf_counter()
    for s in speeds_kmh:
        if not (np.isfinite(s) and s > 0):
            raise ConfigError(f"simulate: 'speed_kmh' expected > 0 km/h, got {s!r}")
    m = build_model(pavement, config, y_offset_mm, slope_bound)
    out = MemberOutput(m, speeds_kmh, vtu_dirs)
    log.info(
        "simulate: %d elements, dt %.3g us, <= %d preload + %s slide steps at %s km/h over %.1f mm",
        m.mesh.n_elements,
        m.dt * 1e6,
        m.n_pre_max,
        out.n_slide.tolist(),
        [float(s) for s in speeds_kmh],
        m.slide_m * 1e3,
    )
    clock = Clock(config, progress)
    clock.t0 = t_wall0
    b = Batch(m, np.arange(len(speeds_kmh)), out.v_slide, laws)
    b = preload_shared(m, b, out, clock)
    slide(m, b, out, clock)
    wall = time.perf_counter() - t_wall0
    phase_s = dict(zip(PHASES, clock.ph))
    phase_s["setup_and_rest"] = wall - sum(clock.ph)
    steps = out.n_pre + out.n_slide
    return [
        out.result(j, s, y_offset_mm, trace_paths[j], wall * float(steps[j]) / float(steps.sum()), phase_s)
        for j, s in enumerate(speeds_kmh)
    ]
