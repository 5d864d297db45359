"""Screening of every candidate cause at every level of error (docs/model-criticism.md, section 2).

Residuals are averaged per site and speed bin; only bins observed at every site of a level are used. Per level:

* covariate tests: the sum of squares of the residual (site mean ``main``, between sites only; centred speed
  profile ``x_speed``) explained by the candidate's basis, against permutations of whole sites (section identity:
  free site permutations; every other covariate: sections as blocks and sites within sections);
* texture-adjusted tests (between sites, sites.csv covariates that vary within sections): the candidate's part
  orthogonal to the leading texture PCs against the residuals of the measured curve on them (Freedman & Lane
  1983; the permuted residuals leverage-corrected per section, so the test holds its level), so a covariate
  that correlates with texture by chance is neither credited with texture's effect nor absorbed by the texture
  model;
* MPD x speed within sites: the amplitude of the shared residual shape against the IFI's 1/Sp(MPD);
* the functional form: the mean residual shape over sites, against random sign flips of whole sections' profiles
  (between sites, the shape the texture model adds to the within-site residual, ``sn_sim - sn_pred``);
* the texture model as a candidate cause (:mod:`.texture_tests`) and the section effect left beyond a column or
  beyond the texture model (:mod:`.section_tests`), on the data every test of a level shares (:mod:`.levels`).

Then false-discovery control (:mod:`skidsim.criticism.fdr`) and ranking (:mod:`skidsim.criticism.ranking`).
Speeds km/h, residuals mu (dimensionless).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .adjustment import adjusted_basis, basis, leverage_corrected, residualise, texture_adjustment
from .causes import Cause, make_causes
from .covariates import CandidateRoles, CandidateSet, candidate_set, lead_count, scores_for
from .crossval import cv_sse, folds, is_section_nested
from .extensions import ifi_speed_constant_kmh
from .fdr import adjust, family_sizes, has_texture_family, permutation_count
from .levels import CandidateTest, LevelContext, level_context, level_data
from .options import DiagnosisOptions
from .permutations import perm_stats, section_flip_shape
from .ranking import rank_causes
from .residuals import require_columns, texture_model_shape
from .section_tests import section_rest_tests, texture_model_basis
from .texture_candidate import section_share
from .texture_tests import _members, beyond_lead_clusters, texture_beyond_lead, texture_model_tests, texture_speed_tests
from .wlf import label_law_form


@dataclass
class TextureAdjusted:
    """Nuisance of the texture-adjusted tests of one level: ``k`` PCs conditioned on (design ``N``), ``k_cv`` PCs
    of the best predictive texture model, the PC ``scores``, the measured curve per kind (``Ys_cv``), its
    residuals on ``N`` (``Ys_adj``, the observed statistic) and their leverage-corrected form that is permuted
    (``Ys_perm``, :func:`~skidsim.criticism.adjustment.leverage_corrected`), and which candidates are tested this
    way (``adjusted``)."""

    k: int
    k_cv: int
    N: np.ndarray
    scores: np.ndarray
    Ys_cv: dict
    Ys_adj: dict
    adjusted: dict
    Ys_perm: dict


def texture_adjusted(ctx: LevelContext, cands: CandidateSet, pcs: pd.DataFrame | None) -> TextureAdjusted | None:
    """The texture adjustment of a between-site level (:func:`texture_adjustment` of the measured curve on the
    texture model's columns ``pcs``: the prediction model's lead columns when
    :func:`~skidsim.criticism.adjustment.texture_model_scores` chose them, then texture PCs); None within sites,
    without the measured matrix, or with too few sections to condition on a PC
    (the residual test is kept)."""
    M = ctx.data.measured
    if ctx.data.level != "between-site" or M is None:
        return None
    scores = scores_for(ctx.data.site_ids, pcs, cands.covariates, cands.info)
    if scores.shape[1] == 0:
        return None
    n_lead = lead_count(ctx.data.site_ids, pcs)
    k, N, k_cv = texture_adjustment(M, scores, ctx.sec, n_lead=n_lead)
    if k < 1:
        return None
    DM = M - M.mean(axis=1, keepdims=True)
    Ys_cv = {"main": (M.mean(axis=1) - M.mean())[:, None], "x_speed": DM - DM.mean(axis=0)}
    Ys_adj = {kind: residualise(Yc, N) for kind, Yc in Ys_cv.items()}
    adjusted = {
        c: ctx.info[c][0] == "sites" and not ctx.section_level[c] and not ctx.is_section_id[c] for c in ctx.C.columns
    }
    Ys_perm = {kind: leverage_corrected(R, N, ctx.sec) for kind, R in Ys_adj.items()}
    return TextureAdjusted(k, k_cv, N, scores, Ys_cv, Ys_adj, adjusted, Ys_perm)


@dataclass
class _Batch:
    """Tests of one kind that share a permutation set and an adjustment (``adj``): the tested residual ``Y`` and
    each candidate's (adjusted) basis ``bases``."""

    kind: str
    Y: np.ndarray
    adj: bool
    bases: dict


