"""Exported files follow the user's umask, like any file the user writes (``tempfile.mkstemp`` alone gives 0600)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import file_mode

from skidsim.atomic import current_umask, honour_umask
from skidsim.exports import write_inp, write_stl
from skidsim.friction import ExponentialDecay
from skidsim.reconstruct import Heightfield
from skidsim.runlog import write_json
from skidsim.slidermesh import SliderMesh


def patch() -> Heightfield:
    x = np.arange(61) * 0.5e-3  # 30 x 25 mm: room for the 20 x 16 mm slider footprint
    X, Y = np.meshgrid(x, x[:51])
    return Heightfield(
        0.3e-3 * np.sin(2 * np.pi * X / 0.006) * np.cos(2 * np.pi * Y / 0.005), 0.5e-3, 0.5e-3, (0.0, 0.0), name="p"
    )


@pytest.mark.parametrize("mask,expected", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_mesh_exports_follow_umask(tmp_path, umask, mask, expected):
    umask(mask)
    assert current_umask() == mask
    stl = write_stl(patch(), tmp_path / "pavement.stl")
    inp = tmp_path / "deck.inp"
    write_inp(inp, SliderMesh.box(element_mm=4.0), patch(), ExponentialDecay(0.4, 0.35, 0.6), load_n=11.8)
    json_path = tmp_path / "x.json"
    write_json(json_path, {"a": 1})
    npz = patch().to_npz(tmp_path / "pavement.npz")
    for p in (stl, inp, json_path, npz):
        assert file_mode(p) == expected, (p, oct(file_mode(p)))


def test_honour_umask_sets_open_mode(tmp_path, umask):
    umask(0o027)
    p = tmp_path / "f"
    p.write_text("x")
    os.chmod(p, 0o600)
    honour_umask(p)
    assert file_mode(p) == 0o640
