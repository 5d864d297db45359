"""Tests of skidsim.exports: STL, VTU, gmsh, .inp decks and the CalculiX runner."""

from __future__ import annotations

import os
import re
import shutil

import numpy as np
import pytest

from skidsim.errors import InputError
from skidsim.exports import (
    CalculixError,
    hex_volumes,
    is_watertight,
    parse_dat,
    pavement_hex_mesh,
    pavement_surface_mesh,
    run_calculix,
    slider_placement,
    stl_bytes,
    triangulated_volume_m3,
    write_gmsh,
    write_inp,
    write_stl,
    write_vtu_pavement,
    write_vtu_slider,
)
from skidsim.friction import ExponentialDecay
from skidsim.reconstruct import Heightfield
from skidsim.slidermesh import SliderMesh

LAW = ExponentialDecay(mu_s=0.4, mu_k=0.35, alpha=0.6)


def _patch(lx_mm=26.0, ly_mm=20.0, h_mm=0.5, seed=0, origin=(0.0, 0.0)):
    """A textured patch: smooth bumps plus 0.1 mm noise, SI heightfield."""
    rng = np.random.default_rng(seed)
    h = h_mm * 1e-3
    x = np.arange(int(round(lx_mm / h_mm)) + 1) * h
    y = np.arange(int(round(ly_mm / h_mm)) + 1) * h
    X, Y = np.meshgrid(x, y)
    z = 0.4e-3 * np.sin(2 * np.pi * X / 0.006) * np.cos(2 * np.pi * Y / 0.005) + 0.1e-3 * rng.standard_normal(X.shape)
    return Heightfield(z, h, h, origin, name="patch")


def _ccx_or_skip():
    if shutil.which("ccx") is None:
        if os.environ.get("SKIDSIM_REQUIRE_CCX") == "1":
            pytest.fail("ccx not on PATH and SKIDSIM_REQUIRE_CCX=1")
        pytest.skip("CalculiX (ccx) not on PATH")


def test_stl_watertight_volume_bounds(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    hf = _patch(20.0, 12.0, origin=(0.003, -0.002))
    p = write_stl(hf, tmp_path / "pave.stl")
    m = trimesh.load(p, file_type="stl")  # from the file: vertices merged by trimesh
    assert m.is_watertight and m.is_winding_consistent
    v_bilinear_mm3 = hf.volume_m3() * 1e9
    assert m.volume > 0 and abs(m.volume - v_bilinear_mm3) / v_bilinear_mm3 < 1e-3
    # Stronger: exactly the volume of the triangulated solid (float32 STL rounding only).
    assert np.isclose(m.volume, triangulated_volume_m3(hf) * 1e9, rtol=1e-5)
    lo, hi = m.bounds
    np.testing.assert_allclose(lo, [3.0, -2.0, hf.z_bottom_m * 1e3], atol=1e-4)
    np.testing.assert_allclose(hi, [23.0, 10.0, hf.max_height_m * 1e3], atol=1e-4)
    assert [q.name for q in tmp_path.iterdir()] == ["pave.stl"]


def test_stl_bytes_are_trimeshs(tmp_path):
    """The STL writer gives the bytes trimesh's exporter gives for the same mesh (it replaced trimesh in the
    reconstruct job to save its import); a degenerate face gets a zero normal in both; open meshes are not
    watertight in both."""
    trimesh = pytest.importorskip("trimesh")
    for hf, unit in ((_patch(20.0, 12.0, origin=(0.003, -0.002)), 1e3), (_patch(7.0, 5.0, seed=3), 1.0)):
        v, f = pavement_surface_mesh(hf)
        assert stl_bytes(v * unit, f) == trimesh.Trimesh(vertices=v * unit, faces=f, process=False).export(
            file_type="stl"
        )
        assert is_watertight(f) and trimesh.Trimesh(vertices=v, faces=f, process=False).is_watertight
        assert not is_watertight(f[1:]) and not trimesh.Trimesh(vertices=v, faces=f[1:], process=False).is_watertight
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 0.0, 0.0]])
    f = np.array([[0, 1, 2], [0, 1, 3]])  # the second face is degenerate (collinear corners)
    assert stl_bytes(v, f) == trimesh.Trimesh(vertices=v, faces=f, process=False).export(file_type="stl")
    hf = _patch(6.0, 4.0, h_mm=1.0)
    v, f = pavement_surface_mesh(hf)
    assert write_stl(hf, tmp_path / "p.stl").read_bytes() == stl_bytes(v * 1e3, f)  # mm by default


