# Model criticism: residuals within and between sites, candidate causes with permutation p-values and FDR control,
# the extension for the named cause, and its gain on held-out speeds and sites.
DIAG = f"{RESULTS}/diagnosis"


checkpoint diagnosis:
    """Find what the simulation gets wrong, name the cause, extend the model, measure the gain."""
    input:
        ingest=INGEST,
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        wide=f"{RESULTS}/texture/campaign.parquet",
        params=f"{RESULTS}/calibration/parameters.parquet",
        validation=f"{RESULTS}/calibration/validation.parquet",
        identifiability=f"{RESULTS}/calibration/identifiability.csv",
        cv_predictions=f"{REG}/cv_predictions.csv",
        best_model=f"{REG}/best_model.txt",
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
    log:
        "logs/diagnosis.log",
    benchmark:
        "benchmarks/out/diagnosis.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    params:
        cfg=config["diagnosis"],
        calibration_method=config["regression"]["calibration_method"],
        calibration_speeds=config["speeds"]["calibration_kmh"],
        validation_speeds=config["speeds"]["validation_kmh"],
    script:
        "../scripts/diagnosis.py"
