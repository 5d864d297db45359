"""False-discovery control of the screening (docs/model-criticism.md, section 2): testing units (a candidate, a
texture cluster tested by its max-statistic, or the texture model's members tested by minP) in two families,
*primary* (functional form, temperature columns between sites, MPD x speed) and *secondary* (the rest), each with
a step-up procedure at its share of ``fdr`` (FDR is subadditive over a partition, so the FDR over units is <=
``fdr``), and a gatekeeper step for the section-level explanations of a significant section effect (Yekutieli
2008)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from .permutations import min_p, permutation_p


def adjust_pvalues(p, method: str = "bh") -> np.ndarray:
    """Benjamini-Hochberg (``"bh"``) or Benjamini-Yekutieli (``"by"``) adjusted p-values (step-up, monotone)."""
    p = np.asarray(p, dtype=float)
    m = len(p)
    if m == 0:
        return p
    if method not in ("bh", "by"):
        raise ConfigError(f"fdr method must be 'bh' or 'by', got {method!r}")
    cm = np.sum(1.0 / np.arange(1, m + 1)) if method == "by" else 1.0
    order = np.argsort(p)
    adj = p[order] * m * cm / np.arange(1, m + 1)
    adj = np.minimum.accumulate(adj[::-1])[::-1]
    out = np.empty(m)
    out[order] = np.minimum(adj, 1.0)
    return out


def auto_permutations(n_candidates: int, fdr: float) -> int:
    """Default permutation count: with m candidates, BH can only declare a cause if its p-value <= fdr/m, and the
    smallest permutation p-value is 1/(P+1); we use P = max(999, ceil(4 m / fdr) - 1)."""
    return int(max(999, math.ceil(4 * n_candidates / fdr) - 1))


def family_shares(primary_share: float, texture_share: float = 0.0) -> dict:
    """The share of ``fdr`` of each family: ``primary``, ``secondary`` and, when ``texture_share`` > 0, ``texture``
    (the texture clusters and lone texture columns, taken out of the secondary family). The shares sum to 1."""
    share = {"primary": primary_share, "secondary": 1.0 - primary_share - texture_share}
    if texture_share > 0:
        share["texture"] = texture_share
    return share


def has_texture_family(options) -> bool:
    """Whether the texture clusters form a family of their own under ``options`` (a share of ``fdr`` in
    :func:`family_shares`)."""
    return "texture" in family_shares(options.primary_share, options.texture_share)


def family_sizes(levels, candidates, texture_family: bool = False, level_clusters: dict | None = None) -> dict:
    """Number of testing units per family over the screened ``levels`` (within-site: x_speed only; between-site:
    main and x_speed) of a :class:`~skidsim.criticism.covariates.CandidateSet`; with ``texture_family`` the texture
    clusters count in a family ``texture`` of their own; ``level_clusters``: the texture clusters of a level where
    they are not ``candidates.clusters`` (:func:`testing_units`)."""
    m_fam = {"primary": 0, "secondary": 0, "texture": 0}
    clusters = "texture" if texture_family else "secondary"
    meta = [c for c in candidates.covariates.columns if candidates.info[c][0] != "texture"]
    has_texture = len(meta) < len(candidates.covariates.columns)
    for lv in levels:
        m_fam["primary"] += 1  # functional form
        for kind in ("x_speed",) if lv == "within-site" else ("main", "x_speed"):
            n_temp = len(candidates.temperature) if lv == "between-site" else 0
            m_fam["primary"] += n_temp + (1 if (candidates.mpd is not None and kind == "x_speed") else 0)
            if lv == "between-site" and kind == "main" and has_texture:
                m_fam["primary"] += 1  # the texture model (skidsim.criticism.texture_candidate)
            m_fam["secondary"] += len(meta) - n_temp
            m_fam[clusters] += len((level_clusters or {}).get(lv, candidates.clusters))
    return m_fam


def permutation_count(m_fam: dict, options) -> int:
    """Permutations per test: ``options.n_permutations`` or :func:`auto_permutations` for the larger family size
    divided by its share of ``fdr``; warns when no single cause could ever be significant."""
    share = family_shares(options.primary_share, options.texture_share)
    n_tests = int(math.ceil(max(m_fam[f] / share[f] for f in m_fam if m_fam[f] > 0)))
    P = auto_permutations(n_tests, options.fdr) if options.n_permutations is None else int(options.n_permutations)
    if P < 1:
        raise ConfigError(f"n_permutations must be >= 1, got {P}")
    if (P + 1) * options.fdr < n_tests:
        warnings.warn(
            f"n_permutations={P} with {n_tests} effective units: the smallest permutation p-value "
            f"1/{P + 1} exceeds share * fdr / m = {options.fdr / n_tests:.2g}, so a single cause can "
            f"never be significant; use n_permutations=None (auto: "
            f"{auto_permutations(n_tests, options.fdr)})",
            RuntimeWarning,
            stacklevel=3,
        )
    return P


@dataclass
class Unit:
    """A testing unit: its ``family``, reported ``name`` (``cluster:<representative>`` for a texture cluster) and
    the indices of its member tests."""

    family: str
    name: str | None
    members: list = field(default_factory=list)


def testing_units(tests, candidates, texture_family: bool = False, level_clusters: dict | None = None) -> dict:
    """{key: Unit} over the tests: primary singles, the texture-model members (one primary unit per level and
    kind, tested by single-step minP), texture clusters (per level and kind), secondary singles. The texture
    clusters and lone texture columns are secondary units, or with ``texture_family`` units of the family
    ``texture``. ``level_clusters``: {level: clusters} where a level's tests see other columns than
    ``candidates.clusters`` were made of (between sites: the columns beyond the prediction model's terms,
    :func:`~skidsim.criticism.texture_tests.beyond_lead_clusters`)."""
    tex_fam = "texture" if texture_family else "secondary"
    level_clusters = level_clusters or {}
    clusters_at = {}
    for lv in {t.level for t in tests}:
        cl = level_clusters.get(lv, candidates.clusters)
        clusters_at[lv] = (cl, {c: k for k, members in enumerate(cl) for c in members})
    units = {}
    for j, t in enumerate(tests):
        v = t.variable
        clusters, cluster_of = clusters_at[t.level]
        if t.source == "texture_model":  # the richer texture models: one unit, minP (primary family)
            key, fam, name = ("texture_model", t.level, t.kind), "primary", None
        elif (
            t.kind == "functional_form"
            or (v in candidates.temperature and t.level == "between-site")
            or (v == candidates.mpd and t.kind == "x_speed")
        ):
            key, fam, name = ("single", j), "primary", v
        elif v in cluster_of and len(clusters[cluster_of[v]]) > 1:
            key, fam, name = ("cluster", t.level, t.kind, cluster_of[v]), tex_fam, None
        else:
            fam = tex_fam if v in cluster_of else "secondary"
            key, name = ("single", j), v
        units.setdefault(key, Unit(fam, name))
        units[key].members.append(j)
    return units


def _unit_pvalues(tests, units: dict, pvals: np.ndarray) -> tuple[dict, np.ndarray]:
    """Unit p-values (max-statistic for a cluster, which also names the cluster by its top member; single-step minP
    for the texture-model members, whose designs differ in width: :func:`~skidsim.criticism.permutations.min_p`,
    named by the member of the smallest p) and the single-step maxT (minP) p (Westfall & Young 1993) of every test
    within its unit."""
    unit_p, wy_p = {}, np.ones(len(tests))
    for key, u in units.items():
        mem = u.members
        if len(mem) == 1:
            unit_p[key] = wy_p[mem[0]] = pvals[mem[0]]
            continue
        Tobs = np.array([tests[j].T for j in mem])
        if key[0] == "texture_model":  # members of different widths: minP (each on its own null scale)
            unit_p[key], adj, k = min_p(Tobs, np.stack([tests[j].Tp for j in mem], axis=1))
            u.name = tests[mem[k]].variable
            for j, pj in zip(mem, adj):
                wy_p[j] = pj
            continue
        Tmax_perm = np.max(np.stack([tests[j].Tp for j in mem]), axis=0)
        top = tests[mem[int(np.argmax(Tobs))]].variable
        u.name = f"cluster:{top}"
        unit_p[key] = permutation_p(Tobs.max(), Tmax_perm)
        for j, tj in zip(mem, Tobs):
            wy_p[j] = permutation_p(tj, Tmax_perm)
    return unit_p, wy_p


def _gatekeeper(tests, pvals: np.ndarray, padj: np.ndarray, candidates, fdr: float, method: str) -> None:
    """Where section identity is significant at a level and kind, the section-level covariates of that level and
    kind (coarser groupings such as mix, section-constant numbers) are the candidate explanations of the section
    effect and form a child family adjusted on its own (Yekutieli 2008). Updates ``padj`` in place."""
    n_sections = candidates.section_of.nunique()
    sec_name = [
        t.variable
        for t in tests
        if t.dtype == "categorical" and t.section_level and candidates.covariates[t.variable].nunique() == n_sections
    ]
    for k, t in enumerate(tests):
        if t.variable in sec_name and padj[k] <= fdr:
            fam = [
                j
                for j, u in enumerate(tests)
                if u.section_level and u.variable not in sec_name and u.level == t.level and u.kind == t.kind
            ]
            if fam:
                child = adjust_pvalues(pvals[fam], method)
                for j, pc in zip(fam, child):
                    padj[j] = min(padj[j], max(pc, padj[k]))


@dataclass
class Adjustment:
    """The multiple-testing result of a screening: per test its permutation ``p`` and FDR-scale ``p_adjusted``
    and its unit key (``unit_of``); the ``units`` and their p-values (``unit_p``)."""

    p: np.ndarray
    p_adjusted: np.ndarray
    unit_of: list
    units: dict
    unit_p: dict


def adjust(tests, candidates, options, level_clusters: dict | None = None) -> Adjustment:
    """Permutation p-values, testing units, per-family step-up adjustment (p_adjusted on the fdr scale: the
    family-adjusted unit p / share; for a cluster member at least its within-cluster maxT p), gatekeeper."""
    pvals = np.array([permutation_p(t.T, t.Tp) for t in tests])
    units = testing_units(tests, candidates, has_texture_family(options), level_clusters)
    unit_p, wy_p = _unit_pvalues(tests, units, pvals)
    share = family_shares(options.primary_share, options.texture_share)
    unit_adj = {}
    for fam in share:
        keys = [k for k, u in units.items() if u.family == fam]
        if keys:
            a = adjust_pvalues(np.array([unit_p[k] for k in keys]), options.fdr_method) / share[fam]
            unit_adj.update({k: float(min(x, 1.0)) for k, x in zip(keys, a)})
    padj, unit_of = np.ones(len(tests)), [None] * len(tests)
    for key, u in units.items():
        for j in u.members:
            padj[j] = max(unit_adj[key], wy_p[j])
            unit_of[j] = key
    _gatekeeper(tests, pvals, padj, candidates, options.fdr, options.fdr_method)
    return Adjustment(pvals, padj, unit_of, units, unit_p)
