"""The naming rule of a section effect (docs/model-criticism.md, section 2, "Naming a section effect"): which
texture cause or sites.csv column is named for a significant section identity, or whether it is ``section
(unexplained)`` or the texture model's misfit (:func:`section_rule`), and the rules that make a column the
explanation of a section effect although its own test does not pass the multiplicity control (rule 3b,
:func:`section_explanations`; rule 3d, :func:`beyond_texture_explanations`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .causes import (
    BEYOND_TEXTURE,
    MISFIT_CORRELATE,
    NOT_BEYOND_TEXTURE,
    SECTION_UNEXPLAINED,
    TEXTURE_MISFIT,
    TEXTURE_SOURCES,
    Cause,
    _move,
    _pos,
    _test_name,
    explains_section_effect,
    section_effect_label,
)
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
      prediction model's terms (``S.section_rest_p > fdr``, :func:`skidsim.criticism.section_tests.section_rest_tests`;
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
      (:func:`skidsim.criticism.section_tests.section_rest_tests`; between sites beyond it and the texture model's
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
      (``beyond_texture_share``, :func:`skidsim.criticism.section_tests.beyond_texture_tests`), at least
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


def columns_beyond_texture(causes: list[Cause], fdr: float) -> list[Cause]:
    """Rule 7 of the naming rule of a section effect: a section-level sites.csv column significant between sites (on
    its own, or by rule 3b) whose effect the measured curves do not show beyond the quadratic texture model
    (``beyond_texture_p > fdr``, :func:`skidsim.criticism.section_tests.beyond_texture_tests`: the column tested
    over the sections on the measured curves net of that model) is not named: ``significant`` false, label
    ``NOT_BEYOND_TEXTURE``, explanation rule "7". Why: between sites the residual is the held-out error of the
    texture model, whose misfit clusters by section through the per-section textures; a column that acts on friction
    beyond the texture (traffic, a mix, an aggregate) acts on the measured curves beyond the texture model too, where
    a column that only follows the texture model's misfit across the 12 sections does not. Applied before the
    ranking, so the rules of a section effect do not take such a column as an explanation. No test (NaN: no
    texture model terms, or the column in the texture model's span) leaves the column as it is."""
    out = []
    for c in causes:
        if (
            c.significant
            and c.source == "sites"
            and c.level == "between-site"
            and c.section_level
            and not c.section_id
            and np.isfinite(c.beyond_texture_p)
            and c.beyond_texture_p > fdr
        ):
            c = replace(c, significant=False, label=NOT_BEYOND_TEXTURE, explanation_rule="7")
        out.append(c)
    return out
