"""The whole regression stage for the workflow: :func:`run_analysis` and :func:`write_analysis`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from skidsim.atomic import atomic_path, write_text
from skidsim.errors import InputError

from .design import Design
from .options import RegressionOptions
from .pca import fit_pca_tables, table5, table5_statistics, table6
from .prediction import predict_parameters
from .selection import rank_models
from .skill import BASELINE_MODEL, MEAN_MODEL, baseline_notes, prediction_skill
from .splits import split_sites
from .targets import dft_targets
from .validation import cross_validated_predictions, score_predictions


@dataclass
class RegressionAnalysis:
    """Everything the regression rule writes (see :func:`run_analysis` and :func:`write_analysis`).

    ``table5``/``table6``/``statistics`` hold the PCA regressions fitted on the training sites with the
    configured rule and with the study's rule (column ``rule``); ``cv_predictions``/``cv_table``/``ranking``
    the leave-one-section-out comparison on all sites; ``best`` its winner; ``test_parameters`` the predicted
    friction parameters of the test sites (column ``model``) that the FE runs of Figure 11 take as input.
    """

    train_ids: list
    test_ids: list
    fits: dict
    study_fits: dict
    table5: pd.DataFrame
    table6: pd.DataFrame
    statistics: pd.DataFrame
    cv_predictions: pd.DataFrame
    cv_table: pd.DataFrame
    ranking: pd.DataFrame
    best: str
    test_parameters: pd.DataFrame
    skill: pd.DataFrame | None = None


def _pca_tables(Xtr: pd.DataFrame, Ytr: pd.DataFrame, gtr: pd.Series, options: RegressionOptions, selection: str):
    """The PCA regressions of the training sites with the configured rule and the study's, and their Tables 5
    (with statistics) and 6 (column ``rule``; ``rule_config`` in the statistics)."""
    rule = options.rule
    fits = fit_pca_tables(
        Xtr,
        Ytr,
        rule=rule,
        groups=gtr.to_numpy(),
        seed=options.seed,
        inner_folds=options.inner_folds,
        selection=selection,
    )
    study = fits if rule == "study" else fit_pca_tables(Xtr, Ytr, rule="study")
    parts5, parts6, stats = [], [], []
    for r, f in ((rule, fits), ("study", study)) if rule != "study" else (("study", study),):
        t5, t6, st = table5(f), table6(f), table5_statistics(f)
        t5.insert(0, "rule", r), t6.insert(0, "rule", r), st.insert(0, "rule_config", r)
        parts5.append(t5), parts6.append(t6), stats.append(st)
    return (
        fits,
        study,
        pd.concat(parts5, ignore_index=True),
        pd.concat(parts6, ignore_index=True),
        pd.concat(stats, ignore_index=True),
    )


def _test_parameters(
    design: Design,
    train: list,
    test: list,
    best: str,
    options: RegressionOptions,
    dft: pd.DataFrame,
    g: pd.DataFrame | None,
    selection: str,
) -> pd.DataFrame:
    """The predicted parameters of the test sites by each of ``options.figure11_models`` (``"best"`` = ``best``),
    fitted on the training sites; columns site, model, the parameters (and the model's extra columns)."""
    Xtr, Ytr, gtr = design.X.loc[train], design.Y.loc[train], design.groups.loc[train]
    preds = []
    for m in dict.fromkeys(best if m == "best" else m for m in options.figure11_models):
        p = predict_parameters(
            m,
            Xtr,
            Ytr,
            design.X.loc[test],
            groups_train=gtr.to_numpy(),
            seed=options.seed,
            inner_folds=options.inner_folds,
            selection=selection,
            dft_train=dft.loc[train],
            g_test=g,
        )
        p.insert(0, "model", m)
        p.insert(0, "site", p.index.astype(str))
        preds.append(p.reset_index(drop=True))
    return pd.concat(preds, ignore_index=True)


def run_analysis(
    design: Design,
    options: RegressionOptions | None = None,
    *,
    n_train: int | None = None,
    g: pd.DataFrame | None = None,
    measured_dft: pd.DataFrame | None = None,
    selection: str = "one_se",
    workers: int = 1,
) -> RegressionAnalysis:
    """The study's analysis plus the honest comparison, on a :class:`Design` with friction.

    Split (:func:`split_sites`: ``n_train`` training sites, default all but ``options.n_test``; ``grouped_by``),
    PCA regression Tables 5 and 6 on the training sites (``options.rule`` and ``"study"``),
    leave-one-section-out CV of ``options.models`` on all sites, the best model by ``options.criterion``
    (:func:`rank_models`) and, for each of ``options.figure11_models`` (``"best"`` = the winner, or any model name
    such as ``"pca:study"``), the predicted parameters of the test sites, fitted on the training sites.
    ``g``/``measured_dft`` as in :func:`score_predictions`; the DFT speeds are ``options.prediction_speeds_kmh``.
    ``selection``: ``"one_se"`` or ``"min"`` (:mod:`.paths`). ``workers``: processes of the cross-validation
    (:func:`cross_validated_predictions`; same numbers for any value). The intercept-only :data:`MEAN_MODEL` and
    the baseline :data:`BASELINE_MODEL` are always cross-validated (appended to the CV when ``options.models``
    lacks them): they are the references of the prediction-skill table (:func:`prediction_skill`, ``skill``).
    The best model is chosen among ``options.models`` only, so the references compete for it only when listed
    (the default configuration lists both).
    """
    options = RegressionOptions() if options is None else options
    if design.Y is None:
        raise InputError(None, "a friction table (mu_s, mu_k, alpha per site)", column="mu_s")
    sites = pd.DataFrame({"site": design.X.index.astype(str), "section": design.groups.to_numpy()})
    n_train = len(sites) - options.n_test if n_train is None else n_train
    train, test = split_sites(sites, n_train, options.seed, options.grouped_by)
    fits, study, t5, t6, stats = _pca_tables(
        design.X.loc[train], design.Y.loc[train], design.groups.loc[train], options, selection
    )
    listed = list(dict.fromkeys(options.models))
    compared = list(dict.fromkeys(listed + [MEAN_MODEL, BASELINE_MODEL]))
    speeds = options.prediction_speeds_kmh
    dft = dft_targets(design.Y, measured_dft=measured_dft, g=g, speeds_kmh=speeds)
    cvp = cross_validated_predictions(
        design.X,
        design.Y,
        design.groups,
        compared,
        seed=options.seed,
        inner_folds=options.inner_folds,
        selection=selection,
        workers=workers,
        dft=dft,
        g=g,
    )
    cvt = score_predictions(cvp, design.Y, g=g, measured_dft=measured_dft, speeds_kmh=speeds)
    ranking = rank_models(cvt[cvt["model"].isin(listed)], options.criterion)
    best = str(ranking["model"].iloc[0])
    skill = prediction_skill(cvt, best, notes=baseline_notes(cvp))
    tp = _test_parameters(design, train, test, best, options, dft, g, selection)
    return RegressionAnalysis(train, test, fits, study, t5, t6, stats, cvp, cvt, ranking, best, tp, skill)


def write_analysis(analysis: RegressionAnalysis, directory) -> dict:
    """Write the analysis as CSV files (each atomically, :mod:`skidsim.atomic`) into ``directory``.

    Files: split.csv, table5.csv, table5_statistics.csv, table6.csv, cv_predictions.csv, cv_table.csv,
    cv_ranking.csv, test_parameters.csv, prediction_skill.csv (when ``analysis.skill`` is set),
    best_model.txt. Returns {name: path}.
    """
    d = Path(directory)
    split = pd.DataFrame(
        {
            "site": analysis.train_ids + analysis.test_ids,
            "set": ["train"] * len(analysis.train_ids) + ["test"] * len(analysis.test_ids),
        }
    )
    out = {
        "split": split,
        "table5": analysis.table5,
        "table5_statistics": analysis.statistics,
        "table6": analysis.table6,
        "cv_predictions": analysis.cv_predictions,
        "cv_table": analysis.cv_table,
        "cv_ranking": analysis.ranking,
        "test_parameters": analysis.test_parameters,
    }
    if analysis.skill is not None:
        out["prediction_skill"] = analysis.skill
    paths = {}
    for name, df in out.items():
        paths[name] = d / f"{name}.csv"
        with atomic_path(paths[name]) as tmp:
            df.to_csv(tmp, index=False)
    paths["best_model"] = write_text(d / "best_model.txt", analysis.best + "\n")
    return paths
