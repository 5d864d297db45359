"""One validation of a campaign and its configuration, used by ``skidsim validate``, by the workflow when it
builds its plan (``workflow/rules/common.smk``) and by its first rule (``validate_campaign``).

Every check returns problems, never stops at the first one: each problem is a :class:`~skidsim.errors.InputError`
naming the file, the row or field, what was expected and what was found. :func:`check_campaign` gathers them
and raises one :class:`~skidsim.errors.CampaignError` listing all of them (``err.errors``).

Levels (cheapest first; each includes the ones before it):

* ``table``: ``sites.csv`` (columns, ids safe for file names, unique ids, temperatures), every path inside the
  campaign directory (unless allowed), every named file exists, the DFT traces (read in full: they are small)
  covering every calibration and validation speed, config cross-checks. No scan is opened. The workflow runs
  this level when it builds its plan.
* ``header``: plus DFT samples at 2 speeds within the smoothing window of each speed; each scan's header: X3P
  archive, checksum of main.xml, data sizes, a Z increment for integer codes; spacing and extent against the strip
  and the texture band. Text grids are read in full.
* ``full`` (default): plus every scan decoded: MD5 of data.bin and valid.bin, share of valid points, height span.
  About 0.2-0.4 s per LS-40 scan (2048 x 2448 points).

What the configuration asks of the data is a :class:`Requirements`, built from the workflow's config mapping
(:meth:`Requirements.from_config`) or left at the defaults, which are those of the options dataclass of each config
section (:class:`SpeedOptions`, :class:`IngestOptions`, :class:`~skidsim.reconstruct.MeshOptions`,
:class:`~skidsim.texture.TextureOptions`, :class:`~skidsim.solver.mesh_study.MeshStudyOptions`);
``tests/test_defaults.py`` keeps ``config/config.yaml`` and the schema equal to them.
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from .errors import CampaignError, ConfigError, DftError, InputError
from .options import options_from_dict
from .reconstruct import MeshOptions
from .solver.mesh_study import MeshStudyOptions
from .texture.parameters import TextureOptions

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


def _quality_options(config: dict):
    from .texture.quality import QualityOptions

    q = QualityOptions.from_dict(config.get("quality"))
    return None if q == QualityOptions() else q  # None: the defaults, as Requirements() has them


def check_relief(path, surface, req: Requirements) -> list[InputError]:
    """The relief of a decoded scan against the ``quality:`` limits (:func:`skidsim.texture.quality.relief_mm`):
    outside them a problem naming the scan (``action: stop``) or a WARNING (``action: warn``)."""
    import logging

    from .texture.quality import QualityOptions, relief_breach, relief_mm

    opt = req.quality or QualityOptions()
    relief = relief_mm(surface)
    breach = relief_breach(relief, opt)
    if breach is None:
        return []
    if opt.action == "warn":
        logging.getLogger("skidsim").warning("SCAN RELIEF %s: %s (quality.action: warn)", path, breach)
        return []
    return [
        InputError(
            path,
            f"a relief of a pavement surface, {opt.min_relief_mm:g} to {opt.max_relief_mm:g} mm "
            "(quality.min_relief_mm, quality.max_relief_mm; 0.5-99.5 % of the heights about their plane)",
            column="heights",
            got=f"{relief:.3g} mm",
            hint=f"{breach}; quality.action: stop",
        )
    ]


class ConfigProblem(InputError):
    """A configuration value that does not fit the others (file = the config, column = the key)."""


def _speeds_text(v) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"


def check_config(req: Requirements) -> list[InputError]:
    """Config cross-checks the schema cannot express: speed sets, band and strip sizes."""
    out: list[InputError] = []
    src = req.source
    for key, speeds in (("speeds.calibration_kmh", req.calibration_kmh), ("speeds.validation_kmh", req.validation_kmh)):
        if not speeds:
            out.append(ConfigProblem(src, "at least one speed in km/h", column=key, got="[]"))
            continue
        dup = sorted({v for v in speeds if list(speeds).count(v) > 1})
        if dup:
            out.append(
                ConfigProblem(
                    src,
                    "distinct speeds (a repeated speed is silently dropped)",
                    column=key,
                    got=_speeds_text(speeds),
                    hint=f"{_speeds_text(dup)} km/h repeated",
                )
            )
        bad = [v for v in speeds if not (math.isfinite(v) and v > 0)]
        if bad:
            out.append(ConfigProblem(src, "speeds > 0 km/h", column=key, got=_speeds_text(speeds)))
    both = sorted(set(req.calibration_kmh) & set(req.validation_kmh))
    if both:
        out.append(
            ConfigProblem(
                src,
                "validation speeds disjoint from calibration speeds (a speed used to calibrate cannot validate)",
                column="speeds.validation_kmh",
                got=_speeds_text(req.validation_kmh),
                hint=f"{_speeds_text(both)} km/h also in speeds.calibration_kmh {_speeds_text(req.calibration_kmh)}",
            )
        )
    lo, hi = req.macro_mm
    if not (0 < lo < hi):
        out.append(ConfigProblem(src, "0 < low < high (mm)", column="texture.macro_mm", got=[lo, hi]))
    if req.smooth_window_kmh is not None and not req.smooth_window_kmh > 0:
        out.append(
            ConfigProblem(
                src,
                "a positive window in km/h or null",
                column="ingest.dft_smooth_window_kmh",
                got=req.smooth_window_kmh,
            )
        )
    if req.crop_y_mm is not None and req.crop_y_mm < req.strip_width_mm:
        out.append(
            ConfigProblem(
                src,
                f"a texture band at least as wide as the FE strip (mesh.width_mm {req.strip_width_mm:g} mm)",
                column="texture.crop_y_mm",
                got=req.crop_y_mm,
            )
        )
    if not 0 <= req.min_valid_share <= 1:
        out.append(
            ConfigProblem(src, "a share between 0 and 1", column="ingest.min_valid_share", got=req.min_valid_share)
        )
    return out


# --------------------------------------------------------------------------------------------------- sites.csv


def check_table(directory, req: Requirements = Requirements(), points: bool = True) -> tuple[object, list[InputError]]:
    """``sites.csv``, the files it names and the DFT traces: ``(campaign or None, problems)``.

    Uses :func:`skidsim.campaign.load_campaign` for the table and the traces (each must cover every calibration
    and validation speed), and adds: paths inside the campaign directory, the mesh study's site and, with
    ``points``, DFT samples at 2 speeds within the smoothing window of each speed (levels header and full).
    """
    from .campaign import SITES_FILE, load_campaign

    directory = Path(directory).expanduser().absolute()
    sites_csv = directory / SITES_FILE
    problems: list[InputError] = []
    camp = None
    try:
        camp = load_campaign(directory, speeds_kmh=req.speeds_kmh, check_scans=False, allow_outside=req.allow_outside)
    except CampaignError as err:
        problems.extend(getattr(err, "errors", None) or [err])
    if camp is not None:
        if points and req.smooth_window_kmh is not None:
            for site in camp.site_ids:
                tr = camp.traces[site]
                try:
                    tr.smooth_at(req.speeds_kmh, req.smooth_window_kmh)
                except DftError as exc:
                    problems.append(
                        CampaignError(
                            sites_csv,
                            "a DFT trace with samples near every speed",
                            row=camp.rows[site],
                            column="dft",
                            got=_rel(directory, tr.path),
                            hint=str(exc),
                        )
                    )
        if req.mesh_study_site is not None and req.mesh_study_site not in camp.site_ids:
            problems.append(
                ConfigProblem(
                    req.source, f"a site id of {sites_csv}", column="mesh_study.site", got=req.mesh_study_site
                )
            )
    return camp, problems


def _rel(directory: Path, path) -> str:
    try:
        return str(Path(path).relative_to(directory))
    except ValueError:
        return str(path)


# -------------------------------------------------------------------------------------------------------- scans


def _x3p_extras(path: Path, full: bool) -> dict:
    """What :func:`skidsim.x3p.read_x3p` does not report: whether main.xml states a CZ increment, and (``full``)
    the stated and actual MD5 of valid.bin."""
    from .x3p import MAIN_XML, _strip_namespaces

    with zipfile.ZipFile(path) as zf:
        root = ElementTree.fromstring(zf.read(MAIN_XML))
        _strip_namespaces(root)
        cz_inc = root.find("Record1/Axes/CZ/Increment")
        out = {"cz_increment": None if cz_inc is None or not (cz_inc.text or "").strip() else cz_inc.text.strip()}
        link = root.find("Record3/DataLink")
        if full and link is not None:
            v_link, v_md5 = link.find("ValidPointsLink"), link.find("MD5ChecksumValidPoints")
            if v_link is not None and v_md5 is not None and (v_md5.text or "").strip():
                out["valid_md5"] = (v_md5.text.strip().lower(), hashlib.md5(zf.read(v_link.text.strip())).hexdigest())
    return out


def _one_line(exc: InputError) -> InputError:
    """``exc`` itself, or (a reader's message over several lines, e.g. SurfaceTopography's list of every reader it
    tried) the same error with only the first line of what was found."""
    if not (isinstance(exc.got, str) and "\n" in exc.got.strip()):
        return exc
    first = str(exc.got).strip().splitlines()[0].rstrip(": ") if exc.got is not None else None
    short = InputError(
        exc.file,
        exc.expected,
        row=exc.row,
        column=exc.column,
        got=None if first is None else f"{first} ... (first line of the reader's message)",
    )
    short.__cause__ = exc
    return short


def check_geometry(path, shape, dx_mm: float, dy_mm: float, req: Requirements) -> list[InputError]:
    """Spacing and extent of a scan against the strip, the texture band and the FE resolution."""
    out: list[InputError] = []
    rows, cols = shape
    length, width = (cols - 1) * dx_mm, (rows - 1) * dy_mm  # first to last point, as the reconstruction measures
    lo, hi = req.macro_mm
    max_spacing = min(lo / 2.0, req.resolution_mm)
    for name, d in (("dx", dx_mm), ("dy", dy_mm)):
        if not d <= max_spacing * (1 + 1e-9):
            out.append(
                InputError(
                    path,
                    f"a lateral spacing <= {max_spacing:g} mm (2 points per {lo:g} mm, the "
                    f"lower limit of texture.macro_mm, and no coarser than mesh.resolution_mm "
                    f"{req.resolution_mm:g} mm)",
                    column=f"{name}_mm",
                    got=f"{d:g} mm",
                )
            )
    x0 = req.strip_x0_mm if req.strip_x0_mm is not None else 0.0
    y0 = req.strip_y0_mm if req.strip_y0_mm is not None else 0.0
    if x0 + req.strip_length_mm > length * (1 + 1e-9) or x0 < 0:
        out.append(
            InputError(
                path,
                f"a scan length (x, first to last of {cols} points at {dx_mm:g} mm) holding the FE strip "
                f"(mesh.length_mm {req.strip_length_mm:g} mm from x0 {x0:g} mm)",
                column="extent_x",
                got=f"{length:g} mm",
            )
        )
    if y0 + req.strip_width_mm > width * (1 + 1e-9) or y0 < 0:
        out.append(
            InputError(
                path,
                f"a scan width (y, first to last of {rows} points at {dy_mm:g} mm) holding the FE strip "
                f"(mesh.width_mm {req.strip_width_mm:g} mm from y0 {y0:g} mm)",
                column="extent_y",
                got=f"{width:g} mm",
            )
        )
    if req.crop_y_mm is not None and req.crop_y_mm > width * (1 + 1e-9):
        out.append(
            InputError(
                path,
                f"a scan width of at least texture.crop_y_mm {req.crop_y_mm:g} mm",
                column="extent_y",
                got=f"{width:g} mm",
            )
        )
    if hi > length * (1 + 1e-9):
        out.append(
            InputError(
                path,
                f"a scan length of at least the upper limit of texture.macro_mm ({hi:g} mm)",
                column="extent_x",
                got=f"{length:g} mm",
            )
        )
    return out


def check_scan(path, req: Requirements = Requirements(), level: str = "full") -> list[InputError]:
    """Problems of one scan file at ``level`` ``header`` or ``full`` (see the module docstring)."""
    from .scans import read_scan
    from .x3p import read_x3p_header

    path = Path(path)
    is_x3p = path.suffix.lower() == ".x3p"
    try:
        if is_x3p:
            hdr = read_x3p_header(path)
            extras = _x3p_extras(path, full=level == "full")
            if hdr.dtype in ("I", "L") and extras["cz_increment"] is None:
                return [
                    InputError(
                        path,
                        f"a CZ Increment (metres per code) for integer height codes (type {hdr.dtype})",
                        column="Record1/Axes/CZ/Increment",
                        got="missing",
                        hint="heights would read as raw codes in metres",
                    )
                ]
            problems = check_geometry(path, hdr.shape, hdr.dx_mm, hdr.dy_mm, req)
            if level != "full":
                return problems
            if "valid_md5" in extras and extras["valid_md5"][0] != extras["valid_md5"][1]:
                problems.append(
                    InputError(
                        path,
                        f"bindata/valid.bin with the MD5 stated in main.xml ({extras['valid_md5'][0]})",
                        column="Record3/DataLink/MD5ChecksumValidPoints",
                        got=extras["valid_md5"][1],
                        hint="corrupt valid-point mask",
                    )
                )
        else:
            problems = []
        surface = read_scan(path)  # decodes, checks MD5 of data.bin
    except InputError as exc:
        return [_one_line(exc)]
    except (zipfile.BadZipFile, ElementTree.ParseError, KeyError, OSError) as exc:
        return [InputError(path, "a readable scan file", got=f"{type(exc).__name__}: {exc}")]
    if not is_x3p:
        problems = check_geometry(path, surface.shape, surface.dx, surface.dy, req)
    h = surface.heights
    valid = np.isfinite(h)
    share = float(valid.mean()) if h.size else 0.0
    if share < req.min_valid_share:
        problems.append(
            InputError(
                path,
                f"at least {req.min_valid_share:.0%} valid points (ingest.min_valid_share)",
                column="heights",
                got=f"{share:.1%} valid",
            )
        )
    elif valid.any():
        span = float(h[valid].max() - h[valid].min())
        if span > req.max_height_span_mm:
            problems.append(
                InputError(
                    path,
                    f"valid heights spanning at most {req.max_height_span_mm:g} mm "
                    "(ingest.max_height_span_mm; more means a wrong unit or Z increment)",
                    column="heights",
                    got=f"{span:.4g} mm",
                )
            )
        else:
            problems += check_relief(path, surface, req)
    return problems


# ----------------------------------------------------------------------------------------------------- campaign


def _as_row_problem(sites_csv: Path, row: int, raw: str, exc: InputError) -> CampaignError:
    """A scan problem on its ``sites.csv`` cell, keeping the scan file's own message."""
    err = CampaignError(sites_csv, "a usable scan", row=row, column="scan", got=raw, hint=str(exc))
    err.cause = exc
    return err


