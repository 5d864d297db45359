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
  (between sites, the shape the texture model adds to the within-site residual, ``sn_sim - sn_pred``).

Then false-discovery control (:mod:`skidsim.criticism.fdr`) and ranking (:mod:`skidsim.criticism.causes`).
Speeds km/h, residuals mu (dimensionless).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from .adjustment import adjusted_basis, basis, lead_design, leverage_corrected, residualise, texture_adjustment
from .causes import Cause, make_causes, rank_causes
from .covariates import CandidateRoles, CandidateSet, candidate_set, scores_for
from .crossval import cv_sse, cv_sse_design, folds, is_section_nested
from .extensions import ifi_speed_constant_kmh
from .fdr import adjust, family_sizes, has_texture_family, permutation_count
from .options import DiagnosisOptions
from .permutations import nested_permutations, perm_stats, permutation_p, site_permutations
from .residuals import LEVELS, level_matrix, require_columns, texture_model_shape
from .texture_candidate import PCS_MEMBER, TextureMember, centred_basis, member_basis, section_share, texture_members


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


def level_data(residuals: pd.DataFrame, options: DiagnosisOptions) -> dict:
    """{level: LevelData} for every level with residuals at >= 4 sites."""
    out = {}
    for level in LEVELS:
        res = residuals[residuals["level"] == level]
        if res["site"].nunique() < 4:
            continue
        site_ids, bins, R = level_matrix(residuals, level, options.speed_bin_kmh)
        out[level] = LevelData(level, site_ids, bins, R)
        if level == "between-site" and options.adjust_texture and "measured" in res.columns:
            ids_m, bins_m, M = level_matrix(residuals, level, options.speed_bin_kmh, value="measured")
            out[level].measured = M if (ids_m == site_ids and np.array_equal(bins_m, bins)) else None
    if not out:
        raise InputError("residuals", "at least 4 sites with residuals at one level")
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
    n_lead = int(pcs.attrs.get("n_lead", 0)) if pcs is not None and set(pcs.index) == set(ctx.data.site_ids) else 0
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
    n, sec_index = ctx.n, np.unique(ctx.sec, return_inverse=True)[1]
    flips = rng.choice(np.array([-1.0, 1.0]), size=(P, int(sec_index.max()) + 1))[:, sec_index]
    Tff = n * float((Dff.mean(axis=0) ** 2).sum())
    Tffp = ((flips @ Dff) ** 2).sum(axis=1) / n
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


def rest_residuals(ctx: LevelContext, F: np.ndarray | None) -> dict | None:
    """Between sites, the residual section identity is tested on beyond the texture model
    (:func:`section_rest_tests`): per kind (``main``, ``x_speed``, as in ``ctx.Ys``) the measured curves net of
    ``F`` (:func:`texture_model_basis`: the prediction model's terms and their second-order terms), fitted over all
    the sites. The between-site residual is the held-out-section error of the texture model: a section whose
    texture the other sections do not span (high leverage) keeps an error that clusters by section whether or not
    anything beyond the texture acts on it (spectral campaigns: two low-MPD sections whose held-out errors have
    opposite signs); the measured curves net of a texture model fitted over all sites do not hold that error.
    None within sites, without the measured matrix or without ``F``."""
    M = ctx.data.measured
    if ctx.data.level != "between-site" or M is None or F is None:
        return None
    Ycv = curve_responses(M)[1]
    return {kind: residualise(Ycv[kind], F) for kind in ctx.Ys}


def texture_model_basis(ctx: LevelContext, cands: CandidateSet, lead, members: list[TextureMember]):
    """``[1, lead columns, the curved-in member's design]`` (:func:`lead_basis`; the member
    ``curved in <a> and <b>`` of :func:`~skidsim.criticism.texture_candidate.texture_members`: the products and
    squares of the prediction model's two texture terms) over the between-site sites: a quadratic texture model
    in the prediction model's terms, which spans a level set by one term times a speed dependence set by the
    other (the IFI and Rado forms) to second order. :func:`lead_basis` alone where that member is missing; None
    without lead terms."""
    F = lead_basis(ctx.data, cands.covariates, lead)
    curved = next((m for m in members if m.name.startswith("curved in ")), None)
    return F if F is None or curved is None else np.c_[F, curved.design]


