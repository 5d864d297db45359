"""Report gallery: reduced JPEG copies of the per-site figures for the HTML report.

``snakemake --report`` embeds every file it shows in one HTML page (base64, 4/3 of the file size). Embedded as
they are, the three per-site figures (study Figure 7 a-b, the reconstruction and the FE model; 108 PNGs on the
36-site default campaign) make that page over 100 MB. The report shows copies scaled by
:attr:`ThumbnailOptions.scale` and stored as JPEG instead; the full-size PNGs stay in ``results/sites/<site>/``.
docs/workflow.md (section Report) gives the measured sizes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from PIL import Image, UnidentifiedImageError

from skidsim.atomic import atomic_path

__all__ = ["ThumbnailOptions", "thumbnail", "write_gallery"]


@dataclass(frozen=True)
class ThumbnailOptions:
    """How a report copy is made.

    scale: linear scale factor applied to the width and height in pixels (0 < scale <= 1); 0.6 turns the
        figures' 130 dpi into 78 dpi, where 9 pt axis labels stay legible.
    jpeg_quality: JPEG quality, 1 (smallest) to 95 (Pillow's highest useful setting).
    """

    scale: float = 0.6
    jpeg_quality: int = 75

    def __post_init__(self):
        if not 0.0 < self.scale <= 1.0:
            raise ValueError(f"ThumbnailOptions.scale: expected 0 < scale <= 1, got {self.scale!r}")
        if not (isinstance(self.jpeg_quality, int) and 1 <= self.jpeg_quality <= 95):
            raise ValueError(f"ThumbnailOptions.jpeg_quality: expected an integer 1 to 95, got {self.jpeg_quality!r}")


def _flatten(image: Image.Image) -> Image.Image:
    """RGB image; transparent pixels become white (JPEG has no alpha channel)."""
    if image.mode in ("RGBA", "LA") or (image.mode == "P" and "transparency" in image.info):
        rgba = image.convert("RGBA")
        background = Image.new("RGB", rgba.size, (255, 255, 255))
        background.paste(rgba, mask=rgba.getchannel("A"))
        return background
    return image.convert("RGB")


def thumbnail(source: str | Path, target: str | Path, options: ThumbnailOptions = ThumbnailOptions()) -> Path:
    """Write a JPEG copy of the image ``source`` scaled by ``options.scale`` (Lanczos filter) to ``target``.

    Each side becomes ``round(side * scale)`` pixels, at least 1. Raises ``ValueError`` naming ``source`` when it
    is missing or not an image.
    """
    source = Path(source)
    try:
        with Image.open(source) as opened:
            image = _flatten(opened)
    except FileNotFoundError:
        raise ValueError(f"{source}: figure for the report gallery not found") from None
    except UnidentifiedImageError:
        raise ValueError(f"{source}: expected an image (PNG) for the report gallery, found another file") from None
    size = (max(1, round(image.width * options.scale)), max(1, round(image.height * options.scale)))
    if size != image.size:
        image = image.resize(size, Image.Resampling.LANCZOS)
    with atomic_path(target) as tmp:
        image.save(tmp, format="JPEG", quality=options.jpeg_quality, optimize=True, progressive=True)
    return Path(target)


def write_gallery(
    sources: Mapping[str, str | Path], directory: str | Path, options: ThumbnailOptions = ThumbnailOptions()
) -> list[Path]:
    """``<directory>/<name>.jpg`` for every ``name -> figure`` of ``sources`` (names are site ids)."""
    directory = Path(directory)
    for name in sources:
        if not name or "/" in name or name.startswith("."):
            raise ValueError(f"report gallery {directory}: {name!r} is not usable as a file name (expected a site id)")
    return [thumbnail(path, directory / f"{name}.jpg", options) for name, path in sources.items()]
