"""Small synthetic campaigns with one hidden effect, for the model-criticism tests (test helper, not a test).

Independent of skidsim's fitting code: the calibration uses scipy.optimize.curve_fit, the texture regression a
ridge solve written here. Only the campaign-level tables are handed to the analysis; the truth stays here.

Units: speeds km/h, slip speed m/s, alpha s/m, temperature deg C, MPD mm, mu dimensionless.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy.optimize import curve_fit

SPEEDS_CAL_KMH = (20.0, 40.0, 60.0)
SPEEDS_VAL_KMH = (30.0, 50.0, 70.0)
SIM_SPEEDS_KMH = np.arange(10.0, 95.0, 5.0)
EFFECTS = (None, "temperature", "drainage", "squeeze", "wear", "mix")
#: truth constants of the hidden effects
WLF_TR_C = -40.0
T_ANCHOR_C = 16.0
DRAIN_KAPPA = 0.5
#: partial hydroplaning: x (1 - kappa (v^2 - 20^2) / Sp^2), as skidsim.generators.truth's "squeeze" form
SQUEEZE_KAPPA = 0.3
WEAR_LOSS = 0.20
#: principal components kept by the texture model: all 11 (= least squares on every texture parameter, an
#: unbiased model, so the null campaign is a true null; fewer components leave section-structured texture out)
N_PCS = 11
MIX_OFFSET = {"A": -0.08, "B": 0.0, "C": 0.08}


def _law(v_kmh, mu_s, mu_k, alpha):
    return mu_k + (mu_s - mu_k) * np.exp(-alpha * np.asarray(v_kmh, float) / 3.6)


def _wlf(t_c, tr_c=WLF_TR_C, c1=8.86, c2=101.6):
    dt = np.asarray(t_c, float) - tr_c
    return -c1 * dt / (c2 + dt)


def make_campaign(
    seed: int,
    effect: str | None = None,
    *,
    n_sections: int = 12,
    sites_per_section: int = 3,
    noise_mu: float = 0.005,
    trace_step_kmh: float = 4.0,
):
    """Return (tables, truth). tables: sites, measured, simulated, predicted, texture (what the analysis sees)."""
    sites, measured, tex, truth = generate_campaign(
        seed,
        effect,
        n_sections=n_sections,
        sites_per_section=sites_per_section,
        noise_mu=noise_mu,
        trace_step_kmh=trace_step_kmh,
    )
    return derive_tables(sites, measured, tex), truth


def generate_campaign(
    seed: int,
    effect: str | None = None,
    *,
    n_sections: int = 12,
    sites_per_section: int = 3,
    noise_mu: float = 0.005,
    trace_step_kmh: float = 4.0,
):
    """Return (sites, measured, texture, truth): the campaign's raw data (measured: site, speed_kmh, mu, kind)."""
    if effect not in EFFECTS:
        raise ValueError(effect)
    rng = np.random.default_rng(seed)
    n = n_sections * sites_per_section
    sec_names = [f"S{k + 1:02d}" for k in range(n_sections)]
    section = np.repeat(sec_names, sites_per_section)
    mixes = rng.permutation(np.resize(np.array(["A", "B", "C"]), n_sections))
    mix = np.repeat(mixes, sites_per_section)
    site = [f"{s}-{k + 1}" for s in sec_names for k in range(sites_per_section)]
    sec_idx = np.repeat(np.arange(n_sections), sites_per_section)
    macro = 0.8 * rng.normal(size=n_sections)[sec_idx] + 0.6 * rng.normal(size=n)
    micro = 0.8 * rng.normal(size=n_sections)[sec_idx] + 0.6 * rng.normal(size=n)
    mpd = np.clip(0.8 + 0.22 * macro, 0.25, None)
    tex = pd.DataFrame(
        {
            "site": site,
            "mpd_mm": mpd,
            "macro_Sq_mm": 0.55 * mpd + 0.02 * rng.normal(size=n),
            "macro_Sa_mm": 0.42 * mpd + 0.02 * rng.normal(size=n),
            "macro_Sdr_pct": 8.0 + 3.0 * macro + 0.4 * rng.normal(size=n),
            "macro_Ssk": -0.5 + 0.3 * rng.normal(size=n),
            "macro_Sku": 3.2 + 0.4 * rng.normal(size=n),
            "macro_Str": 0.6 + 0.1 * rng.normal(size=n),
            "micro_Sq_mm": 0.030 + 0.005 * micro + 0.0008 * rng.normal(size=n),
            "micro_Sdq": 0.40 + 0.06 * micro + 0.01 * rng.normal(size=n),
            "micro_Ssk": -0.2 + 0.3 * rng.normal(size=n),
            "micro_Str": 0.7 + 0.1 * rng.normal(size=n),
        }
    )
    temperature = rng.uniform(9.0, 23.0, size=n)
    order = rng.permutation(n) + 1
    sites = pd.DataFrame(
        {
            "site": site,
            "section": section,
            "temperature_c": np.round(temperature, 2),
            "mix": mix,
            "test_order": order,
            "operator": rng.choice(["JD", "KL"], size=n),
            "scan": [f"scans/{s}.x3p" for s in site],
            "dft": [f"dft/{s}.csv" for s in site],
        }
    )
    rng.normal(size=n)  # (was the FE geometric factor g, which cancels in SN_sim = g mu_cal; keeps the stream)
    mu_k = 0.30 + 0.04 * micro + 0.012 * rng.normal(size=n)
    mu_s = mu_k + 0.30 + 0.04 * micro + 0.015 * rng.normal(size=n)
    alpha = 0.10 * np.exp(0.10 * rng.normal(size=n))
    sp = 14.2 + 89.7 * mpd
    speed_factor = 10.0 ** (_wlf(temperature) - _wlf(T_ANCHOR_C))

    def truth_mu(i, v):
        v = np.asarray(v, float)
        if effect == "temperature":
            mu = _law(v * speed_factor[i], mu_s[i], mu_k[i], alpha[i])
        else:
            mu = _law(v, mu_s[i], mu_k[i], alpha[i])
        if effect == "drainage":
            mu = mu * np.exp(-DRAIN_KAPPA * (v - 20.0) / sp[i])
        elif effect == "squeeze":
            mu = mu * np.maximum(0.05, 1.0 - SQUEEZE_KAPPA * (v * v - 400.0) / sp[i] ** 2)
        elif effect == "wear":
            mu = mu * (1.0 - WEAR_LOSS * (order[i] - 1) / (n - 1))
        elif effect == "mix":
            mu = mu + MIX_OFFSET[mix[i]]
        return mu

    measured = measured_points(site, truth_mu, noise_mu, trace_step_kmh, rng)
    truth = {
        "effect": effect,
        "variable": {
            None: None,
            "temperature": "temperature_c",
            "drainage": "mpd_mm",
            "squeeze": "mpd_mm",
            "wear": "test_order",
            "mix": "mix",
        }[effect],
    }
    return sites, measured, tex, truth


