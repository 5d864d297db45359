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
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.errors import ConfigError
from skidsim.friction import kmh_to_ms
from skidsim.slidermesh import SliderMesh
from skidsim.solver.config import SolverConfig
from skidsim.solver.contact_friction import damped_step_factor, penalty_friction, rayleigh_coefficients
from skidsim.solver.kernel import StructuredKernel, to_internal, to_mesh_layout
from skidsim.solver.material import RubberMaterial, element_matrices, lumped_mass
from skidsim.solver.results import SimulationResult, VtuSeriesWriter, write_trace_parquet
from skidsim.solver.surfaces import SurfaceBound, pavement_extent_m

log = logging.getLogger("skidsim.solver")

#: Phases of a time step timed by :func:`simulate` (``result.meta["phase_s"]``, wall s, plus ``setup_and_rest``):
#: internal force (kernel and Prony update), damping and load, contact (candidate search, surface evaluation,
#: penalty forces), friction, update (holder, velocities, positions, energy bookkeeping), output (trace rows,
#: preload check, VTU, progress).
PHASES = ("internal_force", "damping_load", "contact", "friction", "update", "output")

#: sliding steps between direct evaluations of K u when it is otherwise updated by dt K v (Rayleigh damping)
KU_REFRESH_STEPS = 1024


def _spring_energy(force_n: np.ndarray, k_n_per_m: np.ndarray) -> float:
    """Energy (J) stored in springs of stiffness ``k_n_per_m`` (n,) carrying forces ``force_n`` (3, n) (N)."""
    return 0.5 * float(((force_n * force_n).sum(axis=0) / k_n_per_m).sum())


def material_from_config(config: SolverConfig) -> RubberMaterial:
    """The :class:`RubberMaterial` of a :class:`SolverConfig`."""
    return RubberMaterial(
        config.youngs_modulus_pa, config.poisson, config.density_kg_m3, config.prony_g, config.prony_tau_s
    )


def build_kernel(mesh: SliderMesh, material: RubberMaterial) -> StructuredKernel:
    """Slicing kernel with the long-term elastic matrix and the Prony branches of ``material``."""
    k_vol, k_dev = element_matrices(mesh.hx, mesh.hy, mesh.hz)
    k_inf = material.bulk_modulus_pa * k_vol + material.shear_modulus_pa * k_dev
    return StructuredKernel(
        mesh, k_inf, k_dev_unit=k_dev, branch_g_pa=material.branch_shear_moduli_pa, branch_tau_s=material.prony_tau_s
    )


def max_frequency_power_iteration(
    mesh: SliderMesh,
    material: RubberMaterial,
    mass_kg: np.ndarray,
    *,
    iterations: int = 150,
    tol: float = 1e-5,
    seed: int = 0,
) -> float:
    """Highest circular frequency (rad/s) of the free slider, ``sqrt(lambda_max(M^-1/2 K_0 M^-1/2))``.

    Power iteration with the instantaneous stiffness K_0 and lumped masses ``mass_kg`` (internal layout
    ``(nz+1, ny+1, nx+1)``); the Rayleigh quotient converges from below, which ``dt_safety`` covers. Seeded
    with ``numpy.random.default_rng(seed)``.
    """
    k_vol, k_dev = element_matrices(mesh.hx, mesh.hy, mesh.hz)
    k0 = material.bulk_modulus_pa * k_vol + material.instantaneous_shear_modulus_pa * k_dev
    kern = StructuredKernel(mesh, k0)
    s = 1.0 / np.sqrt(mass_kg)[None]
    z = np.random.default_rng(seed).standard_normal((3,) + mass_kg.shape)
    z /= np.linalg.norm(z)
    out = np.empty_like(z)
    lam_old = 0.0
    lam = 0.0
    for it in range(iterations):
        kern.force(z * s, out)
        out *= s
        lam = float(np.vdot(z, out))
        nrm = np.linalg.norm(out)
        z = out / nrm
        if it > 20 and abs(lam - lam_old) < tol * lam:
            break
        lam_old = lam
    return math.sqrt(max(lam, 0.0))


