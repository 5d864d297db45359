# Back-calculation of (mu_s, mu_k, alpha) per site: the study's nested bisection and our fast method; validation at
# speeds never used in calibration; the study's Table 2 and Figure 10. FE evaluations are cached per site in
# results/cache/<site>/ (not a declared output: a failed or repeated run reuses every simulation already done).


rule calibrate:
    """Calibrate one site's friction law with one method (study | ours)."""
    input:
        pavement=f"{RESULTS}/sites/{{site}}/pavement.npz",
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        prior=calibration_prior_of,
    output:
        result=f"{RESULTS}/sites/{{site}}/calibration_{{method}}.json",
        history=f"{RESULTS}/sites/{{site}}/calibration_{{method}}_history.parquet",
    log:
        "logs/calibrate/{site}_{method}.log",
    benchmark:
        "benchmarks/out/calibrate/{site}_{method}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=120,
    params:
        calibration=config["calibration"],
        solver=config["solver"],
        speeds=config["speeds"]["calibration_kmh"],
        cache=f"{RESULTS}/cache/{{site}}/fe.parquet",
    script:
        "../scripts/calibrate.py"


rule validate_speeds:
    """Simulate the site at calibration and validation speeds with each method's parameters; then, from those runs
    and the site's DFT trace, the quality and identifiability record of each method's calibration: fit vs the
    trace's noise, flags with reasons (not_converged, at_bound, outside_law, fe_not_smooth, fit_beyond_noise),
    standard errors, profile-likelihood intervals and the identified combinations
    (skidsim.calibration.identifiability; no further FE runs)."""
    input:
        pavement=f"{RESULTS}/sites/{{site}}/pavement.npz",
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        calibrations=expand(f"{RESULTS}/sites/{{{{site}}}}/calibration_{{method}}.json", method=METHODS),
    output:
        table=f"{RESULTS}/sites/{{site}}/validation.parquet",
        records=expand(f"{RESULTS}/sites/{{{{site}}}}/identifiability_{{method}}.json", method=METHODS),
    log:
        "logs/validate_speeds/{site}.log",
    benchmark:
        "benchmarks/out/validate_speeds/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=60,
    params:
        solver=config["solver"],
        methods=METHODS,
        calibration_speeds=config["speeds"]["calibration_kmh"],
        validation_speeds=config["speeds"]["validation_kmh"],
        cache=f"{RESULTS}/cache/{{site}}/fe.parquet",
        identifiability=config["calibration"].get("identifiability", {}),
    script:
        "../scripts/validate_speeds.py"


rule calibration_summary:
    """Table 2 (parameters per site), the cost/fit comparison of the two methods, Figure 10, the campaign's
    identifiability table and figure (per-site records of rule validate_speeds)."""
    input:
        ingest=INGEST,
        calibrations=expand(f"{RESULTS}/sites/{{site}}/calibration_{{method}}.json", site=SITES, method=METHODS),
        validations=expand(f"{RESULTS}/sites/{{site}}/validation.parquet", site=SITES),
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        ifi=f"{RESULTS}/ifi/ifi.csv",  # the PIARC/IFI speed model beside the FE laws (rule ifi in ifi.smk)
        identifiability=expand(f"{RESULTS}/sites/{{site}}/identifiability_{{method}}.json", site=SITES, method=METHODS),
    output:
        table2=report(
            f"{RESULTS}/calibration/table2.csv", caption="../report/table2.csv.rst", category="3 Back-calculation"
        ),
        comparison=report(
            f"{RESULTS}/calibration/comparison.csv", caption="../report/comparison.rst", category="3 Back-calculation"
        ),
        stats=report(
            f"{RESULTS}/calibration/fit_statistics.csv",
            caption="../report/fit_statistics.rst",
            category="3 Back-calculation",
        ),
        validation=f"{RESULTS}/calibration/validation.parquet",
        params=f"{RESULTS}/calibration/parameters.parquet",
        figure10=report(
            f"{RESULTS}/calibration/figure10.png", caption="../report/figure10.rst", category="3 Back-calculation"
        ),
        curves=report(
            f"{RESULTS}/calibration/curves.png", caption="../report/curves.rst", category="3 Back-calculation"
        ),
        identifiability=report(
            f"{RESULTS}/calibration/identifiability.csv",
            caption="../report/identifiability.rst",
            category="3 Back-calculation",
        ),
        identifiability_figure=report(
            f"{RESULTS}/calibration/identifiability.png",
            caption="../report/identifiability_figure.rst",
            category="3 Back-calculation",
        ),
    log:
        "logs/calibration_summary.log",
    benchmark:
        "benchmarks/out/calibration_summary.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        methods=METHODS,
    script:
        "../scripts/calibration_summary.py"