def _covariate_test(
    ctx: LevelContext, ta: TextureAdjusted | None, batch: _Batch, c: str, T: float, Tp: np.ndarray
) -> CandidateTest:
    dtype, kind, Y, adj = ctx.info[c][1], batch.kind, batch.Y, batch.adj
    nested = dtype == "categorical" and is_section_nested(ctx.C[c].to_numpy(), ctx.sec)
    if adj:
        sse0, sse1 = cv_sse(ta.Ys_cv[kind], ctx.C[c], dtype, folds(ctx.sec, nested), nuisance=ta.scores[:, : ta.k_cv])
    else:
        sse0, sse1 = cv_sse(Y, ctx.cv_columns.get(c, ctx.C[c]), dtype, folds(ctx.sec, nested))
    direction = 0
    if dtype == "numeric":
        col = ctx.cv_columns.get(c, ctx.C[c])
        zc = col.to_numpy(float) - col.mean()
        bk = batch.bases[c]
        z = bk[:, 0] * np.sign(bk[:, 0] @ zc) if adj else zc
        target = Y[:, 0] if kind == "main" else (Y if adj else ctx.D) @ ctx.speed_c
        direction = int(np.sign(z @ target))
    return CandidateTest(
        c,
        ctx.data.level,
        kind,
        T,
        Tp,
        sse0,
        sse1,
        ctx.n,
        Y.shape[1],
        direction,
        ctx.info[c][0],
        dtype,
        ctx.section_level[c],
        ta.k if adj else -1,
        ta.k_cv if adj else -1,
    )


def _covariate_batch(
    ctx: LevelContext, ta: TextureAdjusted | None, kind: str, is_id: bool, perms: np.ndarray, adj: bool
) -> list[CandidateTest]:
    """The tests of one kind that share a permutation set and an adjustment: all candidates at once."""
    Y = ta.Ys_adj[kind] if adj else ctx.Ys[kind]
    adjusted = ta.adjusted if ta is not None else {}
    bk = {
        c: (adjusted_basis(ctx.bases[c], ta.N) if adj else ctx.bases[c])
        for c in ctx.C.columns
        if ctx.is_section_id[c] == is_id
        and adjusted.get(c, False) == adj
        and ctx.bases[c].shape[1] > 0
        and not (c == ctx.amp_col and kind == "x_speed")
    }
    names = [c for c in bk if bk[c].shape[1] > 0]
    if not names:
        return []
    Q = np.concatenate([bk[c] for c in names], axis=1)
    owner = np.concatenate([np.full(bk[c].shape[1], k) for k, c in enumerate(names)])
    A = Q.T @ Y
    T = np.bincount(owner, weights=(A * A).sum(axis=1), minlength=len(names))
    Tp = perm_stats(ta.Ys_perm[kind] if adj else Y, Q, owner, len(names), perms)
    batch = _Batch(kind, Y, adj, bk)
    return [_covariate_test(ctx, ta, batch, c, T[k], Tp[:, k]) for k, c in enumerate(names)]


