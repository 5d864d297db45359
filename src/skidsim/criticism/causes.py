"""Causes: one record per screened candidate with its evidence, and the ranking that names the top cause."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
import pandas as pd

from .covariates import names_temperature
from .options import DiagnosisOptions

#: The naming rule of a section effect: a candidate is named for it only when it explains at least this share of
#: the section effect's sum of squares (:func:`section_rule`).
SECTION_SHARE_MIN = 0.5
#: Rule 3d of the naming rule of a section effect: the share of the section effect beyond the texture model that a
#: column must carry to be named for it (:func:`beyond_texture_explanations`).
BEYOND_TEXTURE_SHARE_MIN = 0.9
#: The lower tier of rule 3d: a column that carries at least this share (below :data:`BEYOND_TEXTURE_SHARE_MIN`) is
#: named only when its exact test passes fdr divided by the number of columns that compete for the section effect.
BEYOND_TEXTURE_SHARE_LOW = 0.8
#: The suffix of ``Cause.explains`` for a column named by rule 3d.
BEYOND_TEXTURE = " beyond the texture model"
#: The label of section identity when it is significant and nothing explains most of it.
SECTION_UNEXPLAINED = "section (unexplained)"
#: Label of a between-site section effect that the measured curves do not show beyond a quadratic texture model in
#: the prediction model's terms (rule 6 of :func:`section_rule`).
TEXTURE_MISFIT = "the texture model's misfit (no section effect in the measured curves beyond its quadratic form)"
#: Label of a significant section-level column that explains less than half of a section effect labelled
#: :data:`TEXTURE_MISFIT` (rule 1 of :func:`section_rule` keeps it from the name; rule 6 takes it with that effect).
MISFIT_CORRELATE = (
    "a section-level column that explains less than half of a section effect the texture model's misfit carries"
)
#: How ``Cause.explains`` of a column named for a section effect begins (:func:`section_effect_label`).
SECTION_EFFECT_PREFIX = "section ("


def section_effect_label(level: str, kind: str, beyond_texture: bool = False) -> str:
    """``Cause.explains`` of a section-level column named for the section effect of ``level`` and ``kind``:
    ``section (<level>, <kind>)`` by rule 3b of :func:`section_rule`; with ``beyond_texture`` (rule 3d) followed by
    :data:`BEYOND_TEXTURE`."""
    return f"{SECTION_EFFECT_PREFIX}{level}, {kind})" + (BEYOND_TEXTURE if beyond_texture else "")


def explains_section_effect(explains: str) -> bool:
    """Whether ``Cause.explains`` names a section effect (rules 3b, 3d: :func:`section_effect_label`) rather than a
    finer grouping (rule 3c) or nothing."""
    return str(explains).startswith(SECTION_EFFECT_PREFIX)


#: The kinds of cause :attr:`Cause.category` names.
CATEGORIES = (
    "texture model",
    "drainage",
    "texture parameter",
    "section (unexplained)",
    "section",
    "temperature",
    "sites.csv column",
    "functional form",
)
#: Sources of the texture explanations of a section effect (texture parameters, the texture-model candidate).
TEXTURE_SOURCES = ("texture", "texture_model")


@dataclass(frozen=True)
class Cause:
    """One candidate cause and its evidence.

    ``effect``: RMS (over sites and speed bins) of the residual part the candidate explains, in friction units (mu);
    ``direction``: sign of the association (+1: residual, or its slope over speed for ``x_speed``, grows with the
    covariate; 0 for categorical / functional form); ``cv_gain``: 1 - MSE_with / MSE_without of the cross-validated
    residual model (fraction of held-out residual variance explained; <= 0 means no predictive value);
    ``cv_msr``: cross-validated reduction of the mean squared residual per (site, speed bin) cell, mu^2 (a level
    term acts on every bin of a site), used to rank significant causes: comparable across kinds and levels;
    ``z``: (T - mean T_perm) / sd T_perm (standardised statistic); ``group``: numeric candidates with
    |Pearson r| >= corr_group across sites (itself included), or for texture parameters the members of its
    texture cluster; ``significant``: p_adjusted <= fdr and cv_gain > 0, or named for a significant section
    effect by rule 3b of the naming rule (``explains``; :func:`section_explanations`) or as the coarser description
    of a finer significant grouping by rule 3c (:func:`refinement_descriptions`). ``family``: "primary"
    (functional form and the physical hypotheses: temperature, MPD x speed), "secondary" (every other candidate)
    or "child" (the texture model x speed between sites, asked only under a significant section x speed effect:
    :func:`skidsim.criticism.screening.texture_speed_tests`); ``unit``: the
    tested unit (the variable itself, or ``cluster:<representative>`` for a texture cluster tested by its
    max-statistic); ``unit_p``: the unit's permutation p-value (max-statistic p for a cluster);
    ``texture_pcs``: for a between-site sites.csv covariate that varies within sections, the number of texture
    principal components its test is conditioned on (the texture-adjusted test,
    :func:`skidsim.criticism.adjustment.texture_adjustment`); -1 for the residual test; ``texture_pcs_cv``: the
    leading PCs of the best predictive texture model (leave-one-section-out), against which ``cv_gain`` and the
    texture-refit extension are computed. ``section_share``: the share of the section effect of the tested
    residual (same level and kind) that the candidate explains,
    ``1 - SS_sec(residual net of the candidate) / SS_sec(residual)``
    (:func:`skidsim.criticism.texture_candidate.section_share`; NaN where not computed); ``section_share_main``:
    the same for the site means (between sites); ``section_id``: the candidate is section identity; ``label``:
    what the report names (``section (unexplained)``, ``TEXTURE_MISFIT``, ``MISFIT_CORRELATE``, or the texture
    model in words; empty: the variable);
    ``section_rest_p``: for a section-level column, the permutation p of the section effect left beyond it (between
    sites beyond it and the texture model's member of the leading texture PCs); for
    section identity between sites, the p of a section effect in the measured curves beyond a quadratic texture
    model in the prediction model's terms (:func:`skidsim.criticism.screening.section_rest_tests`; NaN
    elsewhere); ``explains``: the section effect (``section (<level>, <kind>)``) a section-level column is named
    for by rule 3b of :func:`section_rule`, or the finer significant grouping (``<column> (<level>, <kind>)``) it
    describes by rule 3c (:func:`refinement_descriptions`), or ``section (between-site, <kind>) beyond the
    texture model`` by rule 3d (:func:`beyond_texture_explanations`); each makes it significant although its own
    p_adjusted is above fdr (empty otherwise); ``beyond_texture_share``, ``beyond_texture_p``: for a section-level
    sites.csv column between sites, its share of the section effect in the measured curves beyond the quadratic
    texture model of rule 6 and its exact permutation p there
    (:func:`skidsim.criticism.screening.beyond_texture_tests`; NaN elsewhere); ``explanation_rule``,
    ``explained_by``: for a significant section identity, the rule of :func:`section_rule` that explains it and
    the test that does (``<variable> (<level>, <kind>)``): "2" a texture cause, "3" a sites.csv column significant
    by its own test, "3b", "3c" or "3d" one that rule 3b, 3c or 3d made significant (:func:`_column_rule`), "3e"
    a column of the other kind that carries it beyond the texture model; "6" with an empty ``explained_by`` for
    the texture model's misfit (``TEXTURE_MISFIT``); both empty for ``section (unexplained)`` and for every other
    cause.
    """

    variable: str
    level: str
    kind: str
    effect: float
    cv_gain: float
    p_value: float
    p_adjusted: float
    significant: bool
    group: tuple[str, ...] = ()
    cv_msr: float = 0.0
    statistic: float = 0.0
    z: float = 0.0
    direction: int = 0
    source: str = ""
    dtype: str = ""
    section_level: bool = False
    n_sites: int = 0
    n_permutations: int = 0
    family: str = ""
    unit: str = ""
    unit_p: float = float("nan")
    texture_pcs: int = -1
    texture_pcs_cv: int = -1
    section_share: float = float("nan")
    section_share_main: float = float("nan")
    section_id: bool = False
    label: str = ""
    section_rest_p: float = float("nan")
    explains: str = ""
    beyond_texture_share: float = float("nan")
    beyond_texture_p: float = float("nan")
    explanation_rule: str = ""
    explained_by: str = ""

    @property
    def category(self) -> str:
        """What kind of cause this is, in one of :data:`CATEGORIES` (``category`` in causes.json and gain.json):
        ``texture model`` for a texture-model candidate, a texture parameter between sites (labelled as the texture
        model's misfit; the MPD column x speed between sites as the IFI speed constant the texture model misses)
        and section identity labelled ``TEXTURE_MISFIT``; ``drainage`` for the MPD column x speed within sites
        (the only texture test of the primary family there); ``texture parameter`` for the other texture tests
        within sites; ``section (unexplained)`` and ``section`` for section identity (the latter explained by a
        column); ``temperature`` for a temperature column of sites.csv
        (:func:`skidsim.criticism.covariates.temperature_columns`); ``sites.csv column`` for any other sites.csv
        column; ``functional form`` for the shape of the friction law."""
        if reads_as_texture_model(self.source, self.level) or self.label == TEXTURE_MISFIT:
            return "texture model"
        if self.section_id:
            return SECTION_UNEXPLAINED if self.label == SECTION_UNEXPLAINED else "section"
        if self.source == "texture":
            return "drainage" if (self.family == "primary" and self.kind == "x_speed") else "texture parameter"
        if self.variable == "functional_form":
            return "functional form"
        if names_temperature(self.variable, self.dtype):
            return "temperature"
        return "sites.csv column"

    def as_dict(self) -> dict:
        d = asdict(self)
        d["group"] = list(self.group)
        d["category"] = self.category
        return d


def _group(variable: str, candidates, corr: pd.DataFrame, corr_group: float) -> tuple:
    members = candidates.cluster_of(variable)
    if members is not None:
        return tuple(sorted(members))
    if variable in corr.columns:
        row = corr[variable]
        return tuple(sorted(row.index[row >= corr_group]))
    return ()


def reads_as_texture_model(source: str, level: str) -> bool:
    """Whether a test of this ``source`` at this ``level`` is reported as the texture model: a texture-model
    candidate, or a texture parameter between sites (the between-site residual is the texture model's held-out
    error, so a texture column that explains it shows what the texture model misses). One rule for the label of
    :func:`_label` and for :attr:`Cause.category`."""
    return source == "texture_model" or (source == "texture" and level == "between-site")


def _label(t, mpd: str | None) -> str:
    """What the report names for a test: the texture model in words for a texture-model candidate, and for a
    texture parameter between sites the texture model's misfit it shows (for the MPD column x speed: the IFI speed
    constant, drainage through the macrotexture, which the texture model's per-speed terms do not follow); section
    identity is labelled by :func:`section_rule`; else empty (the variable itself)."""
    if not reads_as_texture_model(t.source, t.level):
        return ""
    if t.source == "texture_model":
        return f"the texture model: {t.words}"
    what = "friction level" if t.kind == "main" else "speed shape of friction"
    ifi = " (the IFI speed constant Sp = 14.2 + 89.7 MPD: drainage through the macrotexture)"
    return f"the texture model misses how {t.variable} changes the {what}" + (
        ifi if (t.variable == mpd and t.kind == "x_speed") else ""
    )


def make_causes(tests, adjustment, candidates, options, n_permutations: int) -> list[Cause]:
    """One :class:`Cause` per screened test (``tests``: :class:`~skidsim.criticism.screening.CandidateTest`),
    in test order, from the multiple-testing ``adjustment`` (:func:`skidsim.criticism.fdr.adjust`)."""
    cov, info = candidates.covariates, candidates.info
    num = [c for c in cov.columns if info[c][1] == "numeric"]
    corr = cov[num].corr().abs() if num else pd.DataFrame()
    causes = []
    for j, t in enumerate(tests):
        p, pa = adjustment.p[j], adjustment.p_adjusted[j]
        sd = float(np.std(t.Tp))
        z = (t.T - float(np.mean(t.Tp))) / sd if sd > 0 else 0.0
        cvg = 1.0 - t.sse1 / t.sse0 if t.sse0 > 0 else 0.0
        key = adjustment.unit_of[j]
        causes.append(
            Cause(
                variable=t.variable,
                level=t.level,
                kind=t.kind,
                effect=float(math.sqrt(max(t.T, 0.0) / (t.n * t.S))),
                cv_gain=float(cvg),
                p_value=float(p),
                p_adjusted=float(pa),
                significant=bool(pa <= options.fdr and cvg > 0.0),
                group=_group(t.variable, candidates, corr, options.corr_group),
                cv_msr=float((t.sse0 - t.sse1) / (t.n * t.S)),
                statistic=float(t.T),
                z=float(z),
                direction=t.direction,
                source=t.source,
                dtype=t.dtype,
                section_level=t.section_level,
                n_sites=t.n,
                n_permutations=n_permutations,
                family=adjustment.units[key].family,
                unit=adjustment.units[key].name,
                unit_p=float(adjustment.unit_p[key]),
                texture_pcs=int(t.texture_pcs),
                texture_pcs_cv=int(t.texture_pcs_cv),
                section_share=float(t.section_share),
                section_share_main=float(t.section_share_main),
                section_id=bool(t.section_id),
                label=_label(t, candidates.mpd),
                section_rest_p=float(getattr(t, "section_rest_p", float("nan"))),
                beyond_texture_share=float(getattr(t, "beyond_texture_share", float("nan"))),
                beyond_texture_p=float(getattr(t, "beyond_texture_p", float("nan"))),
            )
        )
    return causes


# ----------------------------------------------------------------------------------------------------------------
# ranking
# ----------------------------------------------------------------------------------------------------------------


def refines(fine: Cause, coarse: Cause, cov: pd.DataFrame) -> bool:
    """Whether ``fine`` (a significant categorical section-level cause) refines ``coarse`` (a significant
    section-level cause of the same level and kind): each level of ``fine`` lies within one value of ``coarse``,
    and ``coarse`` has fewer distinct values, or as many and is a number (a section-constant number names a
    quantity, section identity only the sections). ``cov``: one row per site, the candidate columns."""
    if not (
        fine.significant
        and coarse.significant
        and fine.section_level
        and coarse.section_level
        and fine.dtype == "categorical"
        and fine.level == coarse.level
        and fine.kind == coarse.kind
        and fine.variable in cov.columns
        and coarse.variable in cov.columns
    ):
        return False
    pair = pd.DataFrame({"f": cov[fine.variable], "c": cov[coarse.variable]}).dropna()
    if not len(pair) or int(pair.groupby("f")["c"].nunique().max()) != 1:
        return False
    n_fine, n_coarse = pair["f"].nunique(), pair["c"].nunique()
    return n_coarse < n_fine or (n_coarse == n_fine and coarse.dtype != "categorical")


def _nests(fine: str, coarse: str, cov: pd.DataFrame) -> pd.DataFrame | None:
    """The sections' values of ``fine`` and ``coarse`` (columns ``f``, ``c``; one row per section) when ``fine``'s
    partition of the sections refines ``coarse``'s strictly (every level of ``fine`` within one value of
    ``coarse``, and more levels); else None. Needs a ``section`` column in ``cov`` (one row per site)."""
    if not {"section", fine, coarse} <= set(cov.columns) or fine == coarse:
        return None
    pair = pd.DataFrame({"s": cov["section"], "f": cov[fine], "c": cov[coarse]}).dropna()
    if not len(pair) or int(pair.groupby("s")[["f", "c"]].nunique().max().max()) != 1:
        return None  # not constant within sections
    sec = pair.drop_duplicates("s")
    if int(sec.groupby("f")["c"].nunique().max()) != 1 or sec["f"].nunique() <= sec["c"].nunique():
        return None
    return sec[["f", "c"]]


def split_arrangements(sec: pd.DataFrame) -> int:
    """The number of distinct partitions of the sections that the finer grouping (``sec["f"]``, one row per section)
    can take within the levels of the coarser one (``sec["c"]``) it refines: per coarser level of ``n`` sections
    split into groups of sizes ``k_1 .. k_m``, ``n! / (prod k_i! prod_s m_s!)`` (``m_s`` groups of size ``s``:
    swapping two equal groups gives the same partition), multiplied over the levels. An exact permutation test of
    the finer grouping beyond the coarser one (its labels permuted over the sections within the coarser levels) has
    ``p >= 1 / split_arrangements``."""
    total = 1
    for _, g in sec.groupby("c"):
        sizes = g["f"].value_counts().to_numpy()
        n = int(sizes.sum())
        count = math.factorial(n)
        for k in sizes:
            count //= math.factorial(int(k))
        for m in pd.Series(sizes).value_counts().to_numpy():
            count //= math.factorial(int(m))
        total *= count
    return total


def refinement_descriptions(
    causes: list[Cause], cov: pd.DataFrame, fdr: float, share_min: float = SECTION_SHARE_MIN
) -> list[Cause]:
    """Rule 3c of the naming rule (docs/model-criticism.md): a significant section-level grouping F (a sites.csv
    column) that refines a coarser sites.csv column C (same level and kind; :func:`_nests`) which is not significant
    on its own is described by C, when

    * the split F adds to C cannot be established at any data: its exact permutation test within C's levels has
      :func:`split_arrangements` ``N`` arrangements, ``1 / N > fdr`` (e.g. a free-text comment that sets one of the
      seven HMA sections apart: N = 7, p >= 0.14);
    * C has its own evidence: its permutation p over the sections ``<= fdr`` and ``cv_gain > 0``;
    * C carries at least ``share_min`` of what F explains: ``C.section_share >= share_min F.section_share`` (the
      shares of the same section effect; C's partition is nested in F's).

    Why: what F explains beyond C is, by the design, indistinguishable from section identity (a single section's
    deviation); the part both hold is C's contrast, which has its own evidence, and F's significance is the
    discovery that a section-level grouping matters. C is returned with ``significant`` True and ``explains`` =
    ``F (level, kind)``; the refinement rule (:func:`order_by_refinement`) then ranks it above F. Of several such
    C, the one with the largest share."""
    out = list(causes)
    for F in [c for c in out if c.significant and c.section_level and c.source == "sites" and not c.section_id]:
        if F.dtype != "categorical" or not np.isfinite(F.section_share) or F.section_share <= 0:
            continue
        best, best_share = None, -np.inf
        for C in out:
            if (
                C.significant
                or C is F
                or C.level != F.level
                or C.kind != F.kind
                or not C.section_level
                or C.source != "sites"
                or C.section_id
                or not (C.p_value <= fdr and C.cv_gain > 0.0)
                or not (np.isfinite(C.section_share) and C.section_share >= share_min * F.section_share)
            ):
                continue
            sec = _nests(F.variable, C.variable, cov)
            if sec is None or 1.0 / split_arrangements(sec) <= fdr:
                continue
            if C.section_share > best_share:
                best, best_share = C, C.section_share
        if best is not None:
            out[_pos(out, best)] = replace(best, significant=True, explains=_test_name(F))
    return out


def name_of_test(variable: str, level: str, kind: str) -> str:
    """``<variable> (<level>, <kind>)``: how ``explains`` and ``explained_by`` name a test (one spelling for
    causes.json and report.md)."""
    return f"{variable} ({level}, {kind})"


def _test_name(c: Cause) -> str:
    """:func:`name_of_test` of a cause (rule 3c)."""
    return name_of_test(c.variable, c.level, c.kind)


def _descriptions_at_their_groupings(causes: list[Cause]) -> None:
    """A coarser description of rule 3c (:func:`refinement_descriptions`) takes the rank of the finer grouping it
    describes: it moves right above it, whatever its own cv_msr (it renames that grouping's evidence, no more). In
    place."""
    for C in [c for c in causes if c.explains and not explains_section_effect(c.explains)]:
        F = next((f for f in causes if _test_name(f) == C.explains and f.significant), None)
        if F is not None:
            _move(causes, C, _pos(causes, F) if _pos(causes, C) > _pos(causes, F) else _pos(causes, F) - 1)


def order_by_refinement(causes: list[Cause], cov: pd.DataFrame) -> list[Cause]:
    """Parsimony between section-level groupings: a cause moves right below the first significant coarser one of
    the same level and kind whose partition it refines (:func:`refines`): section identity below mix, a free-text
    comment that splits the mixes below mix. The finer one holds the coarser one's evidence; the coarser names the
    effect with fewer levels. Other causes keep their order."""
    causes = list(causes)
    moved = True
    while moved:  # terminates: a cause moves only below a number or a grouping with strictly fewer levels
        moved = False
        for k, c in enumerate(causes):
            below = [j for j in range(k + 1, len(causes)) if refines(c, causes[j], cov)]
            if below:
                causes.insert(below[0], causes.pop(k))
                moved = True
                break
    return causes


def _mpd_above_its_clusters(causes: list[Cause], mpd_col: str | None) -> None:
    """The physical hypothesis on the MPD column ranks above the texture clusters that hold MPD (e.g. drainage
    makes the texture model misfit the level of shallow-texture sites: the macrotexture height cluster is
    significant between sites; MPD x speed names the mechanism), and above a texture-model candidate x speed built
    on MPD (``texture_model[nonlinear in <MPD>]``, x_speed: its cubic nests the drainage hypothesis's linear
    column, and the physical hypothesis is the more specific name). In place."""
    if mpd_col is None:
        return
    mp = [k for k, c in enumerate(causes) if c.significant and c.variable == mpd_col and c.kind == "x_speed"]

    def holds_mpd(c: Cause) -> bool:
        if c.source == "texture_model":
            axes = (mpd_col, f"log({mpd_col})")
            return c.kind == "x_speed" and c.variable in {f"texture_model[nonlinear in {a}]" for a in axes}
        return mpd_col in c.group and c.unit is not None and str(c.unit).startswith("cluster:")

    above = [k for k, c in enumerate(causes) if c.significant and mp and k < mp[0] and holds_mpd(c)]
    if mp and above:
        causes.insert(above[0], causes.pop(mp[0]))


def _shape_below_its_covariate(causes: list[Cause]) -> None:
    """Hierarchy of within-site shapes: where the functional form and a covariate x speed are both significant
    within sites, the shape's amplitude follows the covariate and the shared shape is its mean over the sites; the
    covariate names the mechanism (its model, shared profile + covariate x profile, nests the functional form's),
    so the functional form ranks right below the first such cause. In place."""
    ff = [k for k, c in enumerate(causes) if c.significant and c.kind == "functional_form" and c.level == "within-site"]
    xs = [k for k, c in enumerate(causes) if c.significant and c.kind == "x_speed" and c.level == "within-site"]
    if ff and xs and ff[0] < xs[0]:
        causes.insert(xs[0], causes.pop(ff[0]))


def _share_of(c: Cause, kind: str) -> float:
    """The share of a section effect of ``kind`` that cause ``c`` explains (its own kind, or the site means)."""
    if c.kind == kind:
        return c.section_share
    return c.section_share_main if kind == "main" else float("nan")


def _explains(c: Cause, kind: str, share_min: float) -> bool:
    s = _share_of(c, kind)
    return bool(np.isfinite(s) and s >= share_min)


def _explanation(c: Cause, S: Cause, texture: bool, share_min: float) -> bool:
    """Whether ``c`` explains at least ``share_min`` of the section effect ``S``: a texture cause (``texture``;
    of S's kind, or of any kind for a section effect on the site means) or a section-level column of S's kind."""
    if c is S or not c.significant or c.level != S.level:
        return False
    K = S.kind
    if texture:
        return c.source in TEXTURE_SOURCES and (c.kind == K or K == "main") and _explains(c, K, share_min)
    return c.kind == K and c.section_level and not c.section_id and (_explains(c, K, share_min) or _names(c, S))


def _names(c: Cause, S: Cause) -> bool:
    """Whether column ``c`` was named for the section effect ``S`` by rule 3d (:func:`section_explanations`): it
    explains most of S beyond the texture model, whatever its share of the residual's section effect."""
    named = c.explains == section_effect_label(S.level, S.kind, beyond_texture=True)
    return named and np.isfinite(c.beyond_texture_share)


def _column_explains(c: Cause, S: Cause, causes: list[Cause], share_min: float) -> float:
    """The share of the section effect ``S`` that ``c``, a significant sites.csv column (not section identity;
    section-level, or varying within sections as a temperature does) of any level and kind, explains through its
    test at S's level: of S's kind, or of any kind when S is the site means' effect (the same basis on the same
    site means). A column established at one level or kind (e.g. the polished aggregate x speed within sites) is
    thereby the explanation of the section effect it carries at another, even where its own test there has less
    power than section identity's; a site-level column whose section means carry most of the section effect (the
    test temperature, drawn per section and per site) is its explanation, although section identity, with a free
    mean per section, explains more of the site means. NaN when it does not explain at least ``share_min``."""
    if c is S or not c.significant or not (c.section_level or c.source == "sites") or c.section_id:
        return float("nan")
    shares = [
        _share_of(x, S.kind)
        for x in causes
        if x.variable == c.variable and x.level == S.level and (x.kind == S.kind or S.kind == "main")
    ]
    shares = [v for v in shares if np.isfinite(v) and v >= share_min]
    if _names(c, S):
        shares.append(c.beyond_texture_share)
    return max(shares) if shares else float("nan")


def _pos(causes: list[Cause], c: Cause) -> int:
    """Index of ``c`` in ``causes`` by identity."""
    return next(k for k, x in enumerate(causes) if x is c)


def _move(causes: list[Cause], c: Cause, to: int) -> None:
    """Move ``c`` to index ``to`` (an index of the list without ``c``). In place."""
    causes.pop(_pos(causes, c))
    causes.insert(to, c)


def _explains_its_own(c: Cause, S: Cause, share_min: float) -> bool:
    """Whether ``c`` is a significant texture cause of S's level and another kind that explains at least
    ``share_min`` of the section effect of its own kind, whether or not that section effect is significant (a
    texture x speed cause that carries most of the section means' speed shapes, beside a section effect on the
    site means that it does not carry)."""
    return (
        c.significant
        and c.level == S.level
        and c.kind != S.kind
        and c.source in TEXTURE_SOURCES
        and _explains(c, c.kind, share_min)
    )


def _column_beyond_texture(S: Cause, causes: list[Cause], share_min: float, fdr: float) -> Cause | None:
    """A significant section-level sites.csv column (not section identity) of another kind at S's level that
    explains the section effect of its own kind (at least ``share_min`` of it, or named for it by rule 3d; a
    column that correlates with it by chance moves below it, :func:`section_rule`) and whose test of S's kind
    carries at least ``share_min`` of S beyond the texture model
    (``beyond_texture_share``, with its exact permutation test ``beyond_texture_p <= fdr``,
    :func:`beyond_texture_explanations`): the column is then the explanation of S too, as a column established at
    one kind is of the section effect it carries at another (:func:`_column_explains`), although that share is
    below rule 3d's ``BEYOND_TEXTURE_SHARE_MIN`` for naming a column that is significant nowhere (traffic polishing
    on a Rado curve: significant on the section x speed effect, 0.90 of the section means' effect beyond the texture
    model). The significant cause with the largest such share, or None."""
    carried = {}
    for x in causes:
        if x.level == S.level and x.kind == S.kind and x.section_level and not x.section_id and x is not S:
            b = x.beyond_texture_share
            if np.isfinite(b) and b >= share_min and x.beyond_texture_p <= fdr:
                carried[x.variable] = max(b, carried.get(x.variable, 0.0))
    cols = [
        c
        for c in causes
        if c.significant
        and c.level == S.level
        and c.kind != S.kind
        and c.section_level
        and not c.section_id
        and c.source == "sites"
        and c.variable in carried
        and (_explains(c, c.kind, share_min) or _names(c, c))  # c's own level and kind: named there by 3d
    ]
    return max(cols, key=lambda c: carried[c.variable]) if cols else None


def _texture_above_unexplained(causes: list[Cause], used: set, share_min: float = SECTION_SHARE_MIN) -> None:
    """An unexplained section effect ranks below a texture cause that explains another section effect of its level
    (``used``: the ids of the texture explanations rule 2 moved or found; or a significant texture cause of another
    kind that explains at least ``share_min`` of its own kind's section effect, significant or not,
    :func:`_explains_its_own`): the texture model, or the texture measure, is then established as a misfit that
    clusters by section (e.g. the texture model explains the section x speed effect), and the section effect it
    does not explain (the section means) stays listed, labelled unexplained, right below it. The largest share of
    its own section effect first; the causes moved are added to ``used``. In place."""
    for S in [c for c in causes if c.section_id and c.significant and c.label == SECTION_UNEXPLAINED]:
        expl = [
            c
            for c in causes
            if (id(c) in used or _explains_its_own(c, S, share_min))
            and c.level == S.level
            and _pos(causes, c) > _pos(causes, S)
        ]
        if expl:
            best = max(expl, key=lambda c: c.section_share)
            used.add(id(best))
            _move(causes, best, _pos(causes, S))


def section_rule(causes: list[Cause], share_min: float = SECTION_SHARE_MIN, fdr: float | None = None) -> list[Cause]:
    """The naming rule of a section effect (docs/model-criticism.md, section 2, "Naming a section effect").

    For every significant section identity S (level L, kind K):

    * a significant section-level column of L and K that explains less than ``share_min`` of S's sum of squares
      (``section_share``) is not named for it: it moves right below S (a column that correlates with the section
      means by chance, however little it explains, no longer takes the name);
    * a significant texture explanation at L (a texture cluster, MPD, or the texture model; of kind K, or of any
      kind when K is ``main`` and it explains that share of the site means' section effect) that explains at least
      ``share_min`` of it moves right above S (the one with the largest share): the texture model, or the texture
      measure, is the cause; unless a sites.csv column of the next rule also explains that share and predicts
      held-out sites better (a larger ``cv_msr``), which then moves right above S instead (a section-clustered
      test temperature that a 3-column texture member also fits over 12 sections);
    * else a significant sites.csv column (section-level, or varying within sections) that explains at least
      ``share_min`` of S through its test at L (:func:`_column_explains`: of kind K, or of any kind when K is
      ``main``; the column itself may be significant at another level or kind) moves right above S (the one with
      the largest share);
    * (rule 3b, :func:`section_explanations`, applied by :func:`rank_causes` before the ranking: a section-level
      column that carries S and leaves nothing beyond it is significant by then and counts as such a column;
      rule 3d, :func:`beyond_texture_explanations`: so is a column that carries most of S beyond the texture
      model);
    * else a significant section-level column of another kind that explains its own kind's section effect and
      whose test of S's kind carries at least ``share_min`` of S beyond the texture model
      (:func:`_column_beyond_texture`) moves right above S;
    * if no explanation (such a texture cause, or such a column) ranks above S, S is labelled
      ``section (unexplained)``; it then ranks below a texture explanation of another section effect of its level
      (:func:`_texture_above_unexplained`: a texture cause rule 2 moved for another section effect, or a
      significant texture cause of another kind that explains at least ``share_min`` of its own kind's section
      effect, significant or not);
    * (rule 6) unless the measured curves show no section effect beyond a quadratic texture model in the
      prediction model's terms (``S.section_rest_p > fdr``, :func:`skidsim.criticism.screening.section_rest_tests`;
      None: the default of :class:`~skidsim.criticism.options.DiagnosisOptions`): S is then the texture model's
      misfit (its error on held-out sections, or a curvature of friction in its terms that clusters by section
      through the per-section textures), labelled ``TEXTURE_MISFIT``, not significant, and it goes right below
      every significant cause; so does every significant section-level column of L and K that the first rule kept
      from the name (it explains less than ``share_min`` of S), labelled ``MISFIT_CORRELATE``: a column named
      instead of section must explain most of the section effect, else the cause is section or the texture model
      (issue 33, item 2).

    Then a texture-model candidate that explains no significant section effect goes below every other significant
    cause (it is evidence about the texture model, not the first explanation of a site-level residual)."""
    fdr = DiagnosisOptions().fdr if fdr is None else fdr
    causes = list(causes)
    used, held_out = set(), []
    for S0 in [c for c in causes if c.section_id and c.significant]:
        S, L, K = S0, S0.level, S0.kind
        weak = [
            c
            for c in causes
            if c.significant and c.level == L and c.kind == K and c.section_level and not c.section_id
            if not _explanation(c, S, False, share_min)
        ]
        for c in weak:
            if _pos(causes, c) < _pos(causes, S):
                _move(causes, c, _pos(causes, S))  # right below S (S moved up by one)
        expl = [c for c in causes if _explanation(c, S, True, share_min)]
        cols = {id(c): v for c in causes if np.isfinite(v := _column_explains(c, S, causes, share_min))}
        used.update(id(c) for c in expl)
        col_best = max((c for c in causes if id(c) in cols), key=lambda c: cols[id(c)], default=None)
        best = max(expl, key=lambda c: _share_of(c, K)) if expl else col_best
        if expl and col_best is not None and col_best.cv_msr > best.cv_msr:
            best = col_best  # the column predicts held-out sites better: it is the better explanation
        if best is not None and _pos(causes, best) > _pos(causes, S):
            _move(causes, best, _pos(causes, S))
        k = _pos(causes, S)
        if best is not None:
            rule = _column_rule(best) if id(best) in cols else "2"
            S = causes[k] = replace(S, explanation_rule=rule, explained_by=_test_name(best))
        if not any(_explanation(c, S, True, share_min) or id(c) in cols for c in causes[:k]):
            col = _column_beyond_texture(S, causes, share_min, fdr)
            if col is not None:
                if _pos(causes, col) > k:
                    _move(causes, col, k)
                k = _pos(causes, S)
                S = causes[k] = replace(S, explanation_rule="3e", explained_by=_test_name(col))
            elif np.isfinite(S.section_rest_p) and S.section_rest_p > fdr:
                causes[k] = replace(S, label=TEXTURE_MISFIT, significant=False, explanation_rule="6")
                held_out.append(causes[k])
                for c in weak:  # rule 1's columns go with the misfit they correlate with
                    j = _pos(causes, c)
                    causes[j] = replace(c, significant=False, label=MISFIT_CORRELATE, explanation_rule="6")
                    held_out.append(causes[j])
            else:
                causes[k] = replace(S, label=SECTION_UNEXPLAINED)
    for S in held_out:  # no longer significant: right below every significant cause
        causes.pop(_pos(causes, S))
        causes.insert(max((i for i, c in enumerate(causes) if c.significant), default=-1) + 1, S)
    _texture_above_unexplained(causes, used, share_min)
    tm = [c for c in causes if c.significant and c.source == "texture_model" and id(c) not in used]
    others = [c for c in causes if c.significant and c.source != "texture_model"]
    if tm and others:
        last = max(_pos(causes, c) for c in others)
        demote = [c for c in tm if _pos(causes, c) < last]
        rest = [c for c in causes if all(c is not d for d in demote)]
        pos = max(_pos(rest, c) for c in others) + 1
        causes = rest[:pos] + demote + rest[pos:]
    return causes


def _column_rule(c: Cause) -> str:
    """The rule that made the sites.csv column ``c`` a significant explanation of a section effect (rule 3 of
    :func:`section_rule`): "3b" (``explains`` a section effect, :func:`section_explanations`), "3d" (``explains``
    it beyond the texture model, :func:`beyond_texture_explanations`, either tier), "3c" (``explains`` a finer
    grouping, :func:`refinement_descriptions`), "3" (significant by its own test)."""
    if c.explains.endswith(BEYOND_TEXTURE):
        return "3d"
    if explains_section_effect(c.explains):
        return "3b"
    return "3c" if c.explains else "3"


def section_explanations(causes: list[Cause], fdr: float, share_min: float = SECTION_SHARE_MIN) -> list[Cause]:
    """Rule 3b of the naming rule of a section effect: the section-level column that explains a significant
    section effect S (level L, kind K) is named for it although its own test does not pass the multiplicity
    control of the section-level columns, when

    * no texture cause explains at least ``share_min`` of S (rule 2 has precedence);
    * of the section-level sites.csv columns of L and K it explains the largest share of S, at least ``share_min``,
      and no significant column explains a larger share (rule 3 would name that one);
    * its own exact permutation test over the sections (the nested permutations) has ``p_value <= fdr``, and it
      predicts held-out sections (``cv_gain > 0``);
    * no section effect is left beyond it: ``section_rest_p > fdr``
      (:func:`skidsim.criticism.screening.section_rest_tests`; between sites beyond it and the texture model's
      member of the leading texture PCs, whose misfit clusters by section through the per-section textures).

    Why: S is the discovery (its p_adjusted passed the false-discovery control); the column is its description.
    With 12 sections, a column whose one level of 3 sections carries the effect cannot reach a permutation p below
    about 4 / C(12, 3) = 1 / 55 (the arrangements that keep those sections in one level), while the child family of
    the 7 section-level columns asks p <= fdr / 7 of the first; labelling S ``section (unexplained)`` when one
    column carries it and nothing is left beyond it misnames it. The column is returned with ``significant`` True
    and ``explains`` = ``section (L, K)``; its p_value and p_adjusted are unchanged (the report shows both)."""
    out = list(causes)
    for S in [c for c in out if c.section_id and c.significant]:
        L, K = S.level, S.kind
        if any(_explanation(c, S, True, share_min) for c in out):
            continue
        cols = [
            c
            for c in out
            if c.level == L
            and c.kind == K
            and c.section_level
            and not c.section_id
            and c.source == "sites"
            and np.isfinite(c.section_share)
        ]
        if not cols:
            continue
        best = max(cols, key=lambda c: c.section_share)
        sig = [v for c in out if np.isfinite(v := _column_explains(c, S, out, share_min))]
        if (
            best.significant
            or (sig and max(sig) > best.section_share)
            or not (best.section_share >= share_min and best.p_value <= fdr and best.cv_gain > 0.0)
            or not (np.isfinite(best.section_rest_p) and best.section_rest_p > fdr)
        ):
            continue
        out[_pos(out, best)] = replace(best, significant=True, explains=section_effect_label(L, K))
    return out


def beyond_texture_explanations(causes: list[Cause], fdr: float, share_min: float = SECTION_SHARE_MIN) -> list[Cause]:
    """Rule 3d of the naming rule of a section effect: between sites, the section-level sites.csv column that
    carries most of the section effect **beyond the texture model** is named for a significant section effect S
    (kind K) that no texture cause and no column explains through the residual's own shares (rules 2, 3, 3b), when

    * the measured curves hold a section effect beyond the quadratic texture model (``S.section_rest_p <= fdr``,
      the test of rule 6: that effect is not the texture model's);
    * of the section-level columns of kind K the column carries the largest share of that effect
      (``beyond_texture_share``, :func:`skidsim.criticism.screening.beyond_texture_tests`), at least
      :data:`BEYOND_TEXTURE_SHARE_MIN`, and its exact permutation test over the sections there has
      ``beyond_texture_p <= fdr``;
    * or it is numeric (one degree of freedom over the sections: a categorical column of k levels fits k - 1 of
      the 11 section contrasts of 12 sections for free), carries at least :data:`BEYOND_TEXTURE_SHARE_LOW`, and
      that test has ``beyond_texture_p <= fdr / m``, m the number of section-level columns of kind K tested there
      (Bonferroni over the columns the largest share is chosen from). Below 0.9 a categorical chance correlate of
      a real section effect that no column holds carries such shares (the aggregate 0.87, the mix 0.83 with exact
      p 0.006 in ``+sectionlatent`` campaigns of the rates); traffic polishing on Rado curves carries 0.81-0.90
      with exact p 0.0005-0.002.

    Why: between sites the residual is the texture model's held-out error plus what acts beyond the texture. Where
    the texture model's misfit clusters by section (the texture designs are drawn per section) it dilutes a
    column's share of the residual's section effect below ``share_min`` although the column carries nearly all of
    what the texture does not describe (spectral categorical x speed campaigns of the rates: the aggregate 0.35-0.66
    of the residual's section effect, 0.94-0.99 of the effect beyond the texture model). The column is returned
    with ``significant`` True and ``explains`` = ``section (between-site, K) beyond the texture model``; its
    p_value and p_adjusted are unchanged and the report gives both shares."""
    out = list(causes)
    for S in [c for c in out if c.section_id and c.significant and c.level == "between-site"]:
        K = S.kind
        if not (np.isfinite(S.section_rest_p) and S.section_rest_p <= fdr):
            continue
        if any(_explanation(c, S, True, share_min) or np.isfinite(_column_explains(c, S, out, share_min)) for c in out):
            continue  # a texture cause (rule 2) or a significant column (rules 3, 3b) explains S
        cols = [c for c in out if c.level == S.level and c.kind == K and np.isfinite(c.beyond_texture_share)]
        if not cols:
            continue
        best = max(cols, key=lambda c: c.beyond_texture_share)
        b, p = best.beyond_texture_share, best.beyond_texture_p
        low = best.dtype == "numeric" and b >= BEYOND_TEXTURE_SHARE_LOW
        if (b >= BEYOND_TEXTURE_SHARE_MIN and p <= fdr) or (low and p <= fdr / len({c.variable for c in cols})):
            label = section_effect_label(S.level, K, beyond_texture=True)
            out[_pos(out, best)] = replace(best, significant=True, explains=label)
    return out


def _tie(x: float) -> float:
    """``x`` to 10 significant digits: an affine copy of a column (the texture stage's ETD = 1.1 MPD) gets the same
    statistics up to rounding in the last bits, which should not decide the order."""
    return float(f"{x:.10g}")


def _rank_key(c: Cause, mpd_col: str | None) -> tuple:
    """The ranking's sort key (:func:`rank_causes`): significant first, then cv_msr (significant) or p_adjusted,
    then z; on ties (to 10 digits) the MPD column first."""
    return (not c.significant, _tie(-c.cv_msr) if c.significant else c.p_adjusted, _tie(-c.z), c.variable != mpd_col)


def rank_causes(causes: list[Cause], cov: pd.DataFrame, mpd_col: str | None, fdr: float | None = None) -> list[Cause]:
    """Rules 3b, 3d and 3c of the naming rule of a section effect first (:func:`section_explanations`,
    :func:`beyond_texture_explanations`, :func:`refinement_descriptions`, at ``fdr``; None: the default of
    :class:`~skidsim.criticism.options.DiagnosisOptions`); then
    significant causes first, among them by ``cv_msr`` (predictive evidence), the rest by ``p_adjusted``, then
    ``z``, and on ties (to 10 significant digits) the MPD column ``mpd_col`` first (a texture table also holds its
    affine copies, e.g. ETD); then the parsimony rules: :func:`order_by_refinement`, the naming rule of a section effect
    (:func:`section_rule`), MPD x speed above the texture clusters holding MPD, the within-site functional form
    below a significant within-site covariate x speed."""
    if fdr is None:
        fdr = DiagnosisOptions().fdr
    causes = section_explanations(causes, fdr)
    causes = beyond_texture_explanations(causes, fdr)
    causes = refinement_descriptions(causes, cov, fdr)
    causes = sorted(causes, key=lambda c: _rank_key(c, mpd_col))
    _descriptions_at_their_groupings(causes)
    causes = order_by_refinement(causes, cov)
    causes = section_rule(causes, fdr=fdr)
    _mpd_above_its_clusters(causes, mpd_col)
    _shape_below_its_covariate(causes)
    return causes


def named_cause(causes: list[Cause]) -> Cause | None:
    """The top significant cause, or None."""
    return causes[0] if causes and causes[0].significant else None