def derive_tables(sites: pd.DataFrame, measured: pd.DataFrame, tex: pd.DataFrame) -> dict:
    """The diagnosis inputs derived from a campaign's raw data, by the cheap path (no FE): per-site calibration
    of the exponential law through the calibration speeds (scipy curve_fit; the FE geometric factor g cancels in
    SN_sim = g mu_cal, so the simulated curve is the fitted law) and leave-one-section-out texture predictions."""
    site = sites["site"].astype(str).tolist()
    n = len(site)
    sec_codes = pd.factorize(sites["section"].astype(str))[0]
    n_sections = int(sec_codes.max()) + 1
    sec_idx = sec_codes
    tex = tex.set_index(tex["site"].astype(str)).loc[site].reset_index(drop=True)
    g = np.ones(n)
    # calibration: SN_sim = g mu_cal through 20/40/60 (independent fit: scipy curve_fit)
    cal = np.empty((n, 3))
    for i in range(n):
        m = measured[(measured["site"] == site[i]) & (measured["kind"] == "calibration")].sort_values("speed_kmh")
        v, y = m["speed_kmh"].to_numpy(), m["mu"].to_numpy()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p, _ = curve_fit(
                lambda vv, a, b, c: b + a * np.exp(-c * vv / 3.6),
                v,
                y,
                p0=(0.3, 0.3, 0.1),
                bounds=([-2, -2, 1e-4], [2, 2, 3.0]),
                maxfev=20000,
            )
        cal[i] = (p[1] + p[0], p[1], p[2])  # (g mu_s, g mu_k, alpha)
    cal_mu_s, cal_mu_k, cal_alpha = cal[:, 0] / g, cal[:, 1] / g, cal[:, 2]
    simulated = pd.DataFrame(
        [
            (site[i], v, float(g[i] * _law(v, cal_mu_s[i], cal_mu_k[i], cal_alpha[i])))
            for i in range(n)
            for v in SIM_SPEEDS_KMH
        ],
        columns=["site", "speed_kmh", "sn"],
    )
    # texture model (what a regression on texture would predict for held-out sites, as in the study: principal
    # component regression): leave-one-section-out least squares of each site's level (mean calibrated SN over the
    # simulated speeds) on the first N_PCS principal components of the standardised texture parameters, times the
    # training sites' mean normalised curve shape.
    X = tex.drop(columns="site").to_numpy(float)
    X = X[:, np.isfinite(X).all(axis=0) & (np.ptp(X, axis=0) > 0)]  # constant or incomplete columns carry no PC
    X = (X - X.mean(0)) / X.std(0)
    Y = simulated.pivot(index="site", columns="speed_kmh", values="sn").loc[site].to_numpy(float)
    level = Y.mean(axis=1)
    pred = np.empty_like(Y)
    for s in range(n_sections):
        te, tr = sec_idx == s, sec_idx != s
        mu_x = X[tr].mean(0)
        _, _, vt = np.linalg.svd(X[tr] - mu_x, full_matrices=False)
        Z = (X - mu_x) @ vt[:N_PCS].T
        A = np.c_[np.ones(tr.sum()), Z[tr]]
        beta = np.linalg.lstsq(A, level[tr], rcond=None)[0]
        shape = (Y[tr] / level[tr, None]).mean(axis=0)
        pred[te] = (np.c_[np.ones(te.sum()), Z[te]] @ beta)[:, None] * shape[None, :]
    predicted = pd.DataFrame(
        [(site[i], float(v), float(pred[i, j])) for i in range(n) for j, v in enumerate(SIM_SPEEDS_KMH)],
        columns=["site", "speed_kmh", "sn_pred"],
    )
    return {"sites": sites, "measured": measured, "simulated": simulated, "predicted": predicted, "texture": tex}


