"""The checks of one scan file: header (archive, checksums, spacing and extent against the strip and the texture
band), decoded points (share of valid points, height span) and the relief a pavement can have."""

from __future__ import annotations

import hashlib
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..errors import InputError
from .requirements import DEFAULT_REQUIREMENTS, Requirements


def check_relief(path, surface, req: Requirements) -> list[InputError]:
    """The relief of a decoded scan against the ``quality:`` limits (:func:`skidsim.texture.quality.relief_mm`):
    outside them a problem naming the scan (``action: stop``) or a WARNING (``action: warn``)."""
    import logging

    from ..texture.quality import QualityOptions, relief_breach, relief_mm

    opt = req.quality or QualityOptions()
    relief = relief_mm(surface)
    breach = relief_breach(relief, opt)
    if breach is None:
        return []
    if opt.action == "warn":
        logging.getLogger("skidsim").warning("SCAN RELIEF %s: %s (quality.action: warn)", path, breach)
        return []
    return [
        InputError(
            path,
            f"a relief of a pavement surface, {opt.min_relief_mm:g} to {opt.max_relief_mm:g} mm "
            "(quality.min_relief_mm, quality.max_relief_mm; 0.5-99.5 % of the heights about their plane)",
            column="heights",
            got=f"{relief:.3g} mm",
            hint=f"{breach}; quality.action: stop",
        )
    ]


def _x3p_extras(path: Path, full: bool) -> dict:
    """What :func:`skidsim.x3p.read_x3p` does not report: whether main.xml states a CZ increment, and (``full``)
    the stated and actual MD5 of valid.bin."""
    from ..x3p import MAIN_XML, strip_namespaces

    with zipfile.ZipFile(path) as zf:
        root = ElementTree.fromstring(zf.read(MAIN_XML))
        strip_namespaces(root)
        cz_inc = root.find("Record1/Axes/CZ/Increment")
        out = {"cz_increment": None if cz_inc is None or not (cz_inc.text or "").strip() else cz_inc.text.strip()}
        link = root.find("Record3/DataLink")
        if full and link is not None:
            v_link, v_md5 = link.find("ValidPointsLink"), link.find("MD5ChecksumValidPoints")
            if v_link is not None and v_md5 is not None and (v_md5.text or "").strip():
                out["valid_md5"] = (v_md5.text.strip().lower(), hashlib.md5(zf.read(v_link.text.strip())).hexdigest())
    return out


def _one_line(exc: InputError) -> InputError:
    """``exc`` itself, or (a reader's message over several lines, e.g. SurfaceTopography's list of every reader it
    tried) the same error with only the first line of what was found."""
    if not (isinstance(exc.got, str) and "\n" in exc.got.strip()):
        return exc
    first = str(exc.got).strip().splitlines()[0].rstrip(": ") if exc.got is not None else None
    short = InputError(
        exc.file,
        exc.expected,
        row=exc.row,
        column=exc.column,
        got=None if first is None else f"{first} ... (first line of the reader's message)",
    )
    short.__cause__ = exc
    return short