def _max_slope_sq(pavement, x0, x1, y0, y1, spacing_m) -> float:
    """max |grad z|^2 of the pavement sampled on a grid over the swept region (m)."""
    nx = max(2, int(math.ceil((x1 - x0) / spacing_m)) + 1)
    ny = max(2, int(math.ceil((y1 - y0) / spacing_m)) + 1)
    x = np.linspace(x0, x1, nx)
    y = np.linspace(y0, y1, ny)
    X, Y = np.meshgrid(x, y, indexing="ij")
    _, fx, fy = pavement.evaluate(X.ravel(), Y.ravel())
    return float(np.nanmax(np.asarray(fx) ** 2 + np.asarray(fy) ** 2))


def _ramp(t, t_ramp):
    return 1.0 if t >= t_ramp else 0.5 * (1.0 - math.cos(math.pi * t / t_ramp))


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
    """Simulate one DFT slide of the rubber slider (see :func:`_simulate` for the parameters)."""
    config = SolverConfig.reference() if config is None else config
    limiter = None
    if config.blas_threads is not None:
        try:
            from threadpoolctl import threadpool_limits

            limiter = threadpool_limits(limits=int(config.blas_threads), user_api="blas")
        except ImportError:  # pragma: no cover - optional
            limiter = None
    try:
        return _simulate(
            pavement,
            speed_kmh,
            law,
            config,
            y_offset_mm=y_offset_mm,
            progress=progress,
            trace_path=trace_path,
            vtu_dir=vtu_dir,
            slope_bound=slope_bound,
        )
    finally:
        if limiter is not None:
            limiter.restore_original_limits()


