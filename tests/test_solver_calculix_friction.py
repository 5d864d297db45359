"""Against CalculiX with its own friction model: the tangential/normal force ratio of a block pushed over a rigid
sinusoidal surface, quasi-statically, at and after the onset of sliding (issue 23, item 3).

CalculiX: :func:`skidsim.exports.write_inp` with ``step="push"``: step 1 puts the 11.8 N load on the rigid holder,
step 2 prescribes the x displacement of the holder (top) nodes in equal increments; node-to-surface penalty
contact with ``*FRICTION`` (constant mu, stick slope = our ``friction_stiffness_pa_per_m``, the same elastic
stick + Coulomb return mapping per node), normal penalty ``penalty_scale * E / h_z`` as ours, C3D8 elements
(C3D8R hourglasses under the point-like contact forces of a coarse mesh: 19 nodes in contact where C3D8 and our
element have 7). Ours: :func:`skidsim.solver.simulate` at 1 km/h with ``friction_model="penalty"`` and
:class:`ConstantFriction`, on the same :class:`Heightfield` (CalculiX sees its bilinear facets, we its C1
interpolant). The force ratio is the pavement's resisting F_x over F_z.

1. Steepest flank of a 200 mm corrugation (slope 0.2, mu 0.3): front-edge line contact; the onset-of-sliding
   ratio of a block pushed up a slope is (mu + tan theta) / (1 - mu tan theta) = 0.5319.
2. Egg-box texture, 7 mm x 9 mm wavelengths, 0.15 mm amplitude, mu 0.3: six separate contact points at the onset;
   the ratio changes by +-5 % along the push (the contacts climb or descend). CalculiX's pavement is faceted (1/3 mm
   cells), so its ratio is a sawtooth over each cell; the slider's nodes start mid-cell (where the facet slope is
   the exact slope) and the ratios are compared at the onset and as means over whole cells (two cells).
"""

import shutil
import time

import numpy as np
import pytest
from conftest import corrugation_flank, simulate_centre_m
from scipy import ndimage

from skidsim.friction import ConstantFriction
from skidsim.slidermesh import SliderMesh
from skidsim.solver import SinusoidalSurface, SolverConfig, simulate
from skidsim.solver.surfaces import to_heightfield

CCX = shutil.which("ccx")
needs_ccx = pytest.mark.skipif(CCX is None, reason="CalculiX (ccx) not installed")

MU = 0.3
#: one configuration for ours and the deck: 2 mm elements, normal penalty 10 E / h_z, tangential
#: SolverConfig's default (5e10 Pa/m)
BASE = SolverConfig(element_mm=2.0, friction_model="penalty", penalty_scale=10.0, edge_margin_mm=0.5)


def _push(tmp_path, hf, cfg, push_m, increments):
    """Write and run the CalculiX push deck; returns ``(deck, history, ccx wall s)``."""
    from skidsim.exports import parse_push_history, run_calculix, write_inp

    slider = SliderMesh.box(cfg.slider_length_mm, cfg.slider_width_mm, cfg.slider_thickness_mm, cfg.element_mm)
    centre = simulate_centre_m(hf, cfg, slider)
    deck = write_inp(
        tmp_path / "push.inp",
        slider,
        hf,
        ConstantFriction(MU),
        load_n=cfg.load_n,
        speed_kmh=1.0,
        step="push",
        center_xy_m=centre,
        slide_distance_m=push_m,
        push_increments=increments,
        penalty_pa_per_m=cfg.penalty_scale * cfg.youngs_modulus_pa / slider.hz,
        stick_slope_pa_per_m=cfg.friction_stiffness_pa_per_m,
        element_type="C3D8",
    )
    t0 = time.perf_counter()
    run_calculix(deck.path, tmp_path, deck=deck, ccx=CCX)
    wall = time.perf_counter() - t0
    hist = parse_push_history(tmp_path / "push.dat", deck)
    assert len(hist.time) == increments  # no cut-backs: every increment converged at the requested size
    assert hist.holder_x_m[-1] == pytest.approx(push_m, rel=1e-6)
    assert hist.force_n[:, 2] == pytest.approx(cfg.load_n, rel=1e-4)  # static: the pavement carries the load
    return deck, hist, wall