def section_rest_tests(
    ctx: LevelContext,
    tests: list[CandidateTest],
    chunk: int = 512,
    F: np.ndarray | None = None,
    members: list[TextureMember] = (),
) -> None:
    """For every section-level column (not section identity; residual test) of one level: is a section effect left
    beyond the column? The statistic is the between-section sum of squares of the tested residual net of the
    column's basis, ``SS_sec((I - Q Q') Y)`` (:func:`section_sum_of_squares`), the part of section identity's
    statistic the column does not carry; its p-value (``section_rest_p``) is Freedman & Lane (1983): the reduced
    model's residuals ``(I - Q Q') Y`` permuted over the sites by section identity's own free site permutations and
    taken net of ``Q`` again (no new draws; the null is no section effect beyond the column, under which the sites
    are exchangeable apart from the column's groups). That statistic is not pivotal, and Freedman & Lane wants one
    (Winkler et al. 2014, NeuroImage 92, 381): it rejects a true null more often than its level where ``Q`` takes
    much of the section space. Rule 3b names a column only where this p is *above* fdr, so the error makes 3b
    stricter; measured with the F ratio below instead, 3b named one more false column on the spectral nulls and no
    more right ones (docs/model-criticism.md, rule 6).
    Between sites, where ``members`` holds the texture model's member of the leading texture PCs
    (:data:`~skidsim.criticism.texture_candidate.PCS_MEMBER`), the reduced model is the column and that member
    together: the texture designs of a campaign are drawn per section, so the texture model's misfit clusters by
    section too, and what the column leaves that the texture PCs carry is the texture model's, not a section
    effect no column explains. Used by the naming rule of a section effect
    (:func:`skidsim.criticism.causes.section_rule`, rule 3b). Between
    sites with a texture model ``F`` (:func:`texture_model_basis`, ``[1, ...]``) and the measured curves, section
    identity is tested too: its ``section_rest_p`` is the p of a section effect in the measured curves net of
    ``F`` (:func:`rest_residuals`; the reduced model ``F``, the same free site permutations), which rule 6 of the
    naming rule reads (a between-site section effect that the measured curves do not show beyond the texture
    model is the texture model's misfit); so is each section-level column, on its share of that section effect
    and by an exact test there (:func:`beyond_texture_tests`, read by rule 3d). Section identity's statistic is the
    F ratio of the section indicators beyond ``F`` (:func:`section_f_ratio`: the sum of squares of the rest
    residual on the section indicators net of ``[1, F]`` over what is left beyond them), a pivotal statistic: the
    texture of a campaign sits mostly between its sections, so ``F`` takes much of the section space, and the
    section sum of squares rejected a true null at 0.05 in 14 of 80 seeds of such a design where the F ratio does
    in 4 (``tests/test_criticism_naming.py``). No p (NaN) where the sections and ``F`` leave no residual degree of
    freedom. In place."""
    secs, inv = np.unique(ctx.sec, return_inverse=True)
    G = np.zeros((ctx.n, len(secs)))
    G[np.arange(ctx.n), inv] = 1.0
    P = ctx.perm_site.shape[0]
    rest = rest_residuals(ctx, F)
    pcs = None
    if ctx.data.level == "between-site":
        pcs = next((m for m in members if m.name == PCS_MEMBER), None)
    if rest is not None:
        Fq = centred_basis(F[:, 1:])
        Fq = np.c_[np.full(ctx.n, 1.0 / np.sqrt(ctx.n)), Fq]  # [1, F beyond its intercept], orthonormal
    for t in tests:
        Q = ctx.bases.get(t.variable)
        is_id = ctx.is_section_id.get(t.variable, False)
        if (
            Q is None
            or Q.shape[1] == 0
            or not ctx.section_level.get(t.variable, False)
            or (is_id and rest is None)
            or t.texture_pcs >= 0
            or t.kind not in ctx.Ys
        ):
            continue
        Y = ctx.Ys[t.kind]
        if is_id:  # the reduced model F (rest[kind] is orthogonal to F already)
            Y, Q = rest[t.kind], Fq
        elif pcs is not None:  # the column and the texture PCs
            Q = centred_basis(np.c_[Q, pcs.design])
        R = Y - Q @ (Q.T @ Y)
        if is_id:  # beyond the texture model: the F ratio (see the docstring)
            Qg = section_beyond_basis(G, Q)
            # Q (= Fq) holds the constant and Qg is orthogonal to it: the reduced model plus the sections span
            # Q.shape[1] + Qg.shape[1] orthonormal columns
            if ctx.n - Q.shape[1] - Qg.shape[1] <= 0:  # no residual degree of freedom
                continue
            stat = section_f_ratio
        else:  # beyond a column: the section sum of squares (see the docstring)
            Qg, stat = G / np.sqrt(G.sum(axis=0)), section_sum_of_squares
        T = float(stat(R[None], Qg)[0])
        Tp = np.empty(P)
        for a in range(0, P, chunk):
            Rp = R[ctx.perm_site[a : a + chunk]]  # (c, n, S)
            Rp = Rp - np.einsum("nq,pqs->pns", Q, np.einsum("nq,pns->pqs", Q, Rp))
            Tp[a : a + chunk] = stat(Rp, Qg)
        t.section_rest_p = float(permutation_p(T, Tp))
    if rest is not None:
        beyond_texture_tests(ctx, tests, rest, Fq, chunk)