def _simulate(
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
    t_wall0 = time.perf_counter()
    config = SolverConfig.reference() if config is None else config
    if not (np.isfinite(speed_kmh) and speed_kmh > 0):
        raise ConfigError(f"simulate: 'speed_kmh' expected > 0 km/h, got {speed_kmh!r}")
    v_slide = float(kmh_to_ms(speed_kmh))
    mat = material_from_config(config)
    ext = pavement_extent_m(pavement)

    # ---- geometry and placement -------------------------------------------------------------------------------
    L, W = config.slider_length_mm * 1e-3, config.slider_width_mm * 1e-3
    margin = config.edge_margin_mm * 1e-3
    x0 = ext[0] + margin
    y_c = 0.5 * (ext[2] + ext[3]) + y_offset_mm * 1e-3
    y0 = y_c - 0.5 * W
    if y0 < ext[2] - 1e-12 or y0 + W > ext[3] + 1e-12:
        raise ConfigError(
            f"simulate: 'y_offset_mm' = {y_offset_mm} puts the {config.slider_width_mm} mm wide slider "
            f"outside the pavement strip y in [{ext[2] * 1e3:.3f}, {ext[3] * 1e3:.3f}] mm"
        )
    available = ext[1] - margin - (x0 + L)
    slide = config.slide_length_mm * 1e-3
    clamped = False
    if slide > available + 1e-12:
        if not config.clamp_slide or available <= config.window_start_mm * 1e-3:
            raise ConfigError(
                f"simulate: 'slide_length_mm' = {config.slide_length_mm} does not fit the pavement "
                f"strip (x extent {(ext[1] - ext[0]) * 1e3:.2f} mm leaves {available * 1e3:.2f} mm for a "
                f"{config.slider_length_mm} mm slider with {config.edge_margin_mm} mm margins)"
            )
        slide, clamped = available, True

    mesh = SliderMesh.box(
        config.slider_length_mm,
        config.slider_width_mm,
        config.slider_thickness_mm,
        config.element_mm,
        origin_m=(x0, y0, 0.0),
    )
    X = to_internal(mesh.coordinates)  # (3, nz+1, ny+1, nx+1)
    zs0, _, _ = pavement.evaluate(X[0, 0].ravel(), X[1, 0].ravel())
    zs0 = np.asarray(zs0, dtype=float)
    if not np.all(np.isfinite(zs0)):
        raise ConfigError("simulate: the pavement returned non-finite heights under the slider's start position")
    X[2] += zs0.max()  # bottom face touches the highest point under its nodes

    # ---- masses, stiffness, loads ---------------------------------------------------------------------------------
    mass = to_internal(lumped_mass(mesh, mat.density_kg_m3 * config.mass_scaling))
    minv = 1.0 / mass
    kern = build_kernel(mesh, mat)
    area_b = mesh.nodal_tributary_area_bottom().T.copy()  # (ny+1, nx+1) m^2
    h_pen = mesh.hz if config.penalty_length_mm is None else config.penalty_length_mm * 1e-3  # m
    k_pen = config.penalty_scale * mat.youngs_modulus_pa * area_b / h_pen  # N/m per bottom node
    f_top = -config.load_n * area_b / area_b.sum()  # N per top node (same tributary pattern)
    m_b = mass[0]
    m_holder = float(mass[-1].sum())  # the top face moves as one rigid holder in z
    vz_holder = 0.0
    c_holder = config.holder_damping_per_s * float(mass.sum())  # N s/m
    omega_el = max_frequency_power_iteration(mesh, mat, mass)
    if slope_bound is None:
        slope_bound = _max_slope_sq(
            pavement, x0, min(ext[1], x0 + L + slide), y0, y0 + W, spacing_m=min(mesh.hx, mesh.hy) / 4
        )
    normal_gap = config.contact_gap == "normal"
    fric_penalty = config.friction_model == "penalty"
    k_fric = config.friction_stiffness_pa_per_m * area_b  # N/m per bottom node (penalty friction)
    # normal stiffness of the contact: k (1 + |grad z|^2) for the vertical gap, k for the normal gap; the
    # tangential penalty k_t acts in the tangent plane, orthogonal to it: the node's largest eigenvalue is the max
    k_contact = k_pen * (1.0 if normal_gap else 1.0 + slope_bound)
    if fric_penalty:
        k_contact = np.maximum(k_contact, k_fric)
    omega_pen_sq = float(np.max(k_contact / m_b))
    omega = math.sqrt(omega_el**2 + omega_pen_sq)
    dt = config.dt_safety * 2.0 / omega
    rayleigh = config.slide_damping_model == "rayleigh"
    alpha_r, beta_r = rayleigh_coefficients(config.loss_factor, config.loss_band_hz) if rayleigh else (0.0, 0.0)
    kern_beta = None
    # elastic slider with Rayleigh damping: one kernel product per sliding step, K v(n-1/2), serves both the
    # damping force -beta K v and K u(n) = K u(n-1) + dt K v(n-1/2) (linear in u; recomputed from u every
    # KU_REFRESH_STEPS steps so that rounding cannot accumulate). With Prony terms the force is not linear in u
    # alone (history), so there the damping has its own product.
    incremental_ku = rayleigh and not kern.g.size
    if rayleigh:
        dt *= damped_step_factor(omega, alpha_r, beta_r)
        if not incremental_ku:
            kern_beta = StructuredKernel(mesh, beta_r * kern.k)  # stiffness-proportional damping, N s/m

    n_pre_max = max(1, int(math.ceil(config.preload_time_s / dt)))
    n_ramp = min(n_pre_max, max(1, int(math.ceil(config.preload_ramp_s / dt))))
    n_check = max(1, int(math.ceil(config.preload_check_s / dt)))
    n_slide = max(1, int(math.ceil(slide / (v_slide * dt))))
    n_pre = n_pre_max  # lowered when the preload has converged
    n_total = n_pre + n_slide
    t_ramp = n_ramp * dt
    fz_prev_check = None
    c_cached = None
    neg_cm = None

    # ---- state ---------------------------------------------------------------------------------------------------
    u = np.zeros_like(X)
    v = np.zeros_like(X)
    f = np.zeros_like(X)
    fint = np.zeros_like(X)
    tmp = np.zeros_like(X)
    fdamp = np.zeros_like(X)
    fbeta = np.zeros_like(X) if kern_beta is not None else None
    nku = np.zeros_like(X) if incremental_ku else None  # -K u(n), N
    nkv = np.zeros_like(X) if incremental_ku else None  # -K v(n-1/2), N/s
    dt_minv = dt * minv[None]
    # bottom face as flat views (3, (ny+1)(nx+1)): each component's face block is contiguous in the layout
    ub, vb, fb = u[:, 0].reshape(3, -1), v[:, 0].reshape(3, -1), f[:, 0].reshape(3, -1)
    assert np.shares_memory(ub, u) and np.shares_memory(vb, v) and np.shares_memory(fb, f)
    Xb = X[:, 0].reshape(3, -1)
    m_bf = m_b.ravel()
    k_pen_f = k_pen.ravel()
    k_fric_f = k_fric.ravel()
    k_fric_dt_f = k_fric_f * dt  # N s/m: the tangential penalty on a velocity over one step
    ft_state = np.zeros((3, m_bf.size))  # penalty friction: tangential force per bottom node, N
    fric_energy = 0.0  # J stored in the tangential penalty springs
    area_bf = area_b.ravel()
    inv_mb_dt = dt / m_bf
    mb_over_dt = m_bf / dt
    bound = SurfaceBound.of(pavement)  # per-cell upper bound of the surface (None: every node is a candidate)
    all_nodes = np.arange(m_bf.size)

    every = int(config.trace_every)
    n_rec = (n_slide + every - 1) // every
    rec_t = np.empty(n_rec)
    rec_x = np.empty(n_rec)
    rec_ft = np.empty(n_rec)
    rec_fn = np.empty(n_rec)
    rec_a = np.empty(n_rec)
    rec_ff = np.empty(n_rec)
    rec_nc = np.empty(n_rec, dtype=np.int64)
    rec_ns = np.empty(n_rec, dtype=np.int64)
    rec_sl = np.empty(n_rec)

    e = dict(external=0.0, friction=0.0, damping=0.0, viscous=0.0)
    state0 = {}
    vtu = VtuSeriesWriter(vtu_dir, mesh) if vtu_dir is not None else None
    vtu_steps = set()
    if vtu is not None:
        vtu_steps = set(np.unique(np.linspace(0, n_slide - 1, int(config.vtu_frames)).round().astype(int)).tolist())
    max_pen = 0.0
    preload_force = preload_area = 0.0
    fz_sum = area_now = pen_energy = 0.0  # contact force (N), area (m^2), penalty energy (J) of the last step
    last_log = t_wall0
    fric = np.zeros((3, 0))
    fcn = np.zeros((3, 0))
    ia = all_nodes[:0]
    n_stick = 0
    N = np.zeros(0)
    log.info(
        "simulate: %d elements, dt %.3g us, <= %d preload + %d slide steps at %.1f km/h over %.1f mm",
        mesh.n_elements,
        dt * 1e6,
        n_pre,
        n_slide,
        speed_kmh,
        slide * 1e3,
    )

    rec = 0
    step = -1
    perf = time.perf_counter
    ph = [0.0] * 6  # wall s per phase: internal force, damping + load, contact, friction, update, output
    while step + 1 < n_total:
        step += 1
        sliding = step >= n_pre
        if step == n_pre:  # ---- start of sliding: every node gets the test speed
            preload_force, preload_area = fz_sum, area_now
            log.info(
                "preload: contact force %.4f N (load %.4f N) after %d steps (%.3g ms)",
                preload_force,
                config.load_n,
                n_pre,
                n_pre * dt * 1e3,
            )
            v[0] += v_slide
            kern.force(u, fint)
            if fric_penalty:
                fric_energy = _spring_energy(ft_state, k_fric_f)
            state0 = dict(
                kinetic=0.5 * float(np.vdot(mass, (v * v).sum(axis=0))),
                strain=kern.strain_energy(),
                contact=pen_energy,
                friction_elastic=fric_energy,
            )
        # ---- internal force (and Prony history) at u(n)
        t_a = perf()
        if sliding and incremental_ku:
            kern.force(v, nkv, negate=True)
            if (step - n_pre) % KU_REFRESH_STEPS == 0:
                kern.force(u, nku, negate=True)
            else:
                np.multiply(nkv, dt, out=tmp)
                nku += tmp
            np.multiply(nkv, beta_r, out=f)  # the Rayleigh stiffness part -beta K v, here rather than below
            f += nku
        else:
            kern.force(u, f, negate=True)  # f = -f_int, bit for bit
        if kern.g.size:
            diss = kern.relax(dt)
            if sliding:
                e["viscous"] += diss
        lf = 1.0 if sliding else _ramp(step * dt, t_ramp)
        f[2, -1] += lf * f_top
        t_b = perf()
        ph[0] += t_b - t_a
        # ---- damping (mass proportional, velocity relative to the holder)
        c = (alpha_r if rayleigh else config.slide_damping_per_s) if sliding else config.preload_damping_per_s
        vx_frame = v_slide if sliding else 0.0
        # sliding: dashpots to the holder (moving with (v_slide, 0, vz_holder)), so the rigid vertical motion that
        # follows the texture is not resisted; preload: to the ground (dynamic relaxation of the whole slider)
        vz_frame = vz_holder if sliding else 0.0
        if c > 0:
            if c != c_cached:
                c_cached = c
                neg_cm = -c * mass
            np.multiply(v, neg_cm[None], out=fdamp)  # -c m (v - v_frame), frame terms on two components
            if vx_frame:
                fdamp[0] -= vx_frame * neg_cm
            if vz_frame:
                fdamp[2] -= vz_frame * neg_cm
            f += fdamp
        if sliding and kern_beta is not None:  # -beta K v: rigid (frame) motion is in K's null space
            kern_beta.force(v, fbeta, negate=True)
            f += fbeta
        t_a = perf()
        ph[1] += t_a - t_b
        # ---- contact normal (penalty, conservative), evaluated on the candidate nodes only: those below the
        # upper bound of the surface in their cell (a node above it cannot penetrate; exact, no tolerance)
        xb = Xb[0] + ub[0]
        yb = Xb[1] + ub[1]
        zb = Xb[2] + ub[2]
        cand = all_nodes if bound is None else bound.candidates(xb, yb, zb)
        if cand.size:
            zs, gx, gy = pavement.evaluate(xb[cand], yb[cand])
            d = zs - zb[cand]
            act = d > 0.0
            ia = cand[act]  # nodes in contact
            d = d[act]
            gx = gx[act]
            gy = gy[act]
        else:
            ia = cand
            d = gx = gy = np.zeros(0)
        kd = k_pen_f[ia] * d
        if normal_gap:  # k d_n along the normal: vertical component k d / (1 + |grad z|^2)
            kd /= 1.0 + gx * gx + gy * gy
        fcn = np.empty((3, ia.size))
        np.multiply(kd, gx, out=fcn[0])
        np.negative(fcn[0], out=fcn[0])
        np.multiply(kd, gy, out=fcn[1])
        np.negative(fcn[1], out=fcn[1])
        fcn[2] = kd
        fb[:, ia] += fcn
        pen_energy = 0.5 * float(np.dot(kd, d))
        t_b = perf()
        ph[2] += t_b - t_a
        # ---- friction: stick limit or penalty with return mapping (nodes in contact; the others carry none)
        n_len = np.sqrt(1.0 + gx * gx + gy * gy)
        N = kd * n_len
        nxh, nyh, nzh = -gx / n_len, -gy / n_len, 1.0 / n_len
        if fric_penalty:
            # elastic predictor on the step's displacement increment dt v(n-1/2), return mapping onto mu(s) N;
            # s = tangential speed of the node over the step (the slip rate once it slides)
            vt = vb[:, ia]
            vn = vt[0] * nxh + vt[1] * nyh + vt[2] * nzh
            s = np.sqrt(np.maximum((vt * vt).sum(axis=0) - vn * vn, 0.0))
            mu_n = law.mu(s) * N
            # (k_t dt) v = k_t du: the step's displacement increment without forming it
            fric, stuck = penalty_friction(ft_state[:, ia], vt, k_fric_dt_f[ia], mu_n, (nxh, nyh, nzh))
            n_stick = int(np.count_nonzero(stuck))  # nodes in the elastic (stick) regime (diagnostic)
            ft_state.fill(0.0)  # nodes out of contact lose their tangential force
            ft_state[:, ia] = fric
        else:
            vt = vb[:, ia] + fb[:, ia] * inv_mb_dt[ia]  # trial velocity without friction
            vn = vt[0] * nxh + vt[1] * nyh + vt[2] * nzh
            vt[0] -= vn * nxh
            vt[1] -= vn * nyh
            vt[2] -= vn * nzh
            s = np.sqrt((vt * vt).sum(axis=0))
            mu_n = law.mu(s) * N
            stick_lim = mb_over_dt[ia] * s
            n_stick = int(np.count_nonzero(stick_lim < mu_n))  # nodes held by the stick limit (diagnostic)
            fmag = np.minimum(mu_n, stick_lim)
            scale = np.where(s > 0.0, -fmag / np.where(s > 0.0, s, 1.0), 0.0)
            fric = vt * scale
        fb[:, ia] += fric
        t_a = perf()
        ph[3] += t_a - t_b
        # ---- rigid holder: top x/y velocity prescribed (reaction = -(net force) there), one common z velocity
        react_x = -float(f[0, -1].sum())
        fz_holder = float(f[2, -1].sum())
        vz_old = vz_holder
        fz_hd = -c_holder * vz_holder if sliding else 0.0  # holder suspension dashpot (to the ground)
        vz_holder = vz_holder + dt * (fz_holder + fz_hd) / m_holder
        # ---- update
        if sliding:
            vb_old = vb[:, ia]
            if c > 0:
                fd_dot_v_old = float(np.vdot(fdamp, v))  # avoids copying v: f_d.(v_old + v_new) in two dots
            if fbeta is not None:
                fb_dot_v_old = float(np.vdot(fbeta, v))
            elif nkv is not None:
                fb_dot_v_old = beta_r * float(np.vdot(nkv, v))
        np.multiply(f, dt_minv, out=tmp)
        v += tmp
        v[0, -1] = vx_frame
        v[1, -1] = 0.0
        v[2, -1] = vz_holder
        if sliding:
            h = 0.5 * dt
            e["external"] += h * (-config.load_n * (vz_old + vz_holder) + react_x * 2.0 * vx_frame)
            e["damping"] -= h * fz_hd * (vz_old + vz_holder)
            e["friction"] -= h * float(np.vdot(fric, vb_old + vb[:, ia]))
            if c > 0:
                # dashpots between each node and the frame (vx_frame, 0, vz_frame): they dissipate
                # c m |w|^2 (w = velocity relative to the frame, >= 0), the holder feeds them f_d . v_frame
                fd_frame = 2.0 * (vx_frame * float(fdamp[0].sum()) + vz_frame * float(fdamp[2].sum()))
                e["damping"] -= h * (fd_dot_v_old + float(np.vdot(fdamp, v)) - fd_frame)
                e["external"] += h * fd_frame
            if fbeta is not None:
                e["damping"] -= h * (fb_dot_v_old + float(np.vdot(fbeta, v)))
            elif nkv is not None:  # the Rayleigh stiffness part -beta K v(n-1/2) is beta * nkv
                e["damping"] -= h * (fb_dot_v_old + beta_r * float(np.vdot(nkv, v)))
        np.multiply(v, dt, out=tmp)
        u += tmp
        t_b = perf()
        ph[4] += t_b - t_a
        # ---- pavement force on the slider (at step n)
        fz_sum = float(fcn[2].sum() + fric[2].sum())
        area_now = float(area_bf[ia].sum())
        if not sliding and step >= n_ramp and (step - n_ramp) % n_check == 0:
            # preload converged: contact force within tolerance of the load at two checks in a row
            ok = abs(fz_sum - config.load_n) <= config.preload_tolerance * config.load_n
            if ok and fz_prev_check is not None and step + 1 < n_pre:
                n_pre = step + 1
                n_total = n_pre + n_slide
            fz_prev_check = fz_sum if ok else None
        if sliding:
            if d.size and d.max() > max_pen:
                max_pen = float(d.max())
            i = step - n_pre
            if i % every == 0:
                rec_t[rec] = i * dt
                rec_x[rec] = v_slide * i * dt
                rec_ft[rec] = -float(fcn[0].sum() + fric[0].sum())
                rec_fn[rec] = fz_sum
                rec_a[rec] = area_now
                rec_ff[rec] = -float(fric[0].sum())
                rec_nc[rec] = ia.size
                rec_ns[rec] = n_stick
                n_sum = float(N.sum())
                rec_sl[rec] = float(np.dot(N, s)) / n_sum if n_sum > 0.0 else np.nan
                rec += 1
            if vtu is not None and i in vtu_steps:
                p = np.zeros(mass.shape)
                p[0].reshape(-1)[ia] = N / area_bf[ia]
                vtu.write(i * dt, mesh.coordinates, to_mesh_layout(u), to_mesh_layout(p))
        now = perf()
        ph[5] += now - t_b
        if now - last_log >= config.progress_every_s:
            last_log = now
            el = now - t_wall0
            eta = el / (step + 1) * (n_total - step - 1)
            log.info(
                "step %d/%d (%.0f %%), %.1f s elapsed, %.1f s left",
                step + 1,
                n_total,
                100.0 * (step + 1) / n_total,
                el,
                eta,
            )
            if progress is not None:
                progress(step + 1, n_total, el, eta)

    # ---- energies of the sliding phase
    kern.force(u, fint)
    if fric_penalty:
        fric_energy = _spring_energy(ft_state, k_fric_f)
    kinetic = 0.5 * float(np.vdot(mass, (v * v).sum(axis=0)))
    # the tangential penalty springs' stored energy is contact energy; the friction entry is what they dissipate
    d_fric_elastic = fric_energy - state0["friction_elastic"]
    energies = dict(
        external=e["external"],
        kinetic=kinetic - state0["kinetic"],
        strain=kern.strain_energy() - state0["strain"],
        contact=pen_energy - state0["contact"] + d_fric_elastic,
        friction=e["friction"] - d_fric_elastic,
        hourglass=0.0,
        damping=e["damping"],
        viscous=e["viscous"],
    )
    energies["residual"] = energies["external"] - sum(
        energies[k] for k in ("kinetic", "strain", "contact", "friction", "hourglass", "damping", "viscous")
    )
    trace = pd.DataFrame(
        {
            "time_s": rec_t[:rec],
            "position_mm": rec_x[:rec] * 1e3,
            "tangential_n": rec_ft[:rec],
            "normal_n": rec_fn[:rec],
            "contact_area_mm2": rec_a[:rec] * 1e6,
            "friction_x_n": rec_ff[:rec],
            "contact_nodes": rec_nc[:rec],
            "stick_nodes": rec_ns[:rec],
            "slip_speed_ms": rec_sl[:rec],
        }
    )
    w0 = config.window_start_mm
    w1 = slide * 1e3 if config.window_end_mm is None else min(config.window_end_mm, slide * 1e3)
    win = (trace["position_mm"] >= w0) & (trace["position_mm"] <= w1)
    if not win.any():
        raise ConfigError(
            f"simulate: the steady window [{w0}, {w1}] mm holds no trace rows (slide {slide * 1e3:.2f} mm)"
        )
    ft = float(trace.loc[win, "tangential_n"].mean())
    fn = float(trace.loc[win, "normal_n"].mean())
    if trace_path is not None:
        write_trace_parquet(trace, trace_path)
    wall = time.perf_counter() - t_wall0
    phase_s = dict(zip(PHASES, ph))
    phase_s["setup_and_rest"] = wall - sum(ph)
    log.info("simulate: SN %.4f (Ft %.4f N / Fn %.4f N), %d steps in %.1f s", ft / fn, ft, fn, n_total, wall)
    return SimulationResult(
        sn=ft / fn,
        tangential_n=ft,
        normal_n=fn,
        n_steps=n_total,
        dt_s=dt,
        wall_s=wall,
        energies=energies,
        trace=trace,
        speed_kmh=float(speed_kmh),
        slide_length_mm=slide * 1e3,
        slide_clamped=clamped,
        window_mm=(float(w0), float(w1)),
        preload_steps=n_pre,
        preload_contact_force_n=preload_force,
        preload_contact_area_mm2=preload_area * 1e6,
        max_penetration_um=max_pen * 1e6,
        n_elements=mesh.n_elements,
        omega_max_rad_s=omega,
        mean_contact_area_mm2=float(trace.loc[win, "contact_area_mm2"].mean()),
        mean_slip_speed_ms=float(trace.loc[win, "slip_speed_ms"].mean()),
        meta=dict(
            config=config.as_dict(),
            y_offset_mm=float(y_offset_mm),
            omega_elastic_rad_s=omega_el,
            rayleigh_alpha_per_s=alpha_r,
            rayleigh_beta_s=beta_r,
            slope_bound=float(slope_bound),
            element_size_m=(mesh.hx, mesh.hy, mesh.hz),
            phase_s=phase_s,
        ),
    )
