# The HTML report (`snakemake --report report.html`) embeds every file it shows. The per-site figures enter it as
# reduced JPEG copies made here (skidsim.plotting.gallery); the full-size PNGs stay in results/sites/<site>/.


rule report_gallery:
    """Every site's Figure 7, reconstruction and FE model figure scaled to 0.6 and stored as JPEG, for the report."""
    input:
        figure7=expand(rules.figure7.output.figure, site=SITES),
        reconstruction=expand(rules.reconstruct.output.reconstruction, site=SITES),
        fe_model=expand(rules.reconstruct.output.figure, site=SITES),
    output:
        figure7=report(
            directory(f"{RESULTS}/report/figure7"),
            patterns=["{site}.jpg"],
            caption="../report/figure7.rst",
            category="1 Texture",
            subcategory="Figure 7 per site",
            labels={"site": "{site}"},
        ),
        reconstruction=report(
            directory(f"{RESULTS}/report/reconstruction"),
            patterns=["{site}.jpg"],
            caption="../report/reconstruction.rst",
            category="1 Texture",
            subcategory="Figure 7 c-d per site",
            labels={"site": "{site}", "figure": "reconstruction"},
        ),
        fe_model=report(
            directory(f"{RESULTS}/report/fe_model"),
            patterns=["{site}.jpg"],
            caption="../report/fe_model.rst",
            category="1 Texture",
            subcategory="Figure 7 c-d per site",
            labels={"site": "{site}", "figure": "FE model"},
        ),
    log:
        "logs/report_gallery.log",
    benchmark:
        "benchmarks/out/report_gallery.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    params:
        sites=SITES,
    script:
        "../scripts/report_gallery.py"
