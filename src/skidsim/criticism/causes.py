"""Causes: one record per screened candidate with its evidence (:class:`Cause`), the labels and categories the
report gives it, how a test is named, and where a cause sits in a ranked list (:func:`_pos`, :func:`_move`: the
rules that reorder the ranking share them).

The naming rule of a section effect is :mod:`.section_naming`, the parsimony between nested section-level groupings
:mod:`.refinement`, and the ranking that names the top cause :mod:`.ranking`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from .covariates import names_temperature

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


#: Label prefix of a within-site functional form where the measured curves are not exponential decays of speed
#: (:func:`skidsim.criticism.wlf.label_law_form`): the shape the sites share is the exponential-decay law's form.
LAW_FORM = "the exponential-decay law's form"


#: Label of a section-level sites.csv column significant between sites whose effect the measured curves do not show
#: beyond the quadratic texture model (rule 7, :func:`skidsim.criticism.section_naming.columns_beyond_texture`).
NOT_BEYOND_TEXTURE = (
    "a section-level column whose effect the measured curves do not show beyond the texture model "
    "(it follows the texture model's misfit)"
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
    "friction law",
)

#: The categories of :data:`CATEGORIES` that are faults of the model itself, not of a variable of the data: the
#: texture model, and the exponential-decay law's form where the measured curves are not exponential decays.
MODEL_CATEGORIES = ("texture model", "friction law")


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
    :func:`skidsim.criticism.texture_tests.texture_speed_tests`); ``unit``: the
    tested unit (the variable itself, or ``cluster:<representative>`` for a texture cluster tested by its
    max-statistic, or the texture model's member of the smallest p); ``unit_p``: the unit's permutation p-value
    (max-statistic p for a cluster, single-step minP p for the texture model's members);
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
    model in the prediction model's terms (:func:`skidsim.criticism.section_tests.section_rest_tests`; NaN
    elsewhere); ``explains``: the section effect (``section (<level>, <kind>)``) a section-level column is named
    for by rule 3b of :func:`section_rule`, or the finer significant grouping (``<column> (<level>, <kind>)``) it
    describes by rule 3c (:func:`refinement_descriptions`), or ``section (between-site, <kind>) beyond the
    texture model`` by rule 3d (:func:`beyond_texture_explanations`); each makes it significant although its own
    p_adjusted is above fdr (empty otherwise); ``beyond_texture_share``, ``beyond_texture_p``: for a section-level
    sites.csv column between sites, its share of the section effect in the measured curves beyond the quadratic
    texture model of rule 6 and its exact permutation p there
    (:func:`skidsim.criticism.section_tests.beyond_texture_tests`; NaN elsewhere); ``explanation_rule``,
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
        column; ``friction law`` for a within-site functional form labelled :data:`LAW_FORM` (the measured curves
        are not exponential decays of speed, so the shape is the exponential-decay law's form: a cause in the model,
        like the texture model) and ``functional form`` for any other functional form (the simulated curve's
        shape)."""
        if reads_as_texture_model(self.source, self.level) or self.label == TEXTURE_MISFIT:
            return "texture model"
        if self.section_id:
            return SECTION_UNEXPLAINED if self.label == SECTION_UNEXPLAINED else "section"
        if self.source == "texture":
            return "drainage" if (self.family == "primary" and self.kind == "x_speed") else "texture parameter"
        if self.variable == "functional_form":
            return "friction law" if self.label.startswith(LAW_FORM) else "functional form"
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
    """One :class:`Cause` per screened test (``tests``: :class:`~skidsim.criticism.levels.CandidateTest`),
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


def name_of_test(variable: str, level: str, kind: str) -> str:
    """``<variable> (<level>, <kind>)``: how ``explains`` and ``explained_by`` name a test (one spelling for
    causes.json and report.md)."""
    return f"{variable} ({level}, {kind})"


def _test_name(c: Cause) -> str:
    """:func:`name_of_test` of a cause (rule 3c)."""
    return name_of_test(c.variable, c.level, c.kind)


def _pos(causes: list[Cause], c: Cause) -> int:
    """Index of ``c`` in ``causes`` by identity."""
    return next(k for k, x in enumerate(causes) if x is c)


def _move(causes: list[Cause], c: Cause, to: int) -> None:
    """Move ``c`` to index ``to`` (an index of the list without ``c``). In place."""
    causes.pop(_pos(causes, c))
    causes.insert(to, c)
