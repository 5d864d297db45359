"""Every model of the comparison on DFT targets as one explicit linear map: :class:`LinearMap`, :func:`fit_map`.

All ``<model>@dft`` models of :mod:`skidsim.regression` are linear in their (transformed) feature columns once
fitted: ``mean`` (a constant), ``ols2`` and ``two_variable`` (OLS on at most two columns), ``physics2`` (OLS on MPD
and micro Sq or their logs), and ``pca``, ``ridge``, ``lasso``, ``pls`` (linear maps of the standardised
features). A fitted model is therefore stored as numbers only, and predicts

``dft@v = intercept[v] + sum_j coef[j, v] * (t_j(x_j) - centre[j]) / scale[j]``,

with ``t_j`` the identity or ``ln(max(x_j, floor_j))`` (``physics2``'s log form; floor in the column's unit) and
a missing value (NaN) replaced by the training median of ``t_j(x_j)``. :func:`fit_map` fits a model with exactly
the calls of :func:`skidsim.regression.predict_targets` (the workflow's cross-validation), reads its map, and checks
on the training rows that the map reproduces the fitted model (to 1e-9 in friction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from skidsim.errors import InputError
from skidsim.regression.models import DFT_SUFFIX, fit_model
from skidsim.regression.physics import PHYSICS_OLS, fit_physics_ols
from skidsim.regression.subset import SUBSET_OLS, fit_subset_ols

#: Largest difference (friction) allowed between the map and the fitted model on the training rows.
MAP_TOLERANCE = 1e-9
TRANSFORMS = ("identity", "log")


@dataclass(frozen=True)
class LinearMap:
    """A fitted model as numbers (module docstring). ``features``: column names; ``transforms``: ``identity`` or
    ``log`` per column; ``floors``: lower clip of a log column (its unit; NaN for identity); ``medians``: NaN
    imputation (of the transformed column); ``centre``/``scale``: standardisation (0 and 1 when the model works in
    the column's own unit); ``coef`` ``(p, k)`` friction per scaled unit; ``intercept`` ``(k,)`` friction;
    ``targets``: ``dft@<v>`` names; ``label``: what the model chose (e.g. ``log(profile_MPD)+log(micro_Sq)``)."""

    features: tuple[str, ...]
    transforms: tuple[str, ...]
    floors: np.ndarray
    medians: np.ndarray
    centre: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    targets: tuple[str, ...]
    label: str = ""

    def transformed(self, X: pd.DataFrame, source="feature table") -> np.ndarray:
        """``t_j(x_j)`` of the rows of ``X`` ``(n, p)``, NaN imputed with the training medians."""
        missing = [c for c in self.features if c not in X.columns]
        if missing:
            raise InputError(source, "every texture feature the model uses", column=missing[0], got=len(X.columns))
        A = X.loc[:, list(self.features)].to_numpy(dtype=float, copy=True) if self.features else np.zeros((len(X), 0))
        logs = np.array([t == "log" for t in self.transforms], dtype=bool)
        if logs.any():
            with np.errstate(invalid="ignore"):
                A[:, logs] = np.log(np.maximum(A[:, logs], self.floors[logs]))
        return np.where(np.isnan(A), self.medians, A)

    def scaled(self, X: pd.DataFrame, source="feature table") -> np.ndarray:
        """The model's design ``(t(x) - centre) / scale`` ``(n, p)``."""
        return (self.transformed(X, source) - self.centre) / self.scale

    def predict(self, X: pd.DataFrame, source="feature table") -> pd.DataFrame:
        """Predicted DFT (friction) ``(n, k)``, indexed like ``X``, columns :attr:`targets`."""
        P = self.intercept[None, :] + self.scaled(X, source) @ self.coef
        return pd.DataFrame(P, index=X.index, columns=list(self.targets))

    def to_dict(self) -> dict:
        return {
            "features": list(self.features),
            "transforms": list(self.transforms),
            "floors": [None if not np.isfinite(v) else float(v) for v in self.floors],
            "medians": [float(v) for v in self.medians],
            "centre": [float(v) for v in self.centre],
            "scale": [float(v) for v in self.scale],
            "coef": [[float(v) for v in row] for row in self.coef],
            "intercept": [float(v) for v in self.intercept],
            "targets": list(self.targets),
            "label": self.label,
        }

    @classmethod
    def from_dict(cls, d: dict, source="model file", field="map") -> LinearMap:
        """Read and check a map written by :meth:`to_dict` (InputError naming ``source`` and the field)."""
        try:
            features = tuple(str(c) for c in d["features"])
            targets = tuple(str(c) for c in d["targets"])
            p, k = len(features), len(targets)
            transforms = tuple(str(t) for t in d["transforms"])
            vec = {
                n: np.asarray([np.nan if v is None else v for v in d[n]], dtype=float)
                for n in ("floors", "medians", "centre", "scale")
            }
            coef = np.asarray(d["coef"], dtype=float).reshape(p, k)
            intercept = np.asarray(d["intercept"], dtype=float)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(
                source,
                "a linear map with features, transforms, floors, medians, centre, scale, "
                "coef (features x targets), intercept and targets",
                column=field,
                got=str(e),
            ) from None
        bad = [n for n, v in vec.items() if v.shape != (p,)] + (["intercept"] if intercept.shape != (k,) else [])
        if bad or len(transforms) != p or any(t not in TRANSFORMS for t in transforms):
            raise InputError(
                source,
                f"one value per feature ({p}) and per target ({k}); transforms {TRANSFORMS}",
                column=f"{field}.{bad[0] if bad else 'transforms'}",
            )
        logs = np.array([t == "log" for t in transforms], dtype=bool)
        if (
            not np.all(np.isfinite(coef))
            or not np.all(np.isfinite(intercept))
            or not np.all(np.isfinite(vec["medians"]))
            or not np.all(vec["scale"] > 0)
            or not np.all(np.isfinite(vec["floors"][logs]))
        ):
            raise InputError(source, "finite coefficients, medians and floors, positive scales", column=field)
        return cls(
            features,
            transforms,
            vec["floors"],
            vec["medians"],
            vec["centre"],
            vec["scale"],
            coef,
            intercept,
            targets,
            str(d.get("label", "")),
        )


def _identity_map(columns, medians, intercept, coef, targets, label, transforms=None, floors=None) -> LinearMap:
    p = len(columns)
    return LinearMap(
        tuple(columns),
        tuple(transforms or ("identity",) * p),
        np.full(p, np.nan) if floors is None else np.asarray(floors, dtype=float),
        np.asarray(medians, dtype=float).reshape(p),
        np.zeros(p),
        np.ones(p),
        np.asarray(coef, dtype=float).reshape(p, len(targets)),
        np.asarray(intercept, dtype=float).reshape(len(targets)),
        tuple(targets),
        label,
    )


def _standardised_map(fits: list, targets) -> LinearMap:
    """One map of per-target models that share the standardiser (ridge, lasso, pls, pca): the coefficients are
    read by probing each model at the origin and the unit vectors of the standardised space."""
    st = fits[0].standardiser
    for f in fits[1:]:
        if f.standardiser.columns != st.columns or not np.array_equal(f.standardiser.means, st.means):
            raise RuntimeError("per-target models with different standardisers: cannot write one map")
    p = len(st.columns)
    probe = pd.DataFrame(np.vstack([np.zeros(p), np.eye(p)]) * st.sds + st.means, columns=list(st.columns))
    coef, intercept = np.zeros((p, len(fits))), np.zeros(len(fits))
    for k, f in enumerate(fits):
        v = f.predict(probe).to_numpy(dtype=float)
        intercept[k] = v[0]
        coef[:, k] = v[1:] - v[0]
    return LinearMap(
        tuple(st.columns),
        ("identity",) * p,
        np.full(p, np.nan),
        np.asarray(st.medians, float),
        np.asarray(st.means, float),
        np.asarray(st.sds, float),
        coef,
        intercept,
        tuple(targets),
    )


def fit_map(
    model: str,
    X: pd.DataFrame,
    D: pd.DataFrame,
    *,
    groups=None,
    seed: int = 0,
    inner_folds: int = 5,
    selection: str = "one_se",
) -> LinearMap:
    """Fit ``model`` (``<base>@dft``) on the texture table ``X`` and the DFT table ``D`` (sites x ``dft@<v>``,
    friction), with the calls and arguments of the workflow's cross-validation, and return it as a
    :class:`LinearMap` (checked against the fitted model on these rows)."""
    if not model.endswith(DFT_SUFFIX):
        raise InputError(
            None, "a model on DFT targets (<model>@dft) for a prediction model file", column="model", got=model
        )
    base = model[: -len(DFT_SUFFIX)]
    targets = [str(c) for c in D.columns]
    if base == SUBSET_OLS:
        m = fit_subset_ols(X, D, groups=groups, seed=seed, inner_folds=inner_folds)
        out, ref = _identity_map(m.columns, m.medians, m.intercept, m.coef, targets, m.label), m.predict(X)
    elif base == PHYSICS_OLS:
        m = fit_physics_ols(X, D, groups=groups, seed=seed, inner_folds=inner_folds)
        tr = (m.form,) * len(m.floor)
        floors = m.floor if m.form == "log" else None
        out = _identity_map(("profile_MPD", "micro_Sq"), m.medians, m.intercept, m.coef, targets, m.label, tr, floors)
        ref = m.predict(X)
    else:
        fits = [
            fit_model(base, X, D[c], groups=groups, seed=seed, inner_folds=inner_folds, selection=selection)
            for c in targets
        ]
        ref = pd.DataFrame({c: f.predict(X).to_numpy() for c, f in zip(targets, fits)}, index=X.index)
        if base == "mean":
            out = _identity_map((), [], [f.estimator for f in fits], np.zeros((0, len(targets))), targets, "mean")
        elif base == "two_variable":
            out = _identity_map(
                ("profile_MPD", "micro_Sq"),
                fits[0].hyper["medians"],
                [np.asarray(f.estimator.params)[0] for f in fits],
                np.column_stack([np.asarray(f.estimator.params)[1:] for f in fits]),
                targets,
                "profile_MPD+micro_Sq",
            )
        else:
            out = _standardised_map(fits, targets)
            out = LinearMap(
                *[getattr(out, n) for n in LinearMap.__dataclass_fields__ if n != "label"],
                label=_hyper_label(base, fits),
            )
    gap = float(np.max(np.abs(out.predict(X).to_numpy() - ref.to_numpy(dtype=float)))) if len(X) else 0.0
    if not gap <= MAP_TOLERANCE:
        raise RuntimeError(f"the linear map of {model} differs from the fitted model by {gap:.3g} on its training rows")
    return out


def _hyper_label(base: str, fits: list) -> str:
    """What the inner CV chose for each target (e.g. ``ridge alpha 10, 10, ...``)."""
    if base.startswith("pca"):
        return f"{base}: components " + ", ".join(str(f.n_components) for f in fits)
    key = "n_components" if base == "pls" else "alpha"
    return f"{base}: {key} " + ", ".join(f"{f.hyper[key]:.4g}" for f in fits)
