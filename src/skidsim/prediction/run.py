"""``skidsim predict`` and the workflow's ``predict_scans`` rule in one call: :func:`predict_scans` (scans through
the model file's texture pipeline, then :func:`~.apply.predict_rows`) and :func:`write_predictions`."""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.atomic import atomic_path
from skidsim.errors import InputError, SkidsimError
from skidsim.regression.design import TEMPERATURE_COLUMN

from .apply import DFT_COLUMNS, IFI_COLUMNS, predict_rows
from .intervals import check_level
from .model_file import PredictionModel
from .scan import scan_features

log = logging.getLogger("skidsim")
#: Scan file suffixes :func:`scan_paths` takes from a directory.
SCAN_SUFFIXES = (".x3p", ".txt", ".asc", ".csv", ".dat")


def scan_paths(paths) -> list[Path]:
    """The scan files of ``paths``: files as given, directories expanded to their scan files (sorted)."""
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in SCAN_SUFFIXES)
            if not found:
                raise InputError(p, f"scan files ({', '.join(SCAN_SUFFIXES)}) in the directory", got="none")
            out += found
        else:
            out.append(p)
    names = [p.stem for p in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(
            out[names.index(dup[0])], "one scan per name (the scan id is the file name's stem)", got=dup[0]
        )
    return out


def _temperatures(names: list[str], temperature_c: float | None, sites_csv) -> dict:
    """Temperature (deg C) per scan from ``sites_csv`` (site, temperature_c) or one value for all."""
    if sites_csv is None:
        return dict.fromkeys(names, np.nan if temperature_c is None else float(temperature_c))
    t = pd.read_csv(sites_csv)
    for c in ("site", TEMPERATURE_COLUMN):
        if c not in t.columns:
            raise InputError(sites_csv, f"a '{c}' column", column=c, got=list(t.columns))
    m = dict(zip(t["site"].astype(str), pd.to_numeric(t[TEMPERATURE_COLUMN], errors="coerce")))
    return {n: m.get(n, np.nan if temperature_c is None else float(temperature_c)) for n in names}


def predict_scans(
    model: PredictionModel,
    paths,
    level: float = 0.9,
    *,
    jobs: int = 1,
    temperature_c: float | None = None,
    sites_csv=None,
    progress=None,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The DFT and IFI tables (:func:`~.apply.predict_rows`) of the scan files ``paths`` (files or directories):
    each scan through the model file's texture pipeline (``jobs`` scans at a time); a scan that cannot be read is
    ``refused`` with the error as its reason. ``temperature_c`` (deg C) or ``sites_csv`` (site, temperature_c)
    give the temperature when the model uses it. ``progress(done)`` is called after each scan."""
    level = check_level(level)
    files = scan_paths(paths)
    tex, qual = model.texture_options, model.quality_options

    def one(p):
        try:
            return scan_features(p, tex, qual)
        except (SkidsimError, ValueError, OSError) as e:
            return e

    results, done = [], 0
    with ThreadPoolExecutor(max_workers=max(1, int(jobs))) as pool:
        for r in pool.map(one, files):
            results.append(r)
            done += 1
            if progress is not None:
                progress(done)
    good = [r for r in results if not isinstance(r, Exception)]
    temps = _temperatures([r.site for r in good], temperature_c, sites_csv)
    X = pd.DataFrame([r.features for r in good], index=pd.Index([r.site for r in good], name="scan"))
    X[TEMPERATURE_COLUMN] = [temps[s] for s in X.index]
    if not model_uses_temperature(model):
        X = X.drop(columns=TEMPERATURE_COLUMN)
    dft, ifi = predict_rows(model, X, level, {r.site: r.breaches for r in good}) if good else (None, None)
    bad_dft, bad_ifi = [], []
    for p, r in zip(files, results):
        if isinstance(r, Exception):
            for v in model.speeds_kmh:
                bad_dft.append(
                    {
                        "scan": p.stem,
                        "speed_kmh": float(v),
                        "extrapolation": False,
                        "level": level,
                        "model": model.chosen.name,
                        "status": "refused",
                        "reason": f"scan unreadable: {r}",
                    }
                )
            bad_ifi.append(
                {"scan": p.stem, "extrapolation": False, "status": "refused", "reason": f"scan unreadable: {r}"}
            )
    frames_dft = [f for f in (dft, pd.DataFrame(bad_dft, columns=DFT_COLUMNS)) if f is not None and len(f)]
    frames_ifi = [f for f in (ifi, pd.DataFrame(bad_ifi, columns=IFI_COLUMNS)) if f is not None and len(f)]
    order = {p.stem: i for i, p in enumerate(files)}
    dft = pd.concat(frames_dft, ignore_index=True).sort_values("scan", key=lambda s: s.map(order), kind="stable")
    ifi = pd.concat(frames_ifi, ignore_index=True).sort_values("scan", key=lambda s: s.map(order), kind="stable")
    return dft.reset_index(drop=True), ifi.reset_index(drop=True)


def model_uses_temperature(model: PredictionModel) -> bool:
    return any(TEMPERATURE_COLUMN in p.map.features for p in (model.chosen, model.baseline))


def ifi_path(out) -> Path:
    """Where the IFI table goes beside the DFT table ``out``: ``<stem>_ifi.csv``."""
    out = Path(out)
    return out.with_name(out.stem + "_ifi.csv")


def write_predictions(dft: pd.DataFrame, ifi: pd.DataFrame, out) -> tuple[Path, Path]:
    """Write the DFT table to ``out`` and the IFI table beside it (:func:`ifi_path`), each atomically."""
    paths = (Path(out), ifi_path(out))
    for path, df in zip(paths, (dft, ifi)):
        with atomic_path(path) as tmp:
            df.to_csv(tmp, index=False)
    return paths
