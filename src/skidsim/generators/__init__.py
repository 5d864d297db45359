"""Campaign generators independent of :mod:`skidsim.generators.default`.

Two generators, each a texture model with a friction-speed model of the literature whose parameters are driven by
texture measured on the generated surface (docs/synthetic-campaign.md, "Independent generators"):

* ``chips``: polygonal aggregate chips with flat facets in a flat binder, Weierstrass-Mandelbrot microtexture on
  the chip tops (:mod:`.chips`); friction: the PIARC/IFI exponential speed model, Sp from MPD.
* ``spectral``: a negatively skewed random field from an anisotropic power spectrum, sand-grain shot-noise
  microtexture (:mod:`.spectral`); friction: Rado's log-normal speed model.

The Penn State model is available to either (``overrides={"friction": {"model": "penn_state"}}``), and either may
carry a hidden texture-and-speed effect on top (``{"friction": {"hidden_effect": "squeeze", "hidden_kappa": 0.3}}``;
:func:`.friction_models.hidden_factor`), absent by default.
"""

__all__ = [
    "GENERATORS",
    "SiteData",
    "design_campaign",
    "generate_site",
    "generator_config",
    "site_mu",
    "texture_measures",
    "write_campaign",
    "write_site",
]


def __getattr__(name: str):
    """The names of :mod:`.campaign`, imported on first use (PEP 562): it loads scipy.signal and scipy.spatial
    (the ``spectral`` and ``chips`` generators), which ``from skidsim.generators import default`` (the embedded
    campaign's generator, every synth_site job and the workflow's parse) never needs."""
    if name in __all__:
        from . import campaign

        return getattr(campaign, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