def covariate_tests(ctx: LevelContext, ta: TextureAdjusted | None) -> list[CandidateTest]:
    """Every covariate test of a level: per kind, section identity (free site permutations), the other
    covariates (nested permutations), and the texture-adjusted ones (nested permutations)."""
    tests = []
    for kind in ctx.Ys:
        for is_id, perms, adj in (
            (True, ctx.perm_site, False),
            (False, ctx.perm_nested, False),
            (False, ctx.perm_nested, True),
        ):
            if adj and ta is None:
                continue
            tests += _covariate_batch(ctx, ta, kind, is_id, perms, adj)
    return tests


def mpd_amplitude_test(ctx: LevelContext) -> CandidateTest:
    """MPD x speed within sites: the amplitude of the shared residual shape against the IFI's 1/Sp(MPD) (drainage
    changes how strongly the law's shape is wrong, not its form, in proportion to 1/Sp, Sp = 14.2 + 89.7 MPD
    km/h): Y projected on the unit mean shape, one degree of freedom instead of a free profile; the mean shape is
    invariant to permuting sites, so the nested permutations stay exact."""
    col = ctx.amp_col
    f = ctx.D.mean(axis=0)
    fn = float(np.linalg.norm(f))
    Ya = (ctx.Ys["x_speed"] @ (f / fn))[:, None] if fn > 0 else np.zeros((ctx.n, 1))
    inv_sp = pd.Series(1.0 / ifi_speed_constant_kmh(np.maximum(ctx.C[col].to_numpy(float), 0.0)), index=ctx.C.index)
    q = basis(inv_sp, "numeric")
    A = q.T @ Ya
    Tp = perm_stats(Ya, q, np.zeros(q.shape[1], dtype=int), 1, ctx.perm_nested)
    sse0, sse1 = cv_sse(Ya, inv_sp, "numeric", folds(ctx.sec, False))
    zc = ctx.C[col].to_numpy(float) - ctx.C[col].mean()
    return CandidateTest(
        col,
        ctx.data.level,
        "x_speed",
        float((A * A).sum()),
        Tp[:, 0],
        sse0,
        sse1,
        ctx.n,
        1,
        int(np.sign(zc @ Ya[:, 0])),
        ctx.info[col][0],
        "numeric",
        ctx.section_level[col],
    )


def functional_form_test(ctx: LevelContext, ff_delta: pd.DataFrame | None, P: int, rng) -> CandidateTest:
    """The functional form: mean residual shape over sites, random sign flips of whole sections' profiles. Between
    sites the shape tested is the part the texture model adds to the within-site residual (``ff_delta``,
    :func:`~skidsim.criticism.residuals.texture_model_shape`): the between-site residuals of all held-out sites
    share the texture model's estimate of the simulated shape, so flipping their section profiles is
    anti-conservative."""
    Dff = ctx.D
    if ctx.data.level == "between-site" and ff_delta is not None:
        Dff = ff_delta.loc[ctx.data.site_ids].to_numpy(float)
        Dff = Dff - Dff.mean(axis=1, keepdims=True)
    n = ctx.n
    Tff, Tffp = section_flip_shape(Dff, ctx.sec, P, rng)
    sse0, sse1 = cv_sse(Dff, None, "", folds(ctx.sec, False))
    return CandidateTest(
        "functional_form",
        ctx.data.level,
        "functional_form",
        Tff,
        Tffp,
        sse0,
        sse1,
        n,
        Dff.shape[1],
        0,
        "residual",
        "",
        False,
    )


def section_shares(ctx: LevelContext, tests: list[CandidateTest]) -> None:
    """Fill, for the covariate tests of one level, the share of the section effect the candidate's (plain) basis
    explains in its own kind's residual (``section_share``) and in the site means (``section_share_main``,
    between sites), and whether it is section identity (:func:`~skidsim.criticism.texture_candidate.section_share`).
    In place."""
    for t in tests:
        if t.variable not in ctx.bases:
            continue
        Q = ctx.bases[t.variable]
        t.section_id = bool(ctx.is_section_id[t.variable])
        t.section_share = section_share(Q, ctx.Ys[t.kind], ctx.sec)
        if "main" in ctx.Ys:
            t.section_share_main = section_share(Q, ctx.Ys["main"], ctx.sec)