def _scan_rows(directory: Path, req: Requirements) -> list[tuple[int, str, Path]]:
    """``(row, scan as written, path)`` of every site row whose scan file exists (the table check names the rest)."""
    from .campaign import inside, site_rows

    out = []
    for line, rec in site_rows(directory):
        raw = (rec.get("scan") or "").strip()
        if not raw or (not req.allow_outside and not inside(directory, raw)):
            continue
        p = Path(raw).expanduser()
        p = p if p.is_absolute() else directory / p
        if p.is_file():
            out.append((line, raw, p))
    return out


def problems(directory, req: Requirements = Requirements(), level: str = "full", progress=None, workers: int = 1):
    """Every problem of a campaign at ``level``: ``(campaign or None, [InputError, ...])``.

    ``progress``: optional callable ``(n_done)`` after each scan. ``workers`` > 1 checks that many scans at a time
    in threads (decompression, MD5 and the array checks release the GIL); the problems come in row order either
    way.
    """
    if level not in LEVELS:
        raise ValueError(f"level must be one of {LEVELS}, got {level!r}")
    from .campaign import SITES_FILE

    out = check_config(req)
    camp, table = check_table(directory, req, points=level != "table")
    out += table
    if level == "table":
        return camp, out
    directory = Path(directory).expanduser().absolute()
    sites_csv = directory / SITES_FILE
    rows = _scan_rows(directory, req)
    with ThreadPoolExecutor(max_workers=max(1, int(workers))) as pool:
        found = pool.map(lambda r: check_scan(r[2], req, level), rows)
        for checked, ((line, raw, _), scan_problems) in enumerate(zip(rows, found), start=1):
            out += [_as_row_problem(sites_csv, line, raw, exc) for exc in scan_problems]
            if progress is not None:
                progress(checked)
    return camp, out


