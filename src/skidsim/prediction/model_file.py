"""The prediction model as a file users keep: :class:`PredictionModel`, :func:`train_model`, :func:`save_model`,
:func:`load_model` (``results/prediction/model.json``; the format is in docs/prediction.md).

The file is plain JSON: numbers, strings and lists. Loading it parses JSON and checks every field; it never
imports or executes anything named in the file (no pickle), so a model file from someone else is safe to open.
It holds, for the chosen model on DFT targets and the ``ols2@dft`` baseline: the linear map of the model fitted
on all training sites (:class:`~.linear.LinearMap`: features, transforms, standardiser, coefficients), its
section folds and out-of-section residuals (the CV+ intervals, :mod:`.intervals`), its training domain
(:mod:`.domain`) and its measured skill; and for the whole file: the texture and quality options that produced
the features (so :func:`~.scan.scan_features` runs the same pipeline on a new scan), the speeds (km/h), the
regression settings, the training sites and sections, digests of the training tables and of the config, the
skidsim version and :data:`FORMAT_VERSION`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.atomic import write_text
from skidsim.errors import ConfigError, InputError
from skidsim.regression.targets import dft_column, dft_speeds
from skidsim.texture import TextureOptions
from skidsim.texture.quality import QualityOptions

from .domain import DOMAIN_ALPHA, Domain, fit_domain
from .intervals import SectionCVPlus, fit_cvplus
from .linear import LinearMap, fit_map

FORMAT = "skidsim-prediction-model"
FORMAT_VERSION = 1
BASELINE = "ols2@dft"


def _finite(obj):
    """``obj`` with every non-finite float replaced by None (JSON has no NaN; a measure that does not exist, e.g.
    the RMSE of the flagged sites when none is flagged, is null in the file)."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


@dataclass(frozen=True)
class ModelPart:
    """One model of the file: ``name`` (e.g. ``physics2@dft``), ``map`` (fitted on all training sites),
    ``intervals`` (CV+ over the sections), ``domain`` and ``skill`` (measured numbers: section-grouped CV RMSE and
    R^2 of the DFT pooled over the speeds, friction; nested coverage when measured)."""

    name: str
    map: LinearMap
    intervals: SectionCVPlus
    domain: Domain
    skill: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "map": self.map.to_dict(),
            "intervals": self.intervals.to_dict(),
            "domain": self.domain.to_dict(),
            "skill": _finite(self.skill),
        }

    @classmethod
    def from_dict(cls, d: dict, source, key: str) -> ModelPart:
        if not isinstance(d, dict) or "name" not in d:
            raise InputError(source, "a model with name, map, intervals, domain, skill", column=key)
        return cls(
            str(d["name"]),
            LinearMap.from_dict(d.get("map", {}), source, f"{key}.map"),
            SectionCVPlus.from_dict(d.get("intervals", {}), source, f"{key}.intervals"),
            Domain.from_dict(d.get("domain", {}), source, f"{key}.domain"),
            dict(d.get("skill") or {}),
        )


@dataclass(frozen=True)
class PredictionModel:
    """The content of a model file (module docstring). ``chosen`` and ``baseline`` are :class:`ModelPart`;
    ``speeds_kmh`` the DFT speeds; ``texture``/``quality`` the options dicts; ``regression`` the fit settings
    (seed, inner_folds, selection); ``training`` sites, sections and digests; ``meta`` versions and notes."""

    chosen: ModelPart
    baseline: ModelPart
    speeds_kmh: tuple[float, ...]
    texture: dict
    quality: dict
    regression: dict
    training: dict
    meta: dict

    @property
    def texture_options(self) -> TextureOptions:
        d = dict(self.texture)
        d["macro_mm"] = tuple(d["macro_mm"])
        d["groups"] = tuple(d["groups"])
        return TextureOptions(**d)

    @property
    def quality_options(self) -> QualityOptions:
        return QualityOptions(**self.quality)

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            **self.meta,
            "speeds_kmh": list(self.speeds_kmh),
            "texture": self.texture,
            "quality": self.quality,
            "regression": self.regression,
            "training": self.training,
            "chosen": self.chosen.to_dict(),
            "baseline": self.baseline.to_dict(),
        }


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("skidsim")
    except PackageNotFoundError:
        return "unknown"


def table_digest(X: pd.DataFrame, D: pd.DataFrame) -> str:
    """SHA-256 of the training texture and DFT tables (sorted columns, values as exact reprs): the same tables
    give the same digest on any machine."""
    h = hashlib.sha256()
    for t in (X, D):
        t = t.reindex(sorted(t.columns), axis=1)
        h.update(json.dumps([list(map(str, t.index)), list(map(str, t.columns))]).encode())
        h.update(json.dumps([[repr(float(v)) for v in row] for row in t.to_numpy(dtype=float)]).encode())
    return h.hexdigest()