def _between_shape(residuals: pd.DataFrame, data: dict, speed_bin_kmh: float) -> pd.DataFrame | None:
    """``sn_sim - sn_pred`` per between-site site and bin, where it covers exactly the between-site sites."""
    if "between-site" not in data:
        return None
    ff_delta = texture_model_shape(residuals, speed_bin_kmh)
    if ff_delta is not None and set(ff_delta.index) != set(data["between-site"].site_ids):
        return None
    return ff_delta


def screen_candidates(
    residuals: pd.DataFrame,
    sites: pd.DataFrame,
    texture_wide: pd.DataFrame | None = None,
    options: DiagnosisOptions | None = None,
    roles: CandidateRoles | None = None,
    texture_pc_scores: pd.DataFrame | None = None,
    texture_lead=(),
    shape_residuals: pd.DataFrame | None = None,
) -> list[Cause]:
    """Screen every candidate cause at every level; returns the causes ranked by evidence
    (:func:`~skidsim.criticism.ranking.rank_causes`).

    ``residuals``: :func:`~skidsim.criticism.residuals.build_residuals` (the ``measured`` column enables the
    texture-adjusted tests); ``texture_pc_scores``
    (:func:`~skidsim.criticism.covariates.between_site_texture_scores`) supplies the PC scores the between-site
    tests condition on (without it they are computed here, identically); ``texture_lead``: the prediction
    model's texture terms (``DiagnosisInputs.prediction_features``), axes of the texture-model candidate
    (:mod:`skidsim.criticism.texture_candidate`; the MPD column is always one). Random draws: one generator seeded with
    ``options.seed``, per level the site permutations, the nested permutations, then the sign flips. ``options``,
    ``roles``: None for the defaults. ``shape_residuals``: the table the between-site functional form reads the
    texture model's shape from (:func:`~skidsim.criticism.residuals.texture_model_shape`: every site's within-site
    rows, where ``residuals`` leaves some out; None: ``residuals``).
    """
    options = DiagnosisOptions() if options is None else options
    roles = CandidateRoles() if roles is None else roles
    require_columns(residuals, ("site", "level", "speed_kmh", "residual"), "residuals")
    cands = candidate_set(sites, texture_wide, roles, options.cluster_rho)
    data = level_data(residuals, options)
    ff_delta = _between_shape(residuals if shape_residuals is None else shape_residuals, data, options.speed_bin_kmh)
    level_clusters = {}
    for lv, d in data.items():
        cl = beyond_lead_clusters(d, cands, texture_lead, options.cluster_rho)
        if cl is not None:
            level_clusters[lv] = cl
    P = permutation_count(family_sizes(data, cands, has_texture_family(options), level_clusters), options)
    rng = np.random.default_rng(options.seed)
    tests, between = [], None
    for d in data.values():
        ctx = level_context(d, cands, P, rng)
        texture_beyond_lead(ctx, cands, texture_lead)
        cov_tests = covariate_tests(ctx, texture_adjusted(ctx, cands, texture_pc_scores))
        section_shares(ctx, cov_tests)
        members = _members(ctx, cands, texture_pc_scores, texture_lead)
        section_rest_tests(ctx, cov_tests, F=texture_model_basis(ctx, cands, texture_lead, members), members=members)
        tests += cov_tests
        tests += texture_model_tests(ctx, members)
        if ctx.data.level == "between-site":
            between = (ctx, members)
        if ctx.amp_col is not None:
            tests.append(mpd_amplitude_test(ctx))
        tests.append(functional_form_test(ctx, ff_delta, P, rng))
    adjustment = adjust(tests, cands, options, level_clusters)
    causes = make_causes(tests, adjustment, cands, options, P)
    if between is not None:
        causes += texture_speed_tests(*between, causes, cands, options, P)
    causes = rank_causes(causes, cands.covariates, cands.mpd, fdr=options.fdr)
    return label_law_form(causes, residuals)
