# Model criticism: residuals within and between sites, candidate causes with permutation p-values and FDR control,
# the extension for the named cause, and its gain on held-out speeds and sites.
DIAG = f"{RESULTS}/diagnosis"


rule diagnosis:
    """Find what the simulation gets wrong, name the cause, extend the model, measure the gain."""
    input:
        ingest=INGEST,
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        wide=f"{RESULTS}/texture/campaign.parquet",
        params=f"{RESULTS}/calibration/parameters.parquet",
        validation=f"{RESULTS}/calibration/validation.parquet",
        fe_predictions=expand(f"{REG}/fe/{{site}}.parquet", site=TEST_SITES),
        predicted_params=f"{REG}/test_parameters.csv",
    output:
        residuals=f"{DIAG}/residuals.parquet",
        causes=f"{DIAG}/causes.json",
        gain=f"{DIAG}/gain.json",
        report=report(f"{DIAG}/report.md", caption="../report/diagnosis.rst", category="5 Model criticism"),
        figures=report(
            directory(f"{DIAG}/figures"),
            patterns=["{name}.png"],
            caption="../report/diagnosis.rst",
            category="5 Model criticism",
        ),
    params:
        cfg=config["diagnosis"],
        calibration_method=config["regression"]["calibration_method"],
        train=TRAIN_SITES,
        test=TEST_SITES,
    log:
        "logs/diagnosis.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/diagnosis.py"
