"""Options of the prediction stage: :class:`PredictOptions`, the ``predict:`` section of the config."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from skidsim.errors import ConfigError
from skidsim.options import section_items


@dataclass(frozen=True)
class PredictOptions:
    """The prediction stage's options (config keys under ``predict:``, same names and defaults).

    scans: a directory of scans without DFT for the workflow's ``predict_scans`` rule (null: none; the model file
    ``results/prediction/model.json`` is written either way); interval_level: nominal coverage of the CV+
    intervals (0-1);
    domain_alpha: share of sites like the training sites that may lie beyond the extrapolation threshold (0-1,
    :mod:`skidsim.prediction.domain`); jobs: scans processed at a time; temperature_c: temperature (deg C) of
    every scan for a model that uses ``temperature_c`` (null: the model must not need it).
    """

    scans: str | None = None
    interval_level: float = 0.9
    domain_alpha: float = 0.1
    jobs: int = 1
    temperature_c: float | None = None

    def __post_init__(self) -> None:
        def bad(key, expected):
            raise ConfigError(f"predict.{key}: expected {expected}, got {getattr(self, key)!r}")

        for key in ("interval_level", "domain_alpha"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < 1:
                bad(key, "a number between 0 and 1")
        if isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 1:
            bad("jobs", "an integer >= 1")
        if self.scans is not None and not isinstance(self.scans, str):
            bad("scans", "a directory path or null")
        t = self.temperature_c
        if t is not None and (isinstance(t, bool) or not isinstance(t, (int, float))):
            bad("temperature_c", "a temperature in deg C or null")

    @classmethod
    def from_dict(cls, section: Mapping | None) -> PredictOptions:
        """From the config's ``predict:`` mapping (None or {}: the defaults); unknown keys or bad values raise
        :class:`~skidsim.errors.ConfigError` naming the key."""
        return cls(**section_items(cls, section, "predict"))
