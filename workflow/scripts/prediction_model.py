"""Snakemake adapter: the prediction model file (results/prediction/model.json), its card and its coverage at
unseen sections; checks that its section folds reproduce the workflow's cross-validated predictions."""

from pathlib import Path

import numpy as np
import pandas as pd

from skidsim import prediction, regression
from skidsim.atomic import atomic_path
from skidsim.config import config_digest
from skidsim.prediction.options import PredictOptions
from skidsim.regression.models import DFT_SUFFIX
from skidsim.runlog import setup_logging
from skidsim.texture import TextureOptions
from skidsim.texture.quality import QualityOptions

log = setup_logging(snakemake.log[0])
cfg = snakemake.config
options = regression.RegressionOptions.from_config(cfg["regression"])
popts = PredictOptions.from_dict(cfg.get("predict"))
wide = pd.read_parquet(snakemake.input.wide)
design = regression.assemble_design(wide, campaign_file=snakemake.input.wide)
X, groups = design.X, design.groups.to_numpy()
points = pd.read_parquet(snakemake.input.dft)
D = regression.dft_targets(
    None,
    measured_dft=points,
    speeds_kmh=options.prediction_speeds_kmh,
    sites=list(X.index),
    measured_file=snakemake.input.dft,
)
ranking = pd.read_csv(snakemake.input.ranking)
best = Path(snakemake.input.best).read_text().strip()
dft_models = [m for m in ranking["model"] if str(m).endswith(DFT_SUFFIX)]
chosen = dft_models[0] if dft_models else prediction.BASELINE
why = (
    f"best of the listed @dft models by {options.criterion} (workflow best: {best})"
    if dft_models
    else "regression.models lists no @dft model: the baseline"
)
log.info("model file: %s (%s)", chosen, why)
texture = TextureOptions(**cfg["texture"])
quality = QualityOptions.from_dict(cfg.get("quality"), strip_length_mm=cfg["mesh"]["length_mm"])
digest = config_digest({k: cfg.get(k) for k in ("speeds", "ingest", "texture", "quality", "regression", "predict")})
model = prediction.train_model(
    X,
    D,
    groups,
    chosen,
    seed=options.seed,
    inner_folds=options.inner_folds,
    selection="one_se",
    texture=texture,
    quality=quality,
    config_digest=digest,
    notes={"chosen_by": why, "workflow_best": best},
    domain_alpha=popts.domain_alpha,
)

# the folds are the workflow's leave-one-section-out fits: their predictions of the training sites must be the
# cross-validated predictions the regression rule wrote
cvp = pd.read_csv(snakemake.input.cv_predictions)
for part in (model.chosen, model.baseline):
    iv = part.intervals
    oof = np.vstack([iv.folds[j].predict(X.loc[[s]]).to_numpy()[0] for s, j in zip(iv.sites, iv.site_fold)])
    rows = cvp[cvp["model"] == part.name].set_index("site").loc[list(iv.sites), list(part.map.targets)]
    gap = float(np.max(np.abs(oof - rows.to_numpy(dtype=float))))
    log.info("%s: section folds against cv_predictions.csv, largest difference %.3g", part.name, gap)
    if not gap <= 1e-9:
        raise RuntimeError(f"{part.name}: the model file's folds differ from cv_predictions.csv by {gap:.3g}")

cards, tables = [], []
for role, part in (("chosen", model.chosen), ("baseline", model.baseline)):
    scores, table = prediction.heldout_coverage(
        X,
        D,
        groups,
        part.name,
        popts.interval_level,
        seed=options.seed,
        inner_folds=options.inner_folds,
        domain_alpha=popts.domain_alpha,
    )
    part.skill["heldout"] = scores
    tables.append(table.assign(model=part.name))
    cards.append(
        {
            "role": role,
            "model": part.name,
            "features": part.map.label or "+".join(part.map.features),
            "n_features": len(part.map.features),
            "cv_rmse": part.skill["cv_rmse"],
            "cv_r2": part.skill["cv_r2"],
            "interval_level": popts.interval_level,
            "heldout_coverage": scores["coverage"],
            "heldout_mean_width": scores["mean_width"],
            "heldout_share_flagged": scores["share_flagged"],
            "domain_threshold": part.domain.threshold,
            "domain_components": len(part.domain.variances),
            "n_sites": model.training["n_sites"],
            "n_sections": model.training["n_sections"],
            "table_digest": model.training["table_digest"][:12],
        }
    )
    log.info(
        "%s %s: CV RMSE %.4f, R2 %.3f; at unseen sections coverage %.3f (nominal %.2f), mean width %.4f, %.1f %% "
        "flagged",
        role,
        part.name,
        part.skill["cv_rmse"],
        part.skill["cv_r2"],
        scores["coverage"],
        popts.interval_level,
        scores["mean_width"],
        100 * scores["share_flagged"],
    )
prediction.save_model(model, snakemake.output.model)
for path, df in ((snakemake.output.card, pd.DataFrame(cards)), (snakemake.output.heldout, pd.concat(tables))):
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)
