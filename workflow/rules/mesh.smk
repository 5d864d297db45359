# Reconstruction of the pavement strip as a rigid FE heightfield and the DFT model's meshes and exports.


rule reconstruct:
    """114.3 x 40 mm strip, area-averaged to the FE resolution, smoothed; heightfield, STL, VTU, gmsh, .inp."""
    input:
        surfaces=rules.despeckle.output.surfaces,
    output:
        pavement=f"{RESULTS}/sites/{{site}}/pavement.npz",
        stl=f"{RESULTS}/sites/{{site}}/pavement.stl",
        vtu=f"{RESULTS}/sites/{{site}}/pavement.vtu",
        slider=f"{RESULTS}/sites/{{site}}/slider.vtu",
        msh=f"{RESULTS}/sites/{{site}}/pavement.msh",
        inp_static=f"{RESULTS}/sites/{{site}}/dft_static_calculix.inp",
        inp_dynamic=f"{RESULTS}/sites/{{site}}/dft_dynamic_calculix.inp",
        inp_abaqus=f"{RESULTS}/sites/{{site}}/dft_dynamic_abaqus.inp",
        # the two figures are in the report as reduced copies (rule report_gallery, workflow/rules/report.smk)
        reconstruction=f"{RESULTS}/sites/{{site}}/reconstruction.png",
        figure=f"{RESULTS}/sites/{{site}}/fe_model.png",
    log:
        "logs/reconstruct/{site}.log",
    benchmark:
        "benchmarks/out/reconstruct/{site}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        mesh=config["mesh"],
        solver=config["solver"],
        friction_start=config["calibration"]["study"]["start"],
    script:
        "../scripts/reconstruct.py"
