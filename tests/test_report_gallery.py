"""The report gallery: scaled JPEG copies of the per-site figures (skidsim.plotting.gallery)."""

import numpy as np
import pytest
from PIL import Image

from skidsim.plotting.gallery import ThumbnailOptions, thumbnail, write_gallery


def _png(path, width_px=200, height_px=100, alpha=255):
    """Left half pure red, right half pure blue; the alpha channel is ``alpha`` everywhere."""
    rgba = np.zeros((height_px, width_px, 4), dtype=np.uint8)
    rgba[:, : width_px // 2, 0] = 255
    rgba[:, width_px // 2 :, 2] = 255
    rgba[..., 3] = alpha
    Image.fromarray(rgba, "RGBA").save(path)
    return path


def test_thumbnail_scales_each_side_and_keeps_colours(tmp_path):
    out = thumbnail(_png(tmp_path / "f.png"), tmp_path / "g" / "f.jpg", ThumbnailOptions(scale=0.6, jpeg_quality=90))
    with Image.open(out) as im:
        assert im.format == "JPEG" and im.mode == "RGB"
        assert im.size == (120, 60)
        pixels = np.asarray(im).astype(int)
    # away from the red/blue edge (x = 60) the colours survive the Lanczos filter and JPEG within a few levels
    assert np.abs(pixels[30, 20] - [255, 0, 0]).max() <= 12
    assert np.abs(pixels[30, 100] - [0, 0, 255]).max() <= 12


def test_thumbnail_transparent_pixels_become_white(tmp_path):
    out = thumbnail(_png(tmp_path / "f.png", alpha=0), tmp_path / "f.jpg")
    with Image.open(out) as im:
        assert np.asarray(im).min() >= 245


def test_thumbnail_rounds_sizes_and_keeps_at_least_one_pixel(tmp_path):
    out = thumbnail(_png(tmp_path / "f.png", width_px=3, height_px=1), tmp_path / "f.jpg", ThumbnailOptions(scale=0.1))
    with Image.open(out) as im:
        assert im.size == (1, 1)


def test_write_gallery_names_files_by_site_and_leaves_no_temporary_file(tmp_path):
    sources = {"E1-1": _png(tmp_path / "a.png"), "C2.3": _png(tmp_path / "b.png")}
    written = write_gallery(sources, tmp_path / "gallery")
    assert sorted(p.name for p in written) == ["C2.3.jpg", "E1-1.jpg"]
    assert sorted(p.name for p in (tmp_path / "gallery").iterdir()) == ["C2.3.jpg", "E1-1.jpg"]


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"scale": 0.0}, "scale"),
        ({"scale": 1.5}, "scale"),
        ({"jpeg_quality": 0}, "jpeg_quality"),
        ({"jpeg_quality": 75.0}, "jpeg_quality"),
    ],
)
def test_options_refuse_bad_values(kw, field):
    with pytest.raises(ValueError, match=field):
        ThumbnailOptions(**kw)


def test_bad_sources_are_named(tmp_path):
    with pytest.raises(ValueError, match="missing.png.*not found"):
        thumbnail(tmp_path / "missing.png", tmp_path / "x.jpg")
    (tmp_path / "text.png").write_text("not an image")
    with pytest.raises(ValueError, match="text.png.*expected an image"):
        thumbnail(tmp_path / "text.png", tmp_path / "x.jpg")
    assert not (tmp_path / "x.jpg").exists()
    with pytest.raises(ValueError, match="'../E1' is not usable"):
        write_gallery({"../E1": tmp_path / "a.png"}, tmp_path / "g")


def test_default_run_makes_one_gallery_job_from_every_per_site_figure(default_dry_run):
    """The default target includes rule report_gallery, once, fed by the 3 figures of each of the 36 sites; the
    per-site PNGs are its inputs, and its three directories its outputs (the session's dry run of the default
    campaign, tests/conftest.py; a failed dry run fails there with Snakemake's output)."""
    out = default_dry_run
    assert out.count("rule report_gallery:") == 1, "rule report_gallery not in the default target"
    block = out[out.index("rule report_gallery:") :]
    inputs = block[block.index("input: ") + 7 :].split("\n", 1)[0].split(", ")
    assert len(inputs) == 108 and len(set(inputs)) == 108
    for kind in ("figure7", "reconstruction", "fe_model"):
        assert sum(p.endswith(f"/{kind}.png") for p in inputs) == 36, kind
    assert "output: results/report/figure7, results/report/reconstruction, results/report/fe_model" in block
