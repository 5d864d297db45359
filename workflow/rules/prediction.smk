# Friction for scans without DFT (docs/prediction.md): the model file users keep and apply, and its use on a
# directory of scans (config predict.scans).
PRED = f"{RESULTS}/prediction"


def prediction_targets():
    """The model file and its card always (with the regression); the predictions when predict.scans is set."""
    out = [f"{PRED}/model.json", f"{PRED}/model_card.csv"]
    if (config.get("predict") or {}).get("scans"):
        out.append(f"{PRED}/predictions.csv")
    return out


rule prediction_model:
    """The chosen model on DFT targets and the ols2@dft baseline as a JSON file (no pickle): linear maps, CV+
    intervals over the sections, training domain, texture options; its coverage measured at unseen sections."""
    input:
        wide=f"{RESULTS}/texture/campaign.parquet",
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        ranking=f"{RESULTS}/regression/cv_ranking.csv",
        best=f"{RESULTS}/regression/best_model.txt",
        cv_predictions=f"{RESULTS}/regression/cv_predictions.csv",
    output:
        model=f"{PRED}/model.json",
        card=report(f"{PRED}/model_card.csv", caption="../report/model_card.rst", category="4 Regression"),
        heldout=f"{PRED}/heldout_intervals.csv",
    log:
        "logs/prediction_model.log",
    benchmark:
        "benchmarks/out/prediction_model.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/prediction_model.py"


rule predict_scans:
    """The model file applied to every scan of the directory predict.scans: DFT at the model's speeds with
    intervals, F60 and Sp, extrapolation and quality flags."""
    input:
        model=rules.prediction_model.output.model,
    output:
        table=report(f"{PRED}/predictions.csv", caption="../report/model_card.rst", category="4 Regression"),
        ifi=f"{PRED}/predictions_ifi.csv",
    log:
        "logs/predict_scans.log",
    benchmark:
        "benchmarks/out/predict_scans.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    params:
        cfg=config.get("predict") or {},
    script:
        "../scripts/predict_scans.py"
