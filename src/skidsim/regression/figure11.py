"""The study's Figure 11 as tables: predicted vs measured DFT of held-out sites per site and speed, and a summary.

* **Relative error** ``(predicted - measured) / measured``; "within 10 %" means ``|relative error| <= 0.10``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skidsim.errors import InputError

from .targets import keyed_values


def figure11_table(
    pred_dft: pd.DataFrame, measured_dft: pd.DataFrame, *, pred_file="predicted DFT", measured_file="measured DFT"
) -> pd.DataFrame:
    """Per site and speed: predicted, measured, relative error ``(pred - meas)/meas``, ``within_10pct``.

    Both tables are long form with ``site``, ``speed_kmh`` (km/h) and a value column (``mu``, or ``predicted``
    / ``measured``, or ``sn``). Every predicted (site, speed) must have a measurement, else InputError.
    """
    a, _ = keyed_values(pred_dft, ("predicted", "mu", "sn"), pred_file, "predicted", unique=False)
    b, mc = keyed_values(measured_dft, ("measured", "mu", "sn"), measured_file, "measured", unique=True)
    t = a.merge(b.drop(columns="speed_kmh"), on=["site", "key"], how="left")
    miss = t[t["measured"].isna()]
    if len(miss):
        raise InputError(
            measured_file,
            f"a measurement for site {miss['site'].iloc[0]} at {miss['speed_kmh'].iloc[0]:g} km/h",
            column=mc,
        )
    t["relative_error"] = (t["predicted"] - t["measured"]) / t["measured"]
    t["within_10pct"] = np.abs(t["relative_error"]) <= 0.10
    return t.drop(columns="key").sort_values(["speed_kmh", "site"]).reset_index(drop=True)


def figure11_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per speed (and ``speed_kmh`` NaN = all speeds): n, share within 10 %, mean |relative error|, RMSE."""

    def agg(t):
        e = t["predicted"] - t["measured"]
        return {
            "n": int(len(t)),
            "share_within_10pct": float(t["within_10pct"].mean()),
            "mean_abs_rel_error": float(np.abs(t["relative_error"]).mean()),
            "rmse": float(np.sqrt(np.mean(e**2))),
        }

    rows = [{"speed_kmh": float(v), **agg(t)} for v, t in table.groupby("speed_kmh", sort=True)]
    rows.append({"speed_kmh": float("nan"), **agg(table)})
    return pd.DataFrame(rows)
