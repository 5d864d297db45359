# The International Friction Index (ASTM E1960) per site from the DFT at 20 km/h and the MPD, and the PIARC/IFI
# speed model mu(v) = DFT20 exp((20 - v) / Sp) beside the FE-calibrated laws at the validation speeds
# (skidsim.ifi; docs/workflow.md, "IFI").


rule ifi:
    """IFI (F60, Sp) per site: Sp = 14.2 + 89.7 MPD, FR60 = DFT20 exp(-40 / Sp), F60 = 0.081 + 0.732 FR60."""
    input:
        mpd=expand(f"{RESULTS}/sites/{{site}}/mpd.json", site=SITES),
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
    output:
        ifi=report(f"{RESULTS}/ifi/ifi.csv", caption="../report/ifi.rst", category="3 Back-calculation"),
    log:
        "logs/ifi.log",
    benchmark:
        "benchmarks/out/ifi.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        smooth_window_kmh=config["ingest"]["dft_smooth_window_kmh"],
    script:
        "../scripts/ifi.py"


rule ifi_validation:
    """The PIARC/IFI speed model vs the FE-calibrated laws at the validation speeds: RMSE and R^2 side by side."""
    input:
        ifi=rules.ifi.output.ifi,
        validation=f"{RESULTS}/calibration/validation.parquet",
    output:
        table=report(
            f"{RESULTS}/ifi/validation.csv", caption="../report/ifi_validation.rst", category="3 Back-calculation"
        ),
        rows=f"{RESULTS}/ifi/validation_rows.parquet",
        figure=report(f"{RESULTS}/ifi/ifi_vs_fe.png", caption="../report/ifi_figure.rst", category="3 Back-calculation"),
    log:
        "logs/ifi_validation.log",
    benchmark:
        "benchmarks/out/ifi_validation.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        validation_speeds=config["speeds"]["validation_kmh"],
    script:
        "../scripts/ifi_validation.py"
