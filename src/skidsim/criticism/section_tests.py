"""Tests of the section effect beyond a column or beyond the texture model, read by the naming rule of a section
effect (:mod:`.section_naming`): whether a section effect is left beyond each section-level column
(``section_rest_p``, rule 3b), whether the measured curves hold one beyond a quadratic texture model (section
identity's ``section_rest_p``, rule 6), and how much of that effect each section-level column carries, by an
exact test (``beyond_texture_share``, ``beyond_texture_p``, rule 3d). Residuals mu (dimensionless).
"""

from __future__ import annotations

import numpy as np

from .adjustment import residualise
from .covariates import CandidateSet
from .levels import CandidateTest, LevelContext, curve_responses
from .permutations import permutation_p
from .texture_candidate import PCS_MEMBER, TextureMember, centred_basis, section_share
from .texture_tests import lead_basis


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
    (:func:`skidsim.criticism.section_naming.section_rule`, rule 3b). Between
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
    in 4 (``tests/test_criticism_beyond_texture.py``). No p (NaN) where the sections and ``F`` leave no residual
    degree of freedom. In place."""
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
    rule of a section effect (:func:`skidsim.criticism.section_naming.beyond_texture_explanations`): where the texture
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
