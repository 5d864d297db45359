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
* **Code**: a preload loop and a slide loop (:func:`_preload`, :func:`_slide`) around :func:`_step`, which calls
  the internal force, the damping, the contact laws of :mod:`skidsim.solver.contact` and the update in turn, on
  preallocated buffers. **Batches** (:func:`simulate_batch`): runs on the same pavement with the same config share
  the mesh and the time step and are stepped together, nodal arrays ``(3, nz+1, B, ny+1, nx+1)`` (the kernel's
  batched layout); each member gets the SN of its single run bit for bit. :func:`simulate` is the batch of one.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.errors import ConfigError
from skidsim.friction import kmh_to_ms
from skidsim.slidermesh import SliderMesh
from skidsim.solver.config import SolverConfig
from skidsim.solver.contact import (
    Contact,
    FrictionCoefficient,
    Segments,
    normal_contact,
    penalty_step,
    stick_limit_friction,
)
from skidsim.solver.contact_friction import damped_step_factor, rayleigh_coefficients
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


def material_from_config(config: SolverConfig) -> RubberMaterial:
    """The :class:`RubberMaterial` of a :class:`SolverConfig`."""
    return RubberMaterial(
        config.youngs_modulus_pa, config.poisson, config.density_kg_m3, config.prony_g, config.prony_tau_s
    )


