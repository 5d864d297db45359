# Texture -> friction regression (the study's PCA regression, Tables 5-6), honest cross-validated alternatives, and
# FE predictions for the held-out sites (Figure 11). The 27/9 split is seeded, so it is known at parse time.
from skidsim.regression.splits import regression_split

TRAIN_SITES, TEST_SITES = regression_split(config["regression"], SITE_TABLE)
REG = f"{RESULTS}/regression"


rule regression:
    """PCA regression per friction parameter on the training sites (Tables 5-6); CV comparison of models by section;
    prediction-skill table (each model against the mean and the two-column OLS baseline, WARNING when the chosen
    model does not beat both)."""
    input:
        wide=f"{RESULTS}/texture/campaign.parquet",
        params=f"{RESULTS}/calibration/parameters.parquet",
        validation=f"{RESULTS}/calibration/validation.parquet",
        dft=f"{RESULTS}/ingest/dft_points.parquet",
    output:
        split=f"{REG}/split.csv",
        table5=report(f"{REG}/table5.csv", caption="../report/table5.rst", category="4 Regression"),
        table5_statistics=report(
            f"{REG}/table5_statistics.csv", caption="../report/table5.rst", category="4 Regression"
        ),
        table6=report(f"{REG}/table6.csv", caption="../report/table6.rst", category="4 Regression"),
        cv_table=report(f"{REG}/cv_table.csv", caption="../report/cv.rst", category="4 Regression"),
        cv_ranking=report(f"{REG}/cv_ranking.csv", caption="../report/cv.rst", category="4 Regression"),
        skill=report(f"{REG}/prediction_skill.csv", caption="../report/prediction_skill.rst", category="4 Regression"),
        skill_figure=report(
            f"{REG}/prediction_skill.png", caption="../report/prediction_skill.rst", category="4 Regression"
        ),
        cv_predictions=f"{REG}/cv_predictions.csv",
        test_parameters=f"{REG}/test_parameters.csv",
        best_model=f"{REG}/best_model.txt",
        cv_figure=report(f"{REG}/cv_comparison.png", caption="../report/cv.rst", category="4 Regression"),
        table6_figure=report(f"{REG}/table6.png", caption="../report/table6.rst", category="4 Regression"),
    log:
        "logs/regression.log",
    benchmark:
        "benchmarks/out/regression.tsv"
    threads: 2
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        cfg=config["regression"],
        train=TRAIN_SITES,
        test=TEST_SITES,
    script:
        "../scripts/regression.py"


rule predict_fe:
    """FE simulation of a held-out site at 20-70 km/h with friction parameters predicted from its texture."""
    input:
        pavement=f"{RESULTS}/sites/{{site}}/pavement.npz",
        predictions=f"{REG}/test_parameters.csv",
    output:
        table=f"{REG}/fe/{{site}}.parquet",
    log:
        "logs/predict_fe/{site}.log",
    benchmark:
        "benchmarks/out/predict_fe/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=60,
    params:
        solver=config["solver"],
        speeds=config["regression"]["prediction_speeds_kmh"],
        cache=f"{RESULTS}/cache/{{site}}/fe.parquet",
    script:
        "../scripts/predict_fe.py"


rule figure11:
    """Predicted vs measured DFT of the held-out sites at six speeds (study Figure 11) and the error table."""
    input:
        tables=expand(f"{REG}/fe/{{site}}.parquet", site=TEST_SITES),
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        best_model=f"{REG}/best_model.txt",
    output:
        table=report(f"{REG}/figure11_errors.csv", caption="../report/figure11.rst", category="4 Regression"),
        summary=f"{REG}/figure11_summary.csv",
        figure=report(f"{REG}/figure11.png", caption="../report/figure11.rst", category="4 Regression"),
    log:
        "logs/figure11.log",
    benchmark:
        "benchmarks/out/figure11.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    script:
        "../scripts/figure11.py"