def summary_error(directory, found: list[InputError]) -> InputError:
    """One error for ``found``: the problem itself when there is one, else a :class:`CampaignError` whose first
    line is the count and whose further lines (``"  - ..."``) are the problems (all in ``err.errors``)."""
    from .campaign import SITES_FILE

    if len(found) == 1:  # one problem: its own message
        err = found[0]
        err.errors = list(found)
        return err
    sites_csv = Path(directory).expanduser().absolute() / SITES_FILE
    err = CampaignError(
        sites_csv,
        "a campaign without problems",
        got=f"{len(found)} problem(s)",
        hint="all listed below; fix them and run again",
    )
    err.args = (str(err) + "\n" + "\n".join(f"  - {e}" for e in found),)
    err.errors = list(found)
    return err


def check_campaign(directory, req: Requirements = Requirements(), level: str = "full", progress=None, workers: int = 1):
    """The validated :class:`~skidsim.campaign.Campaign`, or one error listing every problem (:func:`summary_error`).

    ``workers``: scans checked at a time (:func:`problems`)."""
    camp, found = problems(directory, req, level, progress, workers)
    if found or camp is None:
        raise summary_error(directory, found)
    return camp


def check_plan(config: dict, campaign_dir) -> list[InputError]:
    """What the workflow checks when it builds its plan: the config cross-checks and, for a user campaign
    (``campaign_dir`` not None), the ``table`` level. Returns the problems."""
    req = Requirements.from_config(config)
    if campaign_dir is None:
        return check_config(req)
    _, found = problems(campaign_dir, req, level="table")
    return found


def format_problems(found: list[InputError]) -> str:
    """The readable block printed by the workflow and the CLI: one line for one problem, else a head line with
    the count and one problem per line."""
    if len(found) == 1:
        return f"skidsim: error: {found[0]}"
    return "\n".join([f"skidsim: error: {len(found)} problems:"] + [f"  - {e}" for e in found])
