"""The model the members of a run share: the slider mesh placed on the pavement, its material, masses and stiffness,
the contact constants and the stable time step (SI units; docs/solver.md, "time step").

:func:`build_model` places the slider ``edge_margin_mm`` after the strip's start with its bottom face on the highest
point under it, and bounds the time step by the slider's highest frequency (power iteration,
:func:`max_frequency_power_iteration`) and the contact penalty on the steepest slope of the swept strip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from skidsim.errors import ConfigError
from skidsim.slidermesh import SliderMesh
from skidsim.solver.config import SolverConfig
from skidsim.solver.contact_friction import damped_step_factor, rayleigh_coefficients
from skidsim.solver.kernel import StructuredKernel, to_internal
from skidsim.solver.material import RubberMaterial, element_matrices, lumped_mass
from skidsim.solver.surfaces import SurfaceBound, pavement_extent_m

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


@dataclass
class SliderModel:
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


def build_model(pavement, config: SolverConfig, y_offset_mm: float, slope_bound: float | None) -> SliderModel:
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
    return SliderModel(
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
