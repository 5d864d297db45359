"""Solver configuration (:class:`SolverConfig`) and its presets.

All fields are SI or carry their unit in the name. The two presets:

* :meth:`SolverConfig.reference`: the study's model (0.5 mm elements, 114.3 mm slide, no mass scaling); the
  benchmark case and the yardstick of the mesh study.
* :meth:`SolverConfig.campaign`: the preset the calibration campaign runs (about 2-3 s of one core per evaluation
  at 20 km/h); chosen from ``benchmarks/mesh_study.py`` and documented with its SN error in ``docs/solver.md``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

from skidsim.errors import ConfigError
from skidsim.options import section_items


@dataclass(frozen=True)
class SolverConfig:
    """Parameters of one explicit DFT-slider simulation.

    Geometry (mm): ``slider_length_mm`` x ``slider_width_mm`` x ``slider_thickness_mm`` (ASTM E1911 slider,
    20 x 16 x 6), meshed with cubes of about ``element_mm``.

    Rubber: ``youngs_modulus_pa`` (Pa), ``poisson``, ``density_kg_m3`` (kg/m^3): long-term elastic constants.
    ``prony_g`` / ``prony_tau_s``: optional Prony series on the shear modulus, g_i relative to the long-term
    shear modulus, tau_i in s (empty: linear elastic).

    Loading: ``load_n`` (N) is the normal load **on the one simulated slider** (ASTM E1911: 11.8 N per slider;
    set 11.8/3 to read the figure as the total of three sliders). It is a dead load on the rigid holder (top
    face), ramped in over ``preload_ramp_s`` (s, smooth cosine ramp) and then held; during this quasi-static
    preload mass-proportional damping ``preload_damping_per_s`` (1/s, absolute velocity) removes the dynamic
    response (dynamic relaxation). The preload ends when the total contact force is within ``preload_tolerance``
    (fraction) of the load at two checks ``preload_check_s`` (s) apart, at the latest after ``preload_time_s``
    (s; the result records the contact force actually reached).

    Sliding: the top face (rigid holder) moves in x at the test speed (y velocity 0, one common vertical velocity);
    the slider slides ``slide_length_mm`` (the study's 114.3 mm). If the pavement strip is too short (slider length
    plus slide plus ``edge_margin_mm`` at each end), the slide is shortened to fit when ``clamp_slide`` (the result
    records the distance actually slid), else a :class:`ConfigError` is raised. ``slide_damping_per_s`` (1/s, read
    with ``slide_damping_model="mass"``) is mass-proportional damping of the velocity relative to the holder during
    sliding. Default 3e4 1/s: without it the undamped elastic slider with Coulomb friction is *unstable*
    (friction-induced mode-coupling vibration: on a flat plane with mu 0.4 the normal force oscillates at ~5 kHz
    with growing amplitude until the slider bounces and SN drops to 0.31); 1e4 1/s is not enough, 3e4 1/s removes it
    (SN = mu to 1e-5). It acts like a rubber loss (damping ratio c/(2 omega): 0.5 at 5 kHz, 0.05 at 50 kHz); set 0
    to study the undamped model. Its dissipation is reported as the ``damping`` energy. These dashpots connect the
    nodes to the *holder* (velocity (v, 0, v_z,holder)), so they do not resist the vertical motion that follows the
    texture (dashpots to the ground did, and carried up to 1.4 N of the 11.8 N load over a 20 mm window). The
    holder's own vertical motion has a suspension dashpot to the ground, ``holder_damping_per_s`` (1/s) times the
    slider mass (default 5e3 1/s, 11.5 N s/m): without it the bounce of the slider on its contacts, excited at the
    start and by the texture, is undamped and short windows do not average the normal force to the load.

    Steady window: SN is averaged over holder displacements from ``window_start_mm`` (after the start of
    sliding: skips the start-up transient) to ``window_end_mm`` (``None``: the end of the slide).

    Time step: ``dt_safety`` times the central-difference limit 2/omega_max, with omega_max from a power
    iteration on the assembled slider plus the contact penalty bound. ``mass_scaling`` (>= 1) multiplies the
    density (dt grows with its square root); time scaling is not offered (friction depends on slip speed).

    Contact gap ``contact_gap``: ``"vertical"`` (default) penalises the vertical penetration ``d = z_s - z`` with
    potential ``k d^2 / 2``; its stiffness along the surface normal is ``k (1 + |grad z|^2)``, so on steep
    flanks the contact is stiffer than ``k`` (31x at the steepest point of site E1-1, slope 5.5) and the
    stable time step shrinks with the steepest slope. ``"normal"`` penalises the normal gap
    ``d_n = d / sqrt(1 + |grad z|^2)`` (force ``k d_n`` along the normal, normal stiffness ``k`` on any slope,
    time step independent of the texture); see docs/solver.md for its effect on SN and cost.

    Penalty length ``penalty_length_mm``: ``None`` (default) uses the element height ``h_z`` in the penalty below,
    so the contact stiffness *per unit area* ``E / h_z`` grows as the mesh is refined (the penalty layer is the
    first element layer's axial compliance); a number (mm) fixes it at ``E / penalty_length_mm`` on every mesh,
    a mesh-independent interface compliance (0.5 mm reproduces the 0.5 mm reference mesh exactly). See the mesh
    study in docs/solver.md.

    Contact: penalty stiffness per bottom node ``penalty_scale * E * A_node / h_z`` (N/m; ``penalty_scale`` 1 is
    the axial stiffness of the first element layer under the node).

    Friction model ``friction_model``: ``"penalty"`` (default): an elastic stick regime with tangential penalty
    stiffness ``friction_stiffness_pa_per_m`` (Pa/m, per unit contact area, times the node's tributary area) and a
    return mapping onto ``|f_t| <= mu(s) N`` (:mod:`skidsim.solver.contact_friction`); the traction law does not
    depend on the element size. Default 5e10 Pa/m = E / 2 mm: an elastic slip of ~24 um at 1.2 MPa of shear
    traction, no stiffer than the normal penalty ``E / h_z`` of any mesh up to 2 mm, so it does not shorten the time
    step there. The stable step includes ``k_t / m`` of every bottom node. ``"stick_limit"`` (the model of the first
    releases, kept for comparison) caps the friction force of a node at ``m |v_t,trial| / dt`` (the force that stops
    its predicted tangential velocity within the step) and applies ``mu(s) N`` above it; the cap depends on the
    nodal mass, so small nodes stick behind asperities and SN falls under mesh refinement below 0.5 mm
    (docs/solver.md).

    Slide damping ``slide_damping_model``: ``"rayleigh"`` (default): ``alpha M + beta K`` with loss factor
    ``loss_factor`` (tan delta) at both ends of ``loss_band_hz`` (Hz; default 0.2 at 1 kHz and 100 kHz: the loss
    factor of a filled tread rubber at room temperature in the texture-excited band, rising towards the glass
    transition above it; docs/solver.md). In between the loss factor dips to 0.04 (at 10 kHz), above 100 kHz it
    rises with frequency (1.0 at 500 kHz), which damps the node-scale contact vibrations of fine meshes. The mass
    part acts on the velocity relative to the holder frame, the stiffness part on the deformation rate (``K`` of the
    long-term modulus); it replaces ``slide_damping_per_s``. The stable step shrinks by ``sqrt(1 + xi^2) - xi``
    (``xi`` the damping ratio at the highest frequency): 0.87 on the campaign preset, 0.66 at 0.5 mm, 0.45 at 0.25
    mm. ``"mass"`` (the model of the first releases) is the ``slide_damping_per_s`` dashpots above; with it the
    bottom nodes slip 1-3 m/s faster than the holder (docs/calibration.md).

    ``blas_threads``: BLAS threads inside :func:`simulate` (via threadpoolctl when installed; ``None`` leaves the
    setting alone). 1 is fastest for the small matrix products here and essential on a busy machine (measured:
    multithreaded OpenBLAS made a 1 mm run 10x slower on 2 shared cores).

    Output: ``trace_every`` (steps between trace rows), ``vtu_frames`` (number of VTU frames when a VTU
    directory is given), ``progress_every_s`` (wall seconds between progress log lines).
    """

    element_mm: float = 0.5
    slider_length_mm: float = 20.0
    slider_width_mm: float = 16.0
    slider_thickness_mm: float = 6.0
    youngs_modulus_pa: float = 100e6
    poisson: float = 0.45
    density_kg_m3: float = 1200.0
    prony_g: tuple[float, ...] = ()
    prony_tau_s: tuple[float, ...] = ()
    load_n: float = 11.8
    slide_length_mm: float = 114.3
    clamp_slide: bool = True
    edge_margin_mm: float = 0.5
    preload_time_s: float = 4.0e-3
    preload_ramp_s: float = 0.2e-3
    preload_check_s: float = 0.05e-3
    preload_tolerance: float = 0.002
    preload_damping_per_s: float = 1.5e4
    slide_damping_per_s: float = 3.0e4
    holder_damping_per_s: float = 5.0e3
    blas_threads: int | None = 1
    window_start_mm: float = 5.0
    window_end_mm: float | None = None
    dt_safety: float = 0.9
    mass_scaling: float = 1.0
    penalty_scale: float = 1.0
    contact_gap: str = "vertical"
    penalty_length_mm: float | None = None
    friction_model: str = "penalty"
    friction_stiffness_pa_per_m: float = 5.0e10
    slide_damping_model: str = "rayleigh"
    loss_factor: float = 0.2
    loss_band_hz: tuple[float, float] = (1.0e3, 1.0e5)
    trace_every: int = 1
    vtu_frames: int = 50
    progress_every_s: float = 10.0

    def __post_init__(self):
        positive = [
            "element_mm",
            "slider_length_mm",
            "slider_width_mm",
            "slider_thickness_mm",
            "load_n",
            "slide_length_mm",
            "preload_time_s",
            "penalty_scale",
            "dt_safety",
            "progress_every_s",
        ]
        for name in positive:
            if not getattr(self, name) > 0:
                raise ConfigError(f"solver config field '{name}': expected > 0, got {getattr(self, name)!r}")
        if not 0 < self.dt_safety <= 1:
            raise ConfigError(f"solver config field 'dt_safety': expected 0 < dt_safety <= 1, got {self.dt_safety}")
        if not self.mass_scaling >= 1:
            raise ConfigError(f"solver config field 'mass_scaling': expected >= 1, got {self.mass_scaling}")
        for name in ("preload_ramp_s", "preload_check_s", "preload_tolerance"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"solver config field '{name}': expected > 0, got {getattr(self, name)!r}")
        if self.preload_damping_per_s < 0 or self.slide_damping_per_s < 0 or self.holder_damping_per_s < 0:
            raise ConfigError("solver config fields 'preload_damping_per_s'/'slide_damping_per_s': expected >= 0 1/s")
        if self.window_start_mm < 0 or (self.window_end_mm is not None and self.window_end_mm <= self.window_start_mm):
            raise ConfigError(
                "solver config fields 'window_start_mm'/'window_end_mm': expected 0 <= start < end mm, "
                f"got {self.window_start_mm}, {self.window_end_mm}"
            )
        if self.window_start_mm >= self.slide_length_mm:
            raise ConfigError(
                f"solver config field 'window_start_mm': expected < slide_length_mm "
                f"({self.slide_length_mm}), got {self.window_start_mm}"
            )
        if int(self.trace_every) < 1 or int(self.vtu_frames) < 1:
            raise ConfigError("solver config fields 'trace_every'/'vtu_frames': expected integers >= 1")
        if self.penalty_length_mm is not None and not self.penalty_length_mm > 0:
            raise ConfigError(
                f"solver config field 'penalty_length_mm': expected None or > 0 mm, got {self.penalty_length_mm!r}"
            )
        if self.contact_gap not in ("vertical", "normal"):
            raise ConfigError(
                f"solver config field 'contact_gap': expected 'vertical' or 'normal', got {self.contact_gap!r}"
            )
        if self.friction_model not in ("stick_limit", "penalty"):
            raise ConfigError(
                f"solver config field 'friction_model': expected 'stick_limit' or 'penalty', "
                f"got {self.friction_model!r}"
            )
        if not self.friction_stiffness_pa_per_m > 0:
            raise ConfigError(
                f"solver config field 'friction_stiffness_pa_per_m': expected > 0 Pa/m, "
                f"got {self.friction_stiffness_pa_per_m!r}"
            )
        if self.slide_damping_model not in ("mass", "rayleigh"):
            raise ConfigError(
                f"solver config field 'slide_damping_model': expected 'mass' or 'rayleigh', "
                f"got {self.slide_damping_model!r}"
            )
        if not self.loss_factor > 0:
            raise ConfigError(f"solver config field 'loss_factor': expected > 0 (tan delta), got {self.loss_factor!r}")
        band = tuple(float(f) for f in self.loss_band_hz)
        if len(band) != 2 or not 0 < band[0] <= band[1]:
            raise ConfigError(
                f"solver config field 'loss_band_hz': expected two frequencies 0 < f1 <= f2 Hz, "
                f"got {self.loss_band_hz!r}"
            )
        object.__setattr__(self, "loss_band_hz", band)
        if self.edge_margin_mm < 0:
            raise ConfigError(f"solver config field 'edge_margin_mm': expected >= 0 mm, got {self.edge_margin_mm}")
        object.__setattr__(self, "prony_g", tuple(float(g) for g in self.prony_g))
        object.__setattr__(self, "prony_tau_s", tuple(float(t) for t in self.prony_tau_s))

    @classmethod
    def reference(cls, **overrides) -> SolverConfig:
        """The study's model: 0.5 mm elements, 114.3 mm slide, no mass scaling (the benchmark case)."""
        return cls(**overrides)

    @classmethod
    def campaign(cls, **overrides) -> SolverConfig:
        """The calibration-campaign preset (see docs/solver.md for its measured SN error and cost).

        1.5 mm elements, the full 114.3 mm slide (window from 5 mm), no mass scaling. Short slides are not
        representative (SN of a 20 mm window differed by up to 11 % from the full slide on a random texture:
        the slider rests on a few asperities, so SN samples the path) and mass scaling biases SN upwards
        (+1.6 % at factor 4, +5.8 % at 64 on a 1 mm mesh; the texture response is partly inertial), so the
        saving comes from the element size alone.
        Measured on RandomTexture(seed 0) with mu_s 0.4, mu_k 0.35, alpha 0.6 s/m: SN +2.2 / +3.1 / +4.7 % against
        the reference preset at 20 / 40 / 60 km/h (a consistent upward bias), 3.4 s of one core at 20 km/h
        (11,061 steps; 1.7 s / 1.2 s at 40 / 60 km/h with 5,855 / 4,120 steps); these figures are of the stick
        limit of the first releases. With the default penalty friction and Rayleigh damping, on site E1-1 of the
        default campaign: +1.2 / +1.6 / +2.6 % against 0.5 mm (measured 2026-11-27, docs/solver.md "Presets").

        Contact on the normal gap (``contact_gap="normal"``): the penalty's normal stiffness is then ``k`` on any
        slope, so the steepest flank no longer shortens the time step (with the vertical gap it is
        ``k (1 + |grad z|^2)``, up to 31 k on site E1-1 of the default campaign). Measured on the default
        campaign's pavements (mu_s 0.45, mu_k 0.30, alpha 0.5 s/m, 20 and 60 km/h): SN -0.8 % (E1-1), -0.2 %
        (C1-1), -0.3 % (C6-3) against the vertical gap, run time -52 % / -19 % / -23 %; over the 977 FE runs of a
        default reproduction the step count falls by about 30 % (docs/solver.md, "Campaign preset").
        """
        base = dict(element_mm=1.5, slide_length_mm=114.3, window_start_mm=5.0, mass_scaling=1.0, contact_gap="normal")
        base.update(overrides)
        return cls(**base)

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "<config>") -> SolverConfig:
        """Build from a mapping (e.g. the workflow config's ``solver`` section); unknown keys raise ConfigError."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ConfigError(f"{source}: unknown solver config field(s) {unknown}; expected some of {sorted(names)}")
        d = dict(d)
        for key in ("prony_g", "prony_tau_s", "loss_band_hz"):
            if key in d and d[key] is not None:
                d[key] = tuple(d[key])
        return cls(**d)

    def replace(self, **changes) -> SolverConfig:
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return asdict(self)


#: Presets of the workflow's ``solver.preset`` (``quick``: the campaign preset on a coarser mesh, config/quick.yaml).
PRESETS = ("campaign", "reference", "quick")


@dataclass(frozen=True)
class SolverOptions:
    """The workflow's ``solver:`` section (the defaults of ``config/config.yaml``).

    preset: base :class:`SolverConfig`, one of :data:`PRESETS`; load_n: normal load in N on the one simulated
    slider (the default is :class:`SolverConfig`'s, ASTM E1911); overrides: any :class:`SolverConfig` field, applied
    on top of the preset.
    """

    preset: str = "campaign"
    load_n: float = SolverConfig.load_n
    overrides: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.preset not in PRESETS:
            raise ConfigError(f"solver.preset: expected one of {', '.join(PRESETS)}, got {self.preset!r}")
        if not (isinstance(self.load_n, (int, float)) and self.load_n > 0):
            raise ConfigError(f"solver.load_n: expected a load > 0 N, got {self.load_n!r}")
        if not isinstance(self.overrides, dict):
            raise ConfigError(f"solver.overrides: expected a mapping of SolverConfig fields, got {self.overrides!r}")

    @classmethod
    def from_dict(cls, d: dict | None) -> SolverOptions:
        """From the ``solver:`` config block; an unknown key raises :class:`ConfigError`."""
        d = section_items(cls, d, "solver")
        if d.get("overrides") is None:
            d.pop("overrides", None)
        return cls(**d)
