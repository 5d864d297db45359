# The solver's mesh study (study Figure 9) on one site's reconstructed pavement.
MESH_STUDY_SITE = config["mesh_study"].get("site") or SITES[0]


rule mesh_study:
    """SN against slider element size at the configured speeds; error against the finest mesh, compute time."""
    input:
        pavement=f"{RESULTS}/sites/{MESH_STUDY_SITE}/pavement.npz",
    output:
        table=report(f"{RESULTS}/mesh_study/table.csv", caption="../report/mesh_study.rst", category="2 Mesh study"),
        figure=report(f"{RESULTS}/mesh_study/figure9.png", caption="../report/mesh_study.rst", category="2 Mesh study"),
    log:
        "logs/mesh_study.log",
    benchmark:
        "benchmarks/out/mesh_study.tsv"
    # one long job on one site's pavement: started early it runs beside the per-site jobs; started last it held a
    # core while the 2-thread regression waited for it (68 s of one idle core, make reproduce 2026-11-29, f550989)
    priority: 50
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    params:
        cfg=config["mesh_study"],
        solver=config["solver"],
        site=MESH_STUDY_SITE,
    script:
        "../scripts/mesh_study.py"
