"""Issue 34, items 3 and 5: prediction intervals and extrapolation flags at unseen sections and campaigns.

    .venv/bin/python benchmarks/prediction_across_campaigns.py WORKDIR [--generators chips spectral default]
        [--seeds 20261125 20261131] [--sites 36] [--shape 100 600] [--spacing-mm 0.2] [--model physics2@dft]
        [--level 0.9] [--configfile config/config.yaml] [--workers 2]

For each generator (``chips`` and ``spectral`` of :mod:`skidsim.generators`, ``default``: the embedded generator
:mod:`skidsim.generators.default`) and each seed a campaign is written to ``WORKDIR/<generator>-<seed>`` and its
texture and DFT tables computed without the workflow (:func:`skidsim.prediction.campaign_tables`: the workflow's
texture pipeline per scan with the config's ``texture`` and ``quality`` options, the DFT read at 20-70 km/h as its
ingest does; a site whose DFT file the reader refuses, e.g. a value >= 1.5 that the spectral generator writes for
some seeds, is left out with a WARNING). No FE is involved: the model is a ``<model>@dft``.

1. **Unseen sections** (first seed of each generator): :func:`skidsim.prediction.heldout_coverage`: each section
   held out in turn, the whole model-file content (model, CV+ folds, domain) fitted on the others; coverage of the
   nominal ``--level`` interval, mean width, RMSE, share flagged as extrapolation.
2. **Unseen campaigns**: the model file trained on all sites of the first seed of each generator
   (:func:`skidsim.prediction.train_model`) applied to the second seed of the same generator and of the other
   generators (:func:`skidsim.prediction.transfer_scores`).

Prints two markdown tables and writes ``WORKDIR/heldout.csv`` and ``WORKDIR/transfer.csv``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from skidsim.atomic import atomic_path

ROOT = Path(__file__).resolve().parents[1]
SPEEDS_KMH = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)


def generate(gen: str, campaign: Path, seed: int, a) -> None:
    """Write the campaign (skipped when its sites.csv exists)."""
    if (campaign / "sites.csv").exists():
        return
    if gen == "default":
        from skidsim.generators import default as synthetic

        cfg = synthetic.resolve_config({"seed": seed, "shape": list(a.shape), "spacing_mm": a.spacing_mm})
        design = synthetic.design_campaign(cfg).head(a.sites)
        truth = campaign.parent / (campaign.name + "-truth")
        for _, row in design.iterrows():
            site = row["site"]
            synthetic.write_site(
                synthetic.generate_site(row, cfg),
                campaign / "scans" / f"{site}.x3p",
                campaign / "dft" / f"{site}.csv",
                truth / f"{site}.json",
            )
        synthetic.write_sites_csv(design, campaign, campaign / "sites.csv")
        return
    from skidsim.generators import write_campaign

    write_campaign(
        campaign, gen, {"n_sites": a.sites, "shape": list(a.shape), "spacing_mm": a.spacing_mm, "seed": seed}
    )


def options(configfile: Path):
    from skidsim.texture import TextureOptions
    from skidsim.texture.quality import QualityOptions

    cfg = yaml.safe_load(configfile.read_text())
    tex = dict(cfg.get("texture") or {})
    for k in ("macro_mm", "groups"):
        if k in tex:
            tex[k] = tuple(tex[k])
    quality = QualityOptions.from_dict(cfg.get("quality"), strip_length_mm=cfg["mesh"]["length_mm"])
    window = (cfg.get("ingest") or {}).get("dft_smooth_window_kmh", 5.0)
    return TextureOptions(**tex), quality, window


def tables(campaign: Path, tex, quality, window, workers: int):
    """(X, D, sections) of a campaign, cached as parquet beside it."""
    from skidsim.prediction import campaign_tables

    cx, cd, cg = (campaign.parent / f"{campaign.name}-{n}.parquet" for n in ("X", "D", "sections"))
    if not cx.exists():
        X, D, groups, _ = campaign_tables(
            campaign, tex, quality, SPEEDS_KMH, window, workers=workers, skip_refused_dft=True
        )
        for path, df in ((cx, X), (cd, D), (cg, pd.DataFrame({"section": groups}, index=X.index))):
            with atomic_path(path) as tmp:
                df.to_parquet(tmp)
    X, D, g = pd.read_parquet(cx), pd.read_parquet(cd), pd.read_parquet(cg)
    return X, D, g["section"].to_numpy()


def main(argv=None) -> int:
    import logging

    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    from skidsim.prediction import heldout_coverage, train_model, transfer_scores

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("workdir", type=Path)
    p.add_argument("--generators", nargs="+", default=["chips", "spectral", "default"])
    p.add_argument("--seeds", nargs=2, type=int, default=[20261125, 20261131])
    p.add_argument("--sites", type=int, default=36)
    p.add_argument("--shape", nargs=2, type=int, default=[100, 600])
    p.add_argument("--spacing-mm", type=float, default=0.2)
    p.add_argument("--model", default="physics2@dft")
    p.add_argument("--level", type=float, default=0.9)
    p.add_argument("--configfile", type=Path, default=ROOT / "config" / "config.yaml")
    p.add_argument("--workers", type=int, default=2)
    a = p.parse_args(argv)
    tex, quality, window = options(a.configfile)
    data = {}
    for gen in a.generators:
        for seed in a.seeds:
            camp = a.workdir / f"{gen}-{seed}"
            generate(gen, camp, seed, a)
            data[gen, seed] = tables(camp, tex, quality, window, a.workers)
            print(f"tables {gen}-{seed}: {data[gen, seed][0].shape}", flush=True)
    held, models = [], {}
    for gen in a.generators:
        X, D, g = data[gen, a.seeds[0]]
        s, _ = heldout_coverage(X, D, g, a.model, a.level)
        held.append({"generator": gen, "seed": a.seeds[0], **s})
        models[gen] = train_model(X, D, g, a.model).chosen
    transfer = []
    for tr in a.generators:
        for te in a.generators:
            X, D, _ = data[te, a.seeds[1]]
            s = transfer_scores(models[tr], X, D, a.level)
            transfer.append({"train": f"{tr}-{a.seeds[0]}", "test": f"{te}-{a.seeds[1]}", "model": a.model, **s})
    held, transfer = pd.DataFrame(held), pd.DataFrame(transfer)
    for name, df in (("heldout", held), ("transfer", transfer)):
        with atomic_path(a.workdir / f"{name}.csv") as tmp:
            df.to_csv(tmp, index=False)
    cols = ["rmse", "mean_width", "coverage", "share_flagged", "coverage_unflagged"]
    print(held[["generator", "model", "n_sites", *cols]].round(4).to_markdown(index=False))
    print()
    print(transfer[["train", "test", *cols]].round(4).to_markdown(index=False))
    return 0 if np.isfinite(held["coverage"]).all() else 1


if __name__ == "__main__":
    raise SystemExit(main())