def section_beyond_basis(G: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n, r) of the section indicators ``G`` (n, n_sections) net of ``[1, Q]`` (``Q``
    orthonormal, n x q, centred or holding the constant): the directions in which sections differ that the reduced
    model does not span (:func:`~skidsim.criticism.texture_candidate.centred_basis` of ``G`` net of ``Q``)."""
    return centred_basis(G - Q @ (Q.T @ G))


def section_sum_of_squares(R: np.ndarray, Gn: np.ndarray) -> np.ndarray:
    """Per stacked residual matrix ``R`` (c, n, S): the between-section sum of squares ``sum_g n_g |mean_g R|^2``
    (mu^2), ``Gn`` the section indicators scaled by ``1 / sqrt(n_g)``. (c,)."""
    A = np.einsum("nq,cns->cqs", Gn, R)
    return (A * A).sum(axis=(1, 2))


def section_f_ratio(R: np.ndarray, Qg: np.ndarray) -> np.ndarray:
    """Per stacked residual matrix ``R`` (c, n, S; each orthogonal to the reduced model): the F ratio (up to its
    constant degrees of freedom) of a section effect beyond the reduced model, ``|Qg' R|^2 / (|R|^2 - |Qg' R|^2)``,
    sums over the speed columns; ``Qg``: :func:`section_beyond_basis`. Dimensionless, (c,)."""
    A = np.einsum("nq,cns->cqs", Qg, R)
    ess = (A * A).sum(axis=(1, 2))
    rss = (R * R).sum(axis=(1, 2)) - ess
    return ess / np.maximum(rss, 1e-300)


#: The first permutations of the nested set that :func:`beyond_texture_tests` uses (its p is only compared with fdr).
BEYOND_TEXTURE_PERMUTATIONS = 1999


def beyond_texture_tests(ctx: LevelContext, tests: list[CandidateTest], rest: dict, Fq: np.ndarray, chunk: int = 512):
    """Between sites, for every section-level sites.csv column (not section identity; residual test): how much of
    the section effect in the measured curves beyond the quadratic texture model it carries. ``rest``
    (:func:`rest_residuals`): per kind the measured curves net of the texture model ``F``; ``Fq``: the orthonormal
    basis of ``[1, F]``. The column's basis net of ``F``, ``Qf``, gives ``beyond_texture_share``
    (:func:`~skidsim.criticism.texture_candidate.section_share` of ``Qf`` in ``rest``: the share of that section
    effect the column explains) and ``beyond_texture_p``, an exact permutation test of the column there: the sum of
    squares of the residuals ``R`` on ``F`` projected on the column's basis net of ``F``, with the column's values
    moved over the sections by the first :data:`BEYOND_TEXTURE_PERMUTATIONS` nested permutations (the column's own
    test over the sections) and each permuted basis taken net of ``F`` again (the column tested conditional on the
    texture model; permuting ``R`` instead, Freedman & Lane, would rarely line a permuted residual up with ``Qf``
    as well as the observed one, whose part along ``F`` was removed from both, and gave p 1e-4 where 4 of the 220
    arrangements of 3 sections among 12 keep them in one level of a 4-level column). Read by rule 3d of the naming
    rule of a section effect (:func:`skidsim.criticism.causes.beyond_texture_explanations`): where the texture
    model's misfit and a column's effect cluster by the same sections, the column is judged on what the texture
    model leaves. In place."""
    P = min(ctx.perm_nested.shape[0], BEYOND_TEXTURE_PERMUTATIONS)
    for t in tests:
        Q = ctx.bases.get(t.variable)
        if (
            Q is None
            or Q.shape[1] == 0
            or t.source != "sites"
            or not ctx.section_level.get(t.variable, False)
            or ctx.is_section_id.get(t.variable, False)
            or t.texture_pcs >= 0
            or t.kind not in rest
        ):
            continue
        Qf = centred_basis(Q - Fq @ (Fq.T @ Q))
        if Qf.shape[1] == 0:
            continue
        R = rest[t.kind]
        t.beyond_texture_share = section_share(Qf, R, ctx.sec)
        T = _net_projection_ss(Q[None], Fq, R)[0]
        Tp = np.empty(P)
        for a in range(0, P, chunk):
            Tp[a : a + chunk] = _net_projection_ss(Q[ctx.perm_nested[a : min(a + chunk, P)]], Fq, R)
        t.beyond_texture_p = float(permutation_p(T, Tp))


def _net_projection_ss(Qs: np.ndarray, Fq: np.ndarray, R: np.ndarray) -> np.ndarray:
    """For a stack of column bases ``Qs`` (c, n, q): the sum of squares of ``R`` (n, S; orthogonal to ``Fq``)
    projected on each basis net of the orthonormal ``Fq`` (n, f), ``tr(R' Qn (Qn' Qn)^+ Qn' R)`` with
    ``Qn = (I - Fq Fq') Q`` (c,); directions of ``Qn`` below 1e-10 of ``Q``'s scale (inside ``F``'s span) count
    as none."""
    Qn = Qs - np.einsum("nf,cfq->cnq", Fq, np.einsum("nf,cnq->cfq", Fq, Qs))
    w, V = np.linalg.eigh(np.einsum("cnq,cnr->cqr", Qn, Qn))
    scale = np.einsum("cnq,cnq->cq", Qs, Qs).max(axis=1, keepdims=True)
    inv = np.where(w > 1e-10 * scale, 1.0 / np.where(w > 0, w, 1.0), 0.0)  # directions inside F's span: none
    B = np.einsum("cqk,cqs->cks", V, np.einsum("cnq,ns->cqs", Qn, R))
    return np.einsum("ck,cks->c", inv, B * B)


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
    members' x_speed tests (:func:`texture_model_tests`) are one unit tested by their max-statistic, each
    member's p_adjusted ``max(unit p, its single-step maxT p, the section effect's p_adjusted)``. Their permutations are
    the level's nested permutations (no new draws: every other test is unchanged). Family ``child``."""
    from .fdr import Adjustment, Unit
    from .permutations import permutation_p

    parent = [c for c in causes if c.section_id and c.significant and c.level == "between-site" and c.kind == "x_speed"]
    tests = texture_model_tests(ctx, members, "x_speed") if parent else []
    if not tests:
        return []
    p = np.array([permutation_p(t.T, t.Tp) for t in tests])
    Tmax = np.max(np.stack([t.Tp for t in tests]), axis=0)
    Tobs = np.array([t.T for t in tests])
    unit_p = permutation_p(Tobs.max(), Tmax)
    gate = min(c.p_adjusted for c in parent)
    padj = np.array([max(unit_p, permutation_p(t, Tmax), gate) for t in Tobs])
    key = ("texture_model_child", "between-site", "x_speed")
    unit = Unit("child", tests[int(np.argmax(Tobs))].variable, list(range(len(tests))))
    adjustment = Adjustment(p, padj, [key] * len(tests), {key: unit}, {key: unit_p})
    return make_causes(tests, adjustment, cands, options, P)


def _members(ctx: LevelContext, cands: CandidateSet, pcs: pd.DataFrame | None, lead) -> list[TextureMember]:
    """The richer texture models of a between-site level (none within sites or without texture columns)."""
    if ctx.data.level != "between-site":
        return []
    if not any(cands.info[c][0] == "texture" for c in cands.covariates.columns):
        return []
    scores = scores_for(ctx.data.site_ids, pcs, cands.covariates, cands.info)
    n_lead = int(pcs.attrs.get("n_lead", 0)) if pcs is not None and set(pcs.index) == set(ctx.data.site_ids) else 0
    return texture_members(ctx.data.site_ids, cands.covariates, cands.mpd, scores, tuple(lead), n_lead)


def lead_basis(data: LevelData, cov: pd.DataFrame, lead) -> np.ndarray | None:
    """``[1, lead columns]`` (n_sites, 1 + k) of the between-site sites of ``data``: the prediction model's terms
    ``lead`` (:func:`~skidsim.criticism.adjustment.lead_design`); None when it names none or they are missing from
    ``cov``."""
    L = lead_design(cov.loc[data.site_ids], lead) if lead else None
    return None if L is None else np.c_[np.ones(len(data.site_ids)), L]


def column_beyond_lead(
    residuals: pd.DataFrame, cov: pd.DataFrame, column: str, lead, options: DiagnosisOptions
) -> pd.Series | None:
    """The part of the numeric column ``column`` of ``cov`` (one row per site) orthogonal to :func:`lead_basis` over
    the between-site sites (index: those sites; the column's units): what a texture column named between sites
    adds beyond the prediction model's terms, the column its extension is fitted on (the residual has lost the
    rest; :func:`texture_beyond_lead`). None without between-site residuals or a lead basis."""
    data = level_data(residuals, options).get("between-site")
    if data is None or column not in cov.columns:
        return None
    F = lead_basis(data, cov, lead)
    if F is None:
        return None
    x = pd.to_numeric(cov.loc[data.site_ids, column], errors="coerce").to_numpy(float)
    if not np.isfinite(x).all():
        return None
    return pd.Series(residualise(x[:, None], F)[:, 0], index=list(data.site_ids))


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
        z = residualise(ctx.bases[c], F)[:, 0]
        nz = float(np.linalg.norm(z))
        ctx.bases[c] = (z / nz)[:, None] if nz > 1e-8 * np.sqrt(ctx.n) else np.zeros((ctx.n, 0))
        ctx.cv_columns[c] = pd.Series(z, index=ctx.C.index)


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
) -> list[Cause]:
    """Screen every candidate cause at every level; returns the causes ranked by evidence
    (:func:`~skidsim.criticism.causes.rank_causes`).

    ``residuals``: :func:`~skidsim.criticism.residuals.build_residuals` (the ``measured`` column enables the
    texture-adjusted tests); ``texture_pc_scores``
    (:func:`~skidsim.criticism.covariates.between_site_texture_scores`) supplies the PC scores the between-site
    tests condition on (without it they are computed here, identically); ``texture_lead``: the prediction
    model's texture terms (``DiagnosisInputs.prediction_features``), axes of the texture-model candidate
    (:mod:`skidsim.criticism.texture_candidate`; the MPD column is always one). Random draws: one generator seeded with
    ``options.seed``, per level the site permutations, the nested permutations, then the sign flips. ``options``,
    ``roles``: None for the defaults.
    """
    options = DiagnosisOptions() if options is None else options
    roles = CandidateRoles() if roles is None else roles
    require_columns(residuals, ("site", "level", "speed_kmh", "residual"), "residuals")
    cands = candidate_set(sites, texture_wide, roles, options.cluster_rho)
    data = level_data(residuals, options)
    ff_delta = _between_shape(residuals, data, options.speed_bin_kmh)
    P = permutation_count(family_sizes(data, cands, has_texture_family(options)), options)
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
    adjustment = adjust(tests, cands, options)
    causes = make_causes(tests, adjustment, cands, options, P)
    if between is not None:
        causes += texture_speed_tests(*between, causes, cands, options, P)
    return rank_causes(causes, cands.covariates, cands.mpd, fdr=options.fdr)
