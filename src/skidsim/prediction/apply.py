"""A model file applied to texture rows: the DFT at the model's speeds with CV+ intervals, the IFI (ASTM E1960),
the distance to the training domain and the flags (:func:`predict_rows`).

Per scan and speed: ``dft`` (the chosen model fitted on all training sites, friction), ``dft_lo``/``dft_hi`` (the
CV+ interval at ``level``, :mod:`.intervals`), ``baseline_dft`` (``ols2@dft``), ``distance`` and ``threshold``
(:mod:`.domain`), ``extrapolation`` (distance beyond the threshold), ``status`` and ``reason``. The interval is
**withheld** (NaN) for an extrapolation: the CV+ interval is calibrated on sites like the training sites, and
nothing measures how wide it should be elsewhere; the point prediction is kept and flagged.

IFI per scan (:mod:`skidsim.ifi`): ``Sp = 14.2 + 89.7 MPD`` (km/h) from the scan's own MPD (a measurement of the
scan, not a prediction, so it carries no prediction interval), ``FR60 = DFT20 exp(-40 / Sp)`` and
``F60 = 0.081 + 0.732 FR60`` from the predicted DFT at 20 km/h; F60 is increasing in DFT20, so the DFT20 interval
maps onto an F60 interval with the same coverage.

Scan quality (the model's ``quality`` limits): a scan beyond a limit gets ``status`` ``flagged`` (``action:
warn``) with the breaches in ``reason``, or ``refused`` (``action: stop``): no prediction at all.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skidsim import ifi
from skidsim.errors import InputError
from skidsim.regression.design import TEMPERATURE_COLUMN

from .model_file import PredictionModel

DFT_COLUMNS = [
    "scan", "speed_kmh", "dft", "dft_lo", "dft_hi", "extrapolation", "baseline_dft", "distance", "threshold",
    "level", "model", "status", "reason",
]  # fmt: skip
IFI_COLUMNS = [
    "scan", "mpd_mm", "sp_kmh", "dft20", "dft20_lo", "dft20_hi", "fr60", "f60", "f60_lo", "f60_hi",
    "extrapolation", "status", "reason",
]  # fmt: skip


def check_features(model: PredictionModel, X: pd.DataFrame, source="texture rows") -> None:
    """InputError when ``X`` lacks a feature of the chosen model (``temperature_c`` in deg C named with how to
    give it)."""
    for part in (model.chosen, model.baseline):
        for c in part.map.features:
            if c == TEMPERATURE_COLUMN and (c not in X.columns or X[c].isna().any()):
                bad = "every scan" if c not in X.columns else str(X.index[X[c].isna()][0])
                raise InputError(
                    source,
                    f"the temperature (deg C) of {bad}: model {part.name} uses temperature_c",
                    column=TEMPERATURE_COLUMN,
                    hint="give --temperature-c or --sites with a temperature_c column",
                )
            if c not in X.columns:
                raise InputError(source, f"the texture feature {c} of model {part.name}", column=c)


def predict_rows(
    model: PredictionModel, X: pd.DataFrame, level: float = 0.9, breaches: dict | None = None
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The DFT table (one row per scan and speed, :data:`DFT_COLUMNS`) and the IFI table (one row per scan,
    :data:`IFI_COLUMNS`) of the texture rows ``X`` (indexed by scan). ``breaches``: scan -> quality breaches."""
    breaches = breaches or {}
    check_features(model, X)
    part = model.chosen
    stop = model.quality.get("action") == "stop"
    P = part.map.predict(X).to_numpy(dtype=float)
    B = model.baseline.map.predict(X).to_numpy(dtype=float)
    lo, hi = part.intervals.interval(X, level)
    T = part.map.transformed(X)
    Td = T[:, [part.map.features.index(c) for c in part.domain.features]]
    dist = part.domain.distance(Td)
    out_range = part.domain.out_of_range(X, Td)
    far = part.domain.farthest(Td)
    rows, ifis = [], []
    speeds = np.asarray(model.speeds_kmh, dtype=float)
    for i, scan in enumerate(X.index.astype(str)):
        ext = bool(dist[i] > part.domain.threshold)
        reasons = []
        found = list(breaches.get(scan, ()))
        status = "refused" if (found and stop) else "flagged" if found or ext else "ok"
        if found:
            reasons.append("scan quality: " + "; ".join(found))
        if ext:
            named = out_range[i] or ["no feature out of its range; farthest: " + ", ".join(far[i])]
            reasons.append(
                f"extrapolation: distance {dist[i]:.2f} > {part.domain.threshold:.2f} (interval withheld); "
                + "; ".join(named)
            )
        reason = " | ".join(reasons)
        p, b, lo_i, hi_i = P[i].copy(), B[i].copy(), lo[i].copy(), hi[i].copy()
        if ext:
            lo_i[:], hi_i[:] = np.nan, np.nan
        if status == "refused":
            p[:], b[:], lo_i[:], hi_i[:] = np.nan, np.nan, np.nan, np.nan
        for j, v in enumerate(speeds):
            rows.append(
                [scan, float(v), p[j], lo_i[j], hi_i[j], ext, b[j], float(dist[i]), part.domain.threshold,
                 float(level), part.name, status, reason]
            )  # fmt: skip
        ifis.append(_ifi_row(scan, X, speeds, p, lo_i, hi_i, ext, status, reason))
    return pd.DataFrame(rows, columns=DFT_COLUMNS), pd.DataFrame(ifis, columns=IFI_COLUMNS)


def _ifi_row(scan, X, speeds, p, lo, hi, ext, status, reason) -> list:
    mpd = float(X.loc[scan, "profile_MPD"]) if "profile_MPD" in X.columns else float("nan")
    at20 = np.flatnonzero(np.isclose(speeds, ifi.DFT_REFERENCE_SPEED_KMH))
    d20, d20lo, d20hi = (p[at20[0]], lo[at20[0]], hi[at20[0]]) if len(at20) else (np.nan, np.nan, np.nan)
    sp = float(ifi.speed_constant_kmh(mpd))
    fr, frlo, frhi = (float(ifi.fr60(v, sp)) for v in (d20, d20lo, d20hi))
    f, flo, fhi = (float(ifi.f60(v)) for v in (fr, frlo, frhi))
    return [scan, mpd, sp, d20, d20lo, d20hi, fr, f, flo, fhi, ext, status, reason]


def summary_lines(dft: pd.DataFrame, ifi_table: pd.DataFrame) -> list[str]:
    """One printed line per scan: DFT at the slowest and fastest speed with intervals, F60, Sp, status."""
    out = []
    for scan, t in dft.groupby("scan", sort=False):
        r = ifi_table[ifi_table["scan"] == scan].iloc[0]
        a, b = t.iloc[0], t.iloc[-1]

        def iv(v, lo, hi):
            return f"{v:.3f} " + ("(no interval)" if np.isnan(lo) else f"[{lo:.3f}, {hi:.3f}]")

        line = (
            f"{scan}: DFT{a['speed_kmh']:g} {iv(a['dft'], a['dft_lo'], a['dft_hi'])}, DFT{b['speed_kmh']:g} "
            f"{iv(b['dft'], b['dft_lo'], b['dft_hi'])}, F60 {iv(r['f60'], r['f60_lo'], r['f60_hi'])}, "
            f"Sp {r['sp_kmh']:.1f} km/h; {a['status']}"
        )
        if a["reason"]:
            line += f" ({a['reason']})"
        out.append(line)
    return out
