"""Figure of one synthetic site: the generated scan and its DFT trace against the truth's curves."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..generators import truth as _truth
from .style import COLORS, figure


def plot_synthetic_site(site_data, path: str | Path | None = None, *, max_pixels: int = 600):
    """Height map (mm; every k-th point so that the longer side has at most ``max_pixels``) and DFT trace
    (measured points, true curve, the base exponential-decay curve, each effect's step) of a generated site.

    ``site_data`` is a :class:`skidsim.generators.default.SiteData`. Saves a PNG atomically when ``path`` is given;
    returns the figure's axes' titles (for tests).
    """
    s = site_data.surface
    tr = site_data.truth
    k = max(1, int(np.ceil(max(s.shape) / max_pixels)))
    h = s.heights[::k, ::k]
    with figure(path, ncols=2, figsize=(10.0, 4.0)) as (fig, (ax0, ax1)):
        lo, hi = np.nanpercentile(h, [1, 99.5])
        im = ax0.imshow(
            h, origin="lower", extent=(0, s.width_mm, 0, s.height_mm), vmin=lo, vmax=hi, interpolation="nearest"
        )
        fig.colorbar(im, ax=ax0, label="height, mm")
        ax0.set_xlabel("x (sliding direction), mm")
        ax0.set_ylabel("y, mm")
        d = tr["descriptors"]
        ax0.set_title(f"{s.name}: MPD {d['mpd_mm']:.2f} mm, Ssk {d['ssk']:.2f}, micro Sq {d['micro_sq_mm']:.3f} mm")
        ax0.grid(False)
        v = np.linspace(0.0, max(90.0, float(site_data.dft["speed_kmh"].max())), 200)
        steps = _truth.mu_steps(v, tr)
        ax1.plot(
            site_data.dft["speed_kmh"],
            site_data.dft["mu"],
            ".",
            ms=3,
            color=COLORS["measured"],
            label="DFT trace (synthetic)",
        )
        ax1.plot(v, steps["base"], "--", color=COLORS["study"], label="base (exponential decay)")
        for name in _truth.EFFECT_ORDER:
            if tr["effects"][name]["enabled"] and not np.allclose(steps[name], steps["total"]):
                ax1.plot(v, steps[name], lw=0.8, alpha=0.7, label=f"+ {name}")
        ax1.plot(v, steps["total"], color=COLORS["ours"], lw=1.6, label="truth")
        ax1.set_xlabel("slider speed, km/h")
        ax1.set_ylabel("friction coefficient mu")
        t = tr["effects"]["temperature"]
        ax1.set_title(f"T {t['temperature_c']:.1f} deg C, a_T {t['a_T']:.2f}")
        ax1.legend(loc="upper right")
        titles = [ax0.get_title(), ax1.get_title()]
    return titles
