"""Benchmark: Heightfield.evaluate for 1,400 points (one explicit-solver contact query) vs scipy."""

import time

import numpy as np
from scipy.interpolate import RectBivariateSpline

from skidsim.reconstruct import Heightfield


def median_us(f, n=3000, warm=50):
    for _ in range(warm):
        f()
    ts = np.empty(n)
    for k in range(n):
        t0 = time.perf_counter()
        f()
        ts[k] = time.perf_counter() - t0
    return np.median(ts) * 1e6


rng = np.random.default_rng(0)
hf = Heightfield(rng.normal(0, 0.5e-3, (81, 230)), 0.1143 / 229, 0.5e-3)
# slider bottom nodes: 41 x 33 grid at 0.5 mm, somewhere on the strip
gx, gy = np.meshgrid(0.03 + 0.5e-3 * np.arange(41), 0.012 + 0.5e-3 * np.arange(33), indexing="ij")
px, py = gx.ravel() + 1.234e-4, gy.ravel() + 0.77e-4
print("points", px.size)
t_ours = median_us(lambda: hf.evaluate(px, py))
spl = RectBivariateSpline(hf.y_m(), hf.x_m(), hf.z_m, kx=3, ky=3)
t_rbs = median_us(lambda: (spl.ev(py, px), spl.ev(py, px, dx=0, dy=1), spl.ev(py, px, dx=1, dy=0)), n=500)
rp = rng.permutation(px.size)
t_rand = median_us(lambda: hf.evaluate(px[rp], py[rp]))
print(f"Heightfield.evaluate (z, dz/dx, dz/dy), 1,353 pts: median {t_ours:.1f} us")
print(f"  same points in random order (incl. permutation): {t_rand:.1f} us")
print(f"RectBivariateSpline.ev x3 (z, dz/dx, dz/dy): median {t_rbs:.1f} us  ratio {t_rbs / t_ours:.1f}x")
t0 = time.perf_counter()
hf2 = Heightfield(hf.z_m, hf.dx_m, hf.dy_m)
hf2.evaluate(0.01, 0.01)
t_setup = time.perf_counter() - t0
print(f"coefficient setup (first call): {t_setup * 1e3:.2f} ms")