def build_kernel(mesh: SliderMesh, material: RubberMaterial, *, batch: int = 1) -> StructuredKernel:
    """Slicing kernel with the long-term elastic matrix and the Prony branches of ``material`` (``batch`` sliders)."""
    k_vol, k_dev = element_matrices(mesh.hx, mesh.hy, mesh.hz)
    k_inf = material.bulk_modulus_pa * k_vol + material.shear_modulus_pa * k_dev
    return StructuredKernel(
        mesh,
        k_inf,
        k_dev_unit=k_dev,
        branch_g_pa=material.branch_shear_moduli_pa,
        branch_tau_s=material.prony_tau_s,
        batch=batch,
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


# ---- the model the members share ------------------------------------------------------------------------------------


@dataclass
class _Model:
    """What the members of a batch share (SI units): slider mesh and placement, masses, stiffness, contact
    constants, time step and step counts of the preload. Nodal arrays in the internal layout of one slider."""

    config: SolverConfig
    pavement: object
    bound: SurfaceBound | None
    mesh: SliderMesh
    material: RubberMaterial
    k_inf: np.ndarray  # 24 x 24 long-term element stiffness, N/m
    X: np.ndarray  # (3, nz+1, ny+1, nx+1) reference coordinates, m
    mass: np.ndarray  # (nz+1, ny+1, nx+1) lumped masses, kg
    area_b: np.ndarray  # (ny+1, nx+1) tributary areas of the bottom nodes, m^2
    k_pen: np.ndarray  # (ny+1, nx+1) normal penalty, N/m
    k_fric: np.ndarray  # (ny+1, nx+1) tangential penalty, N/m
    f_top: np.ndarray  # (ny+1, nx+1) dead load per top node, N
    m_holder: float  # kg
    c_holder: float  # N s/m
    slide_m: float
    clamped: bool
    slope_bound: float
    omega_el: float  # rad/s
    omega: float  # rad/s
    dt: float  # s
    alpha_r: float  # 1/s
    beta_r: float  # s
    n_pre_max: int
    n_ramp: int
    n_check: int
    t_ramp: float  # s

    @property
    def n_face(self) -> int:
        return self.area_b.size

    @property
    def rayleigh(self) -> bool:
        return self.config.slide_damping_model == "rayleigh"

    @property
    def incremental_ku(self) -> bool:
        """Elastic slider with Rayleigh damping: one kernel product per sliding step, ``K v(n-1/2)``, serves both
        the damping force ``-beta K v`` and ``K u(n) = K u(n-1) + dt K v(n-1/2)`` (linear in u; recomputed from u
        every ``KU_REFRESH_STEPS`` steps so that rounding cannot accumulate). With Prony terms the force is not
        linear in u alone (history), so there the damping has its own product."""
        return self.rayleigh and not self.config.prony_g


def _place_slider(pavement, config: SolverConfig, y_offset_mm: float):
    """Mesh, reference coordinates (internal layout, bottom face on the highest point under it) and slide length
    (m, clamped to the strip if allowed) of the slider ``edge_margin_mm`` after ``x_min``."""
    ext = pavement_extent_m(pavement)
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
    swept = (x0, min(ext[1], x0 + L + slide), y0, y0 + W)
    return mesh, X, slide, clamped, swept


def _build_model(pavement, config: SolverConfig, y_offset_mm: float, slope_bound: float | None) -> _Model:
    """Slider, masses, stiffness, loads and the stable time step (docs/solver.md, "time step")."""
    mat = material_from_config(config)
    mesh, X, slide, clamped, swept = _place_slider(pavement, config, y_offset_mm)
    mass = to_internal(lumped_mass(mesh, mat.density_kg_m3 * config.mass_scaling))
    k_vol, k_dev = element_matrices(mesh.hx, mesh.hy, mesh.hz)
    area_b = mesh.nodal_tributary_area_bottom().T.copy()  # (ny+1, nx+1) m^2
    h_pen = mesh.hz if config.penalty_length_mm is None else config.penalty_length_mm * 1e-3  # m
    k_pen = config.penalty_scale * mat.youngs_modulus_pa * area_b / h_pen  # N/m per bottom node
    omega_el = max_frequency_power_iteration(mesh, mat, mass)
    if slope_bound is None:
        slope_bound = _max_slope_sq(pavement, *swept, spacing_m=min(mesh.hx, mesh.hy) / 4)
    normal_gap = config.contact_gap == "normal"
    k_fric = config.friction_stiffness_pa_per_m * area_b  # N/m per bottom node (penalty friction)
    # normal stiffness of the contact: k (1 + |grad z|^2) for the vertical gap, k for the normal gap; the
    # tangential penalty k_t acts in the tangent plane, orthogonal to it: the node's largest eigenvalue is the max
    k_contact = k_pen * (1.0 if normal_gap else 1.0 + slope_bound)
    if config.friction_model == "penalty":
        k_contact = np.maximum(k_contact, k_fric)
    omega = math.sqrt(omega_el**2 + float(np.max(k_contact / mass[0])))
    dt = config.dt_safety * 2.0 / omega
    rayleigh = config.slide_damping_model == "rayleigh"
    alpha_r, beta_r = rayleigh_coefficients(config.loss_factor, config.loss_band_hz) if rayleigh else (0.0, 0.0)
    if rayleigh:
        dt *= damped_step_factor(omega, alpha_r, beta_r)
    n_pre_max = max(1, int(math.ceil(config.preload_time_s / dt)))
    n_ramp = min(n_pre_max, max(1, int(math.ceil(config.preload_ramp_s / dt))))
    return _Model(
        config=config,
        pavement=pavement,
        bound=SurfaceBound.of(pavement),  # per-cell upper bound of the surface (None: every node is a candidate)
        mesh=mesh,
        material=mat,
        k_inf=mat.bulk_modulus_pa * k_vol + mat.shear_modulus_pa * k_dev,
        X=X,
        mass=mass,
        area_b=area_b,
        k_pen=k_pen,
        k_fric=k_fric,
        f_top=-config.load_n * area_b / area_b.sum(),  # N per top node (same tributary pattern)
        m_holder=float(mass[-1].sum()),  # the top face moves as one rigid holder in z
        c_holder=config.holder_damping_per_s * float(mass.sum()),
        slide_m=slide,
        clamped=clamped,
        slope_bound=float(slope_bound),
        omega_el=omega_el,
        omega=omega,
        dt=dt,
        alpha_r=alpha_r,
        beta_r=beta_r,
        n_pre_max=n_pre_max,
        n_ramp=n_ramp,
        n_check=max(1, int(math.ceil(config.preload_check_s / dt))),
        t_ramp=n_ramp * dt,
    )


# ---- the state of the members stepped together ----------------------------------------------------------------------


class _Batch:
    """State of the members stepped together. Nodal arrays ``(3, nz+1, B, ny+1, nx+1)`` (the kernel's batched
    layout), the bottom faces as flat views ``(3, B * n_face)``, one entry per member in the 1-d arrays."""

    NODAL = ("u", "v", "nku", "nkv")  # carried nodal state (f, tmp, fdamp, fbeta, fint are per-step scratch)
    MEMBER = ("ids", "v_slide", "vz", "fz_sum", "area_now", "pen_energy", "prev_ok", "max_pen")
    ENERGY = ("external", "friction", "damping", "viscous")

    def __init__(self, m: _Model, ids, v_slide, laws):
        self.m, self.n = m, len(ids)
        shape = (3, m.mesh.nz + 1, self.n, m.mesh.ny + 1, m.mesh.nx + 1)
        self.u, self.v = np.zeros(shape), np.zeros(shape)
        self.nku = np.zeros(shape) if m.incremental_ku else None  # -K u(n), N
        self.nkv = np.zeros(shape) if m.incremental_ku else None  # -K v(n-1/2), N/s
        self.ft_state = np.zeros((3, self.n * m.n_face))  # penalty friction: tangential force per bottom node, N
        self.ids, self.v_slide, self.laws = np.asarray(ids), np.asarray(v_slide, dtype=float), list(laws)
        for name in self.MEMBER[2:]:
            setattr(self, name, np.zeros(self.n))
        self.prev_ok = np.zeros(self.n, dtype=bool)  # the last preload check was within tolerance
        self.e = {k: np.zeros(self.n) for k in self.ENERGY}  # J, accumulated over the slide (floats for one member)
        self.kern = build_kernel(m.mesh, m.material, batch=self.n)
        self._derive()

    def _derive(self) -> None:
        """Scratch arrays, bottom-face views and the per-node constants tiled over the members."""
        m, n = self.m, self.n
        shape = self.u.shape
        self.f, self.tmp, self.fdamp, self.fint = (np.zeros(shape) for _ in range(4))
        self.damp_pair = None  # batch with -K v: the dashpot forces and -K v side by side, (2, *shape)
        if self.nkv is not None and n > 1:
            self.damp_pair = np.zeros((2, *shape))
            self.damp_pair[1] = self.nkv
            self.fdamp, self.nkv = self.damp_pair
        self.kern_beta = None  # stiffness-proportional damping with Prony terms: its own product, N s/m
        if m.rayleigh and not m.incremental_ku:
            self.kern_beta = StructuredKernel(m.mesh, m.beta_r * m.k_inf, batch=n)
        self.fbeta = np.zeros(shape) if self.kern_beta is not None else None
        self.mu = FrictionCoefficient(self.laws)
        self.ub, self.vb, self.fb = (a[:, 0].reshape(3, -1) for a in (self.u, self.v, self.f))
        self.f_top_z = self.f[2, -1]  # views made once: dead load, holder forces, top velocities, dashpot sums
        self.f_top_xz = self.f[::2, -1].reshape(2, n, -1)
        self.fdamp_xz = self.fdamp[::2].reshape(2, -1) if n == 1 else None
        self.fdamp_frame_z = None if n == 1 else np.empty(shape[1:])  # a batch's dashpot frame term in z, N
        self.v_top = self.v[:, -1]
        self.top_v = np.zeros((3, n, 1, 1))  # m/s: (vx, 0, vz) per member
        self.frame_x = None  # sliding: -c m vx (N), the dashpots' frame term in x (made at the first slide step)
        assert np.shares_memory(self.ub, self.u) and np.shares_memory(self.fb, self.f)
        self.Xb = np.tile(m.X[:, 0].reshape(3, -1), (1, n))
        self.xyz_b = np.empty_like(self.Xb)
        self.k_pen_f = np.tile(m.k_pen.ravel(), n)
        self.k_fric_f = np.tile(m.k_fric.ravel(), n)
        self.k_fric_dt_f = self.k_fric_f * m.dt  # N s/m: the tangential penalty on a velocity over one step
        m_bf = np.tile(m.mass[0].ravel(), n)
        self.inv_mb_dt, self.mb_over_dt = m.dt / m_bf, m_bf / m.dt
        self.area_bf = np.tile(m.area_b.ravel(), n)
        self.all_nodes = np.arange(n * m.n_face)
        self.face_starts = np.arange(n + 1) * m.n_face  # first flat bottom node of each member, and the end
        lo = int(self.ids[0])  # rows of the members in the output's per-member arrays: a slice when contiguous
        contiguous = np.array_equal(self.ids, np.arange(lo, lo + n))
        self.rows = slice(lo, lo + n) if contiguous else self.ids
        self.dt_minv = m.dt * (1.0 / m.mass)[:, None]
        # per-member reductions: Python floats for a batch of one (the single run's IEEE operations, without the
        # cost of 1-element arrays), arrays over the members otherwise
        self.one = n == 1
        if self.one:
            self.e = {k: float(np.atleast_1d(v)[0]) for k, v in self.e.items()}
            self.vx1 = float(self.v_slide[0])
            self.mdot = _vdot
        else:
            self.mdot = self._mdot

    def _assemble(self, parts, kern) -> _Batch:
        new = object.__new__(_Batch)
        new.m, new.kern = self.m, kern
        for name in self.NODAL:
            arrs = [getattr(p, name) for p in parts]
            setattr(new, name, None if arrs[0] is None else np.ascontiguousarray(np.concatenate(arrs, axis=2)))
        new.n = new.u.shape[2]
        new.ft_state = np.concatenate([p.ft_state.reshape(3, p.n, -1) for p in parts], axis=1).reshape(3, -1)
        for name in self.MEMBER:
            setattr(new, name, np.concatenate([getattr(p, name) for p in parts]))
        new.e = {k: np.concatenate([np.atleast_1d(p.e[k]) for p in parts]) for k in self.ENERGY}
        new.laws = [law for p in parts for law in p.laws]
        new._derive()
        return new

    def take(self, sel) -> _Batch:
        """The batch of the members selected by the boolean mask ``sel`` (self if all)."""
        idx = np.flatnonzero(sel)
        if idx.size == self.n:
            return self
        return self._pick(idx)

    def _pick(self, idx: np.ndarray, **member) -> _Batch:
        """The batch of the members ``idx`` (indices, repeats allowed), their state copied; ``member`` replaces
        per-member entries of the copies (``ids``, ``v_slide``)."""
        part = object.__new__(_Batch)
        part.n, part.laws = idx.size, [self.laws[i] for i in idx]
        for name in self.NODAL:
            a = getattr(self, name)
            setattr(part, name, None if a is None else a[:, :, idx])
        part.ft_state = self.ft_state.reshape(3, self.n, -1)[:, idx].reshape(3, -1)
        for name in self.MEMBER:
            setattr(part, name, getattr(self, name)[idx])
        for name, value in member.items():
            setattr(part, name, np.asarray(value))
        part.e = {k: np.atleast_1d(v)[idx] for k, v in self.e.items()}
        return self._assemble([part], self.kern.take(idx))

    def spread(self, source: np.ndarray, ids: np.ndarray, v_slide: np.ndarray) -> _Batch:
        """Members ``ids`` (test speeds ``v_slide``, m/s), each a copy of this batch's member ``source[i]``: the
        preload of members that differ only in their test speed is one preload (see :func:`_preload_shared`)."""
        return self._pick(np.asarray(source, dtype=np.intp), ids=ids, v_slide=v_slide)

    @staticmethod
    def concat(batches: list[_Batch]) -> _Batch:
        """One batch of the members of ``batches``, in order of their ids."""
        batches = sorted(batches, key=lambda p: int(p.ids[0]))
        if len(batches) == 1:
            return batches[0]
        return batches[0]._assemble(batches, StructuredKernel.concat([p.kern for p in batches]))

    def _mdot(self, a: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Per-member ``a . c`` of two nodal arrays (``self.mdot``; a float, ``np.vdot``, for one member)."""
        s = (a.shape[0] * a.shape[1], self.n, -1)
        return np.einsum("kbj,kbj->b", a.reshape(s), c.reshape(s))

    def damping_dots(self, v: np.ndarray) -> np.ndarray:
        """Per-member ``f_d . v`` and ``(-K v_old) . v`` (2, B) in one pass (``damp_pair``; a batch with -K v)."""
        k = 3 * self.u.shape[1]
        return np.einsum("pkbj,kbj->pb", self.damp_pair.reshape(2, k, self.n, -1), v.reshape(k, self.n, -1))

    def kinetic(self) -> np.ndarray:
        w = (self.v * self.v).sum(axis=0)
        if self.n == 1:
            return np.array([0.5 * np.vdot(self.m.mass, w)])
        nz1 = w.shape[0]
        return 0.5 * np.einsum("kbj,kj->b", w.reshape(nz1, self.n, -1), self.m.mass.reshape(nz1, -1))

    def friction_elastic(self) -> np.ndarray:
        """Energy (J) stored in the tangential penalty springs of each member (0 with the stick limit)."""
        if self.m.config.friction_model != "penalty":
            return np.zeros(self.n)
        ft = self.ft_state
        return 0.5 * ((ft * ft).sum(axis=0) / self.k_fric_f).reshape(self.n, -1).sum(axis=1)


# ---- one step: internal force, damping, contact, friction, holder, update --------------------------------------------


@dataclass
class _Phase:
    """Preload (ramped load, dashpots to the ground) or slide (dashpots to the holder frame, slide damping)."""

    sliding: bool
    c_per_s: float  # mass-proportional dashpot coefficient, 1/s
    neg_cm: np.ndarray  # -c m (kg/s), (nz+1, 1, ny+1, nx+1): broadcast over the members

    @classmethod
    def of(cls, m: _Model, sliding: bool) -> _Phase:
        cfg = m.config
        c = (m.alpha_r if m.rayleigh else cfg.slide_damping_per_s) if sliding else cfg.preload_damping_per_s
        return cls(sliding, c, (-c * m.mass)[:, None])


@dataclass
class _StepOut:
    """Contact of the step and the per-member sums that enter the trace (N, m^2): the sums of the rows of
    ``contact.rows`` (``(8,)`` for a batch of one, whose ``fz`` and ``area`` are floats, else ``(8, B)``)."""

    contact: Contact
    fric: np.ndarray
    stick: np.ndarray
    s: np.ndarray
    seg: Segments
    sums: np.ndarray  # rows: contact force x, y, z; friction x, y, z; contact area; normal force N
    fz: np.ndarray | float  # pavement force on the slider in z, N
    area: np.ndarray | float  # contact area, m^2


class _Clock:
    """Wall time per phase of the step (``PHASES``) and progress reports."""

    def __init__(self, config: SolverConfig, progress):
        self.t0 = self.last_log = time.perf_counter()
        self.ph = [0.0] * len(PHASES)
        self.every_s, self.progress = config.progress_every_s, progress
        self.t = self.t0
        self._now = time.perf_counter  # bound once: lap runs 7 times a step

    def lap(self, phase: int) -> None:
        now = self._now()
        self.ph[phase] += now - self.t
        self.t = now

    def report(self, done: int, total: int) -> None:
        now = self.t
        if now - self.last_log < self.every_s:
            return
        self.last_log = now
        el = now - self.t0
        eta = el / done * (total - done)
        log.info("step %d/%d (%.0f %%), %.1f s elapsed, %.1f s left", done, total, 100.0 * done / total, el, eta)
        if self.progress is not None:
            self.progress(done, total, el, eta)


def _internal_force(m: _Model, b: _Batch, ph: _Phase, k: int, load_factor: float) -> None:
    """``f = -f_int`` (and the Rayleigh stiffness part ``-beta K v``) at u(n), the Prony update, the dead load."""
    if ph.sliding and m.incremental_ku:
        b.kern.force(b.v, b.nkv, negate=True)
        if k % KU_REFRESH_STEPS == 0:
            b.kern.force(b.u, b.nku, negate=True)
        else:
            np.multiply(b.nkv, m.dt, out=b.tmp)
            b.nku += b.tmp
        np.multiply(b.nkv, m.beta_r, out=b.f)  # the Rayleigh stiffness part -beta K v, here rather than below
        b.f += b.nku
    else:
        b.kern.force(b.u, b.f, negate=True)  # f = -f_int, bit for bit
    if b.kern.g.size:
        diss = b.kern.relax(m.dt)
        if ph.sliding:
            b.e["viscous"] += float(diss[0]) if b.one else diss
    if load_factor == 1.0:  # 1.0 * f_top is f_top: no product
        b.f_top_z += m.f_top
    else:
        b.f_top_z += load_factor * m.f_top


def _damping_force(b: _Batch, ph: _Phase) -> None:
    """Mass-proportional dashpots (velocity relative to the frame) and, with Prony terms, ``-beta K v``.

    Sliding: dashpots to the holder (moving with (v_slide, 0, vz_holder)), so the rigid vertical motion that follows
    the texture is not resisted; preload: to the ground (dynamic relaxation of the whole slider).
    """
    if ph.c_per_s > 0:
        fd = np.multiply(b.v, ph.neg_cm, out=b.fdamp)  # -c m (v - v_frame), frame terms on two components
        if ph.sliding:
            if b.frame_x is None:
                b.frame_x = (b.vx1 if b.one else b.v_slide[:, None, None]) * ph.neg_cm
            np.subtract(fd[0], b.frame_x, out=fd[0])
            if b.one:
                if b.vz[0] != 0.0:
                    np.subtract(fd[2], float(b.vz[0]) * ph.neg_cm, out=fd[2])
            elif b.vz.any():  # a nonzero (or NaN) vz: np.any(vz != 0) without its wrapper
                frame_z = np.multiply(b.vz[:, None, None], ph.neg_cm, out=b.fdamp_frame_z)
                np.subtract(fd[2], frame_z, out=fd[2])
        b.f += fd
    if ph.sliding and b.kern_beta is not None:  # -beta K v: rigid (frame) motion is in K's null space
        b.kern_beta.force(b.v, b.fbeta, negate=True)
        b.f += b.fbeta


def _contact_and_friction(m: _Model, b: _Batch, clock: _Clock) -> _StepOut:
    """Penalty contact on the candidate nodes, then friction (stick limit or penalty with return mapping)."""
    fb, vb = b.fb, b.vb
    xyz = np.add(b.Xb, b.ub, out=b.xyz_b)  # current positions of the bottom nodes, m
    c = normal_contact(m.pavement, m.bound, xyz, b.k_pen_f, b.area_bf, m.config.contact_gap == "normal", b.all_nodes)
    ia = c.ia
    f_c = fb.take(ia, axis=1)  # the contact nodes' forces: + contact, + friction, written back once (same sums)
    f_c += c.force_n
    clock.lap(2)
    seg = Segments(ia, m.n_face, b.n, b.face_starts)
    if b.mu.shared:
        mu = b.mu.laws[0].mu
    else:

        def mu(s):
            return b.mu(s, seg)

    if m.config.friction_model == "penalty":
        fric, stick, s = penalty_step(b.ft_state, vb.take(ia, axis=1), b.k_fric_dt_f.take(ia), c, mu)
    else:
        fric, stick, s = stick_limit_friction(
            vb.take(ia, axis=1), f_c, b.inv_mb_dt.take(ia), b.mb_over_dt.take(ia), c, mu
        )
    f_c += fric
    fb[:, ia] = f_c
    if b.one:
        sums = _add(c.rows, 1)
        out = _StepOut(c, fric, stick, s, seg, sums, float(sums[2] + sums[5]), float(sums[6]))
    else:
        sums = seg.sums(c.rows)
        out = _StepOut(c, fric, stick, s, seg, sums, sums[2] + sums[5], sums[6])
    clock.lap(3)
    return out


def _advance(m: _Model, b: _Batch, ph: _Phase, st: _StepOut) -> None:
    """Rigid holder (top x/y velocity prescribed, one common z velocity), velocities, positions, energies.

    The per-member scalars are arrays over the members, or Python floats for a batch of one (the same IEEE
    operations, without the cost of 1-element arrays).
    """
    one = b.one
    top = _add(b.f_top_xz, 2)  # net x and z forces on the top face, (2, B)
    if one:
        fx_top, fz_holder = top.ravel().tolist()
        vz_old, vx = float(b.vz[0]), b.vx1
    else:
        fx_top, fz_holder = top
        vz_old, vx = b.vz, b.v_slide
    fz_hd = -m.c_holder * vz_old if ph.sliding else (0.0 if one else np.zeros(b.n))  # holder dashpot to the ground
    vz = vz_old + m.dt * (fz_holder + fz_hd) / m.m_holder
    if ph.sliding:
        vb_old = b.vb.take(st.contact.ia, axis=1)
        dots_old = _power_dots(m, b, ph)
    np.multiply(b.f, b.dt_minv, out=b.tmp)
    b.v += b.tmp
    tv = b.top_v  # prescribed x/y velocities of the top face and the holder's vz: one assignment
    if one:
        tv[0, 0, 0, 0] = vx if ph.sliding else 0.0
        tv[2, 0, 0, 0] = vz
        b.vz[0] = vz
    else:
        tv[0, :, 0, 0] = vx if ph.sliding else 0.0
        tv[2, :, 0, 0] = vz
        b.vz = vz
    b.v_top[...] = tv
    if ph.sliding:
        _slide_energies(m, b, ph, st, vb_old, dots_old, (-fx_top, fz_hd, vz_old, vz, vx))
    np.multiply(b.v, m.dt, out=b.tmp)
    b.u += b.tmp
    c = st.contact
    if one:
        b.fz_sum[0], b.area_now[0], b.pen_energy[0] = st.fz, st.area, 0.5 * float(np.dot(c.kd_n, c.d_m))
    else:
        b.fz_sum, b.area_now, b.pen_energy = st.fz, st.area, 0.5 * st.seg.dot(c.kd_n, c.d_m)


def _power_dots(m: _Model, b: _Batch, ph: _Phase) -> tuple:
    """``f_d . v(n-1/2)`` and the stiffness-damping force's ``. v(n-1/2)`` (J/s) before the velocity update (the
    dashpots' power over the step is ``f . (v_old + v_new) / 2``: two dots, no copy of v)."""
    if ph.c_per_s > 0 and b.damp_pair is not None:
        fd_dot, nkv_dot = b.damping_dots(b.v)
        return fd_dot, m.beta_r * nkv_dot
    fd_dot = b.mdot(b.fdamp, b.v) if ph.c_per_s > 0 else 0.0
    if b.fbeta is not None:
        return fd_dot, b.mdot(b.fbeta, b.v)
    if b.nkv is not None:
        return fd_dot, m.beta_r * b.mdot(b.nkv, b.v)
    return fd_dot, 0.0


def _slide_energies(m: _Model, b: _Batch, ph: _Phase, st: _StepOut, vb_old, dots_old, holder) -> None:
    """Energies (J) of the sliding step: external work, friction, dashpots and stiffness damping (trapezoidal in
    the velocities ``vb_old`` / ``b.v`` before / after the update); ``holder``: ``(react_x N, fz_hd N, vz_old m/s,
    vz m/s, vx m/s)``, the reaction in x, the holder dashpot force and the holder's velocities."""
    react_x, fz_hd, vz_old, vz, vx = holder
    fd_dot_v_old, fb_dot_v_old = dots_old
    h = 0.5 * m.dt
    e = b.e
    vz_sum = vz_old + vz
    e["external"] += h * (-m.config.load_n * vz_sum + react_x * 2.0 * vx)
    e["damping"] -= h * fz_hd * vz_sum
    e["friction"] -= h * (_vdot if b.one else st.seg.dot)(st.fric, vb_old + b.vb.take(st.contact.ia, axis=1))
    paired = ph.c_per_s > 0 and b.damp_pair is not None
    if paired:
        fd_dot_v, nkv_dot_v = b.damping_dots(b.v)
    if ph.c_per_s > 0:
        # dashpots between each node and the frame (vx, 0, vz_old): they dissipate c m |w|^2 (w = velocity
        # relative to the frame, >= 0), the holder feeds them f_d . v_frame
        if b.one:
            fdx, fdz = _add(b.fdamp_xz, 1).tolist()
        else:
            fdx, fdz = np.add.reduce(b.fdamp[::2], axis=(1, 3, 4))  # per-member sums of x and z, one call
        fd_frame = 2.0 * (vx * fdx + vz_old * fdz)
        e["damping"] -= h * (fd_dot_v_old + (fd_dot_v if paired else b.mdot(b.fdamp, b.v)) - fd_frame)
        e["external"] += h * fd_frame
    if b.fbeta is not None:
        e["damping"] -= h * (fb_dot_v_old + b.mdot(b.fbeta, b.v))
    elif b.nkv is not None:  # the Rayleigh stiffness part -beta K v(n-1/2) is beta * nkv
        e["damping"] -= h * (fb_dot_v_old + m.beta_r * (nkv_dot_v if paired else b.mdot(b.nkv, b.v)))


def _vdot(a: np.ndarray, c: np.ndarray) -> float:
    """``a . c`` of a batch of one (``_Batch.mdot``)."""
    return float(np.vdot(a, c))


#: ``np.add.reduce``: what ``ndarray.sum()`` calls (the same pairwise sum), without its Python wrapper
_add = np.add.reduce


def _step(m: _Model, b: _Batch, ph: _Phase, k: int, load_factor: float, clock: _Clock) -> _StepOut:
    """One central-difference step of every member of ``b`` (``k``: step index within the phase)."""
    clock.lap(5)
    _internal_force(m, b, ph, k, load_factor)
    clock.lap(0)
    _damping_force(b, ph)
    clock.lap(1)
    st = _contact_and_friction(m, b, clock)
    _advance(m, b, ph, st)
    clock.lap(4)
    return st


# ---- the two phases -------------------------------------------------------------------------------------------------


def _preload(m: _Model, b: _Batch, out: _Output, clock: _Clock) -> _Batch:
    """Dynamic relaxation under the ramped load; a member leaves when its contact force is within tolerance of the
    load at two checks in a row (or after ``n_pre_max`` steps). Returns the preloaded members, in order."""
    ph = _Phase.of(m, sliding=False)
    cfg = m.config
    done = []
    n_total = m.n_pre_max + int(out.n_slide.max())
    for k in range(m.n_pre_max):
        _step(m, b, ph, k, _ramp(k * m.dt, m.t_ramp), clock)
        check = k >= m.n_ramp and (k - m.n_ramp) % m.n_check == 0
        clock.lap(5)
        clock.report(k + 1, n_total)
        if not check and k + 1 < m.n_pre_max:
            continue
        leave = np.full(b.n, k + 1 == m.n_pre_max)
        if check:
            ok = np.abs(b.fz_sum - cfg.load_n) <= cfg.preload_tolerance * cfg.load_n
            leave |= ok & b.prev_ok & (k + 1 < m.n_pre_max)
            b.prev_ok = ok
        if leave.any():
            out.n_pre[b.ids[leave]] = k + 1
            done.append(b.take(leave))
            if leave.all():
                break
            b = b.take(~leave)
    return _Batch.concat(done)


def _same_preload(laws) -> np.ndarray:
    """For each member, the first member with an equal friction law (``==``, or the same object)."""
    return np.array([next(i for i in range(j + 1) if laws[i] is law or laws[i] == law) for j, law in enumerate(laws)])


def _preload_shared(m: _Model, b: _Batch, out: _Output, clock: _Clock) -> _Batch:
    """:func:`_preload` of the members with distinct friction laws only; the others get a copy of their twin's state.

    The preload does not depend on the test speed: the slider is pressed onto the pavement at rest (the speed is
    given at the start of the slide, :meth:`_Output.start_slide`), and every member steps bit for bit as a single
    run (the batch tests), so members with equal laws preload to the same bits. A calibration batch (one law,
    three speeds) preloads once instead of three times, a validation batch of two laws at six speeds twice
    instead of twelve times.
    """
    first = _same_preload(b.laws)
    distinct = first == np.arange(b.n)
    if distinct.all():
        return _preload(m, b, out, clock)
    done = _preload(m, b.take(distinct), out, clock)  # members in id order: the distinct ids
    out.n_pre[b.ids] = out.n_pre[b.ids[first]]
    pos = np.searchsorted(done.ids, b.ids[first])
    return done.spread(pos, b.ids, b.v_slide)


def _slide(m: _Model, b: _Batch, out: _Output, clock: _Clock) -> None:
    """Every node gets the test speed in x, the holder slides; a member leaves when it has slid its length."""
    log.info(
        "preload: contact force %s N (load %.4f N) after %s steps",
        np.array2string(b.fz_sum, precision=4),
        m.config.load_n,
        out.n_pre[b.ids],
    )
    out.start_slide(b)
    ph = _Phase.of(m, sliding=True)
    n_done = int(out.n_pre.max())
    n_slide = out.n_slide[b.ids]
    n_total, next_leave = n_done + int(n_slide.max()), int(n_slide.min())  # the longest slide leaves last
    for i in range(int(n_slide.max())):
        st = _step(m, b, ph, i, 1.0, clock)
        out.record(b, st, i)
        clock.lap(5)
        clock.report(n_done + i + 1, n_total)
        if i + 1 < next_leave:
            continue
        leave = n_slide == i + 1
        out.finish(b.take(leave))
        if leave.all():
            break
        b = b.take(~leave)
        n_slide = out.n_slide[b.ids]
        next_leave = int(n_slide.min())


# ---- per-member output: preload, energies, trace, result ------------------------------------------------------------


class _Output:
    """What each member (by id) reports: preload, energies at the start and the end of its slide, trace rows."""

    FLOAT_ROWS = ("ft", "fn", "a", "ff", "sl")  # time and position: :meth:`trace` (the same IEEE operations)

    def __init__(self, m: _Model, speeds_kmh, vtu_dirs):
        n = len(speeds_kmh)
        self.m = m
        self.v_slide = np.array([float(kmh_to_ms(s)) for s in speeds_kmh])  # m/s
        self.n_slide = np.array([max(1, int(math.ceil(m.slide_m / (v * m.dt)))) for v in self.v_slide])
        self.n_pre = np.full(n, m.n_pre_max)  # lowered when a member's preload converges
        self.every = int(m.config.trace_every)
        self.n_rec = (self.n_slide + self.every - 1) // self.every
        rows = int(self.n_rec.max())
        self.rec = {k: np.empty((n, rows)) for k in self.FLOAT_ROWS}
        self.rec_nc = np.empty((n, rows), dtype=np.int64)
        self.rec_ns = np.empty((n, rows), dtype=np.int64)
        self.preload_force, self.preload_area = np.zeros(n), np.zeros(n)
        self.state0 = {k: np.zeros(n) for k in ("kinetic", "strain", "contact", "friction_elastic")}
        self.final = {k: np.zeros(n) for k in (*self.state0, "max_pen", *_Batch.ENERGY)}
        self.vtu = [None if d is None else VtuSeriesWriter(d, m.mesh) for d in vtu_dirs]
        self.any_vtu = any(w is not None for w in self.vtu)
        frames = int(m.config.vtu_frames)
        self.vtu_steps = [
            set() if w is None else set(np.unique(np.linspace(0, ns - 1, frames).round().astype(int)).tolist())
            for w, ns in zip(self.vtu, self.n_slide)
        ]

    def start_slide(self, b: _Batch) -> None:
        """Start of sliding: every node gets the test speed; the energies the slide's changes are measured from."""
        ids = b.ids
        self.preload_force[ids], self.preload_area[ids] = b.fz_sum, b.area_now
        b.v[0] += b.v_slide[:, None, None]
        b.kern.force(b.u, b.fint)
        self.state0["kinetic"][ids] = b.kinetic()
        self.state0["strain"][ids] = b.kern.member_strain_energy()
        self.state0["contact"][ids] = b.pen_energy
        self.state0["friction_elastic"][ids] = b.friction_elastic()

    def record(self, b: _Batch, st: _StepOut, i: int) -> None:
        """Trace row of slide step ``i`` (pavement forces on the slider at step n), maximum penetration, VTU."""
        c, seg, dt = st.contact, st.seg, self.m.dt
        if b.one:
            self._record_one(b, st, i)
        else:
            if c.d_m.size:
                b.max_pen = np.maximum(b.max_pen, seg.maximum(c.d_m, 0.0))
            if i % self.every == 0:
                self._record_rows(b, st, i)
        if not self.any_vtu:
            return
        for q, j in enumerate(b.ids):
            if self.vtu[j] is not None and i in self.vtu_steps[j]:
                i0, i1 = seg.edges[q], seg.edges[q + 1]
                p = np.zeros(self.m.mass.shape)
                p[0].reshape(-1)[c.ia[i0:i1] - q * self.m.n_face] = c.normal_n[i0:i1] / b.area_bf[c.ia[i0:i1]]
                self.vtu[j].write(i * dt, self.m.mesh.coordinates, to_mesh_layout(b.u[:, :, q]), to_mesh_layout(p))

    def _record_rows(self, b: _Batch, st: _StepOut, i: int) -> None:
        """The trace row of slide step ``i`` of each member of a batch."""
        c, seg, sums = st.contact, st.seg, st.sums
        r, ids, rec = i // self.every, b.rows, self.rec
        rec["ft"][ids, r] = -(sums[0] + sums[3])
        rec["fn"][ids, r] = b.fz_sum
        rec["a"][ids, r] = b.area_now
        rec["ff"][ids, r] = -sums[3]
        self.rec_nc[ids, r] = seg.counts()
        self.rec_ns[ids, r] = seg.count(st.stick)
        n_sum = sums[7]
        has_n = n_sum > 0.0
        rec["sl"][ids, r] = np.divide(seg.dot(c.normal_n, st.s), n_sum, out=np.full(b.n, np.nan), where=has_n)

    def _record_one(self, b: _Batch, st: _StepOut, i: int) -> None:
        """:meth:`record` of a batch of one: the single run's scalar operations."""
        c, sums = st.contact, st.sums
        d = c.d_m
        if d.size:
            d_max = float(d.max())
            if d_max > b.max_pen[0]:
                b.max_pen[0] = d_max
        if i % self.every == 0:
            r, j, rec = i // self.every, int(b.ids[0]), self.rec
            fx = sums[3]
            rec["ft"][j, r] = -float(sums[0] + fx)
            rec["fn"][j, r] = st.fz
            rec["a"][j, r] = st.area
            rec["ff"][j, r] = -float(fx)
            self.rec_nc[j, r] = c.ia.size
            self.rec_ns[j, r] = np.count_nonzero(st.stick)
            n_sum = float(sums[7])
            rec["sl"][j, r] = float(np.dot(c.normal_n, st.s)) / n_sum if n_sum > 0.0 else np.nan

    def finish(self, b: _Batch) -> None:
        """Energies of the members of ``b`` at the end of their slide."""
        ids, f = b.ids, self.final
        b.kern.force(b.u, b.fint)
        f["kinetic"][ids] = b.kinetic()
        f["strain"][ids] = b.kern.member_strain_energy()
        f["contact"][ids] = b.pen_energy
        f["friction_elastic"][ids] = b.friction_elastic()
        f["max_pen"][ids] = b.max_pen
        for k in _Batch.ENERGY:
            f[k][ids] = b.e[k]

    def energies(self, j: int) -> dict:
        """Energy changes (J) of member ``j`` over its slide; the tangential penalty springs' stored energy is
        contact energy, the friction entry is what they dissipate."""
        f, s0 = self.final, self.state0
        d_fric_elastic = float(f["friction_elastic"][j]) - float(s0["friction_elastic"][j])
        energies = dict(
            external=float(f["external"][j]),
            kinetic=float(f["kinetic"][j]) - float(s0["kinetic"][j]),
            strain=float(f["strain"][j]) - float(s0["strain"][j]),
            contact=float(f["contact"][j]) - float(s0["contact"][j]) + d_fric_elastic,
            friction=float(f["friction"][j]) - d_fric_elastic,
            hourglass=0.0,
            damping=float(f["damping"][j]),
            viscous=float(f["viscous"][j]),
        )
        energies["residual"] = energies["external"] - sum(
            energies[k] for k in ("kinetic", "strain", "contact", "friction", "hourglass", "damping", "viscous")
        )
        return energies

    def trace(self, j: int) -> pd.DataFrame:
        n, rec = int(self.n_rec[j]), self.rec
        step = np.arange(n) * self.every  # slide step of each row
        return pd.DataFrame(
            {
                "time_s": step * self.m.dt,
                "position_mm": (self.v_slide[j] * step * self.m.dt) * 1e3,
                "tangential_n": rec["ft"][j, :n].copy(),
                "normal_n": rec["fn"][j, :n].copy(),
                "contact_area_mm2": rec["a"][j, :n] * 1e6,
                "friction_x_n": rec["ff"][j, :n].copy(),
                "contact_nodes": self.rec_nc[j, :n].copy(),
                "stick_nodes": self.rec_ns[j, :n].copy(),
                "slip_speed_ms": rec["sl"][j, :n].copy(),
            }
        )

    def result(self, j: int, speed_kmh: float, y_offset_mm: float, trace_path, wall_s: float, phase_s: dict):
        """The :class:`SimulationResult` of member ``j``: SN = window mean tangential / window mean normal force."""
        m, cfg = self.m, self.m.config
        trace = self.trace(j)
        slide = m.slide_m
        w0 = cfg.window_start_mm
        w1 = slide * 1e3 if cfg.window_end_mm is None else min(cfg.window_end_mm, slide * 1e3)
        win = (trace["position_mm"] >= w0) & (trace["position_mm"] <= w1)
        if not win.any():
            raise ConfigError(
                f"simulate: the steady window [{w0}, {w1}] mm holds no trace rows (slide {slide * 1e3:.2f} mm)"
            )
        ft = float(trace.loc[win, "tangential_n"].mean())
        fn = float(trace.loc[win, "normal_n"].mean())
        if trace_path is not None:
            write_trace_parquet(trace, trace_path)
        n_total = int(self.n_pre[j] + self.n_slide[j])
        log.info("simulate: SN %.4f (Ft %.4f N / Fn %.4f N), %d steps", ft / fn, ft, fn, n_total)
        return SimulationResult(
            sn=ft / fn,
            tangential_n=ft,
            normal_n=fn,
            n_steps=n_total,
            dt_s=m.dt,
            wall_s=wall_s,
            energies=self.energies(j),
            trace=trace,
            speed_kmh=float(speed_kmh),
            slide_length_mm=slide * 1e3,
            slide_clamped=m.clamped,
            window_mm=(float(w0), float(w1)),
            preload_steps=int(self.n_pre[j]),
            preload_contact_force_n=float(self.preload_force[j]),
            preload_contact_area_mm2=float(self.preload_area[j]) * 1e6,
            max_penetration_um=float(self.final["max_pen"][j]) * 1e6,
            n_elements=m.mesh.n_elements,
            omega_max_rad_s=m.omega,
            mean_contact_area_mm2=float(trace.loc[win, "contact_area_mm2"].mean()),
            mean_slip_speed_ms=float(trace.loc[win, "slip_speed_ms"].mean()),
            meta=dict(
                config=cfg.as_dict(),
                y_offset_mm=float(y_offset_mm),
                omega_elastic_rad_s=m.omega_el,
                rayleigh_alpha_per_s=m.alpha_r,
                rayleigh_beta_s=m.beta_r,
                slope_bound=m.slope_bound,
                element_size_m=(m.mesh.hx, m.mesh.hy, m.mesh.hz),
                phase_s=phase_s,
                batch_size=len(self.n_slide),
            ),
        )


def _run(pavement, speeds_kmh, laws, config, y_offset_mm, progress, trace_paths, vtu_dirs, slope_bound):
    """Preload and slide the members (one speed and law each) together; one result per member."""
    t_wall0 = time.perf_counter()
    for s in speeds_kmh:
        if not (np.isfinite(s) and s > 0):
            raise ConfigError(f"simulate: 'speed_kmh' expected > 0 km/h, got {s!r}")
    m = _build_model(pavement, config, y_offset_mm, slope_bound)
    out = _Output(m, speeds_kmh, vtu_dirs)
    log.info(
        "simulate: %d elements, dt %.3g us, <= %d preload + %s slide steps at %s km/h over %.1f mm",
        m.mesh.n_elements,
        m.dt * 1e6,
        m.n_pre_max,
        out.n_slide.tolist(),
        [float(s) for s in speeds_kmh],
        m.slide_m * 1e3,
    )
    clock = _Clock(config, progress)
    clock.t0 = t_wall0
    b = _Batch(m, np.arange(len(speeds_kmh)), out.v_slide, laws)
    b = _preload_shared(m, b, out, clock)
    _slide(m, b, out, clock)
    wall = time.perf_counter() - t_wall0
    phase_s = dict(zip(PHASES, clock.ph))
    phase_s["setup_and_rest"] = wall - sum(clock.ph)
    steps = out.n_pre + out.n_slide
    return [
        out.result(j, s, y_offset_mm, trace_paths[j], wall * float(steps[j]) / float(steps.sum()), phase_s)
        for j, s in enumerate(speeds_kmh)
    ]