def test_surface_mesh_in_memory_is_closed_and_outward():
    hf = _patch(6.0, 4.0, h_mm=1.0)
    v, f = pavement_surface_mesh(hf)
    # Closed 2-manifold: every undirected edge used exactly twice, once in each direction.
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    directed = {tuple(r) for r in e.tolist()}
    assert len(directed) == len(e)
    assert all((b, a) in directed for a, b in directed)
    # Divergence theorem volume (outward orientation gives a positive value).
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    assert np.isclose(vol, triangulated_volume_m3(hf), rtol=1e-12)


def test_hex_mesh_volume_and_orientation():
    hf = _patch(8.0, 6.0, h_mm=0.5)
    for layers in (1, 3):
        pts, hexes = pavement_hex_mesh(hf, layers)
        vols = hex_volumes(pts, hexes)
        assert np.all(vols > 0)
        assert np.isclose(vols.sum(), hf.volume_m3(), rtol=1e-12)
        assert hexes.shape == (layers * (hf.shape[0] - 1) * (hf.shape[1] - 1), 8)
    # Top-layer faces 5-8 carry the surface heights.
    top = pts[hexes[-(hf.shape[0] - 1) * (hf.shape[1] - 1) :, 4]]
    np.testing.assert_allclose(top[:, 2], hf.z_m[:-1, :-1].ravel(), atol=0)
    with pytest.raises(InputError):
        pavement_hex_mesh(hf, 0)


def test_vtu_pavement_and_slider_round_trip(tmp_path):
    meshio = pytest.importorskip("meshio")
    hf = _patch(6.0, 4.0)
    p = write_vtu_pavement(hf, tmp_path / "pave.vtu", layers=2)
    m = meshio.read(p)
    hexes = m.cells_dict["hexahedron"]
    assert hexes.shape[0] == 2 * (hf.shape[0] - 1) * (hf.shape[1] - 1)
    assert np.isclose(hex_volumes(m.points, hexes).sum(), hf.volume_m3() * 1e9, rtol=1e-9)  # mm^3
    np.testing.assert_allclose(m.point_data["height_mm"].max(), hf.max_height_m * 1e3)
    sl = SliderMesh.box(element_mm=4.0)
    u = np.zeros((sl.n_nodes, 3))
    u[:, 2] = -1e-5 * sl.points[:, 0] / sl.size_m[0]
    q = write_vtu_slider(
        sl, tmp_path / "slider.vtu", point_data={"p": np.arange(sl.n_nodes, dtype=float)}, displacement_m=u
    )
    s = meshio.read(q)
    np.testing.assert_allclose(s.points, (sl.points + u) * 1e3, atol=1e-12)
    np.testing.assert_array_equal(s.cells_dict["hexahedron"], sl.connectivity)
    np.testing.assert_array_equal(s.point_data["p"], np.arange(sl.n_nodes))
    assert np.isclose(hex_volumes(s.points - u * 1e3, s.cells_dict["hexahedron"]).sum(), 20 * 16 * 6)
    with pytest.raises(InputError) as e:
        write_vtu_slider(sl, tmp_path / "bad.vtu", point_data={"p": np.zeros(3)})
    assert "point_data" in str(e.value)


def test_gmsh_volume_mesh(tmp_path):
    meshio = pytest.importorskip("meshio")
    pytest.importorskip("gmsh")
    hf = _patch(10.0, 6.0)
    p = write_gmsh(hf, tmp_path / "pave.msh", layers=2, stride=2)
    text = p.read_text()
    assert "$MeshFormat\n4.1" in text and '"pavement"' in text and '"top"' in text
    m = meshio.read(p)
    sub = Heightfield(hf.z_m[::2, ::2], 2 * hf.dx_m, 2 * hf.dy_m, hf.origin_m, hf.z_bottom_m)
    nh = 2 * (sub.shape[0] - 1) * (sub.shape[1] - 1)
    assert m.cells_dict["hexahedron"].shape == (nh, 8)
    assert m.cells_dict["quad"].shape == ((sub.shape[0] - 1) * (sub.shape[1] - 1), 4)
    assert np.isclose(hex_volumes(m.points, m.cells_dict["hexahedron"]).sum(), sub.volume_m3() * 1e9, rtol=1e-9)
    # The quads are the top: their nodes carry the surface heights (mm).
    assert np.isclose(m.points[m.cells_dict["quad"]][..., 2].max(), sub.max_height_m * 1e3)


def _cards(text):
    return [ln for ln in text.splitlines() if ln.startswith("*") and not ln.startswith("**")]


