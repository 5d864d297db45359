"""Texture and DFT tables of a campaign directory without the workflow (:func:`campaign_tables`): every scan
through :func:`~.scan.scan_features` and every DFT trace read at the speeds as the workflow's ingest does (local
linear fit within +- ``ingest.dft_smooth_window_kmh`` km/h, or linear interpolation). Used by the tests and the
benchmarks that measure coverage and transfer on generated campaigns."""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.dft import read_dft
from skidsim.errors import DftError, InputError
from skidsim.regression.design import feature_columns
from skidsim.regression.targets import dft_column
from skidsim.texture import TextureOptions
from skidsim.texture.quality import QualityOptions

from .scan import feature_table, scan_features

log = logging.getLogger("skidsim")


def campaign_tables(
    campaign,
    texture: TextureOptions,
    quality: QualityOptions,
    speeds_kmh=(20.0, 30.0, 40.0, 50.0, 60.0, 70.0),
    smooth_window_kmh: float | None = 5.0,
    workers: int = 1,
    skip_refused_dft: bool = False,
) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray, dict]:
    """``(X, D, sections, breaches)`` of the campaign directory ``campaign`` (sites.csv with site, section, scan,
    dft, temperature_c): the feature table (sites x features, as the workflow's design), the DFT table (sites x
    ``dft@<v>``, friction, at ``speeds_kmh`` km/h), the section of each site and each site's quality breaches.
    ``skip_refused_dft``: a site whose DFT file the reader refuses (:class:`~skidsim.errors.DftError`) is left out
    with a WARNING naming it, instead of stopping (the benchmarks on generated campaigns)."""
    root = Path(campaign)
    sites = pd.read_csv(root / "sites.csv")
    for c in ("site", "section", "scan", "dft"):
        if c not in sites.columns:
            raise InputError(root / "sites.csv", f"a '{c}' column", column=c, got=list(sites.columns))
    keep = []
    for i, path in enumerate(sites["dft"]):
        try:
            read_dft(root / path)
            keep.append(i)
        except DftError as e:
            if not skip_refused_dft:
                raise
            log.warning("site %s left out: %s", sites["site"].iloc[i], e)
    sites = sites.iloc[keep].reset_index(drop=True)
    names = sites["site"].astype(str).tolist()

    def one(i):
        return scan_features(root / sites["scan"].iloc[i], texture, quality, site=names[i])

    with ThreadPoolExecutor(max_workers=max(1, int(workers))) as pool:
        scans = list(pool.map(one, range(len(sites))))
    X = feature_table(scans, sites)
    X = X[feature_columns(X)]
    D = {}
    for site, path in zip(names, sites["dft"]):
        tr = read_dft(root / path)
        v = tr.at(speeds_kmh) if smooth_window_kmh is None else tr.smooth_at(speeds_kmh, smooth_window_kmh)
        D[site] = v
    D = pd.DataFrame.from_dict(D, orient="index", columns=[dft_column(v) for v in speeds_kmh])
    D.index.name = "site"
    return X, D.loc[X.index], sites["section"].astype(str).to_numpy(), {s.site: list(s.breaches) for s in scans}
