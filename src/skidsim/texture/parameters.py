"""All areal parameters of one band: :func:`areal_parameters` (names and units as the workflow expects)."""

from __future__ import annotations

from dataclasses import dataclass, fields

from skidsim.errors import ConfigError
from skidsim.surface import Surface

from .despeckle import METHODS
from .features import PRUNING_PCT, PRUNING_REFERENCES, feature_parameters, motif_parameters, pruning_threshold
from .filters import FILL_METHODS, form_degree
from .furrows import furrow_parameters
from .height import finite_mean, height_parameters
from .hybrid import hybrid_parameters
from .material_ratio import material_ratio_parameters
from .segmentation import segment
from .spatial import spatial_parameters

#: Parameter name -> unit, in output order.
UNITS: dict[str, str] = {
    "Sq": "mm",
    "Ssk": "1",
    "Sku": "1",
    "Sp": "mm",
    "Sv": "mm",
    "Sz": "mm",
    "Sa": "mm",
    "Sal": "mm",
    "Str": "1",
    "Std": "deg",
    "Sdq": "1",
    "Sdr": "%",
    "Vm": "mm^3/mm^2",
    "Vv": "mm^3/mm^2",
    "Vmp": "mm^3/mm^2",
    "Vmc": "mm^3/mm^2",
    "Vvc": "mm^3/mm^2",
    "Vvv": "mm^3/mm^2",
    "Sk": "mm",
    "Spk": "mm",
    "Svk": "mm",
    "Smr1": "%",
    "Smr2": "%",
    "Sa1": "mm^3/mm^2",
    "Sa2": "mm^3/mm^2",
    "Spc": "1/mm",
    "S10z": "mm",
    "S5p": "mm",
    "S5v": "mm",
    "Spd": "1/mm^2",
    "Shv": "mm^3",
    "Fdmax": "mm",
    "Fdmean": "mm",
    "Fden": "cm/cm^2",
    "motif_count": "1",
    "motif_threshold": "mm",
    "motif_mean_volume": "mm^3",
    "motif_mean_height_surface_ratio": "mm/mm^2",
    "motif_mean_area": "mm^2",
    "Sq_top": "mm",
    "Sdq_top": "1",
}

GROUPS = {
    "height": ("Sq", "Ssk", "Sku", "Sp", "Sv", "Sz", "Sa"),
    "spatial": ("Sal", "Str", "Std"),
    "hybrid": ("Sdq", "Sdr"),
    "material_ratio": ("Vm", "Vv", "Vmp", "Vmc", "Vvc", "Vvv", "Sk", "Spk", "Svk", "Smr1", "Smr2", "Sa1", "Sa2"),
    "features": ("Spc", "S10z", "S5p", "S5v", "Spd", "Shv"),
    "furrows": ("Fdmax", "Fdmean", "Fden"),
    "motifs": (
        "motif_count",
        "motif_threshold",
        "motif_mean_volume",
        "motif_mean_height_surface_ratio",
        "motif_mean_area",
    ),
    "contact": ("Sq_top", "Sdq_top"),
}

#: Groups computed from two bands together, reported with one band (:func:`cross_band_parameters`).
CROSS_BAND_GROUPS = {"contact": "micro"}