def test_inp_static_deck_content(tmp_path):
    hf = _patch()
    sl = SliderMesh.box(element_mm=2.0)
    d = write_inp(tmp_path / "static.inp", sl, hf, LAW, load_n=11.8)
    text = d.path.read_text()
    cards = _cards(text)
    assert "*ELEMENT, TYPE=C3D8R, ELSET=SLIDER" in cards
    assert not any(c.startswith("*FRICTION") for c in cards)  # frictionless indentation
    assert re.search(r"\*ELASTIC\n1\.000000e\+08, 0\.45\n\*DENSITY\n1200\n", text)
    # Node and element counts.
    body = text.split("*NODE, NSET=SLIDER_ALL\n")[1].split("*NODE, NSET=PAVE_ALL\n")
    assert len(body[0].strip().splitlines()) == sl.n_nodes
    assert len(body[1].split("*ELEMENT")[0].strip().splitlines()) == hf.z_m.size * 2
    # The load: one CLOAD of -11.8 N on the reference node tied by equations to every top node.
    cl = text.split("*CLOAD\n")[1].splitlines()[0].split(",")
    assert int(cl[0]) == d.ref_node and float(cl[2]) == pytest.approx(-11.8)
    assert text.count("\n2\n") == len(sl.top_nodes()) - 1
    # Placement: exactly one bottom node reaches 1 um into the (bilinear) pavement.
    b = sl.points[sl.bottom_nodes()] + np.array(d.slider_offset_m)
    gap = b[:, 2] - hf.bilinear(b[:, 0], b[:, 1])
    assert np.isclose(gap.min(), -1e-6, atol=1e-12) and np.sum(gap < 0) == 1
    # Distributed holder: tributary loads sum to the load.
    d2 = write_inp(tmp_path / "dist.inp", sl, hf, LAW, holder="distributed")
    rows = d2.path.read_text().split("*CLOAD\n")[1].split("*")[0].strip().splitlines()
    f = np.array([float(r.split(",")[2]) for r in rows])
    assert len(f) == len(sl.top_nodes()) and np.isclose(f.sum(), -11.8, rtol=1e-9)


def test_inp_dynamic_decks(tmp_path):
    hf = _patch(60.0, 20.0)
    sl = SliderMesh.box(element_mm=2.0)
    a = write_inp(tmp_path / "dyn_abq.inp", sl, hf, LAW, speed_kmh=40.0, step="dynamic", dialect="abaqus")
    ta = a.path.read_text()
    assert "*FRICTION, EXPONENTIAL DECAY\n0.4, 0.35, 0.6\n" in ta
    v = 40 / 3.6
    assert a.slide_distance_m == pytest.approx(0.060 - 0.020)
    amp = ta.split("*AMPLITUDE, NAME=SLIDE\n")[1].splitlines()[0].split(",")
    assert float(amp[2]) == pytest.approx(0.040 / v, rel=1e-9)
    assert "*DYNAMIC, EXPLICIT" in ta and "*INITIAL CONDITIONS, TYPE=VELOCITY" in ta
    c = write_inp(tmp_path / "dyn_ccx.inp", sl, hf, LAW, speed_kmh=40.0, step="dynamic", dialect="calculix")
    tc = c.path.read_text()
    assert "EXPONENTIAL DECAY" not in _cards(tc) and c.mu_equivalent == pytest.approx(LAW.mu(v))
    mu = float(tc.split("*FRICTION\n")[1].split(",")[0])
    assert mu == pytest.approx(0.35 + 0.05 * np.exp(-0.6 * v), rel=1e-7)
    with pytest.raises(InputError):
        write_inp(tmp_path / "x.inp", sl, hf, LAW, step="dynamic", slide_distance_m=0.05)
    with pytest.raises(InputError):
        write_inp(tmp_path / "x.inp", sl, hf, LAW, step="implicit")


def test_placement_rejects_footprint_outside():
    hf = _patch(15.0, 20.0)
    with pytest.raises(InputError) as e:
        slider_placement(SliderMesh.box(element_mm=2.0), hf)
    assert e.value.column == "center_xy_m"


