"""The data of one level of error that every screening test shares: the level's residual matrix
(:class:`LevelData`), its candidates, responses, permutations and bases (:class:`LevelContext`), and the record
of one screened test (:class:`CandidateTest`). Speeds km/h, residuals mu (dimensionless).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from .adjustment import basis
from .covariates import CandidateSet
from .options import DiagnosisOptions
from .permutations import nested_permutations, site_permutations
from .residuals import LEVELS, level_matrix


@dataclass
class CandidateTest:
    """One screened candidate at one level and kind: statistic ``T`` and its permutation values ``Tp`` (P,),
    cross-validated SSE without/with the candidate (``sse0``/``sse1``, mu^2), ``n`` sites x ``S`` columns of the
    tested residual, sign ``direction``, the candidate's ``source``/``dtype``/``section_level`` and the texture PCs
    of a texture-adjusted test (``texture_pcs``, ``texture_pcs_cv``; -1 for the residual test)."""

    variable: str
    level: str
    kind: str
    T: float
    Tp: np.ndarray
    sse0: float
    sse1: float
    n: int
    S: int
    direction: int
    source: str
    dtype: str
    section_level: bool
    texture_pcs: int = -1
    texture_pcs_cv: int = -1
    section_share: float = float("nan")
    section_share_main: float = float("nan")
    section_id: bool = False
    words: str = ""
    section_rest_p: float = float("nan")
    beyond_texture_share: float = float("nan")
    beyond_texture_p: float = float("nan")


@dataclass
class LevelData:
    """One level's residual matrix R (sites x speed bins, mu) and, between sites with texture adjustment, the
    measured matrix M over the same sites and bins (else None)."""

    level: str
    site_ids: list
    bins: np.ndarray
    R: np.ndarray
    measured: np.ndarray | None = None


#: The fewest sites with residuals at a level for its tests (fewer: the level is not screened).
MIN_LEVEL_SITES = 4


def level_data(residuals: pd.DataFrame, options: DiagnosisOptions) -> dict:
    """{level: LevelData} for every level with residuals at >= :data:`MIN_LEVEL_SITES` sites."""
    out = {}
    for level in LEVELS:
        res = residuals[residuals["level"] == level]
        if res["site"].nunique() < MIN_LEVEL_SITES:
            continue
        site_ids, bins, R = level_matrix(residuals, level, options.speed_bin_kmh)
        out[level] = LevelData(level, site_ids, bins, R)
        if level == "between-site" and options.adjust_texture and "measured" in res.columns:
            ids_m, bins_m, M = level_matrix(residuals, level, options.speed_bin_kmh, value="measured")
            out[level].measured = M if (ids_m == site_ids and np.array_equal(bins_m, bins)) else None
    if not out:
        raise InputError("residuals", f"at least {MIN_LEVEL_SITES} sites with residuals at one level")
    return out


@dataclass
class LevelContext:
    """What every test of one level shares: candidates ``C`` of its sites, sections ``sec``, the centred residual
    profiles ``D`` and tested residuals ``Ys`` per kind, the permutations, and per candidate its basis and whether
    it is constant within sections (``section_level``) or section identity (``is_section_id``)."""

    data: LevelData
    C: pd.DataFrame
    info: dict
    sec: np.ndarray
    D: np.ndarray
    Ys: dict
    perm_site: np.ndarray
    perm_nested: np.ndarray
    section_level: dict
    is_section_id: dict
    bases: dict
    amp_col: str | None
    cv_columns: dict = field(default_factory=dict)  # tested column in place of C[c] (texture_beyond_lead)

    @property
    def n(self) -> int:
        return len(self.sec)

    @property
    def speed_c(self) -> np.ndarray:
        return self.data.bins - self.data.bins.mean()


def curve_responses(M: np.ndarray) -> tuple[np.ndarray, dict]:
    """The responses of a site x speed matrix ``M`` (n_sites, S; residuals or measured mu): ``D``, each site's curve
    minus its mean, and per kind ``x_speed``, ``D`` column-centred (the speed shapes), and ``main``, the centred
    site means (n_sites, 1)."""
    m = M.mean(axis=1)
    D = M - m[:, None]
    return D, {"x_speed": D - D.mean(axis=0), "main": (m - m.mean())[:, None]}


def level_context(data: LevelData, cands: CandidateSet, P: int, rng) -> LevelContext:
    """The shared data of one level; draws its two permutation sets from ``rng`` (sites, then nested)."""
    missing = [s for s in data.site_ids if s not in cands.covariates.index]
    if missing:
        raise InputError("sites table", "a row for every site with residuals", column="site", got=missing[:5])
    C, info = cands.covariates.loc[data.site_ids], cands.info
    sec = cands.section_of.loc[data.site_ids].to_numpy()
    mpd = cands.mpd
    amp_col = (
        mpd
        if (data.level == "within-site" and mpd is not None and mpd in C.columns and info[mpd][1] == "numeric")
        else None
    )
    D, Ys = curve_responses(data.R)
    if data.level != "between-site":
        del Ys["main"]
    perm_site = site_permutations(len(sec), P, rng)
    perm_nested = nested_permutations(sec, P, rng)
    n_sec = len(np.unique(sec))
    section_level = {c: bool((C[c].groupby(sec).nunique() == 1).all()) for c in C.columns}
    # section identity: a categorical label with one level per section (a section-constant *number*, e.g. traffic
    # per section, is a covariate of the 12 sections, tested by the nested permutations like every covariate)
    is_section_id = {c: section_level[c] and C[c].nunique() == n_sec and info[c][1] == "categorical" for c in C.columns}
    bases = {c: basis(C[c], info[c][1]) for c in C.columns}
    return LevelContext(data, C, info, sec, D, Ys, perm_site, perm_nested, section_level, is_section_id, bases, amp_col)