def _part(name, X, D, groups, fit_kw, domain_alpha: float = DOMAIN_ALPHA) -> ModelPart:
    lin = fit_map(name, X, D, groups=groups, **fit_kw)
    cvp, oof = fit_cvplus(X, D, groups, lambda x, d, g: fit_map(name, x, d, groups=g, **fit_kw))
    e = D.to_numpy(dtype=float) - oof.to_numpy(dtype=float)
    y = D.to_numpy(dtype=float)
    skill = {
        "cv_rmse": float(np.sqrt(np.mean(e**2))),
        "cv_r2": float(1.0 - np.sum(e**2) / np.sum((y - y.mean()) ** 2)),
        "cv_rmse_by_speed": {c: float(np.sqrt(np.mean(e[:, j] ** 2))) for j, c in enumerate(D.columns)},
    }
    return ModelPart(name, lin, cvp, fit_domain(lin, X, groups, domain_alpha), skill)


def train_model(
    X: pd.DataFrame,
    D: pd.DataFrame,
    groups,
    chosen: str,
    *,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
    texture: TextureOptions | None = None,
    quality: QualityOptions | None = None,
    config_digest: str = "",
    notes: dict | None = None,
    domain_alpha: float = DOMAIN_ALPHA,
) -> PredictionModel:
    """Fit the prediction model file's content on the texture table ``X`` (sites x features, as the workflow's
    design), the DFT table ``D`` (same sites, ``dft@<v>`` columns, friction) and the sections ``groups``:
    ``chosen`` (a ``<model>@dft``) and the :data:`BASELINE`, each on all sites and once per held-out section,
    with the workflow's settings (``seed``, ``inner_folds``, ``selection``); ``domain_alpha`` the level of the
    extrapolation threshold (:mod:`.domain`)."""
    if not X.index.equals(D.index):
        raise InputError(None, "texture and DFT tables on the same sites in the same order", column="site")
    groups = np.asarray(groups).astype(str)
    fit_kw = dict(seed=seed, inner_folds=inner_folds, selection=selection)
    speeds = tuple(dft_speeds(D))
    parts = {m: _part(m, X, D, groups, fit_kw, domain_alpha) for m in dict.fromkeys([chosen, BASELINE])}
    texture = texture or TextureOptions()
    quality = quality or QualityOptions()
    tex = {k: (list(v) if isinstance(v, tuple) else v) for k, v in texture.__dict__.items()}
    return PredictionModel(
        parts[chosen],
        parts[BASELINE],
        speeds,
        tex,
        dict(quality.__dict__),
        {**fit_kw, "groups": "section"},
        {
            "sites": [str(s) for s in X.index],
            "sections": [str(g) for g in groups],
            "n_sites": int(len(X)),
            "n_sections": int(len(set(groups))),
            "table_digest": table_digest(X, D),
            "config_digest": config_digest,
        },
        {"skidsim_version": _version(), "notes": dict(notes or {})},
    )


def save_model(model: PredictionModel, path) -> Path:
    """Write ``model`` as JSON to ``path`` (atomically; numbers as exact reprs, no NaN)."""
    text = json.dumps(model.to_dict(), indent=1, allow_nan=False) + "\n"
    return write_text(Path(path), text)


def load_model(path) -> PredictionModel:
    """Read a model file (JSON only; every field checked, InputError naming the file and the field)."""
    path = Path(path)
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, "a model file (results/prediction/model.json)", got="no such file") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(path, "a JSON model file", got=str(e)) from None
    return model_from_dict(d, path)


def model_from_dict(d, source="model file") -> PredictionModel:
    """The :class:`PredictionModel` of a parsed model file (checked)."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise InputError(
            source,
            f"format {FORMAT!r}",
            column="format",
            got=d.get("format") if isinstance(d, dict) else type(d).__name__,
        )
    if d.get("format_version") != FORMAT_VERSION:
        raise InputError(
            source,
            f"format_version {FORMAT_VERSION} (written by this skidsim)",
            column="format_version",
            got=d.get("format_version"),
        )
    for key in ("speeds_kmh", "texture", "quality", "regression", "training", "chosen", "baseline"):
        if key not in d:
            raise InputError(source, f"a '{key}' field", column=key)
    try:
        speeds = tuple(float(v) for v in d["speeds_kmh"])
    except (TypeError, ValueError):
        raise InputError(source, "speeds in km/h", column="speeds_kmh", got=d["speeds_kmh"]) from None
    chosen = ModelPart.from_dict(d["chosen"], source, "chosen")
    baseline = ModelPart.from_dict(d["baseline"], source, "baseline")
    want = tuple(dft_column(v) for v in speeds)
    for key, part in (("chosen", chosen), ("baseline", baseline)):
        if part.map.targets != want:
            raise InputError(
                source, f"targets {list(want)} (the speeds)", column=f"{key}.map.targets", got=list(part.map.targets)
            )
    meta = {k: d[k] for k in ("skidsim_version", "notes") if k in d}
    model = PredictionModel(
        chosen,
        baseline,
        speeds,
        dict(d["texture"]),
        dict(d["quality"]),
        dict(d["regression"]),
        dict(d["training"]),
        meta,
    )
    try:
        model.texture_options, model.quality_options  # noqa: B018 - checks the options
    except (TypeError, ValueError, ConfigError) as e:
        raise InputError(source, "texture and quality options of this skidsim", column="texture", got=str(e)) from None
    return model
