"""Mean profile depth (MPD) per ISO 13473-1:2019 of line profiles.

One procedure (:func:`profile_segments`) serves the profiles of a laser profilometer (read by
:mod:`skidsim.profiles`) and the rows of an areal scan (:func:`mean_profile_depth`). Its conventions are those of
captif-slp 0.22 (MIT), the reference implementation (docs/texture.md), per profile of heights z (mm) at increasing
distances x (mm):

0. Reference plates (``detect_plates``, off by default): heights above ``plate_threshold_mm`` (30 mm; missing
   heights take the last valid height for this test) are plates. The profile starts ``plate_buffer_mm`` (2 mm)
   after the last plate edge in its first half (by sample count) and ends 2 mm before the first plate edge in its
   second half; distances are then counted from the new start.
1. Dropouts (NaN) are flagged on the original samples; then filled: held at the first / last valid height at the
   ends, linear in distance inside.
2. Resampling by **bin mean** to the resampled spacing s: 0.5 mm for profiles sampled at 0.5 mm or finer; a
   profile sampled more coarsely, up to the 1.0 mm ISO 13473-1:2019 allows, is evaluated at its own spacing (its
   mean distance step, rounded to 1e-6 mm and at most 1.0 mm; captif-slp's ``target_sample_spacing_mm``); the
   option ``resample_mm`` sets s (at most 1.0 mm, not finer than the profile's mean step). A profile whose mean
   step exceeds 1.0 mm by more than 2 % is an error (:class:`SpacingError`). A sample at x goes to bin
   k = ceil(x / s) (x = 0 joins bin 1); bin k sits at x = s k; bin means are rounded to 1e-6 mm. A profile whose
   mean step is already s (to 1e-9 relative) is used as it is. (Point sampling instead of bin means moves MPD by
   about +1.6 % at 0.5 mm.)
3. Spikes: a step ``|z[k+1] - z[k]| >= spike_alpha * s`` (s: mean resampled spacing, alpha = 3: 1.5 mm at 0.5 mm,
   3 mm at 1.0 mm) marks both samples as spikes; they are removed and refilled as in 1.
3a. Evaluation lengths (``evaluation_length_m``, off by default; captif-slp's option of the same name for network
   runs): a 2nd-order Butterworth high-pass at ``highpass_mm`` (174.2 mm, captif-slp's cut-off) applied zero-phase
   to the whole resampled profile, and **no** per-segment slope removal in step 5; every segment belongs to the
   evaluation length ``(floor(x0 / E) + 1) * E`` (m), x0 the first original distance in the segment, E the length.
4. Low-pass: 2nd-order Butterworth (scipy ``butter``), cut-off wavelength ``lowpass_mm`` (2.4 mm), applied
   zero-phase (``sosfiltfilt``) to the whole resampled profile; the filter is designed for the resampled spacing.
5. Segments of ``segment_mm`` (100 mm) in absolute distance: (0, L], (L, 2L], ... (the first closed at 0;
   negative distances belong to none). A segment holding fewer than 90 % of L / s resampled samples is not
   evaluated (so a remainder of 90 mm or more counts). Per segment the least-squares line is removed (not with
   evaluation lengths) and the result rounded to 1e-6 mm; MSD = (max of the first half + max of the second half)
   / 2 - segment mean, the halves split at n // 2.
6. A segment is invalid if more than ``max_dropout_pct`` (10 %) of its original samples were dropouts or more than
   ``max_spike_pct`` (5 %) of its resampled samples were spikes. MPD = mean MSD of the valid segments, ``sd_mm``
   their sample SD (ddof = 1). ETD = 1.1 MPD (ISO 13473-1:2019; the 1997 edition used 0.2 + 0.8 MPD). With
   evaluation lengths :func:`evaluation_lengths` gives the MPD of each (valid when at least half its segments are).

Long runs: the segments of a profile are contiguous slices of the sorted resampled samples, so the work is linear
in the number of samples (a 1 km profile at 1 mm, 10^6 samples: 1.3 s of CPU; docs/texture.md).

A profile shorter than one evaluable segment gives no segment; the MPD is then NaN ("not available") and one
warning is logged.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from skidsim.errors import ConfigError, SkidsimError
from skidsim.surface import Surface

log = logging.getLogger("skidsim")

#: a segment is evaluated when it holds at least this share of its nominal number of resampled samples
MIN_SEGMENT_COVERAGE = 0.9
#: resampled spacing (mm) of profiles sampled at 0.5 mm or finer (ISO 13473-1:2019)
STANDARD_SPACING_MM = 0.5
#: coarsest sample spacing (mm) ISO 13473-1:2019 allows; coarser profiles are an error
MAX_SPACING_MM = 1.0
#: a profile's mean distance step may exceed the resampled spacing by this share (recorded distances jitter)
SPACING_TOLERANCE = 0.02
#: cut-off wavelength (mm) of the high-pass of evaluation lengths (captif-slp's HIGHPASS_FILTER_CUTOFF_WAVELENGTH_MM)
HIGHPASS_MM = 174.2


class SpacingError(SkidsimError):
    """A profile sampled more coarsely than ISO 13473-1 allows, or a resampling step finer than the profile's
    sampling. ``expected`` and ``got`` are kept for messages that name the file and the column."""

    def __init__(self, expected: str, got: str):
        self.expected, self.got = expected, got
        super().__init__(f"distances: expected {expected}, got {got}")


@dataclass(frozen=True)
class MPDOptions:
    """Options of the MPD procedure (module docstring); lengths in mm (``evaluation_length_m`` in m), shares in %.

    ``resample_mm``: the resampled spacing s; None (default): 0.5 mm, or the profile's own spacing when it is
    coarser (at most 1.0 mm). ``evaluation_length_m``: None (default, spot measurement) or captif-slp's
    evaluation length of network runs (step 3a).
    """

    segment_mm: float = 100.0
    resample_mm: float | None = None
    lowpass_mm: float | None = 2.4
    spike_alpha: float = 3.0
    max_dropout_pct: float = 10.0
    max_spike_pct: float = 5.0
    detect_plates: bool = False
    plate_threshold_mm: float = 30.0
    plate_buffer_mm: float = 2.0
    evaluation_length_m: float | None = None
    highpass_mm: float = HIGHPASS_MM

    def __post_init__(self) -> None:
        for name in ("segment_mm", "spike_alpha", "plate_buffer_mm", "highpass_mm"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"MPD option {name}: expected a positive number, got {v!r}")
        if self.resample_mm is not None and not (
            np.isfinite(self.resample_mm) and 0 < self.resample_mm <= MAX_SPACING_MM
        ):
            raise ConfigError(
                f"MPD option resample_mm: expected null or a spacing in (0, {MAX_SPACING_MM:g}] mm "
                f"(ISO 13473-1:2019 allows at most {MAX_SPACING_MM:g} mm), got {self.resample_mm!r}"
            )
        v = self.evaluation_length_m
        if v is not None and not (np.isfinite(v) and v > 0):
            raise ConfigError(f"MPD option evaluation_length_m: expected null or a length > 0 m, got {v!r}")
        for name in ("max_dropout_pct", "max_spike_pct"):
            v = getattr(self, name)
            if not 0 <= v <= 100:
                raise ConfigError(f"MPD option {name}: expected a share in % from 0 to 100, got {v!r}")
        if not np.isfinite(self.plate_threshold_mm):
            raise ConfigError(
                f"MPD option plate_threshold_mm: expected a height in mm, got {self.plate_threshold_mm!r}"
            )
        step = self.resample_mm or STANDARD_SPACING_MM
        if self.segment_mm < 4 * step:
            raise ConfigError(
                f"MPD option segment_mm: expected at least 4 resampled samples ({4 * step:g} mm), "
                f"got {self.segment_mm!r}"
            )
        self.check_lowpass(self.resample_mm or STANDARD_SPACING_MM)

    def check_lowpass(self, step_mm: float) -> None:
        """The low-pass must lie below the Nyquist wavelength ``2 * step_mm`` of the resampled profile."""
        if self.lowpass_mm is not None and not self.lowpass_mm > 2 * step_mm:
            raise ConfigError(
                f"MPD option lowpass_mm: expected null or a wavelength above 2 x the resampled spacing "
                f"({2 * step_mm:g} mm), got {self.lowpass_mm!r}"
            )


def resampled_spacing_mm(distance_mm: np.ndarray, resample_mm: float | None = None) -> float:
    """The resampled spacing s (mm) of a profile at ``distance_mm`` (module docstring, step 2). Raises
    :class:`SpacingError` for a mean step above 1.0 mm (+2 %) or above an explicit ``resample_mm`` (+2 %)."""
    x = np.asarray(distance_mm, dtype=np.float64)
    step = float(np.diff(x).mean()) if len(x) > 1 else 0.0
    tol = 1.0 + SPACING_TOLERANCE
    if resample_mm is not None:
        if step > resample_mm * tol:
            raise SpacingError(
                f"a resampling step (resample_mm {resample_mm:g} mm) no finer than the profile's mean distance step; "
                f"leave it unset to evaluate at the profile's own spacing",
                f"mean step {step:.6g} mm",
            )
        return float(resample_mm)
    if step <= STANDARD_SPACING_MM * tol:
        return STANDARD_SPACING_MM
    if step <= MAX_SPACING_MM * tol:
        return min(round(step, 6), MAX_SPACING_MM)
    raise SpacingError(
        f"a mean distance step of at most {MAX_SPACING_MM:g} mm (the coarsest ISO 13473-1:2019 allows; "
        "distances in m or um read as mm give 1000 times too few or too many: state the unit)",
        f"mean step {step:.6g} mm",
    )


@dataclass(frozen=True)
class Segments:
    """Every evaluated segment of a set of profiles (one entry per segment).

    ``profile``: index of the profile; ``start_mm``/``end_mm``: the segment (start, end] in the input's distances
    (plate trimming undone); ``msd_mm``: mean segment depth (mm); ``dropout_pct``: dropouts among its original
    samples (%); ``spike_pct``: spikes among its resampled samples (%); ``valid``; ``evaluation_end_m``: end (m,
    from the profile's start after plate trimming) of the evaluation length holding the segment, NaN without
    evaluation lengths. Per profile: ``trim_start_mm``/``trim_end_mm``: where plate detection cut it (NaN: not cut).
    ``spacing_mm``: the resampled spacing used.
    """

    profile: np.ndarray
    start_mm: np.ndarray
    end_mm: np.ndarray
    msd_mm: np.ndarray
    dropout_pct: np.ndarray
    spike_pct: np.ndarray
    valid: np.ndarray
    trim_start_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    trim_end_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    evaluation_end_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    spacing_mm: float = STANDARD_SPACING_MM

    def to_frame(self):
        """The segments as a DataFrame (columns as the attributes, mm and %; ``evaluation_end_m`` only when
        evaluation lengths were used)."""
        import pandas as pd

        cols = {
            "profile": self.profile,
            "start_mm": self.start_mm,
            "end_mm": self.end_mm,
            "msd_mm": self.msd_mm,
            "dropout_pct": self.dropout_pct,
            "spike_pct": self.spike_pct,
            "valid": self.valid,
        }
        if self.evaluation_end_m.size and np.isfinite(self.evaluation_end_m).any():
            cols["evaluation_end_m"] = self.evaluation_end_m
        return pd.DataFrame(cols)


@dataclass(frozen=True)
class MPDResult:
    """MPD and its SD over segments (mm), segment counts, ETD = 1.1 MPD (mm), and the MSD of each valid segment.

    ``mpd_mm`` is NaN when no segment could be evaluated (profiles shorter than one segment) or none was valid.
    """

    mpd_mm: float
    sd_mm: float
    n_segments: int
    n_invalid_segments: int
    etd_mm: float
    msd_mm: np.ndarray


def _fill(z: np.ndarray, x: np.ndarray) -> None:
    """Fill NaNs of each row of ``z`` in place: held at the ends, linear in ``x`` inside; empty rows become 0."""
    for i in np.flatnonzero(np.isnan(z).any(axis=1)):
        ok = ~np.isnan(z[i])
        z[i, ~ok] = np.interp(x[~ok], x[ok], z[i, ok]) if ok.any() else 0.0


def _resample(z: np.ndarray, x: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Bin means at ``step`` (module docstring, step 2): ``(heights, positions)``."""
    if len(x) > 1 and abs(np.diff(x).mean() - step) <= 1e-9 * step:
        return z, x.copy()
    g = np.ceil(x / step)
    if g[0] == 0:
        g[0] = 1
    starts = np.flatnonzero(np.r_[True, g[1:] != g[:-1]])
    widths = np.diff(np.r_[starts, len(x)])
    return np.round(np.add.reduceat(z, starts, axis=1) / widths, 6), g[starts] * step


def _segment_index(x: np.ndarray, length: float) -> np.ndarray:
    """Segment of each distance: (0, L] -> 0, (L, 2L] -> 1, ...; 0 -> 0; negative -> -1."""
    s = np.ceil(x / length) - 1
    s[x == 0] = 0
    s[x < 0] = -1
    return s.astype(np.int64)


def find_plates(
    x: np.ndarray, z: np.ndarray, threshold_mm: float = 30.0, buffer_mm: float = 2.0
) -> tuple[float | None, float | None]:
    """Where reference plates end and begin (module docstring, step 0): ``(start_mm, end_mm)``, None where the
    profile has no plate edge in that half."""
    idx = np.where(np.isnan(z), 0, np.arange(len(z)))
    held = z[np.maximum.accumulate(idx)]  # forward-filled; leading NaNs stay NaN
    plate = np.nan_to_num(held, nan=-np.inf) > threshold_mm
    if not plate.any():
        return None, None
    edge = np.r_[False, plate[1:] != plate[:-1]]
    mid = int(np.ceil(len(z) / 2))
    first, second = np.flatnonzero(edge[:mid]), np.flatnonzero(edge[mid:])
    start = float(x[first[-1]] + buffer_mm) if first.size else None
    end = float(x[mid + second[0]] - buffer_mm) if second.size else None
    return start, end


def _block(z: np.ndarray, x: np.ndarray, o: MPDOptions, step: float, offset_mm: float = 0.0) -> list[tuple]:
    """Segments of the rows of ``z`` (profiles sharing distances ``x``) at resampled spacing ``step``: a list of
    per-segment tuples."""
    z = np.array(z, dtype=np.float64)
    drop = np.isnan(z)
    if drop.any():
        _fill(z, x)
    res, xr = _resample(z, x, step)
    del z
    seg_x, seg_r = _segment_index(x, o.segment_mm), _segment_index(xr, o.segment_mm)
    nominal = o.segment_mm / step
    ids, counts = np.unique(seg_r[seg_r >= 0], return_counts=True)
    ids = ids[counts / nominal >= MIN_SEGMENT_COVERAGE]
    if ids.size == 0:
        return []
    spike = np.zeros(res.shape, dtype=bool)
    if len(xr) > 1:
        jump = np.abs(np.diff(res, axis=1)) >= round(o.spike_alpha * np.diff(xr).mean(), 6)
        spike[:, 1:] |= jump
        spike[:, :-1] |= jump
        if spike.any():
            res[spike] = np.nan
            _fill(res, xr)
    # scipy.signal's butter and sosfiltfilt, the same bits without its 0.5 s import (skidsim.texture.iir)
    from .iir import butter2_sos, sosfiltfilt

    nyquist = 0.5 / step  # 1/mm
    if o.evaluation_length_m is not None:
        res = sosfiltfilt(butter2_sos((1.0 / o.highpass_mm) / nyquist, "high"), res)
    if o.lowpass_mm:
        res = sosfiltfilt(butter2_sos((1.0 / o.lowpass_mm) / nyquist, "low"), res)
    # segments are contiguous runs of the sorted segment indices
    r_lo, r_hi = np.searchsorted(seg_r, ids, "left"), np.searchsorted(seg_r, ids, "right")
    x_lo, x_hi = np.searchsorted(seg_x, ids, "left"), np.searchsorted(seg_x, ids, "right")
    out = []
    for s, a, b, xa, xb in zip(ids, r_lo, r_hi, x_lo, x_hi):
        n = int(b - a)
        zs = res[:, a:b]
        if o.evaluation_length_m is None:
            xm = xr[a:b] - xr[a:b].mean()
            slope = (zs * xm).sum(axis=1, keepdims=True) / (xm * xm).sum()
            lev = np.round(zs - zs.mean(axis=1, keepdims=True) - slope * xm, 6)
            end_m = np.nan
        else:
            lev = zs
            first = x[xa] if xb > xa else xr[a]
            end_m = (np.floor(first / (o.evaluation_length_m * 1000.0)) + 1) * o.evaluation_length_m
        half = n >> 1
        msd = 0.5 * (lev[:, :half].max(axis=1) + lev[:, half:].max(axis=1)) - lev.mean(axis=1)
        d_ratio = drop[:, xa:xb].mean(axis=1) if xb > xa else np.zeros(len(msd))
        s_ratio = spike[:, a:b].mean(axis=1)
        valid = (d_ratio <= o.max_dropout_pct / 100.0) & (s_ratio <= o.max_spike_pct / 100.0)
        for i in range(len(msd)):
            out.append(
                (
                    i,
                    offset_mm + s * o.segment_mm,
                    offset_mm + (s + 1) * o.segment_mm,
                    msd[i],
                    100.0 * d_ratio[i],
                    100.0 * s_ratio[i],
                    bool(valid[i]),
                    end_m,
                )
            )
    return out


def profile_segments(
    heights: np.ndarray, distance_mm: np.ndarray, options: MPDOptions | None = None, **kwargs
) -> Segments:
    """Evaluate the segments of one profile (1-D ``heights``) or of several sharing distances (2-D, one profile
    per row), heights and distances in mm, NaN heights are dropouts. ``options`` or keyword arguments: the fields
    of :class:`MPDOptions`. Raises :class:`SpacingError` for profiles sampled more coarsely than 1.0 mm."""
    o = options if options is not None else MPDOptions(**kwargs)
    z = np.atleast_2d(np.asarray(heights, dtype=np.float64))
    x = np.asarray(distance_mm, dtype=np.float64)
    if x.ndim != 1 or z.shape[1] != len(x):
        raise ValueError(f"profile_segments: {z.shape[1]} heights per profile but {x.shape} distances")
    if len(x) > 1 and not (np.diff(x) > 0).all():
        raise ValueError("profile_segments: distances must increase strictly")
    step = resampled_spacing_mm(x, o.resample_mm)
    o.check_lowpass(step)
    rows: list[tuple] = []
    trim = np.full((len(z), 2), np.nan)
    if not o.detect_plates:
        rows = _block(z, x, o, step)
    else:
        for i, zi in enumerate(z):
            start, end = find_plates(x, zi, o.plate_threshold_mm, o.plate_buffer_mm)
            keep = np.ones(len(x), dtype=bool)
            if end:
                keep &= x < end
                trim[i, 1] = end
            if start:
                keep &= x >= start
                trim[i, 0] = start
            off = start or 0.0
            if keep.sum() < 2:
                continue
            rows += [(i, *r[1:]) for r in _block(zi[keep][None, :], x[keep] - off, o, step, offset_mm=off)]
    rows.sort(key=lambda r: (r[0], r[1]))
    cols = list(zip(*rows)) if rows else [[]] * 8
    return Segments(
        profile=np.asarray(cols[0], dtype=np.int64),
        start_mm=np.asarray(cols[1], dtype=float),
        end_mm=np.asarray(cols[2], dtype=float),
        msd_mm=np.asarray(cols[3], dtype=float),
        dropout_pct=np.asarray(cols[4], dtype=float),
        spike_pct=np.asarray(cols[5], dtype=float),
        valid=np.asarray(cols[6], dtype=bool),
        trim_start_mm=trim[:, 0],
        trim_end_mm=trim[:, 1],
        evaluation_end_m=np.asarray(cols[7], dtype=float),
        spacing_mm=step,
    )


def summarise(
    segments: Segments,
    *,
    etd_factor: float = 1.1,
    name: str = "",
    profile_mm: float | None = None,
    segment_mm: float = 100.0,
) -> MPDResult:
    """MPD, SD, counts and ETD of evaluated segments; NaN MPD and one warning when no segment is valid
    (``profile_mm``: the profiles' length, for that warning)."""
    vals = segments.msd_mm[segments.valid]
    n_total = int(segments.msd_mm.size)
    who = f"{name}: " if name else ""
    if n_total == 0:
        length = f"profiles are {profile_mm:.2f} mm long, " if profile_mm is not None else ""
        log.warning(
            "%sMPD not available: %sshorter than one %g mm segment (at least %g mm needed)",
            who,
            length,
            segment_mm,
            MIN_SEGMENT_COVERAGE * segment_mm,
        )
    elif vals.size == 0:
        log.warning("%sMPD not available: all %d segments are invalid (dropouts or spikes)", who, n_total)
    mpd = float(vals.mean()) if vals.size else np.nan
    sd = float(vals.std(ddof=1)) if vals.size > 1 else np.nan
    return MPDResult(
        mpd_mm=mpd,
        sd_mm=sd,
        n_segments=n_total,
        n_invalid_segments=int(n_total - vals.size),
        etd_mm=etd_factor * mpd,
        msd_mm=vals,
    )


def evaluation_lengths(segments: Segments):
    """MPD per evaluation length (step 3a) as a DataFrame, one row per (profile, evaluation length):
    ``profile``, ``end_m`` (its end, m), ``mpd_mm`` and ``sd_mm`` (mean and SD, ddof 1, of its valid segments'
    MSD), ``n_segments``, ``n_valid``, ``valid_share`` (0-1) and ``is_valid`` (at least half its segments valid,
    as captif-slp). Raises ValueError for segments evaluated without evaluation lengths."""
    import pandas as pd

    if segments.msd_mm.size and not np.isfinite(segments.evaluation_end_m).all():
        raise ValueError("evaluation_lengths: the segments were evaluated without evaluation_length_m")
    frame = pd.DataFrame(
        {
            "profile": segments.profile,
            "end_m": segments.evaluation_end_m,
            "msd": np.where(segments.valid, segments.msd_mm, np.nan),
            "valid": segments.valid,
        }
    )
    g = frame.groupby(["profile", "end_m"], sort=True)
    out = pd.DataFrame(
        {
            "mpd_mm": g["msd"].mean(),
            "sd_mm": g["msd"].std(ddof=1),
            "n_segments": g["valid"].size(),
            "n_valid": g["valid"].sum(),
        }
    ).reset_index()
    out["valid_share"] = out["n_valid"] / out["n_segments"]
    out["is_valid"] = out["valid_share"] >= 0.5
    return out


def mean_profile_depth(
    surface: Surface,
    *,
    axis: int = 1,
    segment_mm: float = 100.0,
    resample_mm: float | None = None,
    lowpass_mm: float | None = 2.4,
    spike_alpha: float = 3.0,
    max_dropout_pct: float = 10.0,
    max_spike_pct: float = 5.0,
    detect_plates: bool = False,
    plate_threshold_mm: float = 30.0,
    etd_factor: float = 1.1,
) -> MPDResult:
    """MPD (mm) of the profiles of ``surface`` along ``axis`` (1: rows along x, at x = j dx). See the module
    docstring; NaN with one warning when the profiles are shorter than one evaluable segment."""
    if axis not in (0, 1):
        raise ValueError(f"mean_profile_depth: axis must be 0 or 1, got {axis!r}")
    h = surface.heights if axis == 1 else surface.heights.T
    step = surface.dx if axis == 1 else surface.dy
    o = MPDOptions(
        segment_mm=segment_mm,
        resample_mm=resample_mm,
        lowpass_mm=lowpass_mm,
        spike_alpha=spike_alpha,
        max_dropout_pct=max_dropout_pct,
        max_spike_pct=max_spike_pct,
        detect_plates=detect_plates,
        plate_threshold_mm=plate_threshold_mm,
    )
    x = np.arange(h.shape[1]) * step
    segs = profile_segments(h, x, o)
    return summarise(segs, etd_factor=etd_factor, name=surface.name, profile_mm=float(x[-1]), segment_mm=segment_mm)