@needs_ccx
def test_push_up_the_flank_onset_ratio_matches_calculix_and_analytic(tmp_path):
    slope, lam = 0.2, 0.2
    cfg = BASE.replace(slide_length_mm=1.0, window_start_mm=0.3)
    x_front_mid = 0.5e-3 + 20e-3 + 0.5e-3  # front edge at mid-slide, m
    surf = corrugation_flank(slope, lam, x_front_mid)
    hf = to_heightfield(surf, 1e-3)
    analytic = (MU + slope) / (1 - MU * slope)
    deck, h, wall = _push(tmp_path, hf, cfg, 0.6e-3, 15)
    onset = h.onset_index()
    r = simulate(hf, 1.0, ConstantFriction(MU), cfg)
    ccx = float(h.ratio[-1])
    print(
        f"\nflank: CalculiX onset (first gross-slip increment {onset}, {h.holder_x_m[onset] * 1e6:.0f} um) "
        f"{h.ratio[onset]:.5f}, sliding {ccx:.5f}; ours {r.sn:.5f}; analytic {analytic:.5f}; "
        f"CalculiX - ours {100 * (ccx / r.sn - 1):+.3f} %, CalculiX - analytic {100 * (ccx / analytic - 1):+.3f} %; "
        f"{len(h.time)} increments, ccx {wall:.1f} s, ours {r.wall_s:.1f} s"
    )
    # every contact node slips (gross sliding) early in the push, and the ratio is then constant
    assert onset is not None and h.holder_x_m[onset] <= 0.1e-3
    assert np.ptp(h.ratio[len(h.ratio) // 2 :]) < 1e-3 * ccx
    assert h.contact_nodes[-1] == cfg.slider_width_mm / cfg.element_mm + 1  # the front row only: line contact
    assert ccx == pytest.approx(r.sn, rel=0.05)  # measured -0.005 %
    assert ccx == pytest.approx(analytic, rel=0.05)  # measured -0.008 %
    assert r.sn == pytest.approx(analytic, rel=0.005)
    assert ccx == pytest.approx(analytic, rel=0.005)


@needs_ccx
def test_egg_box_several_patches_ratio_matches_calculix(tmp_path):
    cell = 1e-3 / 3  # pavement grid (m): slider nodes at 0.5 + 2k mm (x) and -8 + 2k mm (y) sit mid-cell
    surf = SinusoidalSurface(
        amplitude_m=0.15e-3, wavelength_x_m=7e-3, wavelength_y_m=9e-3, phase=0.7, extent_m=(0.0, 0.025, -8.5e-3, 8.5e-3)
    )
    hf = to_heightfield(surf, cell)
    # window: two whole cells from half a cell on (the first facet crossing), the same for both
    w0, w1 = 0.5 * cell, 2.5 * cell
    cfg = BASE.replace(slide_length_mm=1.0, window_start_mm=w0 * 1e3, window_end_mm=w1 * 1e3)
    per_cell = 12
    deck, h, wall = _push(tmp_path, hf, cfg, w1, int(round(per_cell * w1 / cell)))
    r = simulate(hf, 1.0, ConstantFriction(MU), cfg)

    # onset: the first increment in which every contact node slips; ours at the same holder displacement
    onset = h.onset_index()
    assert onset is not None
    tr = r.trace
    ours_onset = float(np.interp(h.holder_x_m[onset] * 1e3, tr["position_mm"], tr["tangential_n"] / tr["normal_n"]))
    # several contact patches at the onset: connected groups of contact nodes on the bottom grid
    slider = SliderMesh.box(cfg.slider_length_mm, cfg.slider_width_mm, cfg.slider_thickness_mm, cfg.element_mm)
    from skidsim.exports import parse_dat_history

    blocks = [
        b
        for b in parse_dat_history(tmp_path / "push.dat")
        if b["kind"] == "contact stress" and b["time"] == h.time[onset]
    ]
    rows = blocks[0]["rows"]
    touching = set(rows[rows[:, 1] > 0, 0].astype(int).tolist())
    grid = np.isin(deck.bottom_node_ids, list(touching)).reshape(slider.nx + 1, slider.ny + 1)
    n_patches = ndimage.label(grid)[1]

    sel = h.holder_x_m > w0 + 1e-9
    ccx = float(-h.force_n[sel, 0].mean() / h.force_n[sel, 2].mean())
    print(
        f"\negg box: CalculiX onset (increment {onset}, {h.holder_x_m[onset] * 1e6:.1f} um, {int(grid.sum())} "
        f"contact nodes in {n_patches} patches) {h.ratio[onset]:.5f}, ours there {ours_onset:.5f} "
        f"({100 * (h.ratio[onset] / ours_onset - 1):+.2f} %); window {w0 * 1e3:.3f}-{w1 * 1e3:.3f} mm: CalculiX "
        f"{ccx:.5f}, ours {r.sn:.5f} ({100 * (ccx / r.sn - 1):+.2f} %); CalculiX range {h.ratio.min():.4f}-"
        f"{h.ratio.max():.4f}; {len(h.time)} increments, ccx {wall:.1f} s, ours {r.wall_s:.1f} s"
    )
    assert n_patches >= 3
    assert np.ptp(h.ratio) > 0.1 * MU  # the texture matters: not a flat-plane mu
    assert h.ratio[onset] == pytest.approx(ours_onset, rel=0.05)  # measured -0.2 %
    assert ccx == pytest.approx(r.sn, rel=0.05)  # measured +0.83 %


def test_push_deck_and_history_parser_without_calculix(tmp_path):
    """The push deck's friction, steps and outputs, and :func:`parse_push_history` on a hand-written .dat."""
    from skidsim.errors import InputError
    from skidsim.exports import CalculixError, parse_push_history, write_inp

    surf = SinusoidalSurface(
        amplitude_m=0.1e-3, wavelength_x_m=8e-3, wavelength_y_m=8e-3, extent_m=(0, 0.03, -0.01, 0.01)
    )
    hf = to_heightfield(surf, 0.5e-3)
    slider = SliderMesh.box(20, 16, 6, 4.0)
    deck = write_inp(
        tmp_path / "p.inp", slider, hf, ConstantFriction(0.3), step="push", slide_distance_m=0.4e-3, push_increments=8
    )
    text = deck.path.read_text()
    assert "*FRICTION\n0.3, 5.000000e+10\n" in text  # default stick slope: SolverConfig's 5e10 Pa/m
    assert text.count("*STEP") == 2 and text.count("*END STEP") == 2
    assert "*STATIC\n0.125, 1.0, 1.25e-05, 0.125\n*BOUNDARY\nSLIDER_TOP, 1, 1, 4.0000000000e-04\n" in text
    assert deck.mu_equivalent == 0.3 and deck.slide_distance_m == 0.4e-3
    with pytest.raises(InputError, match="dialect"):
        write_inp(tmp_path / "a.inp", slider, hf, ConstantFriction(0.3), step="push", dialect="abaqus")
    with pytest.raises(InputError, match="push_increments"):
        write_inp(tmp_path / "b.inp", slider, hf, ConstantFriction(0.3), step="push", push_increments=0)

    ref, other = deck.ref_node, deck.ref_node + 1
    dat = tmp_path / "p.dat"
    blocks = [" total force (fx,fy,fz) for set PAVE_ALL and time  0.1000000E+01\n\n  1.0E-01  0.0E+00  1.18E+01\n"]
    for t, ux, fx, tau in ((1.5, 2e-4, -3.0, 2.0e5), (2.0, 4e-4, -3.6, 3.0e5)):
        blocks.append(
            f" total force (fx,fy,fz) for set PAVE_ALL and time  {t:.7E}\n\n  {fx:E}  0.0E+00  1.2E+01\n\n"
            f" displacements (vx,vy,vz) for set SLIDER_ALL and time  {t:.7E}\n\n"
            f"  {other}  1.0E-05  0.0E+00  0.0E+00\n  {ref}  {ux:E}  0.0E+00  1.0E-05\n\n"
            f" contact stress (slave node,press,tang1,tang2) for all contact elements and time {t:.7E}\n\n"
            f"  7  1.0E+06  {tau:E}  0.0E+00\n  9  1.0E+06  3.0E+05  1.0E+03\n  11  -1.0E+00  0.0E+00  0.0E+00\n"
        )
    dat.write_text("\n".join(blocks))
    h = parse_push_history(dat, deck)
    assert h.time == pytest.approx([1.5, 2.0])
    assert h.holder_x_m == pytest.approx([2e-4, 4e-4])
    assert h.ratio == pytest.approx([3.0 / 12.0, 3.6 / 12.0])
    assert h.contact_nodes.tolist() == [2, 2] and h.slip_nodes.tolist() == [1, 2]
    assert h.onset_index() == 1
    dat.write_text(blocks[0])  # step 1 only
    with pytest.raises(CalculixError, match="push step"):
        parse_push_history(dat, deck)
