"""The texture model as a candidate cause between sites (docs/model-criticism.md, section 2, "The texture model as
a candidate cause"): the tests of its richer members on the site means and, under a significant section x speed
effect, on the speed shapes (a child family); and the texture columns taken beyond the prediction model's own
texture terms (:func:`lead_basis`), the part of them the between-site residual can still show.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .adjustment import lead_design, residualise
from .causes import Cause, make_causes
from .covariates import CandidateSet, texture_clusters
from .crossval import cv_sse_design, folds
from .levels import CandidateTest, LevelContext, LevelData, level_data
from .options import DiagnosisOptions
from .permutations import perm_stats
from .texture_candidate import TextureMember, member_basis, members_of, section_share


def texture_model_tests(ctx: LevelContext, members: list[TextureMember], kind: str = "main") -> list[CandidateTest]:
    """The texture model as a candidate cause between sites: each richer texture model
    (:func:`~skidsim.criticism.texture_candidate.texture_members`) tested against the residual of ``kind`` (the
    site means, ``main``; or the centred speed profiles, ``x_speed``, as every covariate x speed between sites:
    a free profile per design column) by the nested permutations of every covariate (exact: the members are built
    from the texture alone); ``cv_gain`` is the leave-one-section-out gain of the residual model
    ``[1, member design]`` over the training mean. The members of one kind form one testing unit
    (:func:`skidsim.criticism.fdr.testing_units`; ``x_speed``: :func:`texture_speed_tests`)."""
    if ctx.data.level != "between-site" or not members or kind not in ctx.Ys:
        return []
    Y = ctx.Ys[kind]
    Qs = [member_basis(m) for m in members]
    Q = np.concatenate(Qs, axis=1)
    owner = np.concatenate([np.full(q.shape[1], k) for k, q in enumerate(Qs)])
    A = Q.T @ Y
    T = np.bincount(owner, weights=(A * A).sum(axis=1), minlength=len(members))
    Tp = perm_stats(Y, Q, owner, len(members), ctx.perm_nested)
    fold = folds(ctx.sec, False)
    out = []
    for k, m in enumerate(members):
        sse0, sse1 = cv_sse_design(Y, m.design, fold)
        share = section_share(Qs[k], Y, ctx.sec)
        share_main = section_share(Qs[k], ctx.Ys["main"], ctx.sec) if "main" in ctx.Ys else float("nan")
        out.append(
            CandidateTest(
                m.variable,
                ctx.data.level,
                kind,
                float(T[k]),
                Tp[:, k],
                sse0,
                sse1,
                ctx.n,
                Y.shape[1],
                0,
                "texture_model",
                "texture_model",
                False,
                section_share=share,
                section_share_main=share_main,
                words=m.words if kind == "main" else m.speed_words,
            )
        )
    return out


def texture_speed_tests(
    ctx: LevelContext, members: list[TextureMember], causes: list[Cause], cands: CandidateSet, options, P: int
) -> list[Cause]:
    """The texture model as the explanation of a section x speed effect between sites (docs/model-criticism.md,
    section 2, "The texture model as a candidate cause"): asked only where section identity x speed between
    sites is significant in ``causes`` (the screening's causes), as a child family of that section effect
    (Yekutieli 2008; the gatekeeper of :func:`skidsim.criticism.fdr.adjust` for the section-level columns): the
    members' x_speed tests (:func:`texture_model_tests`) are one unit tested by single-step minP
    (:func:`~skidsim.criticism.permutations.min_p`: the members' designs differ in width), each member's p_adjusted
    ``max(unit p, its single-step minP p, the section effect's p_adjusted)``. Their permutations are
    the level's nested permutations (no new draws: every other test is unchanged). Family ``child``."""
    from .fdr import Adjustment, Unit
    from .permutations import min_p, permutation_p

    parent = [c for c in causes if c.section_id and c.significant and c.level == "between-site" and c.kind == "x_speed"]
    tests = texture_model_tests(ctx, members, "x_speed") if parent else []
    if not tests:
        return []
    p = np.array([permutation_p(t.T, t.Tp) for t in tests])
    unit_p, adj, top = min_p(np.array([t.T for t in tests]), np.stack([t.Tp for t in tests], axis=1))
    gate = min(c.p_adjusted for c in parent)
    padj = np.array([max(unit_p, a, gate) for a in adj])
    key = ("texture_model_child", "between-site", "x_speed")
    unit = Unit("child", tests[top].variable, list(range(len(tests))))
    adjustment = Adjustment(p, padj, [key] * len(tests), {key: unit}, {key: unit_p})
    return make_causes(tests, adjustment, cands, options, P)


def _members(ctx: LevelContext, cands: CandidateSet, pcs: pd.DataFrame | None, lead) -> list[TextureMember]:
    """The richer texture models of a between-site level (none within sites or without texture columns)."""
    if ctx.data.level != "between-site":
        return []
    if not any(cands.info[c][0] == "texture" for c in cands.covariates.columns):
        return []
    return members_of(cands, ctx.data.site_ids, pcs, lead)


def lead_basis(data: LevelData, cov: pd.DataFrame, lead) -> np.ndarray | None:
    """``[1, lead columns]`` (n_sites, 1 + k) of the between-site sites of ``data``: the prediction model's terms
    ``lead`` (:func:`~skidsim.criticism.adjustment.lead_design`); None when it names none or they are missing from
    ``cov``."""
    L = lead_design(cov.loc[data.site_ids], lead) if lead else None
    return None if L is None else np.c_[np.ones(len(data.site_ids)), L]


def parts_beyond_lead(data: LevelData, cov: pd.DataFrame, columns, lead) -> pd.DataFrame | None:
    """The parts of the numeric ``columns`` of ``cov`` (one row per site) orthogonal to :func:`lead_basis` over the
    between-site sites of ``data`` (index: those sites; each column's units): what a texture column adds beyond the
    prediction model's terms. A column with a missing or non-numeric value at one of those sites is left out.
    None without a lead basis."""
    F = lead_basis(data, cov, lead)
    if F is None:
        return None
    columns = list(columns)
    X = cov.loc[data.site_ids, columns].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    ok = np.isfinite(X).all(axis=0)
    kept = [c for c, k in zip(columns, ok) if k]
    return pd.DataFrame(residualise(X[:, ok], F), index=list(data.site_ids), columns=kept)


def column_beyond_lead(
    residuals: pd.DataFrame, cov: pd.DataFrame, column: str, lead, options: DiagnosisOptions
) -> pd.Series | None:
    """The part of the numeric column ``column`` of ``cov`` beyond the prediction model's terms over the between-site
    sites (:func:`parts_beyond_lead`): what a texture column named between sites adds, the column its extension is
    fitted on (the residual has lost the rest; :func:`texture_beyond_lead`). None without between-site residuals, a
    lead basis or a value at every such site."""
    data = level_data(residuals, options).get("between-site")
    if data is None or column not in cov.columns:
        return None
    Z = parts_beyond_lead(data, cov, [column], lead)
    return None if Z is None or column not in Z.columns else Z[column]


def texture_beyond_lead(ctx: LevelContext, cands: CandidateSet, lead) -> None:
    """Between sites, test each texture column for what it adds beyond the prediction model's texture terms
    ``lead`` (e.g. ``log(profile_MPD)``, ``log(micro_Sq)``): its basis becomes the unit part of the centred column
    orthogonal to ``[1, lead columns]`` (empty when the column lies in their span). The between-site residual is
    ``measured - sn_pred`` of a model trained on those terms, so it has lost whatever the terms carry of an
    effect; the raw column correlates with what is left only through that part (chips: macro_Sdq has R^2 0.88 on
    the two terms, so its raw basis catches about 12 % of its own effect's residual). Within sites (the residual
    of the calibrated simulation, which no texture model enters) and without lead terms the bases stay."""
    if ctx.data.level != "between-site":
        return
    F = lead_basis(ctx.data, cands.covariates, lead)
    if F is None:
        return
    for c, (source, dtype) in ctx.info.items():
        if source != "texture" or dtype != "numeric" or c not in ctx.bases or ctx.bases[c].shape[1] != 1:
            continue
        x = ctx.C[c].to_numpy(float)
        z = residualise(ctx.bases[c], F)[:, 0] * np.sign(ctx.bases[c][:, 0] @ (x - x.mean()))  # the column's sign
        nz = float(np.linalg.norm(z))
        ctx.bases[c] = (z / nz)[:, None] if nz > 1e-8 * np.sqrt(ctx.n) else np.zeros((ctx.n, 0))
        ctx.cv_columns[c] = pd.Series(z, index=ctx.C.index)


def beyond_lead_clusters(data: LevelData, cands: CandidateSet, lead, rho: float) -> list[list[str]] | None:
    """The texture clusters of the between-site level ``data`` on what its tests see: each numeric texture column's
    part beyond the prediction model's terms ``lead`` (orthogonal to :func:`lead_basis`, as
    :func:`texture_beyond_lead` makes its basis), clustered as
    :func:`~skidsim.criticism.covariates.texture_clusters` clusters the columns themselves (|Spearman rho| >=
    ``rho`` across the level's sites, complete linkage). Two columns that go together across sites part where the
    lead terms hold what they share, so the cluster of the columns would test such a column by a maximum over
    members whose tested parts are unrelated. None within sites, without lead terms or without texture columns
    (the level tests the columns themselves: their clusters)."""
    tex = [c for c in cands.covariates.columns if cands.info[c] == ("texture", "numeric")]
    if data.level != "between-site" or not tex or not set(data.site_ids) <= set(cands.covariates.index):
        return None  # (a site without a row: level_context names it)
    Z = parts_beyond_lead(data, cands.covariates, tex, lead)
    if Z is None:
        return None
    return texture_clusters(Z, {c: cands.info[c] for c in Z.columns}, rho) + [[c] for c in tex if c not in Z.columns]
