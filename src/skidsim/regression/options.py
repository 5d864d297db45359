"""Options of the regression stage: :class:`RegressionOptions`, the ``regression:`` section of the config."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from skidsim.errors import ConfigError, InputError
from skidsim.options import section_items

from .models import check_model_name
from .pca import parse_rule
from .selection import CRITERIA

#: Whose back-calculated parameters can be the regression targets (the calibration methods).
CALIBRATION_METHODS = ("study", "ours")
#: Keys whose config value is a list (kept as a tuple).
_LISTS = ("models", "figure11_models", "prediction_speeds_kmh")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


@dataclass(frozen=True)
class RegressionOptions:
    """The regression stage's options (config keys under ``regression:``, same names and defaults).

    ``seed``: the generator of the train/test split and of the inner K-folds; ``n_test``: held-out sites of a
    36-site campaign (the study: 9; the workflow keeps the same share for other sizes); ``grouped_by``: None
    (random split, the study) or ``"section"`` (whole sections held out); ``rule``: PCA component retention
    (``cv``, ``study``, ``kaiser``, ``variance:F``; :mod:`.pca`); ``models``: the models of the
    leave-one-section-out comparison (:mod:`.models`; the references ``mean@dft`` and ``ols2@dft`` are always
    compared and compete for the best only when listed); ``figure11_models``: models whose test-site predictions
    go to the FE (``"best"`` = the winner); ``criterion``: how the best is chosen (:func:`.rank_models`);
    ``inner_folds``: folds of the inner CV when there are fewer than 3 sections; ``calibration_method``: whose
    back-calculated parameters are the targets; ``prediction_speeds_kmh``: DFT speeds (km/h) of the DFT targets,
    the scores and Figure 11. Bad values raise :class:`~skidsim.errors.ConfigError` naming the key.
    """

    seed: int = 20170117
    n_test: int = 9
    grouped_by: str | None = None
    rule: str = "cv"
    models: tuple[str, ...] = (
        "mean",
        "pca",
        "pca:study",
        "ridge",
        "pls",
        "lasso",
        "two_variable",
        "pca@curve",
        "ridge@curve",
        "mean@dft",
        "ols2@dft",
        "ridge@dft",
        "pls@dft",
        "pca@dft",
        "physics2@dft",
    )
    figure11_models: tuple[str, ...] = ("best", "pca:study")
    criterion: str = "auto"
    inner_folds: int = 5
    calibration_method: str = "ours"
    prediction_speeds_kmh: tuple[float, ...] = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"regression.{key}: expected {expected}, got {getattr(self, key)!r}")

        if not _is_int(self.seed):
            bad("seed", "an integer")
        if not (_is_int(self.n_test) and self.n_test >= 1):
            bad("n_test", "an integer >= 1")
        if not (self.grouped_by is None or (isinstance(self.grouped_by, str) and self.grouped_by)):
            bad("grouped_by", "null or a column name such as 'section'")
        if not isinstance(self.rule, str) or not _valid(parse_rule, self.rule):
            bad("rule", "'cv', 'study', 'kaiser' or 'variance:F' with 0 < F <= 1")
        if not self.models or not all(_valid(check_model_name, m) for m in self.models):
            bad(
                "models",
                "a non-empty list of model names: mean, ols2, pca, pca:<rule>, ridge, lasso, pls, "
                "two_variable, each optionally with @curve or @dft",
            )
        if not self.figure11_models or not all(
            m == "best" or _valid(check_model_name, m) for m in self.figure11_models
        ):
            bad("figure11_models", "a non-empty list of 'best' or model names")
        if self.criterion not in CRITERIA:
            bad("criterion", f"one of {list(CRITERIA)}")
        if not (_is_int(self.inner_folds) and self.inner_folds >= 2):
            bad("inner_folds", "an integer >= 2")
        if self.calibration_method not in CALIBRATION_METHODS:
            bad("calibration_method", f"one of {list(CALIBRATION_METHODS)}")
        speeds = self.prediction_speeds_kmh
        if not speeds or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 for v in speeds):
            bad("prediction_speeds_kmh", "a non-empty list of speeds > 0 km/h")

    @classmethod
    def from_config(cls, section: Mapping | None) -> RegressionOptions:
        """From the config's ``regression:`` mapping (None or {}: the defaults); lists become tuples. Unknown keys
        or bad values raise :class:`~skidsim.errors.ConfigError` naming the key and what was expected."""
        d = section_items(cls, section, "regression")
        for key in _LISTS:
            if key in d:
                if isinstance(d[key], (str, bytes)) or not hasattr(d[key], "__iter__"):
                    raise ConfigError(f"regression.{key}: expected a list, got {d[key]!r}")
                d[key] = tuple(d[key])
        return cls(**d)

    @classmethod
    def from_dict(cls, section: Mapping | None) -> RegressionOptions:
        """The same as :meth:`from_config` (the name the other stages' options use)."""
        return cls.from_config(section)


def _valid(check, value) -> bool:
    try:
        check(value)
    except InputError:
        return False
    return True
