"""The campaign design: the site table of the default campaign (no surfaces), cheap and deterministic.

One row per site (``<section>-<k>``) in the listed section order with study Table 1's metadata, the stations along
the section, the day's test order and times, and the pavement temperature of a diurnal cycle rescaled onto the
configured range. The design draws from ``numpy.random.SeedSequence([seed, 0x5D5])`` (the sites' own streams are
:mod:`.surface`'s).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .config import resolve_config

METADATA_COLUMNS = (
    "section_type",
    "mix",
    "comment",
    "binder",
    "aggregate_combination",
    "station_ft",
    "test_order",
    "test_time",
    "test_date",
)


def _minutes(hhmm: str) -> float:
    h, m = str(hhmm).split(":")
    return 60.0 * int(h) + float(m)


def design_campaign(cfg: dict | None = None) -> pd.DataFrame:
    """The site table of the campaign (no surfaces): one row per site, deterministic from ``cfg['seed']``.

    Columns: ``site`` (``<section>-<k>``), ``section``, ``temperature_c`` (pavement surface temperature, deg C)
    and metadata: ``section_type``, ``mix``, ``comment``, ``binder``, ``aggregate_combination`` (study Table 1),
    ``station_ft`` (from the section start: 100-ft intervals, 300-ft on control sections), ``test_order``
    (1..n, the day's order), ``test_time`` (HH:MM), ``test_date``.

    Temperatures follow a diurnal cycle over the test times (peak at ``temperature_peak_time``) plus a per-site
    sun/shade scatter, then are rescaled linearly onto ``temperature_range_c`` (study: 11.8-18.9 deg C).
    """
    c = resolve_config(cfg)
    rng = np.random.default_rng(np.random.SeedSequence([int(c["seed"]), 0x5D5]))
    sections = list(c["sections"])
    order = list(rng.permutation(len(sections))) if c["visit_order"] == "shuffled" else list(range(len(sections)))
    n_per = int(c["sites_per_section"])
    rows = []
    t = _minutes(c["start_time"])
    k = 0
    for oi, si in enumerate(order):
        sec = sections[si]
        d = c["section_designs"][sec]
        if oi > 0:
            t += float(c["minutes_between_sections"])
        interval = (
            float(c["station_interval_ft"][d["section_type"]])
            if isinstance(c["station_interval_ft"], dict)
            else float(c["station_interval_ft"])
        )
        for j in range(n_per):
            k += 1
            rows.append(
                {
                    "site": f"{sec}-{j + 1}",
                    "section": sec,
                    "section_type": d["section_type"],
                    "mix": d["mix"],
                    "comment": d["comment"],
                    "binder": d["binder"],
                    "aggregate_combination": int(d["aggregate_combination"]),
                    "station_ft": int(round(j * interval)),
                    "test_order": k,
                    "_t": t,
                }
            )
            t += float(c["minutes_per_site"])
    df = pd.DataFrame(rows)
    tpk = _minutes(c["temperature_peak_time"])
    diurnal = np.cos(2.0 * np.pi * (df["_t"].to_numpy() - tpk) / (24 * 60.0))
    raw = diurnal + rng.normal(0.0, float(c["temperature_site_sd_c"]) / 3.5, len(df))
    lo, hi = (float(x) for x in c["temperature_range_c"])
    span = raw.max() - raw.min()
    scaled = lo + (raw - raw.min()) / span * (hi - lo) if span > 0 else np.full(len(df), 0.5 * (lo + hi))
    df["temperature_c"] = np.round(scaled, 1)
    df["test_time"] = [f"{int(m // 60):02d}:{int(m % 60):02d}" for m in df["_t"]]
    df["test_date"] = str(c["test_date"])
    df = df.drop(columns="_t")
    # table order: the listed section order, sites by station (test_order keeps the day's order)
    df["_s"] = df["section"].map({s: i for i, s in enumerate(sections)})
    df = df.sort_values(["_s", "station_ft"], kind="stable").drop(columns="_s").reset_index(drop=True)
    cols = ["site", "section", "temperature_c", *METADATA_COLUMNS]
    return df[cols]