def check_geometry(path, shape, dx_mm: float, dy_mm: float, req: Requirements) -> list[InputError]:
    """Spacing and extent of a scan against the strip, the texture band and the FE resolution."""
    out: list[InputError] = []
    rows, cols = shape
    length, width = (cols - 1) * dx_mm, (rows - 1) * dy_mm  # first to last point, as the reconstruction measures
    lo, hi = req.macro_mm
    max_spacing = min(lo / 2.0, req.resolution_mm)
    for name, d in (("dx", dx_mm), ("dy", dy_mm)):
        if not d <= max_spacing * (1 + 1e-9):
            out.append(
                InputError(
                    path,
                    f"a lateral spacing <= {max_spacing:g} mm (2 points per {lo:g} mm, the "
                    f"lower limit of texture.macro_mm, and no coarser than mesh.resolution_mm "
                    f"{req.resolution_mm:g} mm)",
                    column=f"{name}_mm",
                    got=f"{d:g} mm",
                )
            )
    x0 = req.strip_x0_mm if req.strip_x0_mm is not None else 0.0
    y0 = req.strip_y0_mm if req.strip_y0_mm is not None else 0.0
    if x0 + req.strip_length_mm > length * (1 + 1e-9) or x0 < 0:
        out.append(
            InputError(
                path,
                f"a scan length (x, first to last of {cols} points at {dx_mm:g} mm) holding the FE strip "
                f"(mesh.length_mm {req.strip_length_mm:g} mm from x0 {x0:g} mm)",
                column="extent_x",
                got=f"{length:g} mm",
            )
        )
    if y0 + req.strip_width_mm > width * (1 + 1e-9) or y0 < 0:
        out.append(
            InputError(
                path,
                f"a scan width (y, first to last of {rows} points at {dy_mm:g} mm) holding the FE strip "
                f"(mesh.width_mm {req.strip_width_mm:g} mm from y0 {y0:g} mm)",
                column="extent_y",
                got=f"{width:g} mm",
            )
        )
    if req.crop_y_mm is not None and req.crop_y_mm > width * (1 + 1e-9):
        out.append(
            InputError(
                path,
                f"a scan width of at least texture.crop_y_mm {req.crop_y_mm:g} mm",
                column="extent_y",
                got=f"{width:g} mm",
            )
        )
    if hi > length * (1 + 1e-9):
        out.append(
            InputError(
                path,
                f"a scan length of at least the upper limit of texture.macro_mm ({hi:g} mm)",
                column="extent_x",
                got=f"{length:g} mm",
            )
        )
    return out


def check_scan(path, req: Requirements = DEFAULT_REQUIREMENTS, level: str = "full") -> list[InputError]:
    """Problems of one scan file at ``level`` ``header`` or ``full`` (see the module docstring)."""
    from ..scans import read_scan
    from ..x3p import read_x3p_header

    path = Path(path)
    is_x3p = path.suffix.lower() == ".x3p"
    try:
        if is_x3p:
            hdr = read_x3p_header(path)
            extras = _x3p_extras(path, full=level == "full")
            if hdr.dtype in ("I", "L") and extras["cz_increment"] is None:
                return [
                    InputError(
                        path,
                        f"a CZ Increment (metres per code) for integer height codes (type {hdr.dtype})",
                        column="Record1/Axes/CZ/Increment",
                        got="missing",
                        hint="heights would read as raw codes in metres",
                    )
                ]
            problems = check_geometry(path, hdr.shape, hdr.dx_mm, hdr.dy_mm, req)
            if level != "full":
                return problems
            if "valid_md5" in extras and extras["valid_md5"][0] != extras["valid_md5"][1]:
                problems.append(
                    InputError(
                        path,
                        f"bindata/valid.bin with the MD5 stated in main.xml ({extras['valid_md5'][0]})",
                        column="Record3/DataLink/MD5ChecksumValidPoints",
                        got=extras["valid_md5"][1],
                        hint="corrupt valid-point mask",
                    )
                )
        else:
            problems = []
        surface = read_scan(path)  # decodes, checks MD5 of data.bin
    except InputError as exc:
        return [_one_line(exc)]
    except (zipfile.BadZipFile, ElementTree.ParseError, KeyError, OSError) as exc:
        return [InputError(path, "a readable scan file", got=f"{type(exc).__name__}: {exc}")]
    if not is_x3p:
        problems = check_geometry(path, surface.shape, surface.dx, surface.dy, req)
    h = surface.heights
    valid = np.isfinite(h)
    share = float(valid.mean()) if h.size else 0.0
    if share < req.min_valid_share:
        problems.append(
            InputError(
                path,
                f"at least {req.min_valid_share:.0%} valid points (ingest.min_valid_share)",
                column="heights",
                got=f"{share:.1%} valid",
            )
        )
    elif valid.any():
        span = float(h[valid].max() - h[valid].min())
        if span > req.max_height_span_mm:
            problems.append(
                InputError(
                    path,
                    f"valid heights spanning at most {req.max_height_span_mm:g} mm "
                    "(ingest.max_height_span_mm; more means a wrong unit or Z increment)",
                    column="heights",
                    got=f"{span:.4g} mm",
                )
            )
        else:
            problems += check_relief(path, surface, req)
    return problems
