"""One site's calibration as the workflow runs it: the FE simulator behind the site's cache, the measured points,
and our calibration from the ingest's trace table with the campaign prior.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from skidsim.calibration.cache import FECache, Simulator, fe_simulator
from skidsim.calibration.joint import calibrate_fast, surrogate_prior
from skidsim.calibration.measured import site_trace
from skidsim.calibration.options import JointOptions
from skidsim.calibration.result import CalibrationResult
from skidsim.config import config_digest, file_digest, solver_config

#: SolverConfig fields that do not change a simulation's result: left out of the FE cache key.
_NOT_IN_CACHE_KEY = ("progress_every_s", "trace_every", "vtu_frames", "blas_threads")
#: Model selectors of the solver: (field, the value of the first releases, {model: the fields only that model
#: reads}). The fields of the models not selected are left out of the key; a selector at the first releases' value
#: is left out too, so the key of the stick limit with mass-proportional damping is the same as before these
#: models existed (its FE caches stay valid); any other choice enters it.
_OPTIONAL_MODELS = (
    ("friction_model", "stick_limit", {"stick_limit": (), "penalty": ("friction_stiffness_pa_per_m",)}),
    ("slide_damping_model", "mass", {"mass": ("slide_damping_per_s",), "rayleigh": ("loss_factor", "loss_band_hz")}),
)


def solver_cache_key(scfg) -> dict:
    """The fields of the resolved :class:`~skidsim.solver.SolverConfig` that make up the FE cache key."""
    from dataclasses import asdict

    key = {k: v for k, v in asdict(scfg).items() if k not in _NOT_IN_CACHE_KEY}
    for selector, first_release, models in _OPTIONAL_MODELS:
        chosen = key.get(selector)
        for model, own_fields in models.items():
            if model != chosen:
                for k in own_fields:
                    key.pop(k, None)
        if chosen == first_release:
            key.pop(selector, None)
    return key


def site_simulator(
    pavement_npz: str | Path, solver_cfg: dict, cache_path: str | Path, site: str
) -> tuple[Simulator, FECache, object]:
    """FE simulator callback ``(speed_kmh, law) -> FEOutcome`` for one site, behind its per-site cache.

    ``solver_cfg``: the workflow's ``solver`` section (:func:`skidsim.config.solver_config`). The cache key holds
    the pavement file's digest and the resolved solver configuration's digest, so changing either never reuses a
    stale simulation, and a rerun or resumed run never repeats one. Returns (simulate, cache, SolverConfig).
    """
    from skidsim.reconstruct import Heightfield

    hf = Heightfield.from_npz(pavement_npz)
    scfg = solver_config(solver_cfg)
    cache = FECache(cache_path, site, pavement=file_digest(pavement_npz), solver=config_digest(solver_cache_key(scfg)))
    return cache.wrap(fe_simulator(hf, scfg)), cache, scfg


def measured_points(dft_points, site: str) -> dict[float, float]:
    """``{speed_kmh: mu}`` of one site from the ingest's DFT points table (columns site, speed_kmh, mu)."""
    d = dft_points[dft_points["site"] == site]
    return {float(v): float(m) for v, m in zip(d["speed_kmh"], d["mu"])}


def calibrate_ours_site(
    simulate: Simulator,
    traces_parquet: str | Path,
    site: str,
    options: JointOptions | Mapping | None,
    speeds_kmh: Sequence[float],
    prior_jsons: Sequence[str | Path],
    log,
) -> CalibrationResult:
    """Our calibration (:func:`calibrate_fast`) of one site as the workflow runs it: the site's DFT trace from the
    ingest's ``traces_parquet``, ``options`` (:class:`JointOptions` or the config mapping ``calibration.ours``),
    calibration speeds in km/h, and the surrogate prior from the reference sites' calibration JSON files
    ``prior_jsons`` (none, or no converged reference: a pilot run, logged). Used by the elastic calibration and
    the viscoelastic recalibration alike."""
    import pandas as pd

    opt = options if isinstance(options, JointOptions) else JointOptions.from_config(options)
    traces = pd.read_parquet(traces_parquet)
    trace = site_trace(traces, site)
    prior = None
    if prior_jsons:
        refs = [CalibrationResult.from_json(p) for p in prior_jsons]
        try:
            prior = surrogate_prior(refs)
        except ValueError as exc:  # e.g. no reference site converged: go on without a prior, say so
            log.warning("%s: no surrogate prior (%s); calibrating with a pilot run", site, exc)
        else:
            log.info(
                "%s: surrogate prior from %d reference site(s): b %s, slip offsets %s km/h at %s km/h",
                site,
                prior["n_sites"],
                [round(x, 4) for x in prior["b"]],
                [round(x, 2) for x in prior["slip_offsets_kmh"]],
                prior["speeds_kmh"],
            )
    return calibrate_fast(
        simulate, trace, opt, speeds_kmh=[float(v) for v in speeds_kmh], source=str(traces_parquet), prior=prior
    )
