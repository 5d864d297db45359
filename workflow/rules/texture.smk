# Texture characterisation, one rule per step and site, then the campaign tables (study Tables 3-4, Figure 7).


rule despeckle:
    """Instrument spikes removed (default rule local; the study's limiting filter by name); scan quality measured
    and checked against config quality: (warn or stop); invalid points filled. The quality limits are read from
    the config, not passed as params, so that changing a limit re-runs only scan_quality, not the texture chain."""
    input:
        scan=scan_of,
        ingest=INGEST,
    output:
        surfaces=temp(f"{RESULTS}/sites/{{site}}/despeckled.npz"),
        stats=f"{RESULTS}/sites/{{site}}/despeckle.json",
        quality=f"{RESULTS}/sites/{{site}}/quality.json",
    log:
        "logs/despeckle/{site}.log",
    benchmark:
        "benchmarks/out/despeckle/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=5,
    params:
        cfg=config["texture"],
    script:
        "../scripts/despeckle.py"


rule separate_bands:
    """Form removal and areal Butterworth separation into raw, macro (0.5-50 mm) and micro (< 0.5 mm) bands."""
    input:
        surfaces=rules.despeckle.output.surfaces,
    output:
        bands=temp(f"{RESULTS}/sites/{{site}}/bands.npz"),
    log:
        "logs/separate_bands/{site}.log",
    benchmark:
        "benchmarks/out/separate_bands/{site}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    params:
        cfg=config["texture"],
    script:
        "../scripts/separate_bands.py"


rule mpd:
    """Mean profile depth per ISO 13473-1:2019 from the scan's profiles, and ETD."""
    input:
        surfaces=rules.despeckle.output.surfaces,
    output:
        mpd=f"{RESULTS}/sites/{{site}}/mpd.json",
    log:
        "logs/mpd/{site}.log",
    benchmark:
        "benchmarks/out/mpd/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=5,
    params:
        cfg=config["texture"],
    script:
        "../scripts/mpd.py"


rule texture_parameters:
    """The study's Table 3 parameters for raw, macro and micro texture, in long form."""
    input:
        bands=rules.separate_bands.output.bands,
        mpd=rules.mpd.output.mpd,
    output:
        table=f"{RESULTS}/sites/{{site}}/texture.parquet",
    log:
        "logs/texture_parameters/{site}.log",
    benchmark:
        "benchmarks/out/texture_parameters/{site}.tsv"
    threads: 1
    resources:
        mem_mb=2500,
        runtime=10,
    params:
        cfg=config["texture"],
    script:
        "../scripts/texture_parameters.py"


rule figure7:
    """Range image, despeckled, macro and micro texture of one site (study Figure 7 a-b)."""
    input:
        scan=scan_of,
        surfaces=rules.despeckle.output.surfaces,
        bands=rules.separate_bands.output.bands,
    output:
        figure=f"{RESULTS}/sites/{{site}}/figure7.png",  # in the report as a reduced copy (rule report_gallery)
    log:
        "logs/figure7/{site}.log",
    benchmark:
        "benchmarks/out/figure7/{site}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    script:
        "../scripts/figure7.py"


rule scan_quality:
    """Scan quality of every site in one table and figure (dropouts, despeckle, height step, tilt, usable length);
    flagged sites are logged as WARNINGs and marked in the report."""
    input:
        quality=expand(f"{RESULTS}/sites/{{site}}/quality.json", site=SITES),
    output:
        table=report(
            f"{RESULTS}/texture/quality.csv",
            caption="../report/quality.rst",
            category="1 Texture",
            subcategory="Scan quality",
        ),
        figure=report(
            f"{RESULTS}/texture/quality.png",
            caption="../report/quality.rst",
            category="1 Texture",
            subcategory="Scan quality",
        ),
    log:
        "logs/scan_quality.log",
    benchmark:
        "benchmarks/out/scan_quality.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        quality=config.get("quality", {}),
        strip_length_mm=config["mesh"]["length_mm"],
    script:
        "../scripts/scan_quality.py"


rule texture_campaign:
    """Join all sites with their metadata; the study's Table 4 statistics; distributions. Needs the scan-quality
    table, so that no campaign texture table is published before every scan's quality was checked."""
    input:
        ingest=INGEST,
        quality=rules.scan_quality.output.table,
        tables=expand(f"{RESULTS}/sites/{{site}}/texture.parquet", site=SITES),
    output:
        long=f"{RESULTS}/texture/texture_long.parquet",
        wide=f"{RESULTS}/texture/campaign.parquet",
        table4=report(f"{RESULTS}/texture/table4.csv", caption="../report/table4.rst", category="1 Texture"),
        figure=report(
            f"{RESULTS}/texture/distributions.png", caption="../report/distributions.rst", category="1 Texture"
        ),
    log:
        "logs/texture_campaign.log",
    benchmark:
        "benchmarks/out/texture_campaign.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    script:
        "../scripts/texture_campaign.py"
