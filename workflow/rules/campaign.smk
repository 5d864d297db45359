# The campaign: the embedded synthetic default (when config `campaign` is unset) and the validation of any campaign.


rule synth_site:
    """Generate one synthetic site: an LS-40-like scan (X3P), its DFT spin-down trace, and its ground truth."""
    output:
        scan=f"{RESULTS}/campaign/scans/{{site}}.x3p",
        dft=f"{RESULTS}/campaign/dft/{{site}}.csv",
        truth=f"{RESULTS}/truth/sites/{{site}}.json",
    log:
        "logs/synth_site/{site}.log",
    benchmark:
        "benchmarks/out/synth_site/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=10,
    script:
        "../scripts/synth_site.py"


rule synth_table:
    """Write the synthetic campaign's sites.csv (the data contract) once every site exists."""
    input:
        scans=expand(f"{RESULTS}/campaign/scans/{{site}}.x3p", site=SITES),
        dfts=expand(f"{RESULTS}/campaign/dft/{{site}}.csv", site=SITES),
    output:
        sites=f"{RESULTS}/campaign/sites.csv",
    log:
        "logs/synth_table.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    script:
        "../scripts/synth_table.py"


rule synth_truth:
    """Gather the synthetic campaign's ground truth (for people and tests; no analysis rule reads results/truth/)."""
    input:
        truths=expand(f"{RESULTS}/truth/sites/{{site}}.json", site=SITES),
    output:
        truth=f"{RESULTS}/truth/campaign.json",
    log:
        "logs/synth_truth.log",
    localrule: True
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    script:
        "../scripts/synth_truth.py"


rule validate_campaign:
    """Check the whole campaign against the data contract; every error is named at once, nothing else runs."""
    input:
        unpack(campaign_inputs),
    output:
        sites=INGEST,
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
    log:
        "logs/validate_campaign.log",
    benchmark:
        "benchmarks/out/validate_campaign.tsv"
    # nothing else is ready while it runs (every analysis rule waits for it): its scans are checked two at a time
    threads: 2
    resources:
        mem_mb=1500,
        runtime=15,
    params:
        campaign=str(CAMPAIGN_DIR),
        speeds=sorted(set(config["speeds"]["calibration_kmh"]) | set(config["speeds"]["validation_kmh"])),
        check_scans=config["ingest"]["check_scans"],
        smooth_window_kmh=config["ingest"]["dft_smooth_window_kmh"],
    script:
        "../scripts/validate_campaign.py"
