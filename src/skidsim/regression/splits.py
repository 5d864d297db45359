"""Splits of the sites: the study's train/test split (:func:`split_sites`) and the inner cross-validation folds
that choose hyper-parameters (:func:`inner_splits`).

* **Split** (:func:`split_sites`): random (the study: 27/9), or whole groups (sections) to one side.
* **Inner CV** (:func:`inner_splits`): leave-one-group-out when at least 3 groups are given, else seeded K-fold.
* **The workflow's split** (:func:`regression_split`): :func:`split_sites` with the ``regression`` config section,
  known when the workflow is parsed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from skidsim.errors import InputError


def inner_splits(n: int, groups=None, *, seed: int = 0, n_folds: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    """Index splits used to choose hyper-parameters on ``n`` training rows.

    Leave-one-group-out when ``groups`` has at least 3 distinct values, else ``min(n_folds, n)``-fold with rows
    shuffled by ``numpy.random.default_rng(seed)``.
    """
    if groups is not None:
        g = np.asarray(groups)
        uniq = sorted(set(g.tolist()))
        if len(uniq) >= 3:
            return [(np.flatnonzero(g != u), np.flatnonzero(g == u)) for u in uniq]
    k = int(min(n_folds, n))
    if k < 2:
        raise InputError(None, "at least 2 rows for an inner cross-validation", got=n)
    perm = np.random.default_rng(seed).permutation(n)
    folds = np.array_split(perm, k)
    return [(np.sort(np.concatenate([f for j, f in enumerate(folds) if j != i])), np.sort(folds[i])) for i in range(k)]


def split_sites(
    sites_df: pd.DataFrame, n_train: int = 27, seed: int = 0, grouped_by: str | None = None, *, file="campaign table"
) -> tuple[list[str], list[str]]:
    """Split sites into training and test ids (the study: 27/9 at random).

    Random split: the sorted site ids are permuted with ``numpy.random.default_rng(seed)``; the first ``n_train``
    train. Grouped split (``grouped_by="section"``): the sorted group names are permuted with the same generator
    and whole groups go to training, in that order, while they fit into ``n_train`` sites (a group that would
    overflow is skipped); all other groups are test. No group is then on both sides; the training size is
    ``n_train`` whenever group sizes allow it, else the largest total not above it. Returned lists are sorted.
    """
    if "site" not in sites_df.columns:
        raise InputError(file, "a 'site' column", column="site", got=list(sites_df.columns)[:8])
    sites = sites_df["site"].astype(str)
    if sites.duplicated().any():
        raise InputError(file, "one row per site", column="site", got=sites[sites.duplicated()].iloc[0])
    n = len(sites)
    if not (1 <= n_train < n):
        raise InputError(file, f"n_train between 1 and {n - 1} (there are {n} sites)", column="site", got=n_train)
    rng = np.random.default_rng(seed)
    if grouped_by is None:
        order = sorted(sites)
        perm = rng.permutation(n)
        train = [order[i] for i in perm[:n_train]]
    else:
        if grouped_by not in sites_df.columns:
            raise InputError(file, f"a '{grouped_by}' column to group the split by", column=grouped_by)
        grp = sites_df[grouped_by].astype(str).to_numpy()
        names = sorted(set(grp.tolist()))
        train, size = [], 0
        for gi in rng.permutation(len(names)):
            members = sites[grp == names[gi]].tolist()
            if size + len(members) <= n_train:
                train += members
                size += len(members)
        if size == 0 or size == n:
            raise InputError(
                file,
                f"groups ('{grouped_by}') small enough to put {n_train} sites in training",
                column=grouped_by,
                got=size,
            )
    train_set = set(train)
    test = sorted(s for s in sites if s not in train_set)
    return sorted(train), test


def regression_split(cfg: dict, sites: pd.DataFrame) -> tuple[list[str], list[str]]:
    """The seeded train/test split of the regression stage from the ``regression`` config section ``cfg``.

    ``cfg['n_test']`` sites are held out (the study: 9 of 36); for smaller campaigns the same share,
    ``round(n * n_test / 36)``, at least 1 when there are 4 sites or more.
    """
    n = len(sites)
    n_test = int(cfg.get("n_test", 9))
    if n != 36:
        n_test = int(round(n * n_test / 36.0))
        n_test = max(1, n_test) if n >= 4 else 0
    if n_test == 0:
        return list(sites["site"]), []
    train, test = split_sites(
        sites, n_train=n - n_test, seed=int(cfg["seed"]), grouped_by=cfg.get("grouped_by") or None
    )
    return [str(s) for s in train], [str(s) for s in test]