@dataclass(frozen=True)
class TextureOptions:
    """Options of the texture stage (config keys under ``texture:``); every one changes numbers.

    despeckle_method/k/axis: see :func:`skidsim.texture.despeckle`; fill: invalid-point filling; form:
    ``"plane"``/``"none"``/degree; macro_mm: (short, long) wavelength limits of macrotexture (mm);
    butterworth_order; acf_threshold (s of Sal/Str); acf_on_border ("nan"/"bound"); material ratios
    vm_p_pct / vv_q_pct (%); mr_classes; pruning_pct and pruning_reference ("Sz"/"Sq"); exclude_edge;
    spc_half_window (points); motif_pruning_pct; furrow_window_mm; furrow_min_depth_pct; groups: the
    parameter groups to compute; mpd_axis, mpd_segment_mm, mpd_spike_alpha, mpd_detect_plates,
    mpd_plate_threshold_mm, mpd_max_dropout_pct: the MPD procedure (:class:`skidsim.texture.mpd.MPDOptions`,
    checked there; :meth:`mpd_kwargs`); contact_top_pct (%): the areal material ratio that bounds the top zone of
    the contact-zone parameters (group ``contact``: micro Sq_top, Sdq_top; :mod:`skidsim.texture.contact`);
    workers (scipy.fft threads); crop_y_mm (mm or None): work on the centred band of this many mm of each scan's
    rows (y) from the despeckle step on, so every texture parameter, the MPD and the FE pavement come from that
    band (the quick configuration: about half the area;
    None: the whole scan).
    """

    despeckle_method: str = "local"
    despeckle_k: float | None = None
    despeckle_axis: int = 1
    fill: str = "linear"
    form: str | int = "plane"
    macro_mm: tuple[float, float] = (0.5, 50.0)
    butterworth_order: int = 2
    acf_threshold: float = 0.2
    acf_on_border: str = "nan"
    vm_p_pct: float = 10.0
    vv_q_pct: float = 80.0
    mr_classes: int = 10001
    pruning_pct: float = PRUNING_PCT
    pruning_reference: str = PRUNING_REFERENCES[0]
    exclude_edge: bool = False
    spc_half_window: int = 2
    motif_pruning_pct: float = PRUNING_PCT
    furrow_window_mm: float = 2.0
    furrow_min_depth_pct: float = 5.0
    groups: tuple[str, ...] = tuple(GROUPS)
    mpd_axis: int = 1
    mpd_segment_mm: float = 100.0
    mpd_spike_alpha: float = 3.0
    mpd_detect_plates: bool = False
    mpd_plate_threshold_mm: float = 30.0
    mpd_max_dropout_pct: float = 10.0
    contact_top_pct: float = 10.0
    workers: int = 1
    crop_y_mm: float | None = None

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"texture.{key}: expected {expected}, got {getattr(self, key)!r}")

        if self.despeckle_method not in METHODS:
            bad("despeckle_method", f"one of {METHODS}")
        if self.despeckle_axis not in (0, 1) or self.mpd_axis not in (0, 1):
            bad("despeckle_axis" if self.despeckle_axis not in (0, 1) else "mpd_axis", "0 or 1")
        if self.fill not in FILL_METHODS:
            bad("fill", f"one of {FILL_METHODS}")
        try:
            form_degree(self.form)
        except ValueError:
            bad("form", "'plane', 'none' or a polynomial degree >= 0")
        if len(self.macro_mm) != 2 or not 0 < self.macro_mm[0] < self.macro_mm[1]:
            bad("macro_mm", "[short_mm, long_mm] with 0 < short < long")
        if self.pruning_reference not in PRUNING_REFERENCES:
            bad("pruning_reference", f"one of {PRUNING_REFERENCES}")
        if self.acf_on_border not in ("nan", "bound"):
            bad("acf_on_border", "'nan' or 'bound'")
        if not 0 < self.acf_threshold < 1:
            bad("acf_threshold", "a number in (0, 1)")
        if not 0 < self.contact_top_pct <= 100:
            bad("contact_top_pct", "a material ratio in (0, 100] %")
        unknown_groups = sorted(set(self.groups) - set(GROUPS))
        if unknown_groups:
            raise ConfigError(f"texture.groups: unknown group(s) {unknown_groups}; expected among {list(GROUPS)}")
        if self.crop_y_mm is not None and not (isinstance(self.crop_y_mm, (int, float)) and self.crop_y_mm > 0):
            bad("crop_y_mm", "null or a positive number of mm")
        if int(self.butterworth_order) < 1 or int(self.workers) < 1 or int(self.spc_half_window) < 1:
            bad("butterworth_order", "butterworth_order, workers, spc_half_window >= 1")
        self.mpd_kwargs()  # the MPD options raise ConfigError naming the bad one

    def mpd_kwargs(self) -> dict:
        """Keyword arguments of :func:`skidsim.texture.mean_profile_depth` from the ``mpd_*`` fields (checked)."""
        from .mpd import MPDOptions

        kw = dict(
            segment_mm=float(self.mpd_segment_mm),
            spike_alpha=float(self.mpd_spike_alpha),
            detect_plates=bool(self.mpd_detect_plates),
            plate_threshold_mm=float(self.mpd_plate_threshold_mm),
            max_dropout_pct=float(self.mpd_max_dropout_pct),
        )
        try:
            MPDOptions(**kw)
        except ConfigError as exc:
            raise ConfigError(f"texture.mpd_{str(exc).removeprefix('MPD option ')}") from None
        return {"axis": self.mpd_axis, **kw}

    @classmethod
    def from_dict(cls, d: dict | None) -> TextureOptions:
        """Build from a config mapping (the workflow's ``texture:`` section); unknown keys or bad values raise
        :class:`skidsim.errors.ConfigError` naming the key and what was expected."""
        d = dict(d or {})
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ConfigError(f"texture: unknown key(s) {unknown}; expected a subset of {sorted(names)}")
        if "macro_mm" in d:
            d["macro_mm"] = tuple(d["macro_mm"])
        if "groups" in d:
            d["groups"] = tuple(d["groups"])
        return cls(**d)


