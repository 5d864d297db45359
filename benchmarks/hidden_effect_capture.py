"""Issue 25, item 5: does the texture model predict a hidden texture-and-speed effect at unseen sections?

    .venv/bin/python benchmarks/hidden_effect_capture.py WORKDIR [--generators chips spectral]
        [--effects squeeze drainage] [--kappa 0.3] [--sites 36] [--shape 300 600] [--spacing-mm 0.2] [--cores 2]

For each generator of :mod:`skidsim.generators` the campaign is written once without a hidden effect and once per
effect (``friction.hidden_effect``, strength ``--kappa``), all from the same seed (``default``: the embedded
generator :mod:`skidsim.generators.default`, its truth's drainage effect off, or on with size ``--kappa`` in the IFI
form
for ``drainage`` and the squeeze form for ``squeeze``): the scans and the trace noise
are the same files (checked byte by byte), only the friction curves differ. The workflow (``config/config.yaml``
+ ``config/quick.yaml``) computes the texture table of the campaign without the effect and the measured DFT
(``results/ingest/dft_points.parquet``) of every campaign. Then :func:`skidsim.regression.effect_capture` with the
workflow's texture model on the independent generators, ``physics2`` (OLS of the DFT at each speed on MPD and
micro Sq, form by inner CV), cross-validated by section: the share of the effect (DFT with minus DFT without, at
20-70 km/h) that the held-out predictions carry, the slope of the predicted on the true effect, the effect's size
per speed, the same for the effect's differences between sites (the part that rides on texture; the campaign-wide
mean per speed is predicted by any intercept), and the model's section-grouped CV R^2 of the DFT on both campaigns.

Prints one markdown table and writes ``WORKDIR/capture.csv`` and ``WORKDIR/capture.json``.
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from skidsim.atomic import atomic_path, write_json
from skidsim.generators.campaign import COMMON

ROOT = Path(__file__).resolve().parents[1]
SPEEDS_KMH = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)


def generate_default(campaign: Path, effect: str | None, a) -> None:
    """The default generator (:mod:`skidsim.generators.default`): its truth's drainage effect on (``effect`` drainage or
    squeeze, size ``--kappa``) or off; the truth's temperature effect stays on in both."""
    from skidsim.generators import default as synthetic

    drainage = {"enabled": effect is not None}
    if effect is not None:
        drainage.update(size=a.kappa, form="ifi" if effect == "drainage" else "squeeze")
    cfg = synthetic.resolve_config(
        {
            "seed": a.seed,
            "shape": list(a.shape),
            "spacing_mm": a.spacing_mm,
            "truth": {"effects": {"drainage": drainage}},
        }
    )
    design = synthetic.design_campaign(cfg).head(a.sites)
    truth = campaign.parent / (campaign.name + "-truth")
    for _, row in design.iterrows():
        data = synthetic.generate_site(row, cfg)
        site = row["site"]
        synthetic.write_site(
            data, campaign / "scans" / f"{site}.x3p", campaign / "dft" / f"{site}.csv", truth / f"{site}.json"
        )
    synthetic.write_sites_csv(design, campaign, campaign / "sites.csv")


def generate(gen: str, campaign: Path, effect: str | None, a) -> None:
    from skidsim.generators import write_campaign

    if (campaign / "sites.csv").exists():
        return
    if gen == "default":
        generate_default(campaign, effect, a)
        return
    over = {"n_sites": a.sites, "shape": list(a.shape), "spacing_mm": a.spacing_mm, "seed": a.seed}
    if effect is not None:
        over["friction"] = {"hidden_effect": effect, "hidden_kappa": a.kappa}
    write_campaign(campaign, gen, over)


def digest_scans(campaign: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((campaign / "scans").glob("*"))}


def snakemake(campaign: Path, rundir: Path, targets: list[str], cores: int) -> None:
    """The workflow with ``config/config.yaml`` + ``config/quick.yaml`` (independent_campaigns.workflow)."""
    from independent_campaigns import workflow

    workflow(campaign, rundir, SimpleNamespace(config=[ROOT / "config" / "quick.yaml"], cores=cores), targets)


def tables(texture: Path, dft: Path) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    """Texture table X (index site), DFT table D (dft@<v> columns, friction) and the sections."""
    from skidsim.regression import capture_tables

    return capture_tables(pd.read_parquet(texture), pd.read_parquet(dft), SPEEDS_KMH)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir", type=Path)
    ap.add_argument("--generators", nargs="+", default=["chips", "spectral"], help="chips, spectral, default")
    ap.add_argument("--effects", nargs="+", default=["squeeze", "drainage"])
    ap.add_argument("--kappa", type=float, default=0.3)
    ap.add_argument("--sites", type=int, default=COMMON["n_sites"])
    ap.add_argument("--shape", type=int, nargs=2, default=[300, 600])
    ap.add_argument("--spacing-mm", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=COMMON["seed"])
    ap.add_argument("--cores", type=int, default=2)
    a = ap.parse_args(argv)
    from skidsim.regression import effect_capture

    wd = a.workdir.resolve()
    rows = []
    for gen in a.generators:
        base = wd / gen / "none" / "campaign"
        generate(gen, base, None, a)
        snakemake(
            base,
            wd / gen / "none" / "run",
            ["results/texture/campaign.parquet", "results/ingest/dft_points.parquet"],
            a.cores,
        )
        res0 = wd / gen / "none" / "run" / "results"
        X, D0, groups = tables(res0 / "texture" / "campaign.parquet", res0 / "ingest" / "dft_points.parquet")
        scans0 = digest_scans(base)
        for eff in a.effects:
            camp = wd / gen / eff / "campaign"
            generate(gen, camp, eff, a)
            if digest_scans(camp) != scans0:
                raise RuntimeError(f"{camp}: the scans differ from {base}'s; the effect must change friction only")
            snakemake(camp, wd / gen / eff / "run", ["results/ingest/dft_points.parquet"], a.cores)
            _, D1, _ = tables(
                res0 / "texture" / "campaign.parquet",
                wd / gen / eff / "run" / "results" / "ingest" / "dft_points.parquet",
            )
            r = effect_capture(X, D0, D1, groups)
            rows.append({"generator": gen, "effect": eff, "kappa": a.kappa, **r})
    t = pd.DataFrame(rows)
    print(
        "| generator | effect (kappa) | effect at 40 / 60 / 70 km/h (mean, mu) | effect rms | captured share "
        "(slope) | between sites: rms, captured share (slope) | CV R^2 without / with |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        e = r["effect_by_speed"]
        print(
            f"| {r['generator']} | {r['effect']} ({r['kappa']:g}) | {e['dft@40']:+.3f} / {e['dft@60']:+.3f} / "
            f"{e['dft@70']:+.3f} | {r['effect_rms']:.3f} | {r['captured_share']:.2f} ({r['slope']:.2f}) | "
            f"{r['between_site_rms']:.4f}, {r['captured_share_between_sites']:.2f} ({r['slope_between_sites']:.2f}) | "
            f"{r['r2_without']:.3f} / {r['r2_with']:.3f} |"
        )
    with atomic_path(wd / "capture.csv") as tmp:
        t.drop(columns=["effect_by_speed"]).to_csv(tmp, index=False)
    write_json(wd / "capture.json", rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
