"""Refinement between section-level groupings: a grouping whose partition of the sections nests in a coarser one
ranks below it (:func:`order_by_refinement`), and a coarser sites.csv column describes a finer significant grouping
whose extra split no data could establish (rule 3c of the naming rule, :func:`refinement_descriptions`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

from .causes import Cause, _move, _pos, _test_name, explains_section_effect
from .section_naming import SECTION_SHARE_MIN


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
