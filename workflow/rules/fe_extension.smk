# FE extension of the model criticism: recalibrate every site with a viscoelastic slider (Prony series on the
# shear modulus; hysteresis on macrotexture) and measure the gain at held-out speeds (docs/model-criticism.md,
# "FE extension: viscoelastic slider"). With diagnosis.fe_extension `auto` the per-site runs are scheduled only
# after the diagnosis checkpoint has named a within-site shape cause; `always` forces them, `never` skips them.
import json
from types import SimpleNamespace

from skidsim.criticism.fe_extension import fe_extension_decision, viscoelastic_solver_cfg

FE_MODE = config["diagnosis"].get("fe_extension", "auto")
FE_SOLVER = viscoelastic_solver_cfg(config["solver"], config["diagnosis"].get("viscoelastic"))


def fe_prior_of(wildcards):
    """The same surrogate prior as the site's elastic calibration with our method (common.smk)."""
    return calibration_prior_of(SimpleNamespace(site=wildcards.site, method="ours"))


rule fe_recalibrate:
    """Recalibrate one site with the viscoelastic solver (our method, same speeds, trace and prior as the elastic
    calibration) and simulate it at the calibration and validation speeds."""
    input:
        pavement=f"{RESULTS}/sites/{{site}}/pavement.npz",
        dft=f"{RESULTS}/ingest/dft_points.parquet",
        traces=f"{RESULTS}/ingest/dft_traces.parquet",
        prior=fe_prior_of,
    output:
        result=f"{RESULTS}/sites/{{site}}/fe_extension/calibration_ours.json",
        history=f"{RESULTS}/sites/{{site}}/fe_extension/calibration_ours_history.parquet",
        validation=f"{RESULTS}/sites/{{site}}/fe_extension/validation.parquet",
    log:
        "logs/fe_recalibrate/{site}.log",
    benchmark:
        "benchmarks/out/fe_recalibrate/{site}.tsv"
    threads: 1
    resources:
        mem_mb=1500,
        runtime=240,
    params:
        calibration=config["calibration"],
        solver=FE_SOLVER,
        calibration_speeds=config["speeds"]["calibration_kmh"],
        validation_speeds=config["speeds"]["validation_kmh"],
        cache=f"{RESULTS}/cache/{{site}}/fe_viscoelastic.parquet",
    script:
        "../scripts/fe_recalibrate.py"


def fe_gain_inputs(wildcards):
    """The per-site viscoelastic runs when the extension applies (auto: decided on the checkpoint's causes.json)."""
    per_site = {
        "elastic": expand(f"{RESULTS}/sites/{{site}}/validation.parquet", site=SITES),
        "visco": expand(f"{RESULTS}/sites/{{site}}/fe_extension/validation.parquet", site=SITES),
        "visco_calibrations": expand(f"{RESULTS}/sites/{{site}}/fe_extension/calibration_ours.json", site=SITES),
        "dft": f"{RESULTS}/ingest/dft_points.parquet",
    }
    if FE_MODE == "never":
        return {}
    if FE_MODE == "always":
        return per_site
    causes = checkpoints.diagnosis.get().output.causes
    with open(causes) as fh:
        apply, _ = fe_extension_decision(FE_MODE, json.load(fh))
    return dict(per_site, causes=causes) if apply else {"causes": causes}


rule fe_gain:
    """Held-out-speed gain of the viscoelastic recalibration over the elastic one (or the not-applied record)."""
    input:
        unpack(fe_gain_inputs),
    output:
        gain=f"{DIAG}/fe_gain.json",
    log:
        "logs/fe_gain.log",
    benchmark:
        "benchmarks/out/fe_gain.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        mode=FE_MODE,
        sites=SITES,
        solver=FE_SOLVER,
        validation_speeds=config["speeds"]["validation_kmh"],
        n_boot=config["diagnosis"]["n_boot"],
        ci=config["diagnosis"]["ci"],
        seed=config["diagnosis"]["seed"],
    script:
        "../scripts/fe_gain.py"