def areal_parameters(
    surface: Surface, band: str = "raw", options: TextureOptions | dict | None = None
) -> dict[str, tuple[float, str]]:
    """All areal parameters of one band surface: ``name -> (value, unit)``.

    ``surface`` must be complete (no NaN; run :func:`skidsim.texture.fill_invalid` / ``separate_bands``
    first). ``band`` is only used in messages. Heights are referenced to their mean plane.
    """
    opt = options if isinstance(options, TextureOptions) else TextureOptions.from_dict(options)
    z = surface.heights
    mean = finite_mean(z)
    if mean is None:
        raise ValueError(
            f"areal_parameters: surface {surface.name!r} band {band!r} has invalid points; "
            "fill them first (fill_invalid)"
        )
    if min(z.shape) < 8:
        raise ValueError(f"areal_parameters: surface {surface.name!r} band {band!r} is {z.shape}, need >= 8x8")
    dx, dy = surface.dx, surface.dy
    zc = z - mean
    out: dict[str, float] = {}
    g = set(opt.groups)
    # the range of zc, read by the pruning threshold (reference Sz) and the furrows' depth limit: once
    sz = float(zc.max() - zc.min()) if g & {"features", "motifs", "furrows"} else None
    if "height" in g:
        out.update(height_parameters(zc))
    if "spatial" in g:
        sp = spatial_parameters(zc, dx, dy, s=opt.acf_threshold, on_border=opt.acf_on_border, workers=opt.workers)
        out.update({"Sal": sp.Sal, "Str": sp.Str, "Std": sp.Std})
    if "hybrid" in g:
        out.update(hybrid_parameters(zc, dx, dy))  # one pair of differences for both
    if "material_ratio" in g:
        out.update(material_ratio_parameters(zc, p_pct=opt.vm_p_pct, q_pct=opt.vv_q_pct, n_classes=opt.mr_classes))
    hills = None
    if "features" in g or "motifs" in g:
        t = pruning_threshold(zc, opt.pruning_pct, opt.pruning_reference, sz=sz)
        hills = segment(-zc, t, dx, dy, keep_peaks="features" in g)  # its peaks: the dales' sinks, for S5v
    if "features" in g:
        out.update(
            feature_parameters(
                zc,
                dx,
                dy,
                pruning_pct=opt.pruning_pct,
                pruning_reference=opt.pruning_reference,
                exclude_edge=opt.exclude_edge,
                spc_half_window=opt.spc_half_window,
                hills=hills,
                sz=sz,
            )
        )
    if "furrows" in g:
        out.update(
            furrow_parameters(zc, dx, dy, window_mm=opt.furrow_window_mm, min_depth_pct=opt.furrow_min_depth_pct, sz=sz)
        )
    if "motifs" in g:
        same = opt.motif_pruning_pct == opt.pruning_pct
        out.update(
            motif_parameters(
                zc,
                dx,
                dy,
                pruning_pct=opt.motif_pruning_pct,
                pruning_reference=opt.pruning_reference,
                exclude_edge=opt.exclude_edge,
                hills=hills if same else None,
                sz=sz,
            )
        )
    return {k: (float(out[k]), UNITS[k]) for k in UNITS if k in out}


def cross_band_parameters(bands, options: TextureOptions | dict | None = None) -> dict[str, dict[str, tuple]]:
    """The parameters of :data:`CROSS_BAND_GROUPS` in ``options.groups`` from the complete band surfaces
    ``bands`` (``{"raw", "macro", "micro"}`` -> Surface): ``{band: {name: (value, unit)}}``, the band they are
    reported with. Group ``contact``: the micro band on the raw surface's top zone
    (:func:`skidsim.texture.contact.contact_parameters`, ``options.contact_top_pct``)."""
    from .contact import contact_parameters

    opt = options if isinstance(options, TextureOptions) else TextureOptions.from_dict(options)
    if "contact" not in opt.groups:
        return {}
    raw, micro = bands["raw"], bands["micro"]
    values = contact_parameters(raw.heights, micro.heights, micro.dx, micro.dy, opt.contact_top_pct)
    return {CROSS_BAND_GROUPS["contact"]: {k: (float(v), UNITS[k]) for k, v in values.items()}}
