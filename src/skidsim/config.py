"""The workflow's configuration as the library reads it (no Snakemake import; pandas only inside the functions
that need it, since the workflow imports this module when it parses the Snakefile).

* :func:`merged`: recursive dict merge (config over defaults).
* :func:`synthetic_config`: the generator's configuration from the ``synthetic`` and ``truth`` sections.
* :func:`site_table`: the site list (site, section, scan, dft) known when the workflow is parsed.
* :func:`plan_check`: the config and campaign check that stops a bad plan before anything runs.
* :func:`solver_config`: the :class:`~skidsim.solver.SolverConfig` of the ``solver`` section.
* :func:`file_digest`, :func:`config_digest`: short SHA-256 digests (FE cache keys).

The calibration sections have their options classes in :mod:`skidsim.calibration.options`; the regression
section's train/test split is :func:`skidsim.regression.splits.regression_split`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from .errors import CampaignError

if TYPE_CHECKING:
    import pandas as pd


def merged(defaults: dict, override: dict | None) -> dict:
    """Recursive dict merge: ``override`` wins; dicts merge key by key."""
    out = dict(defaults)
    for k, v in (override or {}).items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merged(out[k], v)
        else:
            out[k] = v
    return out


def synthetic_config(config: dict) -> dict:
    """The generator's configuration: its defaults overridden by ``config['synthetic']`` and ``config['truth']``."""
    from .generators import default as synthetic

    cfg = merged(synthetic.default_config(), config.get("synthetic") or {})
    if "truth" in config:
        cfg = merged(cfg, {"truth": config["truth"]})
    return cfg


def site_table(config: dict, campaign_dir: str | Path | None) -> pd.DataFrame:
    """Site ids and sections, known at parse time.

    For the synthetic campaign (``campaign_dir`` None) the design is computed from config (cheap, no surfaces).
    For a user campaign ``sites.csv`` is read for its ``site``, ``section``, ``scan`` and ``dft`` columns only;
    everything else is checked by the ``validate_campaign`` rule, which names every problem at once.
    """
    import pandas as pd  # imported on use: most workflow steps never need it

    if campaign_dir is None:
        from .generators import default as synthetic

        design = synthetic.design_campaign(synthetic_config(config))
        return pd.DataFrame(
            {
                "site": design["site"].astype(str),
                "section": design["section"].astype(str),
                "scan": [f"scans/{s}.x3p" for s in design["site"]],
                "dft": [f"dft/{s}.csv" for s in design["site"]],
            }
        )
    path = Path(campaign_dir) / "sites.csv"
    if not path.is_file():
        raise CampaignError(path, "a sites.csv file in the campaign directory (config key 'campaign')", got="missing")
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    missing = [c for c in ("site", "section", "scan", "dft") if c not in df.columns]
    if missing:
        raise CampaignError(path, f"columns {', '.join(missing)} in the header", row=1)
    if df["site"].duplicated().any():
        dup = df.loc[df["site"].duplicated(), "site"].iloc[0]
        row = int(df.index[df["site"] == dup][1]) + 2
        raise CampaignError(path, "unique site ids", row=row, column="site", got=dup)
    return df[["site", "section", "scan", "dft"]].copy()


def plan_check(config: dict, campaign_dir: str | Path | None, stream=None) -> None:
    """The workflow's check when it builds its plan (:func:`skidsim.validate.check_plan`): on problems print them
    (one per line, no traceback) to ``stream`` (stderr) and exit with status 1, so that ``snakemake -n`` already
    refuses a bad campaign or config."""
    import sys

    from .validate import check_plan, format_problems

    found = check_plan(config, campaign_dir)
    if found:
        out = stream or sys.stderr
        print(format_problems(found), file=out)
        print("skidsim: nothing was run; fix the above and run the same command again", file=out)
        out.flush()
        raise SystemExit(1)


#: The quick preset (config/quick.yaml): the campaign preset on a 2 mm slider mesh with a 40 mm slide.
QUICK_SOLVER = {"element_mm": 2.0, "slide_length_mm": 40.0, "window_start_mm": 5.0}


def solver_config(cfg: dict):
    """The :class:`~skidsim.solver.SolverConfig` of the workflow's ``solver`` section.

    ``preset`` (campaign | reference | quick) chooses the base, ``load_n`` (N) and ``overrides`` (any SolverConfig
    field) are applied on top; an unknown field raises :class:`~skidsim.errors.ConfigError`.
    """
    from dataclasses import asdict

    from .solver import SolverConfig

    preset = cfg.get("preset", "campaign")
    if preset == "reference":
        base = SolverConfig.reference()
    elif preset == "campaign":
        base = SolverConfig.campaign()
    elif preset == "quick":
        base = SolverConfig.campaign(**QUICK_SOLVER)
    else:
        from .errors import ConfigError

        raise ConfigError(f"solver.preset: expected campaign, reference or quick, got {preset!r}")
    d = asdict(base)
    d["load_n"] = float(cfg.get("load_n", d["load_n"]))
    d.update(cfg.get("overrides") or {})
    return SolverConfig.from_dict(d, source="config solver.overrides")


def mesh_study_solver_config(cfg: dict, progress_every_s: float = 60.0):
    """The :class:`~skidsim.solver.SolverConfig` of the workflow's mesh study from its ``solver`` section: the
    reference preset's settings (full strip slide, no mass scaling) with the configured load and the contact model
    (``contact_gap``) of the configured preset, so the study measures the discretisation error of the model the
    campaign runs; only the element size then varies (:func:`skidsim.solver.mesh_study.mesh_study`)."""
    from dataclasses import replace

    run = solver_config(cfg)
    ref = solver_config({**cfg, "preset": "reference", "overrides": {}})
    return replace(ref, contact_gap=run.contact_gap, progress_every_s=progress_every_s)


def file_digest(path: str | Path, n: int = 12) -> str:
    """Short SHA-256 of a file's bytes (cache keys: a regenerated pavement invalidates its FE evaluations)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:n]


def config_digest(obj, n: int = 12) -> str:
    """Short SHA-256 of a JSON-serialisable object (sorted keys)."""
    import hashlib
    import json

    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:n]
