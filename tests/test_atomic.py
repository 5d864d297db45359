"""skidsim.atomic: a result appears whole under its final name or not at all, with the umask's permissions."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from conftest import file_mode

from skidsim import atomic


def test_failing_writer_leaves_neither_target_nor_temporary(tmp_path):
    target = tmp_path / "out" / "table.csv"
    with pytest.raises(RuntimeError, match="writer failed"), atomic.atomic_path(target) as tmp:
        tmp.write_text("half a table")
        raise RuntimeError("writer failed")
    assert not target.exists()
    assert list(target.parent.iterdir()) == []  # the directory was created, but nothing is left in it


def test_temporary_is_a_hidden_sibling_with_the_final_suffix(tmp_path):
    target = tmp_path / "mesh.vtu"
    with atomic.atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".mesh.") and tmp.suffix == ".vtu"
        assert not target.exists()
        tmp.write_text("x")
    with atomic.atomic_path(target, suffix=".msh") as tmp:
        assert tmp.suffix == ".msh"
        tmp.write_text("y")
    assert target.read_text() == "y"
    assert [p.name for p in tmp_path.iterdir()] == ["mesh.vtu"]


@pytest.mark.parametrize("mask,expected", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600), (0o027, 0o640)])
def test_success_gives_the_umask_permissions(tmp_path, umask, mask, expected):
    umask(mask)
    assert atomic.current_umask() == mask
    paths = [
        atomic.write_text(tmp_path / "a.txt", "a"),
        atomic.write_bytes(tmp_path / "b.bin", b"\x00\x01"),
        atomic.write_json(tmp_path / "c.json", {"k": 1}),
        atomic.write_parquet(tmp_path / "d.parquet", pd.DataFrame({"x": [1.5]})),
    ]
    with atomic.atomic_path(tmp_path / "e.dat") as tmp:
        tmp.write_text("e")
    for p in [*paths, tmp_path / "e.dat"]:
        assert file_mode(p) == expected, (p.name, oct(file_mode(p)))


def test_keyboard_interrupt_leaves_the_old_file_intact(tmp_path):
    target = atomic.write_text(tmp_path / "result.json", '{"sn": 0.41}')
    with pytest.raises(KeyboardInterrupt), atomic.atomic_path(target) as tmp:
        tmp.write_text('{"sn": 0.')
        raise KeyboardInterrupt
    assert target.read_text() == '{"sn": 0.41}'
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


def test_writers_replace_the_content(tmp_path):
    p = tmp_path / "x.json"
    atomic.write_json(p, {"a": [1, 2]})
    atomic.write_json(p, {"b": 0.5}, indent=None)
    assert json.loads(p.read_text()) == {"b": 0.5} and p.read_text() == '{"b": 0.5}'
    assert atomic.write_bytes(tmp_path / "y.bin", b"\xff\x00", fsync=True).read_bytes() == b"\xff\x00"
    df = pd.DataFrame({"speed_kmh": [20.0, 40.0], "mu": [0.61, 0.55]})
    pd.testing.assert_frame_equal(pd.read_parquet(atomic.write_parquet(tmp_path / "t.parquet", df)), df)
