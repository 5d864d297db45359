"""Scan quality: what the instrument delivered, measured per scan, and the configured limits on it.

Measures (:func:`scan_quality`, on the scan the texture stage works on, i.e. after the ``crop_y_mm`` band):

* ``dropout_pct``: share of invalid (NaN) points, %.
* ``replaced_pct``: share of points the despeckle replaced, % of all points.
* ``height_step_mm``: the height step (quantisation) of the scan, mm; 0 for continuous heights
  (:func:`skidsim.texture.despeckle.height_step`), with ``height_step_source`` x3p / data / none.
* ``spikes_found``: number of 8-connected clusters of replaced points (a 3-point spike counts once).
* ``tilt_deg``: angle of the least-squares plane through the valid points to the instrument's horizontal,
  degrees; ``tilt_x_mm_per_m`` / ``tilt_y_mm_per_m``: its slopes along x and y, mm per m.
* ``relief_mm``: the distance between the 0.5th and 99.5th percentiles of the valid heights about the
  least-squares plane, mm (:func:`relief_mm`): what a pavement texture spans, robust to a tilt and to the spikes and
  dropout edges of a scan (0.5 % of the points on each side are not counted).
* ``usable_length_mm``: the longest run of consecutive columns (x, the sliding direction) in which at least
  ``min_column_valid_pct`` % of the points are valid, as an extent ``(n - 1) * dx`` in mm (a whole valid
  LS-40 scan: 2447 x 0.05 = 122.35 mm); to compare with the FE strip length (``mesh.length_mm``, 114.3 mm).

Limits (:class:`QualityOptions`, config block ``quality:``): above ``max_dropout_pct``, ``max_replaced_pct``,
``max_tilt_deg`` or below ``min_usable_length_mm`` a scan is flagged; so is a relief outside ``min_relief_mm`` ..
``max_relief_mm``, a scan that cannot be a pavement surface (one height everywhere; heights in m read as mm, a
relief of micrometres; a relief of metres). The relief is also checked before any work, by
:mod:`skidsim.validate` (``skidsim validate`` and the workflow's first rule, :func:`relief_breach`).
:func:`check_quality` then logs a WARNING naming the site, the measure, the value and the limit
(``action: warn``), or raises :class:`ScanQualityError` (``action: stop``).
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, fields

import numpy as np

from skidsim.errors import ConfigError, SkidsimError
from skidsim.surface import Surface

ACTIONS = ("warn", "stop")
log = logging.getLogger(__name__)


class ScanQualityError(SkidsimError):
    """A scan beyond a configured quality limit with ``quality.action: stop``."""


@dataclass(frozen=True)
class QualityOptions:
    """Limits on scan quality (config keys under ``quality:``).

    max_dropout_pct: most invalid points, % (10: the share at which ISO 13473-1 drops an MPD segment).
    max_replaced_pct: most points replaced by the despeckle, % (1: ten times the most the ``local`` rule
    replaces on clean scans; more means a broken scan or a rule that cuts into texture).
    max_tilt_deg: steepest plane, degrees (5: a 2.5 % cross-fall and an 8 % grade give 4.8 degrees).
    min_usable_length_mm: shortest usable strip along x, mm; None: the FE strip length ``mesh.length_mm``.
    min_column_valid_pct: a column counts as usable with at least this share of valid points, %.
    min_relief_mm, max_relief_mm: the range of :func:`relief_mm` a pavement surface has, mm. Measured on the
    textures of docs/texture.md (12 sections of the default campaign, 9 flat-binder, chip and porous scans) the
    relief is 1.4-4.9 x the MPD; the MPD of real surfaces is roughly 0.1-3 mm, so their relief is about
    0.14-15 mm. 0.05 mm (5 codes of an LS-40's 0.01 mm; a third of the smoothest) and 30 mm (twice the coarsest)
    leave a margin on both sides and still refuse one height everywhere, heights in m read as mm (a relief of
    micrometres) and heights in um read as mm or a range of metres.
    action: ``"warn"`` (log a WARNING, mark the site in the quality table and the report) or ``"stop"``.
    """

    max_dropout_pct: float = 10.0
    max_replaced_pct: float = 1.0
    max_tilt_deg: float = 5.0
    min_usable_length_mm: float | None = None
    min_column_valid_pct: float = 90.0
    min_relief_mm: float = 0.05
    max_relief_mm: float = 30.0
    action: str = "warn"

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"quality.{key}: expected {expected}, got {getattr(self, key)!r}")

        if self.action not in ACTIONS:
            bad("action", f"one of {ACTIONS}")
        for key in ("max_dropout_pct", "max_replaced_pct", "min_column_valid_pct"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and 0 <= v <= 100):
                bad(key, "a percentage in [0, 100]")
        if not (isinstance(self.max_tilt_deg, (int, float)) and 0 <= self.max_tilt_deg <= 90):
            bad("max_tilt_deg", "an angle in [0, 90] degrees")
        v = self.min_usable_length_mm
        if v is not None and not (isinstance(v, (int, float)) and v >= 0):
            bad("min_usable_length_mm", "a length >= 0 mm or null")
        for key in ("min_relief_mm", "max_relief_mm"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v < float("inf")):
                bad(key, "a height range >= 0 mm")
        if not self.min_relief_mm < self.max_relief_mm:
            bad("max_relief_mm", f"a relief above min_relief_mm ({self.min_relief_mm!r} mm)")

    @classmethod
    def from_dict(cls, d: dict | None, strip_length_mm: float | None = None) -> QualityOptions:
        """From the ``quality:`` config block; ``strip_length_mm`` (mesh.length_mm) fills a null
        ``min_usable_length_mm``. Unknown keys raise :class:`ConfigError`."""
        d = dict(d or {})
        unknown = sorted(set(d) - {f.name for f in fields(cls)})
        if unknown:
            raise ConfigError(f"quality: unknown keys {unknown}; expected some of {[f.name for f in fields(cls)]}")
        if d.get("min_usable_length_mm") is None and strip_length_mm is not None:
            d["min_usable_length_mm"] = float(strip_length_mm)
        return cls(**d)


@dataclass(frozen=True)
class ScanQuality:
    """The measures of one scan (see the module docstring for each unit)."""

    site: str
    n_points: int
    dropout_pct: float
    replaced_pct: float
    height_step_mm: float
    height_step_source: str
    spikes_found: int
    tilt_deg: float
    tilt_x_mm_per_m: float
    tilt_y_mm_per_m: float
    usable_length_mm: float
    scan_length_mm: float
    relief_mm: float = float("nan")

    def to_dict(self) -> dict:
        return asdict(self)


def plane_slopes(surface: Surface) -> tuple[float, float]:
    """Slopes (mm/mm) along x and y of the least-squares plane ``z = a x + b y + c`` through the valid points."""
    h = surface.heights
    ok = np.isfinite(h)
    if ok.sum() < 3:
        return float("nan"), float("nan")
    rows, cols = h.shape
    # the coordinates of the valid points in row-major order (as from np.nonzero, without the index arrays)
    x = np.broadcast_to(np.arange(cols) * surface.dx, h.shape)[ok]
    y = np.broadcast_to((np.arange(rows) * surface.dy)[:, None], h.shape)[ok]
    z = h[ok]
    x -= x.mean()  # in place: x, y, z are fresh arrays (boolean indexing copies)
    y -= y.mean()
    z -= z.mean()
    xy = x @ y
    a = np.array([[x @ x, xy], [xy, y @ y]])
    rhs = np.array([x @ z, y @ z])
    try:
        sx, sy = np.linalg.solve(a, rhs)
    except np.linalg.LinAlgError:  # the valid points lie on one line
        return float("nan"), float("nan")
    return float(sx), float(sy)


#: the percentiles (%) of the heights about the plane whose distance is the relief (:func:`relief_mm`)
RELIEF_PERCENTILES = (0.5, 99.5)


def relief_mm(surface: Surface, slopes: tuple[float, float] | None = None) -> float:
    """The relief of a scan, mm: the distance between the 0.5th and 99.5th percentiles (:data:`RELIEF_PERCENTILES`)
    of its valid heights about the least-squares plane (``slopes`` from :func:`plane_slopes`, computed when not
    given; the heights as they are when the valid points lie on one line). NaN without valid points."""
    h = surface.heights
    ok = np.isfinite(h)
    if not ok.any():
        return float("nan")
    sx, sy = slopes if slopes is not None else plane_slopes(surface)
    if np.isfinite(sx) and np.isfinite(sy):
        x = np.arange(h.shape[1]) * surface.dx
        y = np.arange(h.shape[0]) * surface.dy
        r = h - sx * x[None, :]
        r -= sy * y[:, None]  # (h - sx x) - sy y, in place
        r = r[ok]
    else:
        r = h[ok]
    lo, hi = np.percentile(r, RELIEF_PERCENTILES)
    return float(hi - lo)


def relief_breach(relief: float, opt: QualityOptions) -> str | None:
    """``"relief_mm <value> mm below|above the limit <limit> mm (...)"`` when ``relief`` (mm) is outside the
    limits of ``opt``, else None (NaN: no valid points, left to the other checks)."""
    if relief < opt.min_relief_mm:
        return (
            f"relief_mm {relief:.3g} mm below the limit min_relief_mm {opt.min_relief_mm:g} mm (no pavement is "
            "this flat: one height everywhere, or heights in m read as mm)"
        )
    if relief > opt.max_relief_mm:
        return (
            f"relief_mm {relief:.4g} mm above the limit max_relief_mm {opt.max_relief_mm:g} mm (no pavement "
            "texture spans this much: heights in um read as mm, or not a pavement scan)"
        )
    return None


def usable_length_mm(surface: Surface, min_column_valid_pct: float = 90.0) -> float:
    """Longest run of consecutive columns with at least ``min_column_valid_pct`` % valid points, as an extent
    along x in mm: ``(n - 1) * dx`` for a run of n columns (0 for none or one)."""
    good = np.isfinite(surface.heights).mean(axis=0) * 100.0 >= min_column_valid_pct
    if not good.any():
        return 0.0
    edges = np.diff(np.r_[0, good.astype(np.int8), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    return float((runs.max() - 1) * surface.dx)


def scan_quality(
    site: str,
    surface: Surface,
    replaced: np.ndarray,
    step_mm: float,
    step_source: str,
    min_column_valid_pct: float = 90.0,
) -> ScanQuality:
    """The quality measures of ``surface`` (the scan as the despeckle saw it) given the despeckle's mask of
    replaced points ``replaced`` and the height step it used (:class:`~skidsim.texture.despeckle.DespeckleResult`)."""
    if replaced.shape != surface.shape:
        raise ValueError(f"scan_quality: {site}: replaced mask {replaced.shape} is not the scan's {surface.shape}")
    n = surface.heights.size
    from scipy import ndimage  # here: skidsim.validate imports this module and needs no scipy

    _, n_spikes = ndimage.label(replaced, structure=np.ones((3, 3), dtype=bool))
    sx, sy = plane_slopes(surface)
    return ScanQuality(
        site=site,
        n_points=int(n),
        dropout_pct=100.0 * surface.invalid_fraction,
        replaced_pct=100.0 * float(replaced.sum()) / n,
        height_step_mm=float(step_mm),
        height_step_source=step_source,
        spikes_found=int(n_spikes),
        tilt_deg=float(np.degrees(np.arctan(np.hypot(sx, sy)))),
        tilt_x_mm_per_m=1000.0 * sx,
        tilt_y_mm_per_m=1000.0 * sy,
        usable_length_mm=usable_length_mm(surface, min_column_valid_pct),
        scan_length_mm=surface.width_mm,
        relief_mm=relief_mm(surface, (sx, sy)),
    )


def breaches(q: ScanQuality, opt: QualityOptions) -> list[str]:
    """One line per limit ``q`` breaks: ``"<measure> <value> <unit> above|below the limit <limit>"``."""
    out = []
    if q.dropout_pct > opt.max_dropout_pct:
        out.append(f"dropout_pct {q.dropout_pct:.3g} % above the limit {opt.max_dropout_pct:g} %")
    if q.replaced_pct > opt.max_replaced_pct:
        out.append(f"replaced_pct {q.replaced_pct:.3g} % above the limit {opt.max_replaced_pct:g} %")
    if not q.tilt_deg <= opt.max_tilt_deg:
        out.append(f"tilt_deg {q.tilt_deg:.3g} deg above the limit {opt.max_tilt_deg:g} deg")
    if opt.min_usable_length_mm is not None and q.usable_length_mm < opt.min_usable_length_mm:
        out.append(
            f"usable_length_mm {q.usable_length_mm:.4g} mm below the limit {opt.min_usable_length_mm:g} mm "
            f"(columns with >= {opt.min_column_valid_pct:g} % valid points)"
        )
    relief = relief_breach(q.relief_mm, opt)
    if relief:
        out.append(relief)
    return out


def check_quality(q: ScanQuality, opt: QualityOptions, logger: logging.Logger | None = None) -> list[str]:
    """Apply the limits: returns the breaches (empty when the scan is within them). With ``action: warn`` each
    breach is logged as a WARNING; with ``action: stop`` the first call with a breach raises
    :class:`ScanQualityError` naming the site, every measure, value and limit."""
    found = breaches(q, opt)
    if not found:
        return found
    if opt.action == "stop":
        raise ScanQualityError(
            f"scan quality of site {q.site!r}: "
            + "; ".join(found)
            + " (quality.action: stop; raise the limit in config quality: or set action: warn)"
        )
    lg = logger or log
    for b in found:
        lg.warning("SCAN QUALITY site %s: %s", q.site, b)
    return found


def quality_table(measures: list[ScanQuality], opt: QualityOptions, logger: logging.Logger | None = None):
    """The campaign table (pandas DataFrame, one row per site, the columns of :class:`ScanQuality` plus
    ``flags`` (the breaches joined by "; ") and ``status`` ("ok" / "flagged")). With ``action: warn`` every
    breach is logged as a WARNING; with ``action: stop`` :class:`ScanQualityError` lists every flagged site."""
    import pandas as pd  # only here: the per-site despeckle step starts without pandas

    rows, stops = [], []
    for q in measures:
        found = breaches(q, opt)
        rows.append({**q.to_dict(), "flags": "; ".join(found), "status": "flagged" if found else "ok"})
        if found:
            stops.append(f"site {q.site!r}: " + "; ".join(found))
            if opt.action == "warn":
                for b in found:
                    (logger or log).warning("SCAN QUALITY site %s: %s", q.site, b)
    if stops and opt.action == "stop":
        raise ScanQualityError(
            f"scan quality: {len(stops)} of {len(measures)} sites beyond the limits: "
            + " | ".join(stops)
            + " (quality.action: stop; raise the limits in config quality: "
            "or set action: warn)"
        )
    columns = [f.name for f in fields(ScanQuality)] + ["flags", "status"]
    return pd.DataFrame(rows, columns=columns)