# ---------------------------------------------------------------------------------------------------------------
# the campaign on disk: what a user provides (sites.csv, one DFT trace per site) plus the texture table derived
# from the scans; the truth is returned to the caller and never written there
# ---------------------------------------------------------------------------------------------------------------

TEXTURE_FILE = "texture.csv"


def measured_points(
    site, truth_mu, noise_mu: float, trace_step_kmh: float, rng, trace_from_kmh: float = 20.0
) -> pd.DataFrame:
    """DFT points of every site: ``truth_mu(i, v)`` plus white noise of ``noise_mu`` (mu) at the calibration and
    validation speeds and 1.5 times that on a trace every ``trace_step_kmh`` km/h from 20 to 80 km/h (none for 0),
    and below 20 km/h down to ``trace_from_kmh`` on the same step (a spin-down trace's low speeds, which the
    simulation does not reach); columns site, speed_kmh, mu, kind. Draws from ``rng`` site by site, in that order
    of kinds."""
    trace_v = np.arange(20.0, 80.0 + 1e-9, trace_step_kmh) if trace_step_kmh else np.array([])
    if trace_step_kmh and trace_from_kmh < 20.0:
        trace_v = np.r_[np.arange(20.0 - trace_step_kmh, trace_from_kmh - 1e-9, -trace_step_kmh)[::-1], trace_v]
    rows = []
    for i in range(len(site)):
        for kind, vs, sd in (
            ("calibration", SPEEDS_CAL_KMH, noise_mu),
            ("validation", SPEEDS_VAL_KMH, noise_mu),
            ("trace", trace_v, 1.5 * noise_mu),
        ):
            vs = np.asarray(vs, float)
            if len(vs) == 0:
                continue
            y = truth_mu(i, vs) + sd * rng.normal(size=len(vs))
            rows += [(site[i], float(v), float(m), kind) for v, m in zip(vs, y)]
    return pd.DataFrame(rows, columns=["site", "speed_kmh", "mu", "kind"])


def write_campaign(directory, seed: int, effect: str | None = None, **kw) -> dict:
    """Write a campaign directory: sites.csv (skidsim.generators.default.write_sites_csv: site, section, scan, dft,
    temperature_c, metadata), dft/<site>.csv (one spin-down trace per site, columns speed_kmh, mu: the union of
    the noisy samples, equal speeds averaged) and texture.csv (the texture parameters per site). Returns truth."""
    from pathlib import Path

    from skidsim.generators.default import write_sites_csv

    d = Path(directory)
    (d / "dft").mkdir(parents=True, exist_ok=True)
    sites, measured, tex, truth = generate_campaign(seed, effect, **kw)
    write_sites_csv(sites.drop(columns=["scan", "dft"]), d, d / "sites.csv")
    for s, m in measured.groupby("site"):
        m = m.groupby("speed_kmh", as_index=False)["mu"].mean().sort_values("speed_kmh", ascending=False)
        lines = ["speed_kmh,mu"] + [f"{v:.10g},{mu:.10g}" for v, mu in zip(m["speed_kmh"], m["mu"])]
        (d / "dft" / f"{s}.csv").write_text("\n".join(lines) + "\n")
    tex.to_csv(d / TEXTURE_FILE, index=False)
    return truth


def read_campaign(directory) -> dict:
    """The diagnosis tables from a campaign directory only: sites.csv, the DFT files it names (skidsim.dft.read_dft)
    and texture.csv. DFT points at the calibration and validation speeds are the trace interpolated there (the
    trace holds samples at those speeds); every trace sample within 20-80 km/h is a 'trace' point."""
    from pathlib import Path

    from skidsim.dft import read_dft

    d = Path(directory)
    sites = pd.read_csv(d / "sites.csv")
    rows = []
    for r in sites.itertuples():
        tr = read_dft(d / r.dft)
        v, mu = tr.speeds_kmh, tr.mu
        for kind, speeds in (("calibration", SPEEDS_CAL_KMH), ("validation", SPEEDS_VAL_KMH)):
            rows += [(str(r.site), float(x), float(np.interp(x, v, mu)), kind) for x in speeds]
        keep = (v >= 20.0 - 1e-9) & (v <= 80.0 + 1e-9)
        rows += [(str(r.site), float(x), float(y), "trace") for x, y in zip(v[keep], mu[keep])]
    measured = pd.DataFrame(rows, columns=["site", "speed_kmh", "mu", "kind"])
    tex = pd.read_csv(d / TEXTURE_FILE)
    return derive_tables(sites, measured, tex)
