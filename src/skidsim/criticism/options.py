"""The settings of the model criticism: one frozen dataclass whose fields are the ``diagnosis:`` section of
config/config.yaml, key for key and default for default (docs/model-criticism.md explains each)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from ..errors import ConfigError
from ..options import section_items

#: Values of ``fe_extension`` (the viscoelastic-slider recalibration of :mod:`skidsim.criticism.fe_extension`).
FE_MODES = ("auto", "always", "never")
#: Sites of the within-site level (``within_site_sites``).
WITHIN_SITE_MODES = ("all", "settled")
#: Step-up false-discovery procedures of ``fdr_method``: Benjamini-Hochberg, Benjamini-Yekutieli.
FDR_METHODS = ("bh", "by")


def _default_prony() -> dict:
    return {"prony_g": [0.5, 0.5, 0.5], "prony_tau_s": [1.0e-5, 1.0e-4, 1.0e-3]}


@dataclass(frozen=True)
class DiagnosisOptions:
    """Settings of :func:`skidsim.criticism.diagnose` and of the FE extension (config ``diagnosis:``).

    ``seed``: every random draw (permutations, sign flips, bootstrap); ``n_permutations``: permutations per test
    (None: :func:`skidsim.criticism.fdr.auto_permutations`); ``fdr``: false-discovery rate over testing units;
    ``fdr_method``: "bh" | "by"; ``n_boot``: bootstrap resamples of whole sites for the gain intervals; ``ci``:
    interval level; ``corr_group``: |Pearson r| above which numeric candidates are reported as one group;
    ``speed_bin_kmh``: speed bin (km/h) of the residual matrices; ``cluster_rho``: |Spearman rho| of every pair of
    a texture cluster (one testing unit); ``primary_share``: share of ``fdr`` for the primary family;
    ``texture_share``: share of ``fdr`` for a family of the texture clusters and lone texture columns of their own,
    taken from the secondary family's (0: they stay secondary units, the default);
    ``adjust_texture``: between-site tests of sites.csv covariates conditioned on the texture; ``fe_extension``:
    "auto" | "always" | "never"; ``within_site_sites``: the sites of the within-site level, "all" or "settled"
    (those the calibration settled inside its bounds, where its record is given:
    :func:`skidsim.criticism.calibration_groups.settled_residuals`); ``viscoelastic``: the Prony series of the FE
    extension, ``prony_g`` (relative to the long-term shear modulus) and ``prony_tau_s`` (relaxation times, s).
    """

    seed: int = 11
    n_permutations: int | None = None
    fdr: float = 0.04
    fdr_method: str = "bh"
    n_boot: int = 1000
    ci: float = 0.95
    corr_group: float = 0.9
    speed_bin_kmh: float = 10.0
    cluster_rho: float = 0.8
    primary_share: float = 0.5
    texture_share: float = 0.0
    adjust_texture: bool = True
    fe_extension: str = "auto"
    within_site_sites: str = "settled"
    viscoelastic: dict = field(default_factory=_default_prony)

    def __post_init__(self):
        checks = (
            (0 < self.fdr < 1, "fdr", "a number in (0, 1)"),
            (self.fdr_method in FDR_METHODS, "fdr_method", f"one of {FDR_METHODS}"),
            (0 < self.primary_share < 1, "primary_share", "a number in (0, 1)"),
            (
                0 <= self.texture_share < 1 - self.primary_share,
                "texture_share",
                f"a number in [0, 1 - primary_share) = [0, {1 - self.primary_share:g})",
            ),
            (0 < self.ci < 1, "ci", "a number in (0, 1)"),
            (int(self.n_boot) >= 1, "n_boot", "an integer >= 1"),
            (self.speed_bin_kmh > 0, "speed_bin_kmh", "a positive speed bin (km/h)"),
            (self.n_permutations is None or int(self.n_permutations) >= 1, "n_permutations", "null or an integer >= 1"),
            (self.fe_extension in FE_MODES, "fe_extension", f"one of {FE_MODES}"),
            (self.within_site_sites in WITHIN_SITE_MODES, "within_site_sites", f"one of {WITHIN_SITE_MODES}"),
        )
        for ok, key, expected in checks:
            if not ok:
                raise ConfigError(f"config diagnosis.{key}: expected {expected}, got {getattr(self, key)!r}")

    @classmethod
    def from_config(cls, section: Mapping | None) -> DiagnosisOptions:
        """The options of a config ``diagnosis:`` section; missing keys take the defaults. Raises
        :class:`ConfigError` naming any unknown key."""
        return cls(**section_items(cls, section, "diagnosis"))
