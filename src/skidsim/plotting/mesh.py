"""Figures of the reconstructed pavement and of the FE model (study Fig. 7 c-d)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..reconstruct import Heightfield
from ..slidermesh import SliderMesh
from ..surface import Surface
from .style import COLORS, figure


def plot_reconstruction(
    surface: Surface, heightfield: Heightfield, path: str | Path, max_pixels: int = 800_000
) -> Path:
    """Scan with the strip outlined, the reconstructed heightfield, and a centre-line profile (Fig. 7c).

    Heights in mm. The scan is shown decimated to at most ``max_pixels`` points (display only). The profile
    compares the scan (raw) with the C1 heightfield along the strip's centre line; the heightfield is
    levelled (mean plane removed), so the scan profile is shown with the same plane removed.
    """
    hf = heightfield
    meta = hf.meta
    x0 = float(meta.get("x0_mm", 0.0))
    y0 = float(meta.get("y0_mm", 0.0))
    L = hf.length_m * 1e3
    W = hf.width_m * 1e3
    step = max(1, int(np.ceil(np.sqrt(surface.heights.size / max_pixels))))
    H = surface.heights[::step, ::step]
    with figure(path, nrows=3, ncols=1, figsize=(7.0, 9.0), gridspec_kw={"height_ratios": [2.2, 1.0, 1.0]}) as (
        fig,
        ax,
    ):
        vmin, vmax = np.nanpercentile(H, [1, 99])
        im = ax[0].imshow(
            H,
            origin="lower",
            extent=(0, surface.width_mm, 0, surface.height_mm),
            vmin=vmin,
            vmax=vmax,
            interpolation="nearest",
        )
        ax[0].add_patch(_rect(x0, y0, L, W))
        ax[0].set(
            xlabel="x (mm, sliding direction)",
            ylabel="y (mm)",
            title=f"Scan {surface.name or ''} ({surface.shape[0]} x {surface.shape[1]} points) and FE strip",
        )
        fig.colorbar(im, ax=ax[0], label="height (mm)", shrink=0.8)
        zm = hf.z_m * 1e3
        im2 = ax[1].imshow(zm, origin="lower", extent=(0, L, 0, W), interpolation="nearest", aspect="equal")
        res = meta.get("dx_mm", hf.dx_m * 1e3)
        cut = meta.get("smoothing_cutoff_mm", 0.0)
        ax[1].set(
            xlabel="x (mm)",
            ylabel="y (mm)",
            title=f"Reconstructed heightfield: {zm.shape[1]} x {zm.shape[0]} nodes at {res:.4g} mm, "
            f"Gaussian cutoff {cut:.3g} mm, levelled",
        )
        fig.colorbar(im2, ax=ax[1], label="height (mm)", shrink=0.8)
        # Centre-line profile.
        yc = 0.5 * W
        i = int(round((y0 + yc) / surface.dy))
        j0 = int(np.floor(x0 / surface.dx))
        j1 = int(np.ceil((x0 + L) / surface.dx)) + 1
        xs = np.arange(j0, min(j1, surface.shape[1])) * surface.dx - x0
        raw = surface.heights[i, j0 : j0 + len(xs)]
        plane = meta.get("removed_plane_mm", {})
        raw = raw - (plane.get("a_mm", 0.0) + plane.get("b_mm_per_mm", 0.0) * xs + plane.get("c_mm_per_mm", 0.0) * yc)
        xf = np.linspace(0, L, 4000)
        zf = hf.evaluate(xf * 1e-3 + hf.origin_m[0], np.full_like(xf, yc * 1e-3 + hf.origin_m[1]))[0] * 1e3
        ax[2].plot(xs, raw, lw=0.5, color=COLORS["raw"], label=f"scan ({surface.dx:g} mm)")
        ax[2].plot(xf, zf, lw=1.0, color=COLORS["ours"], label="FE heightfield (C1)")
        ax[2].set(xlabel="x (mm)", ylabel="height (mm)", title=f"Profile at y = {yc:.1f} mm of the strip")
        ax[2].legend(loc="upper right")
    return Path(path)


def _rect(x, y, w, h):
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), w, h, fill=False, edgecolor="white", lw=1.5, ls="--")


def plot_fe_model(
    heightfield: Heightfield, slider: SliderMesh, path: str | Path, center_xy_m=None, max_cells: int = 120
) -> Path:
    """3-D view of the pavement solid with the meshed slider resting on it (Fig. 7d); lengths in mm.

    The slider is placed as in the .inp deck (:func:`skidsim.exports.slider_placement`); the pavement top
    is drawn decimated to at most ``max_cells`` cells along x (display only). The vertical scale is
    exaggerated 2x so the texture stays visible (stated in the title).
    """
    from ..exports import slider_placement

    hf = heightfield
    ex = 2.0
    off = np.array(slider_placement(slider, hf, center_xy_m, 0.0))
    s = max(1, int(np.ceil((hf.shape[1] - 1) / max_cells)))
    X, Y = np.meshgrid(hf.x_m()[::s], hf.y_m()[::s])
    Z = hf.z_m[::s, ::s]
    zb = hf.z_bottom_m
    with figure(path, figsize=(8.0, 5.5), subplot_kw={"projection": "3d"}) as (fig, ax):
        ax.computed_zorder = False  # draw in call order: pavement first, slider on top
        # Side walls of the solid.
        for xs, ys, zs in (
            (X[0], Y[0], Z[0]),
            (X[-1], Y[-1], Z[-1]),
            (X[:, 0], Y[:, 0], Z[:, 0]),
            (X[:, -1], Y[:, -1], Z[:, -1]),
        ):
            xx = np.vstack([xs, xs]) * 1e3
            yy = np.vstack([ys, ys]) * 1e3
            zz = np.vstack([zs, np.full_like(zs, zb)]) * 1e3 * ex
            ax.plot_surface(xx, yy, zz, color="#9c8b7a", alpha=1.0, linewidth=0)
        ax.plot_surface(
            X * 1e3,
            Y * 1e3,
            Z * 1e3 * ex,
            cmap="gist_earth",
            linewidth=0,
            antialiased=False,
            rcount=Z.shape[0],
            ccount=Z.shape[1],
            alpha=0.95,
        )
        # Slider: element edges on its outer faces.
        P = (slider.coordinates + off[:, None, None, None]) * 1e3
        P[2] *= ex
        kw = dict(color=COLORS["study"], lw=0.4, zorder=10)
        nx, ny, nz = slider.node_shape
        for k in (0, nz - 1):
            for i in range(nx):
                ax.plot(P[0, i, :, k], P[1, i, :, k], P[2, i, :, k], **kw)
            for j in range(ny):
                ax.plot(P[0, :, j, k], P[1, :, j, k], P[2, :, j, k], **kw)
        for j in (0, ny - 1):
            for i in range(nx):
                ax.plot(P[0, i, j, :], P[1, i, j, :], P[2, i, j, :], **kw)
            for k in range(nz):
                ax.plot(P[0, :, j, k], P[1, :, j, k], P[2, :, j, k], **kw)
        for i in (0, nx - 1):
            for j in range(ny):
                ax.plot(P[0, i, j, :], P[1, i, j, :], P[2, i, j, :], **kw)
            for k in range(nz):
                ax.plot(P[0, i, :, k], P[1, i, :, k], P[2, i, :, k], **kw)
        L, W = hf.length_m * 1e3, hf.width_m * 1e3
        ax.set_box_aspect((L, W, max(8.0, (P[2].max() - zb * 1e3 * ex))))
        ax.set(xlabel="x (mm)", ylabel="y (mm)", zlabel=f"z (mm) x{ex:g}")
        ax.set_title(
            f"FE model: pavement {L:.1f} x {W:.1f} mm on {(hf.min_height_m - zb) * 1e3:.0f} mm base, "
            f"slider {slider.nx}x{slider.ny}x{slider.nz} hex (vertical x{ex:g})"
        )
        ax.view_init(elev=28, azim=-60)
    return Path(path)
