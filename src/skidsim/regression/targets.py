"""What the models predict besides the parameters: curve targets, DFT targets and the predicted DFT.

* **Curve targets** (``<model>@curve``): the calibrated laws' friction values at :data:`CURVE_ANCHORS_KMH`
  (:func:`curve_targets`), turned back into a law by :func:`law_from_curve`.
* **DFT targets** (``<model>@dft``): the measured DFT at the prediction speeds (:func:`dft_targets`), turned into the
  law handed to the FE by :func:`law_from_dft`.
* **Predicted DFT**: ``DFT(v) = g(site, v) * mu(v)`` with the exponential-decay law of the *predicted*
  parameters (speed in km/h converted to m/s), ``g`` the FE geometric factor (default 1). Predicted parameters are
  clipped to be physical (``mu_s, mu_k, alpha >= 0``) before the law is evaluated (:func:`predict_dft`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from skidsim.errors import InputError
from skidsim.friction import ExponentialDecay

from .design import PARAMETERS

#: DFT speeds of Figure 11, km/h.
DEFAULT_SPEEDS_KMH = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
#: Speeds (km/h) at which the ``@curve`` models' targets are the law's friction values: the DFT's standard
#: calibration speeds (the study's DFT20, DFT40, DFT60).
CURVE_ANCHORS_KMH = (20.0, 40.0, 60.0)


def curve_targets(Y: pd.DataFrame, anchors_kmh: Sequence[float] = CURVE_ANCHORS_KMH) -> pd.DataFrame:
    """The friction law of each row of ``Y`` (``mu_s``, ``mu_k``, ``alpha`` s/m) evaluated at ``anchors_kmh``
    (km/h): columns ``mu@<v>`` (dimensionless), indexed like ``Y``. The targets of the ``<model>@curve`` models."""
    for c in PARAMETERS:
        if c not in Y.columns:
            raise InputError(None, f"a '{c}' column in the friction table", column=c)
    out = {
        f"mu@{v:g}": [ExponentialDecay(r.mu_s, r.mu_k, r.alpha).mu_kmh(float(v)) for r in Y.itertuples()]
        for v in anchors_kmh
    }
    return pd.DataFrame(out, index=Y.index)


def law_from_curve(values, anchors_kmh: Sequence[float] = CURVE_ANCHORS_KMH) -> tuple[float, float, float]:
    """(mu_s, mu_k, alpha s/m) of the law closest to friction ``values`` at ``anchors_kmh`` (km/h), within the
    study's bounds (bounded least squares, :func:`skidsim.calibration.fit_exponential_decay`): exact wherever a
    bounded law passes through the values (three anchors: three equations, three unknowns), else the nearest."""
    from skidsim.calibration import fit_exponential_decay

    law, _ = fit_exponential_decay(np.asarray(anchors_kmh, dtype=float), np.asarray(values, dtype=float))
    return law.mu_s, law.mu_k, law.alpha


def dft_column(speed_kmh: float) -> str:
    """Name of the DFT target column at ``speed_kmh`` (km/h): ``"dft@20"``."""
    return f"dft@{float(speed_kmh):g}"


def dft_speeds(D: pd.DataFrame) -> list[float]:
    """Speeds (km/h) of the ``dft@<v>`` columns of ``D``, in column order."""
    out = []
    for c in D.columns:
        if not (isinstance(c, str) and c.startswith("dft@")):
            raise InputError(None, "DFT target columns named dft@<speed km/h>", column=str(c))
        out.append(float(c[4:]))
    return out


def dft_targets(
    Y: pd.DataFrame | None,
    *,
    measured_dft: pd.DataFrame | None = None,
    g: pd.DataFrame | None = None,
    speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH,
    sites=None,
    measured_file="measured DFT",
) -> pd.DataFrame:
    """The targets of the ``<model>@dft`` models: one row per site, columns ``dft@<v>`` (friction, dimensionless)
    at ``speeds_kmh`` (km/h). The measured DFT (long form site, speed_kmh, mu) when given, else ``g * mu(v)`` of
    the calibrated laws ``Y`` (the same reference as :func:`score_predictions`). ``sites``: the rows wanted
    (default: the index of ``Y``); every site needs a value at every speed, else InputError."""
    if sites is None:
        if Y is None:
            raise InputError(None, "the sites of the DFT targets", column="site")
        sites = list(Y.index.astype(str))
    sites = [str(s) for s in sites]
    if measured_dft is None:
        if Y is None:
            raise InputError(None, "a measured DFT or calibrated laws for the DFT targets", column="mu")
        long = predict_dft(Y.loc[sites], g, speeds_kmh)
    else:
        long = measured_dft
    t, mc = keyed_values(long, ("measured", "mu", "sn"), measured_file, "v", unique=True)
    wide = t.pivot(index="site", columns="key", values="v")
    out = {}
    for v in speeds_kmh:
        k = float(speed_key(v))
        col = wide[k] if k in wide.columns else pd.Series(dtype=float)
        vals = col.reindex(sites)
        if vals.isna().any():
            raise InputError(
                measured_file, f"a DFT value for site {vals.index[vals.isna()][0]} at {v:g} km/h", column=mc
            )
        out[dft_column(v)] = vals.to_numpy(dtype=float)
    return pd.DataFrame(out, index=pd.Index(sites, name="site"))


def g_values(g: pd.DataFrame, site: str, speeds: Sequence[float]) -> np.ndarray:
    """The geometric factors of ``site`` at ``speeds`` (km/h) from the g table (site, speed_kmh, g)."""
    t = g[g["site"].astype(str) == site]
    m = dict(zip(speed_key(t["speed_kmh"]).tolist(), t["g"].astype(float)))
    out = []
    for v in speeds:
        k = float(speed_key(v))
        if k not in m:
            raise InputError("g table", f"a geometric factor for site {site} at {v:g} km/h", column="g")
        out.append(m[k])
    return np.asarray(out, dtype=float)


def law_from_dft(values, speeds_kmh: Sequence[float], g=None) -> tuple[float, float, float]:
    """(mu_s, mu_k, alpha s/m) of the bounded law whose FE response ``g(v) * mu(v)`` is closest (least squares)
    to the DFT ``values`` at ``speeds_kmh`` (km/h); ``g`` None for g = 1. The law a ``<model>@dft`` model hands
    to the FE (Figure 11) and to the parameter rows of the CV table; its DFT score uses the predicted values
    themselves, not this law."""
    from skidsim.calibration import fit_exponential_decay

    law, _ = fit_exponential_decay(
        np.asarray(speeds_kmh, dtype=float),
        np.asarray(values, dtype=float),
        b=None if g is None else np.asarray(g, dtype=float),
    )
    return law.mu_s, law.mu_k, law.alpha


def speed_key(v) -> np.ndarray:
    """Speeds (km/h) rounded to 1e-6 km/h: the key that matches the speeds of two tables."""
    return np.round(np.asarray(v, dtype=float), 6)


def _g_map(g: pd.DataFrame, g_file) -> dict:
    """``{(site, speed key): g}`` of the g table (site, speed_kmh km/h, g)."""
    for c in ("site", "speed_kmh", "g"):
        if c not in g.columns:
            raise InputError(g_file, f"a '{c}' column", column=c, got=list(g.columns))
    return {(str(s), float(v)): float(x) for s, v, x in zip(g["site"], speed_key(g["speed_kmh"]), g["g"].astype(float))}


def predict_dft(
    params: pd.DataFrame,
    g: pd.DataFrame | None = None,
    speeds_kmh: Sequence[float] = DEFAULT_SPEEDS_KMH,
    *,
    clip_physical: bool = True,
    g_file="g table",
) -> pd.DataFrame:
    """DFT predicted from friction parameters: ``g(site, v) * mu(v)``, long form (site, speed_kmh, mu, g).

    ``params`` is indexed by site (or has a ``site`` column) with ``mu_s``, ``mu_k``, ``alpha`` (s/m); ``g`` a
    table (site, speed_kmh, g) covering every site and speed (km/h), ``None`` for g = 1.
    """
    p = params.set_index(params["site"].astype(str)) if "site" in params.columns else params
    for c in PARAMETERS:
        if c not in p.columns:
            raise InputError(None, f"a '{c}' column in the parameter table", column=c)
    gmap = None if g is None else _g_map(g, g_file)
    speeds = np.asarray(speeds_kmh, dtype=float)
    rows = []
    for site, r in p.iterrows():
        ms, mk, a = float(r["mu_s"]), float(r["mu_k"]), float(r["alpha"])
        if clip_physical:
            ms, mk, a = max(ms, 0.0), max(mk, 0.0), max(a, 0.0)
        mu = ExponentialDecay(ms, mk, a).mu_kmh(speeds)
        for v, m in zip(speeds, mu):
            gv = 1.0
            if gmap is not None:
                key = (str(site), float(speed_key(v)))
                if key not in gmap:
                    raise InputError(g_file, f"a geometric factor for site {site} at {v:g} km/h", column="g")
                gv = gmap[key]
            rows.append({"site": str(site), "speed_kmh": float(v), "mu": gv * float(m), "g": gv})
    return pd.DataFrame(rows, columns=["site", "speed_kmh", "mu", "g"])


def value_column(df: pd.DataFrame, candidates, file) -> str:
    """The first of ``candidates`` that is a column of ``df``, else InputError naming ``file``."""
    for c in candidates:
        if c in df.columns:
            return c
    raise InputError(
        file,
        "a value column named " + " or ".join(f"'{c}'" for c in candidates),
        column=candidates[0],
        got=list(df.columns),
    )


def keyed_values(df: pd.DataFrame, candidates, file, name: str, *, unique: bool) -> tuple[pd.DataFrame, str]:
    """A long table (``site``, ``speed_kmh`` km/h, a value column among ``candidates``) as columns ``site``,
    ``key`` (:func:`speed_key`), ``speed_kmh`` and ``name``; ``unique``: one value per site and speed, else
    InputError naming ``file``. Returns the table and the value column's name in ``df``."""
    for c in ("site", "speed_kmh"):
        if c not in df.columns:
            raise InputError(file, f"a '{c}' column", column=c, got=list(df.columns))
    vc = value_column(df, candidates, file)
    t = pd.DataFrame(
        {
            "site": df["site"].astype(str),
            "key": speed_key(df["speed_kmh"]),
            "speed_kmh": df["speed_kmh"].astype(float),
            name: df[vc].astype(float),
        }
    )
    if unique and t.duplicated(["site", "key"]).any():
        d = t[t.duplicated(["site", "key"])].iloc[0]
        raise InputError(
            file, "one value per site and speed", column="speed_kmh", got=f"{d['site']} at {d['key']:g} km/h"
        )
    return t, vc
