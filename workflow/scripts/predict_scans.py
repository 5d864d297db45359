"""Snakemake adapter: the model file applied to every scan of the directory predict.scans."""

from skidsim.allocator import scan_process_memory
from skidsim.prediction import load_model, summary_lines
from skidsim.prediction.options import PredictOptions
from skidsim.prediction.run import predict_scans, scan_paths, write_predictions
from skidsim.runlog import Progress, setup_logging

scan_process_memory()  # scan-sized arrays: reused heap, small pages (speed only; skidsim.allocator)
log = setup_logging(snakemake.log[0])
o = PredictOptions.from_dict(snakemake.params.cfg)
model = load_model(snakemake.input.model)
files = scan_paths([o.scans])
dft, ifi = predict_scans(
    model,
    files,
    o.interval_level,
    jobs=o.jobs,
    temperature_c=o.temperature_c,
    progress=Progress(len(files), "scans", log),
)
for line in summary_lines(dft, ifi):
    log.info("%s", line)
write_predictions(dft, ifi, snakemake.output.table)
flagged = ifi[ifi["status"] != "ok"]
if len(flagged):
    log.warning("%d of %d scans flagged or refused (predictions.csv: status, reason)", len(flagged), len(ifi))
