"""Permutation tests of the screening: the exchangeability structure of a campaign (sections as blocks, sites
within sections; Winkler et al. 2015), the permutation statistics of many candidates at once and their p-values."""

from __future__ import annotations

import numpy as np


def section_permutations(sections: np.ndarray, n_perm: int, rng) -> np.ndarray:
    """(n_perm, n) site index permutations that move whole sections among sections of the same size."""
    secs, inv = np.unique(sections, return_inverse=True)
    members = [np.flatnonzero(inv == k) for k in range(len(secs))]
    sizes = np.array([len(m) for m in members])
    out = np.tile(np.arange(len(sections)), (n_perm, 1))
    for size in np.unique(sizes):
        ks = np.flatnonzero(sizes == size)
        if len(ks) < 2:
            continue
        src = np.stack([members[k] for k in ks])  # (m, size)
        perm = rng.permuted(np.tile(np.arange(len(ks)), (n_perm, 1)), axis=1)  # (P, m)
        out[:, src.reshape(-1)] = src[perm].reshape(n_perm, -1)
    return out


def nested_permutations(sections: np.ndarray, n_perm: int, rng) -> np.ndarray:
    """(n_perm, n) permutations in the nested exchangeability structure of the campaign (Winkler et al. 2015,
    multi-level exchangeability blocks): whole sections move among sections of the same size, and sites are
    shuffled within their section. Valid when residuals share a section effect."""
    out = section_permutations(sections, n_perm, rng)
    secs, inv = np.unique(sections, return_inverse=True)
    for k in range(len(secs)):
        pos = np.flatnonzero(inv == k)
        if len(pos) < 2:
            continue
        out[:, pos] = np.take_along_axis(
            out[:, pos], rng.permuted(np.tile(np.arange(len(pos)), (n_perm, 1)), axis=1), axis=1
        )
    return out


def site_permutations(n_sites: int, n_perm: int, rng) -> np.ndarray:
    """(n_perm, n_sites) free permutations of the sites."""
    return rng.permuted(np.tile(np.arange(n_sites), (n_perm, 1)), axis=1)


def perm_stats(
    Y: np.ndarray, Q: np.ndarray, owner: np.ndarray, n_cand: int, perms: np.ndarray, chunk: int = 512
) -> np.ndarray:
    """Permutation statistics (P, n_cand): T = sum over a candidate's basis columns and Y's columns of
    (Q^T Y_perm)^2."""
    P = perms.shape[0]
    out = np.empty((P, n_cand))
    order = np.argsort(owner, kind="stable")
    Qs, ow = Q[:, order], owner[order]
    starts = np.flatnonzero(np.r_[True, ow[1:] != ow[:-1]])
    ids = ow[starts]
    for a in range(0, P, chunk):
        Yp = Y[perms[a : a + chunk]]  # (c, n, S)
        A = np.einsum("pns,nq->pqs", Yp, Qs, optimize=True)
        sq = (A * A).sum(axis=2)  # (c, q)
        out[a : a + chunk][:, ids] = np.add.reduceat(sq, starts, axis=1)
    return out


def section_flip_shape(D: np.ndarray, sections: np.ndarray, P: int, rng) -> tuple[float, np.ndarray]:
    """The mean-shape statistic of the centred profiles ``D`` (sites x bins), ``T = n sum_b (mean_i D_ib)^2``, and
    its values under ``P`` random sign flips of whole sections' profiles (``sections`` per site; one draw of shape
    (P, sections) from ``rng``): ``(T, Tp)``, the functional form's test."""
    n, sec_index = D.shape[0], np.unique(sections, return_inverse=True)[1]
    flips = rng.choice(np.array([-1.0, 1.0]), size=(P, int(sec_index.max()) + 1))[:, sec_index]
    T = n * float((D.mean(axis=0) ** 2).sum())
    return T, ((flips @ D) ** 2).sum(axis=1) / n


def permutation_p(T: float, Tp: np.ndarray) -> float:
    """Permutation p-value ``(1 + #{T_perm >= T}) / (P + 1)`` (relative tolerance 1e-12 for ties)."""
    return (1 + np.sum(Tp >= T * (1 - 1e-12))) / (len(Tp) + 1)


def min_p(Tobs: np.ndarray, Tp: np.ndarray) -> tuple[float, np.ndarray, int]:
    """Single-step minP over the statistics of one testing unit (Westfall & Young 1993, algorithm 2.8): ``Tobs``
    (m,) the observed statistics and ``Tp`` (P, m) their values under the same P permutations. Each statistic
    is put on its own null scale first: its permutation p (:func:`permutation_p`) for the observation and, for
    permutation b, ``#{a: T_a >= Tp[b, j]} / (P + 1)`` over the P + 1 arrangements a (the observation and the P
    permutations, b itself among them), the p the same rule gives that permutation. So statistics with different
    null distributions (designs of different numbers of columns) enter on one scale, where the max-statistic lets
    the widest dominate; for one statistic the unit p is its :func:`permutation_p`. Returns the unit p
    ``(1 + #{b: min_j p_bj <= min_j p_j}) / (P + 1)``, each statistic's adjusted p ``(1 + #{b: min_j p_bj <=
    p_j}) / (P + 1)`` (m,), and the index of the smallest observed p (ties: the largest ``(T - mean Tp) / sd
    Tp``). The same relative tolerance 1e-12 for ties as :func:`permutation_p`."""
    Tobs = np.asarray(Tobs, float)
    Tp = np.asarray(Tp, float)
    P, m = Tp.shape
    p_obs = np.array([permutation_p(Tobs[j], Tp[:, j]) for j in range(m)])
    p_min_perm = np.full(P, np.inf)
    for j in range(m):
        srt = np.sort(Tp[:, j])
        ge = P - np.searchsorted(srt, Tp[:, j] * (1 - 1e-12), side="left")  # #{b': Tp[b'] >= Tp[b]}, b itself too
        ge = ge + (Tobs[j] >= Tp[:, j] * (1 - 1e-12))  # the observation is one of the P + 1 arrangements
        np.minimum(p_min_perm, ge / (P + 1), out=p_min_perm)
    adj = np.array([(1 + np.sum(p_min_perm <= p * (1 + 1e-12))) / (P + 1) for p in p_obs])
    sd = Tp.std(axis=0)
    z = np.where(sd > 0, (Tobs - Tp.mean(axis=0)) / np.where(sd > 0, sd, 1.0), 0.0)
    top = int(np.lexsort((-z, p_obs))[0])
    return float(adj[top]), adj, top
