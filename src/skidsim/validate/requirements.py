"""What the configuration asks of a campaign's data (:class:`Requirements`) and the options of the config
sections it is built from (``speeds:``, ``ingest:``), in the units of the config (km/h, mm)."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError
from ..options import options_from_dict
from ..reconstruct import MeshOptions
from ..solver.mesh_study import MeshStudyOptions
from ..texture.parameters import TextureOptions

LEVELS = ("table", "header", "full")
CONFIG = "config"
"""File name used in messages about configuration values (the merged config of the workflow or CLI)."""


@dataclass(frozen=True)
class SpeedOptions:
    """The DFT speeds of the analysis in km/h (config keys under ``speeds:``).

    calibration_kmh: the study's back-calculation speeds (DFT20, DFT40, DFT60); validation_kmh: speeds never used
    in calibration, only to validate. :func:`check_config` checks that the two sets are disjoint.
    """

    calibration_kmh: tuple[float, ...] = (20.0, 40.0, 60.0)
    validation_kmh: tuple[float, ...] = (30.0, 50.0, 70.0)

    @classmethod
    def from_dict(cls, d: dict | None) -> SpeedOptions:
        """From the ``speeds:`` config block (speeds as floats)."""
        o = options_from_dict(cls, "speeds", d)
        return cls(tuple(float(v) for v in o.calibration_kmh), tuple(float(v) for v in o.validation_kmh))


#: ``ingest.check_scans`` -> validation level of :func:`check_campaign`.
CHECK_SCANS_LEVEL = {"full": "full", "header": "header", False: "table"}


@dataclass(frozen=True)
class IngestOptions:
    """How the campaign is read and checked (config keys under ``ingest:``).

    check_scans: ``"full"`` (decode every scan), ``"header"`` (headers only) or ``False`` (sites.csv and DFT
    traces only), see :data:`CHECK_SCANS_LEVEL`; min_valid_share: smallest share (0-1) of valid points in a scan;
    max_height_span_mm: largest plausible range of valid heights, mm; allow_outside_campaign: accept sites.csv
    paths outside the campaign directory; dft_smooth_window_kmh: half-width in km/h of the local linear fit that
    reads the DFT at a speed (None: linear interpolation).
    """

    check_scans: str | bool = "full"
    min_valid_share: float = 0.5
    max_height_span_mm: float = 50.0
    allow_outside_campaign: bool = False
    dft_smooth_window_kmh: float | None = 5.0

    def __post_init__(self) -> None:
        if self.check_scans not in CHECK_SCANS_LEVEL:
            raise ConfigError(f"ingest.check_scans: expected one of full, header, false, got {self.check_scans!r}")

    @property
    def level(self) -> str:
        """The :data:`LEVELS` entry of ``check_scans``."""
        return CHECK_SCANS_LEVEL[self.check_scans]

    @classmethod
    def from_dict(cls, d: dict | None) -> IngestOptions:
        """From the ``ingest:`` config block."""
        return options_from_dict(cls, "ingest", d)


@dataclass(frozen=True)
class Requirements:
    """What the analysis needs from every site, in the units of the config.

    calibration_kmh, validation_kmh: DFT speeds (km/h) of calibration and validation; disjoint, each trace must
        cover both.
    smooth_window_kmh: half-width (km/h) of the local linear fit of the DFT value at a speed (None: linear
        interpolation); each speed then needs samples at 2 distinct speeds within the window.
    strip_length_mm, strip_width_mm, strip_x0_mm, strip_y0_mm: the FE pavement strip on the scan (mm; origin
        None = centred): it must lie inside the scan.
    resolution_mm: FE pavement resolution (mm); the scan spacing must not be coarser.
    macro_mm: the macrotexture band (mm): its lower limit needs at least 2 points (spacing <= low / 2), its upper
        limit must fit in the scan's length.
    crop_y_mm: texture works on the centred band of this width (mm; None: the whole scan); it must fit.
    min_valid_share: smallest share of valid (non-dropout) points in a scan (0-1).
    max_height_span_mm: largest plausible range of valid heights (mm); above it heights are in the wrong unit.
    allow_outside: accept scan/DFT paths outside the campaign directory.
    mesh_study_site: the site the mesh study runs on (None: the first site); must be a site of the table.
    quality: the ``quality:`` limits (:class:`~skidsim.texture.quality.QualityOptions`; None: its defaults), of
        which the relief limits and the action apply here (``full`` level: a relief a pavement cannot have is a
        problem with ``action: stop``, a WARNING with ``action: warn``).
    """

    calibration_kmh: tuple[float, ...] = SpeedOptions.calibration_kmh
    validation_kmh: tuple[float, ...] = SpeedOptions.validation_kmh
    smooth_window_kmh: float | None = IngestOptions.dft_smooth_window_kmh
    strip_length_mm: float = MeshOptions.length_mm
    strip_width_mm: float = MeshOptions.width_mm
    strip_x0_mm: float | None = MeshOptions.x0_mm
    strip_y0_mm: float | None = MeshOptions.y0_mm
    resolution_mm: float = MeshOptions.resolution_mm
    macro_mm: tuple[float, float] = TextureOptions.macro_mm
    crop_y_mm: float | None = TextureOptions.crop_y_mm
    min_valid_share: float = IngestOptions.min_valid_share
    max_height_span_mm: float = IngestOptions.max_height_span_mm
    allow_outside: bool = IngestOptions.allow_outside_campaign
    mesh_study_site: str | None = MeshStudyOptions.site
    source: str = CONFIG
    quality: object = None

    @property
    def speeds_kmh(self) -> tuple[float, ...]:
        """Every speed (km/h) a trace must cover, sorted."""
        return tuple(sorted(set(self.calibration_kmh) | set(self.validation_kmh)))

    @classmethod
    def from_config(cls, config: dict, source: str = CONFIG) -> Requirements:
        """From the workflow's config mapping (missing sections keep the defaults)."""
        sp = SpeedOptions.from_dict(config.get("speeds"))
        ing = IngestOptions.from_dict(config.get("ingest"))
        mesh = MeshOptions.from_dict(config.get("mesh"))
        tex = config.get("texture") or {}
        ms = MeshStudyOptions.from_dict(config.get("mesh_study"))

        def opt(v):
            return None if v is None else float(v)

        return cls(
            calibration_kmh=sp.calibration_kmh,
            validation_kmh=sp.validation_kmh,
            smooth_window_kmh=opt(ing.dft_smooth_window_kmh),
            strip_length_mm=float(mesh.length_mm),
            strip_width_mm=float(mesh.width_mm),
            strip_x0_mm=opt(mesh.x0_mm),
            strip_y0_mm=opt(mesh.y0_mm),
            resolution_mm=float(mesh.resolution_mm),
            macro_mm=tuple(float(v) for v in tex.get("macro_mm", TextureOptions.macro_mm)),
            crop_y_mm=opt(tex.get("crop_y_mm", TextureOptions.crop_y_mm)),
            min_valid_share=float(ing.min_valid_share),
            max_height_span_mm=float(ing.max_height_span_mm),
            allow_outside=bool(ing.allow_outside_campaign),
            mesh_study_site=ms.site if ms.sizes_mm else None,
            source=source,
            quality=_quality_options(config),
        )


#: The defaults of every section (frozen: one instance serves as every checker's default argument).
DEFAULT_REQUIREMENTS = Requirements()


def _quality_options(config: dict):
    from ..texture.quality import QualityOptions

    q = QualityOptions.from_dict(config.get("quality"))
    return None if q == QualityOptions() else q  # None: the defaults, as Requirements() has them
