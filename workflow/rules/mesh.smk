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
        inp=f"{RESULTS}/sites/{{site}}/dft_model.inp",
        figure=report(
            f"{RESULTS}/sites/{{site}}/fe_model.png",
            caption="../report/fe_model.rst",
            category="1 Texture",
            subcategory="Figure 7 c-d per site",
            labels={"site": "{site}"},
        ),
    params:
        mesh=config["mesh"],
        solver=config["solver"],
        friction_start=config["calibration"]["study"]["start"],
        load_n=config["solver"]["load_n"],
    log:
        "logs/reconstruct/{site}.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    script:
        "../scripts/reconstruct.py"
