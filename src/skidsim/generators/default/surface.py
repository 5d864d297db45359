"""The surface of one default-campaign site: stones, mastic and microtexture, then the scanner's artefacts.

:func:`synthesize_surface` renders the clean height map of a site from its design row; :func:`_scanner` turns it into
what an LS-40-like scanner records. Conventions that change numbers (all in ``docs/synthetic-campaign.md``):

* Heights in mm, ``z = 0`` is the roller plane (the compacted top of the coarse stones); heights below are
  negative. Columns run along x (2448 points), rows along y, spacing ``spacing_mm`` both ways.
* Surface = max(stone caps, mastic): stones are superellipsoid caps (plan exponent 2-4: rounded to
  rounded-polyhedral; vertical exponent 2-3.5: flat-topped), sizes drawn log-uniformly within each gradation
  component's size range until the component's share of the surface area is reached, placed largest first by
  random sequential placement on a 0.25 mm occupancy grid. A stone's top sits at
  ``min(0, -D_p + f * d) - |N(0, sigma_top)|`` (d its size, f its protrusion share): large stones reach the
  roller plane, small grains sit in the mortar. The mastic (mortar) lies at ``-D_p`` plus a smooth field and
  surface voids (depth up to ``D_v``). ``D_p = protrusion_ratio * d_c`` and ``D_v = void_depth_ratio * d_c``
  with ``d_c`` the area-weighted mean size of the drawn coarse (>= 4.75 mm) stones: larger stones, deeper
  texture. Each site draws a lognormal texture-depth factor (``site_depth_sd``) on D_p and D_v and a lognormal
  factor (``site_void_sd``) on the void fraction.
* Microtexture: one self-affine Gaussian field (PSD ~ (q_r^2 + q^2)^-(1+H)), scaled so that its band below
  0.5 mm wavelength has RMS 1, times a per-point amplitude: the site's aggregate micro Sq times the stone's
  component factor on stones, ``mastic_micro_factor`` of it on mastic.
* Scanner: a small random plane tilt, dropouts (NaN clusters placed preferentially in the lowest 20 % of
  heights, exact configured fraction), speckle (isolated spikes of random sign, exact configured fraction of
  the valid points), then quantisation to ``z_quantum_mm``.
* Random streams: every site draws from ``numpy.random.SeedSequence([seed, crc32(site id)])`` (children for
  layout, micro field, scanner, trace), so one site generated alone is identical to the same site in a full
  campaign. The design draws from ``SeedSequence([seed, 0x5D5])``.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from ...errors import ConfigError
from .config import resolve_config


def _site_seed(seed: int, site: str) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(seed), zlib.crc32(str(site).encode("utf-8"))])


def _smooth_field(rng: np.random.Generator, shape, dx_mm: float, corr_mm: float) -> np.ndarray:
    """Unit-variance Gaussian random field with Gaussian correlation of length ``corr_mm``.

    Drawn on a coarse grid (spacing corr_mm / 4, at least dx) and interpolated bilinearly (cheap)."""
    f = max(1, int(corr_mm / 4.0 / dx_mm))
    cs = (shape[0] // f + 3, shape[1] // f + 3)
    g = ndimage.gaussian_filter(rng.standard_normal(cs), sigma=corr_mm / (f * dx_mm) / 2.0, mode="wrap")
    g /= g.std()
    if f == 1:
        return g[: shape[0], : shape[1]]
    yi = np.arange(shape[0]) / f
    xi = np.arange(shape[1]) / f
    y0 = yi.astype(int)
    x0 = xi.astype(int)
    wy = (yi - y0)[:, None]
    wx = (xi - x0)[None, :]
    t = g[y0] * (1.0 - wy) + g[y0 + 1] * wy  # rows first (cheap), then columns
    out = t[:, x0]
    out *= 1.0 - wx
    out += t[:, x0 + 1] * wx
    return out


def micro_field(
    rng: np.random.Generator, shape, dx_mm: float, hurst: float, rolloff_mm: float, band_mm: float = 0.5
) -> np.ndarray:
    """Self-affine Gaussian field, PSD ~ (q_r^2 + q^2)^-(1 + H), whose band of wavelengths below ``band_mm``
    has expected RMS 1 (mm after scaling by the caller's amplitude)."""
    ny, nx = shape
    qy = 2 * np.pi * sfft.fftfreq(ny, d=dx_mm)[:, None]
    qx = 2 * np.pi * sfft.rfftfreq(nx, d=dx_mm)[None, :]
    q2 = qy * qy + qx * qx
    qr = 2 * np.pi / rolloff_mm
    psd = (qr * qr + q2) ** (-(1.0 + hurst))
    psd[0, 0] = 0.0
    # real-FFT half plane: columns 1..(nx-1)/2 stand for two conjugate coefficients
    weight = np.full(qx.shape, 2.0)
    weight[0, 0] = 1.0
    if nx % 2 == 0:
        weight[0, -1] = 1.0
    band = q2 > (2 * np.pi / band_mm) ** 2
    band_var = float((psd * weight * band).sum()) / (nx * ny)
    amp = np.sqrt(psd / band_var)
    noise = sfft.rfft2(rng.standard_normal(shape))
    return sfft.irfft2(noise * amp, s=shape)


def _draw_stones(rng, c: dict, comb: dict, width_mm: float, height_mm: float, margin_mm: float):
    """Stone list (largest first): size d (mm), component name, shape parameters."""
    area = (width_mm + 2 * margin_mm) * (height_mm + 2 * margin_mm)
    stones = []
    for name, mass in comb["fractions"].items():
        if name not in c["components"]:
            continue  # fines (mineral filler, ...) are part of the mastic
        comp = c["components"][name]
        lo, hi = (float(x) for x in comp["size_mm"])
        lo = max(lo, float(c["min_stone_mm"]))
        if lo >= hi:
            continue
        target = area * float(c["stone_area_factor"]) * float(mass) / 100.0
        acc = 0.0
        while acc < target:
            d = math.exp(rng.uniform(math.log(lo), math.log(hi)))
            aspect = rng.uniform(*comp["aspect"])
            acc += math.pi / 4 * d * d * aspect
            stones.append((d, name, aspect))
    stones.sort(key=lambda s: -s[0])
    return stones


def _stone_cap(u, v, a: float, b: float, n_pl: float, m_v: float, base: float, thick: float, t0: float, t1: float):
    """A stone's plan outline and cap on its patch: ``(inside, z)``.

    ``u``, ``v`` (mm): the patch's points in the stone's axes; ``a``, ``b`` (mm): its half axes; the outline is the
    superellipse ``rho = |u / a|^n_pl + |v / b|^n_pl < 1``; ``z`` (mm), at the ``inside`` points in raster order,
    is ``base + t0 u + t1 v + thick (1 - rho^(m_v / n_pl))^(1 / m_v)``. The powers are taken only in the box
    ``|u / a| < 1``, ``|v / b| < 1``, which holds the outline (outside it one term alone is >= 1); every point
    gets the same arithmetic as over the whole patch (tests/test_synthetic.py compares the two bit for bit)."""
    ua, vb = np.abs(u * (1.0 / a)), np.abs(v * (1.0 / b))
    box = (ua < 1.0) & (vb < 1.0)
    rho = ua[box] ** n_pl + vb[box] ** n_pl
    in_box = rho < 1.0
    inside = np.zeros_like(box)
    inside[box] = in_box
    w = 1.0 - np.minimum(rho[in_box], 1.0) ** (m_v / n_pl)  # 1 - rho^m
    z = base + t0 * u[inside] + t1 * v[inside] + thick * w ** (1.0 / m_v)
    return inside, z


def _render(rng, c: dict, comb: dict, shape, dx: float, depth_factor: float):
    """Clean height map (mm), per-point micro amplitude factor, and structural numbers."""
    ny, nx = shape
    W, H = nx * dx, ny * dx
    dmax = max(float(c["components"][n]["size_mm"][1]) for n in comb["fractions"] if n in c["components"])
    margin = 0.6 * dmax
    stones = _draw_stones(rng, c, comb, W, H, margin)
    coarse = [(d, a) for d, _, a in stones if d >= 4.75]
    d_c = (sum(d * d * a * d for d, a in coarse) / sum(d * d * a for d, a in coarse)) if coarse else 3.0
    D_p = float(comb["protrusion_ratio"]) * d_c * depth_factor
    D_v = float(comb["void_depth_ratio"]) * d_c * depth_factor
    # occupancy grid (0.25 mm) for random sequential placement
    cell = 0.25
    occ = np.zeros((int((H + 2 * margin) / cell) + 2, int((W + 2 * margin) / cell) + 2), dtype=bool)
    top = np.full(shape, -np.inf)
    label = np.zeros(shape, dtype=np.int32)
    micro_of = [float(c["mastic_micro_factor"])]
    ps_lo, ps_hi = (float(x) for x in c["protrusion_share"])
    n_placed = 0
    ns = len(stones)
    U = rng.random((ns, 18))  # all per-stone draws at once: 6 placement tries (x, y), shape, top, micro
    N = rng.standard_normal((ns, 3))
    top_sd = float(c["top_sd_mm"])
    disks: dict = {}
    for k, (d, name, aspect) in enumerate(stones):
        comp = c["components"][name]
        a = d / 2.0
        b = a * aspect
        rr = max(1, int(0.45 * b / cell))
        for t in range(6):
            cx = -margin + U[k, 2 * t] * (W + 2 * margin)
            cy = -margin + U[k, 2 * t + 1] * (H + 2 * margin)
            gi, gj = int((cy + margin) / cell), int((cx + margin) / cell)
            sub = occ[max(0, gi - rr) : gi + rr + 1, max(0, gj - rr) : gj + rr + 1]
            if np.count_nonzero(sub) / sub.size < 0.35:  # sub.mean(): the same count over the same size
                break
        else:
            continue
        if rr not in disks:
            yy, xx = np.ogrid[-rr : rr + 1, -rr : rr + 1]
            disks[rr] = (yy * yy + xx * xx) <= rr * rr
        s_i0, s_j0 = max(0, gi - rr), max(0, gj - rr)
        sub = occ[s_i0 : gi + rr + 1, s_j0 : gj + rr + 1]
        di, dj = s_i0 - (gi - rr), s_j0 - (gj - rr)
        sub |= disks[rr][di : di + sub.shape[0], dj : dj + sub.shape[1]]
        n_placed += 1
        theta = np.pi * U[k, 12]
        pe, ve = comp["plan_exponent"], comp["vertical_exponent"]
        n_pl = pe[0] + (pe[1] - pe[0]) * U[k, 13]
        m_v = ve[0] + (ve[1] - ve[0]) * U[k, 14]
        thick = a * (0.45 + 0.3 * U[k, 15])
        ztop = min(0.0, -D_p + (ps_lo + (ps_hi - ps_lo) * U[k, 16]) * d) - abs(top_sd * N[k, 0])
        t0, t1 = 0.06 * N[k, 1], 0.06 * N[k, 2]
        R = 1.2 * a
        j0, j1 = max(0, int((cx - R) / dx)), min(nx, int((cx + R) / dx) + 2)
        i0, i1 = max(0, int((cy - R) / dx)), min(ny, int((cy + R) / dx) + 2)
        if j0 >= j1 or i0 >= i1:
            continue
        X = np.arange(j0, j1) * dx - cx
        Y = (np.arange(i0, i1) * dx - cy)[:, None]
        ct, st = math.cos(theta), math.sin(theta)
        u = X * ct + Y * st
        v = Y * ct - X * st
        inside, z = _stone_cap(u, v, a, b, n_pl, m_v, ztop - thick, thick, t0, t1)
        patch = top[i0:i1, j0:j1]
        up = np.zeros_like(inside)
        up[inside] = z > patch[inside]
        patch[up] = z[up[inside]]
        label[i0:i1, j0:j1][up] = len(micro_of)
        micro_of.append(float(comp["micro_factor"]) * (0.8 + 0.4 * U[k, 17]))
    # mastic: mortar level, smooth undulation, surface voids
    mastic = -D_p + float(c["mastic_sd_mm"]) * _smooth_field(rng, shape, dx, float(c["mastic_corr_mm"]))
    g = _smooth_field(rng, shape, dx, float(c["void_corr_mm"]))
    q = float(comb["void_fraction"])
    thr = float(np.quantile(g[::8, ::8], 1.0 - q)) if q > 0 else np.inf
    # the power only where the void term is not 0 (0 ** 0.7 is 0: the other points keep their mortar level)
    void = np.clip((g - thr) / 0.6, 0.0, 1.0)
    deep = void > 0.0
    mastic[deep] -= D_v * void[deep] ** 0.7
    on_mastic = mastic >= top
    heights = np.where(on_mastic, mastic, top)
    er = float(c["edge_round_mm"]) / dx
    if er > 0:  # binder films and wear round the stone edges and the void rims
        heights = ndimage.gaussian_filter(heights, er, mode="nearest", truncate=3.0)
    label[on_mastic] = 0
    amp = np.asarray(micro_of)[label]
    info = {
        "coarse_size_mm": d_c,
        "mortar_depth_mm": D_p,
        "void_depth_mm": D_v,
        "stones_placed": n_placed,
        "stone_area_fraction": float(1.0 - on_mastic.mean()),
    }
    return heights, amp, info


def _scanner(rng, heights: np.ndarray, c: dict, dx: float) -> np.ndarray:
    """Tilt, dropouts, speckle, quantisation (see module docstring)."""
    ny, nx = heights.shape
    h = heights.copy()
    slope = rng.uniform(0.0, float(c["tilt_max_percent"])) / 100.0
    phi = rng.uniform(0, 2 * np.pi)
    h += slope * (math.cos(phi) * np.arange(nx)[None, :] * dx + math.sin(phi) * np.arange(ny)[:, None] * dx)
    n = h.size
    # dropouts: clusters, preferably in the lowest 20 % (occlusion in voids)
    target = int(round(float(c["dropout_fraction"]) * n))
    if target > 0:
        flat = heights.ravel()
        low_thr = np.quantile(flat[:: max(1, n // 20000)], 0.2)
        mask = np.zeros(n, dtype=bool)
        count = 0
        rlo, rhi = (float(x) for x in c["dropout_radius_mm"])
        last = None
        while count < target:
            k = int(rng.integers(n))
            if flat[k] > low_thr and rng.random() < 0.75:
                continue
            ci, cj = divmod(k, nx)
            ra = rng.uniform(rlo, rhi) / dx
            rb = ra * rng.uniform(0.5, 1.0)
            th = rng.uniform(0, np.pi)
            R = int(math.ceil(ra)) + 1
            i0, i1, j0, j1 = max(0, ci - R), min(ny, ci + R + 1), max(0, cj - R), min(nx, cj + R + 1)
            Y, X = np.mgrid[i0:i1, j0:j1]
            uu = (X - cj) * math.cos(th) + (Y - ci) * math.sin(th)
            vv = -(X - cj) * math.sin(th) + (Y - ci) * math.cos(th)
            inside = (uu / ra) ** 2 + (vv / rb) ** 2 <= 1.0
            idx = Y[inside] * nx + X[inside]
            new = idx[~mask[idx]]
            if new.size == 0:
                continue
            mask[new] = True
            count += new.size
            last = new
        if count > target and last is not None:
            new = last
            ii, jj = np.divmod(new, nx)
            ci_, cj_ = ii.mean(), jj.mean()
            far = np.argsort(-((ii - ci_) ** 2 + (jj - cj_) ** 2), kind="stable")[: count - target]
            mask[new[far]] = False
        h.ravel()[mask] = np.nan
    # speckle: isolated spikes on valid points
    n_sp = int(round(float(c["speckle_fraction"]) * n))
    if n_sp > 0:
        valid_idx = np.flatnonzero(np.isfinite(h.ravel()))
        pick = rng.choice(valid_idx.size, size=n_sp, replace=False) if valid_idx.size < 4 * n_sp else None
        if pick is None:
            chosen = np.unique(rng.integers(0, valid_idx.size, size=int(n_sp * 1.2) + 16))
            while chosen.size < n_sp:
                chosen = np.unique(np.concatenate([chosen, rng.integers(0, valid_idx.size, size=n_sp)]))
            chosen = rng.permutation(chosen)[:n_sp]
        else:
            chosen = pick
        lo, hi = (float(x) for x in c["speckle_height_mm"])
        spikes = rng.uniform(lo, hi, n_sp) * rng.choice([-1.0, 1.0], n_sp)
        h.ravel()[valid_idx[chosen]] += spikes
    qz = float(c["z_quantum_mm"])
    if qz > 0:
        h = np.rint(h / qz) * qz
    return h


def synthesize_surface(row, cfg: dict | None = None):
    """The clean surface of a site (no scanner artefacts) and structural info; see :func:`.site.generate_site`.

    Returns ``(heights_mm, info)``; ``info`` holds the site's drawn structure (mm) and its micro Sq.
    """
    c = resolve_config(cfg)
    row = dict(row)
    site = str(row["site"])
    comb_key = str(row.get("aggregate_combination", c["section_designs"][str(row["section"])]["aggregate_combination"]))
    if comb_key not in c["gradations"]:
        raise ConfigError(f"synthetic.gradations: no aggregate combination {comb_key!r} (site {site})")
    comb = c["gradations"][comb_key]
    ss = _site_seed(c["seed"], site).spawn(4)
    rng_layout = np.random.default_rng(ss[0])
    rng_micro = np.random.default_rng(ss[1])
    shape = (int(c["shape"][0]), int(c["shape"][1]))
    dx = float(c["spacing_mm"])
    depth_factor = float(np.exp(rng_layout.normal(0.0, float(c["site_depth_sd"]))))
    sq_agg = float(rng_layout.uniform(*c["micro_sq_mm"]))
    void_factor = float(np.exp(rng_layout.normal(0.0, float(c["site_void_sd"]))))
    comb = dict(comb, void_fraction=float(np.clip(float(comb["void_fraction"]) * void_factor, 0.0, 0.6)))
    heights, amp, info = _render(rng_layout, c, comb, shape, dx, depth_factor)
    heights += sq_agg * amp * micro_field(rng_micro, shape, dx, float(c["micro_hurst"]), float(c["micro_rolloff_mm"]))
    info.update(
        site_depth_factor=depth_factor,
        aggregate_micro_sq_mm=sq_agg,
        aggregate_combination=comb_key,
        void_fraction=comb["void_fraction"],
    )
    return heights, info
