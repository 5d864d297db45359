"""Which calibrated sites carry a shape the sites share at held-out speeds.

A within-site functional form on measured curves that are exponential decays of speed (gain.json ``curve_form``,
:func:`~skidsim.criticism.wlf.curve_form_reading`) is the simulated curve's: the FE's response to the law, or the
law fitted at the calibration speeds. The calibration's own records (results/calibration/identifiability.csv,
docs/calibration.md, "Quality and identifiability") tell three groups of sites apart:

* **not settled**: the calibration did not converge, or its best law lies outside the law's family, or the FE did
  not respond smoothly to the law (flags ``not_converged``, ``outside_law``, ``fe_not_smooth``);
* **at the upper bound of mu_s**: the law is pinned at the end of its interval (``at_bound_params`` holds
  ``mu_s:upper``; the study's interval ends at 0.85). A measured curve that extrapolates above it at zero slip speed
  then gets a simulated curve tilted against it: too low at the lowest speeds, too high at the highest
  (docs/calibration.md, "The law's reach");
* **inside the bounds**: the others, whose share is the FE's response to the law between the calibration speeds.

:func:`calibration_groups` works on each site's centred residual profile, as the functional form's test does
(:func:`~skidsim.criticism.screening.functional_form_test`), on the same matrix: the site's mean within-site
residual (measured minus simulated, mu) per speed bin (bins centred on multiples of the diagnosis's
``speed_bin_kmh``, those observed at every site) minus its mean over the bins. Each group's profile ``G_g`` is the
mean of its sites' profiles, and its share of the shape all sites share follows from the mean profile over all sites
``P``, the site-weighted sum of the group profiles, ``P(b) = sum_g n_g G_g(b) / n``: the projections ``share_g =
(n_g / n) sum_b G_g(b) P(b) / sum_b P(b)^2`` add up to 1 (a group whose profile runs against the shared one has a
negative share). Each group is also tested alone by the functional form's statistic, ``T = n_g sum_b G_g(b)^2``
against random sign flips of whole sections' profiles (``p_alone``, :func:`~skidsim.criticism.permutations.
section_flip_shape`): whether its sites alone share a shape. The reading names the group of the largest share.

Speeds km/h, friction mu (dimensionless).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError
from .levels import curve_responses
from .permutations import permutation_p, section_flip_shape
from .residuals import level_matrix, speed_bin_centres

#: The flag of a calibrated law whose ``mu_s`` sits at the upper end of its interval (``at_bound_params``).
BOUND_FLAG = "mu_s:upper"
#: Flags of a calibration that did not settle (``flags`` of identifiability.csv).
UNSETTLED_FLAGS = ("not_converged", "outside_law", "fe_not_smooth")
#: The groups, in the order a site is assigned (the first that applies), and what each means.
GROUPS = {
    "not settled": "the calibration did not settle (not converged, outside the law's family, or the FE not smooth "
    "in the law)",
    "at the upper bound of mu_s": "the calibrated mu_s sits at its upper bound",
    "inside the bounds": "calibrated inside the bounds",
}
#: What the group of the largest share says of the shape.
CONCLUSIONS = {
    "not settled": "the calibration that did not settle at those sites (identifiability.csv says why, site by site)",
    "at the upper bound of mu_s": "the law's upper bound on mu_s: a law free to start higher would follow these "
    "curves more closely (calibration.ours.reach_mu_s_max widens the bound where it costs the fit)",
    "inside the bounds": "the FE's response to the law between the calibration speeds, at sites the calibration "
    "fitted inside its bounds",
}


def _split(values: pd.Series) -> pd.Series:
    return values.fillna("").astype(str).str.split(";")


def site_groups(calibration: pd.DataFrame) -> pd.Series:
    """The group (a key of :data:`GROUPS`) of each site (index) of ``calibration`` (columns site, flags,
    at_bound_params: flags joined by ``;``)."""
    flags, bound = _split(calibration["flags"]), _split(calibration["at_bound_params"])
    unsettled = flags.apply(lambda f: any(x in f for x in UNSETTLED_FLAGS))
    at_bound = bound.apply(lambda f: BOUND_FLAG in f)
    names = np.where(unsettled, "not settled", np.where(at_bound, "at the upper bound of mu_s", "inside the bounds"))
    return pd.Series(names, index=calibration["site"].astype(str).to_numpy())


def settled_residuals(residuals: pd.DataFrame, calibration: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """``residuals`` without the within-site rows of the sites whose calibration did not settle or whose ``mu_s``
    sits at its upper bound (:func:`site_groups`; sites ``calibration`` does not list stay), and those sites per
    group ({group: [sites]}, the groups with any). The between-site rows all stay: they compare the measured
    curves with the texture model's predictions, not with the site's own calibration."""
    group = site_groups(calibration)
    flagged = group[group != "inside the bounds"]
    drop = (residuals["level"] == "within-site") & residuals["site"].astype(str).isin(flagged.index)
    present = set(residuals.loc[drop, "site"].astype(str))
    left_out = {
        name: sorted(s for s in flagged.index[flagged == name] if s in present)
        for name in GROUPS
        if name != "inside the bounds"
    }
    return residuals[~drop].reset_index(drop=True), {k: v for k, v in left_out.items() if v}


def calibration_groups(
    residuals: pd.DataFrame, calibration: pd.DataFrame, bin_kmh: float = 10.0, n_perm: int = 999, seed: int = 11
) -> dict | None:
    """Each group's centred within-site residual profile (mu per speed bin of ``bin_kmh`` km/h), its sites, its
    share of the mean profile over the sites and its own permutation p (``n_perm`` sign flips drawn from ``seed``)
    (module docstring), and the reading. The profiles are the functional form's (:func:`~skidsim.criticism.
    residuals.level_matrix` and :func:`~skidsim.criticism.levels.curve_responses` of the listed sites'
    within-site rows: bins centred on multiples of ``bin_kmh``, those observed at every site). ``residuals``: the
    diagnosis's residual table (site, section, level, speed_kmh, residual); ``calibration``: site, flags,
    at_bound_params per site (sites it does not list take no part). None without within-site rows of a listed
    site, with fewer than 2 bins, or where the mean profile is zero."""
    group = site_groups(calibration)
    w = residuals[(residuals["level"] == "within-site") & residuals["site"].astype(str).isin(group.index)]
    if w.empty:
        return None
    w = w.assign(site=w["site"].astype(str))
    try:
        ids, bins, R = level_matrix(w, "within-site", bin_kmh)
    except InputError:  # no bin observed at every site
        return None
    if bins.size < 2:
        return None
    D = pd.DataFrame(curve_responses(R)[0], index=ids, columns=bins)  # centred profiles, the functional form's
    section = w.groupby("site")["section"].first().astype(str)
    span = w.groupby(speed_bin_centres(w["speed_kmh"], bin_kmh))["speed_kmh"].agg(["min", "max"])
    shared = D.mean(axis=0).to_numpy(float)  # P(b)
    norm = float((shared * shared).sum())
    if not norm > 0:
        return None
    rng = np.random.default_rng(seed)
    groups = []
    for name, words in GROUPS.items():
        sites = [s for s in D.index if group[s] == name]
        if not sites:
            continue
        g = D.loc[sites].to_numpy(float)
        profile = g.mean(axis=0)
        groups.append(
            {
                "group": name,
                "means": words,
                "sites": sites,
                "profile_mu": [float(x) for x in profile],
                "share": float(len(sites) / len(D) * (profile @ shared) / norm),
                "p_alone": float(permutation_p(*section_flip_shape(g, section.loc[sites].to_numpy(), n_perm, rng))),
            }
        )
    out = {
        "bin_kmh": float(bin_kmh),
        "speeds_kmh": [float(b) for b in D.columns],
        "speed_range_kmh": [[float(span.at[b, "min"]), float(span.at[b, "max"])] for b in D.columns],
        "shared_profile_mu": [float(x) for x in shared],
        "n_permutations": int(n_perm),
        "groups": groups,
    }
    out["reading"] = groups_reading(out)
    return out


def groups_reading(rec: dict) -> str:
    """The sentence of :func:`calibration_groups`' record ``rec``: the shared profile from its first bin to its
    last, each group's sites, profile ends, share and own p, and what the group of the largest share says."""
    r0, r1 = (_speeds(r) for r in (rec["speed_range_kmh"][0], rec["speed_range_kmh"][-1]))
    p = rec["shared_profile_mu"]
    n = sum(len(g["sites"]) for g in rec["groups"])
    parts = [
        f"{len(g['sites'])} {g['group']} ({_mu(g['profile_mu'][0])} to {_mu(g['profile_mu'][-1])}) share "
        f"{g['share']:.2f}, alone p {g['p_alone']:.2g}"
        for g in rec["groups"]
    ]
    top = max(rec["groups"], key=lambda g: g["share"])
    lead = "most of it" if top["share"] > 0.5 else "the largest part"
    return (
        f"the mean centred residual over the {n} sites runs from {_mu(p[0])} mu at {r0} km/h to {_mu(p[-1])} at {r1} "
        "km/h; "
        f"its share by the calibration's record of the sites: {'; '.join(parts)}; {lead} is carried by the sites "
        f"{top['group']}: {CONCLUSIONS[top['group']]}"
    )


def _speeds(r) -> str:
    """A bin's speed range (km/h) in words: ``20-29.5``, or one speed."""
    lo, hi = round(r[0], 1), round(r[1], 1)
    return f"{lo:g}" if lo == hi else f"{lo:g}-{hi:g}"


def _mu(x: float) -> str:
    """A residual (mu) to 3 decimals with its sign (no negative zero); ``nan`` where a group has no value."""
    return "nan" if not np.isfinite(x) else f"{round(x, 3) + 0.0:+.3f}"