def test_parse_dat_takes_last_block(tmp_path):
    dat = tmp_path / "j.dat"
    dat.write_text("""
 total force (fx,fy,fz) for set PAVE_ALL and time  0.5000000E+00

        1.000000E+00  0.000000E+00  5.900000E+00

 displacements (vx,vy,vz) for set SLIDER_ALL and time  0.5000000E+00

         1 -1.0E-06 0.000000E+00 -2.000000E-05
         2  0.000000E+00  0.000000E+00 -2.000000E-05

 total force (fx,fy,fz) for set PAVE_ALL and time  0.1000000E+01

        2.000000E+00  1.000000E-01  1.180000E+01

 displacements (vx,vy,vz) for set SLIDER_ALL and time  0.1000000E+01

         1 -2.0E-06 0.000000E+00 -4.000000E-05
         2  0.000000E+00  0.000000E+00 -4.100000E-05

 contact stress (slave node,press,tang1,tang2) for all contact elements and time 0.1000000E+01

         7  8.5E+05  0.000000E+00  0.000000E+00
""")
    r = parse_dat(dat)
    assert r["time"] == 1.0 and r["total_force"] == (2.0, 0.1, 11.8)
    np.testing.assert_array_equal(r["displacements"][0], [1, 2])
    assert r["displacements"][1][1, 2] == -4.1e-5
    assert r["contact"][0].tolist() == [7] and r["contact"][1][0, 0] == 8.5e5
    (tmp_path / "e.dat").write_text("nothing here\n")
    with pytest.raises(CalculixError):
        parse_dat(tmp_path / "e.dat")


@pytest.mark.peer
def test_calculix_static_indentation_balances_load(tmp_path):
    _ccx_or_skip()
    hf = _patch()
    sl = SliderMesh.box(element_mm=2.0)
    d = write_inp(tmp_path / "static.inp", sl, hf, LAW, load_n=11.8, step="static")
    r = run_calculix(d.path, tmp_path / "run", deck=d)
    assert r.time == pytest.approx(1.0)
    assert abs(r.normal_force_n - 11.8) / 11.8 < 0.01
    # Contact: a few nodes (the slider rests on peaks), their area within the footprint.
    assert 1 <= len(r.contact_nodes) < len(d.bottom_node_ids)
    assert 0 < r.contact_area_mm2 < 20 * 16
    assert set(r.contact_nodes.tolist()) <= set(d.bottom_node_ids.tolist())
    # The rigid holder moved down as one (equations), x/y of the top held.
    top = r.slider_displacements_m[sl.top_nodes()]
    assert np.all(top[:, 2] < 0) and np.ptp(top[:, 2]) < 1e-12 and np.abs(top[:, :2]).max() == 0.0


@pytest.mark.peer
def test_calculix_accepts_dynamic_deck(tmp_path):
    _ccx_or_skip()
    hf = _patch(26.0, 20.0)
    sl = SliderMesh.box(element_mm=4.0)
    d = write_inp(
        tmp_path / "dyn.inp",
        sl,
        hf,
        LAW,
        step="dynamic",
        speed_kmh=20.0,
        slide_distance_m=2e-5,
        center_xy_m=(0.013, 0.010),
    )
    r = run_calculix(d.path, deck=d)
    assert r.time == pytest.approx(2e-5 / (20 / 3.6), rel=1e-6)
    top = r.slider_displacements_m[sl.top_nodes()]
    np.testing.assert_allclose(top[:, 0], 2e-5, rtol=1e-9)  # driven at constant speed to the slide distance


def test_figures_render(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    from skidsim.plotting.mesh import plot_fe_model, plot_reconstruction
    from skidsim.reconstruct import pavement_strip
    from skidsim.surface import Surface

    x = np.arange(601) * 0.1
    y = np.arange(301) * 0.1
    X, Y = np.meshgrid(x, y)
    s = Surface(0.5 * np.sin(X / 3.0) * np.cos(Y / 2.0), 0.1, 0.1, "fig")
    hf = pavement_strip(s, length_mm=40.0, width_mm=20.0, resolution_mm=1.0)
    p1 = plot_reconstruction(s, hf, tmp_path / "fig7c.png")
    p2 = plot_fe_model(hf, SliderMesh.box(element_mm=4.0), tmp_path / "fig7d.png")
    for p in (p1, p2):
        img = plt.imread(p)
        assert img.shape[0] > 300 and img.shape[1] > 300 and img[..., :3].std() > 0.05  # not blank
    assert sorted(q.name for q in tmp_path.iterdir()) == ["fig7c.png", "fig7d.png"]


def test_model_bundle_writes_everything(tmp_path):
    from skidsim.exports import write_model_bundle

    hf = _patch(40.0, 20.0)
    paths = write_model_bundle(hf, SliderMesh.box(element_mm=4.0), LAW, tmp_path / "site", speed_kmh=60.0)
    assert sorted(p.name for p in (tmp_path / "site").iterdir()) == sorted(p.name for p in paths.values())
    assert len(paths) == 8
    back = Heightfield.from_npz(paths["npz"])
    assert np.array_equal(back.z_m, hf.z_m)
    assert "EXPONENTIAL DECAY" in paths["inp_dynamic_abaqus"].read_text()
    assert f"{LAW.mu(60 / 3.6):.8g}" in paths["inp_dynamic_calculix"].read_text()
