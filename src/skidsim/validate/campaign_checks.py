"""The checks of the configuration, of ``sites.csv`` and the DFT traces, and of a whole campaign (every scan,
in threads), gathered into one error."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..errors import CampaignError, DftError, InputError
from .requirements import DEFAULT_REQUIREMENTS, LEVELS, Requirements
from .scan_checks import check_scan


class ConfigProblem(InputError):
    """A configuration value that does not fit the others (file = the config, column = the key)."""


def _speeds_text(v) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"


def check_config(req: Requirements) -> list[InputError]:
    """Config cross-checks the schema cannot express: speed sets, band and strip sizes."""
    out: list[InputError] = []
    src = req.source
    for key, speeds in (("speeds.calibration_kmh", req.calibration_kmh), ("speeds.validation_kmh", req.validation_kmh)):
        if not speeds:
            out.append(ConfigProblem(src, "at least one speed in km/h", column=key, got="[]"))
            continue
        dup = sorted({v for v in speeds if list(speeds).count(v) > 1})
        if dup:
            out.append(
                ConfigProblem(
                    src,
                    "distinct speeds (a repeated speed is silently dropped)",
                    column=key,
                    got=_speeds_text(speeds),
                    hint=f"{_speeds_text(dup)} km/h repeated",
                )
            )
        bad = [v for v in speeds if not (math.isfinite(v) and v > 0)]
        if bad:
            out.append(ConfigProblem(src, "speeds > 0 km/h", column=key, got=_speeds_text(speeds)))
    both = sorted(set(req.calibration_kmh) & set(req.validation_kmh))
    if both:
        out.append(
            ConfigProblem(
                src,
                "validation speeds disjoint from calibration speeds (a speed used to calibrate cannot validate)",
                column="speeds.validation_kmh",
                got=_speeds_text(req.validation_kmh),
                hint=f"{_speeds_text(both)} km/h also in speeds.calibration_kmh {_speeds_text(req.calibration_kmh)}",
            )
        )
    lo, hi = req.macro_mm
    if not (0 < lo < hi):
        out.append(ConfigProblem(src, "0 < low < high (mm)", column="texture.macro_mm", got=[lo, hi]))
    if req.smooth_window_kmh is not None and not req.smooth_window_kmh > 0:
        out.append(
            ConfigProblem(
                src,
                "a positive window in km/h or null",
                column="ingest.dft_smooth_window_kmh",
                got=req.smooth_window_kmh,
            )
        )
    if req.crop_y_mm is not None and req.crop_y_mm < req.strip_width_mm:
        out.append(
            ConfigProblem(
                src,
                f"a texture band at least as wide as the FE strip (mesh.width_mm {req.strip_width_mm:g} mm)",
                column="texture.crop_y_mm",
                got=req.crop_y_mm,
            )
        )
    if not 0 <= req.min_valid_share <= 1:
        out.append(
            ConfigProblem(src, "a share between 0 and 1", column="ingest.min_valid_share", got=req.min_valid_share)
        )
    return out


# --------------------------------------------------------------------------------------------------- sites.csv


def check_table(
    directory, req: Requirements = DEFAULT_REQUIREMENTS, points: bool = True
) -> tuple[object, list[InputError]]:
    """``sites.csv``, the files it names and the DFT traces: ``(campaign or None, problems)``.

    Uses :func:`skidsim.campaign.load_campaign` for the table and the traces (each must cover every calibration
    and validation speed), and adds: paths inside the campaign directory, the mesh study's site and, with
    ``points``, DFT samples at 2 speeds within the smoothing window of each speed (levels header and full).
    """
    from ..campaign import SITES_FILE, load_campaign

    directory = Path(directory).expanduser().absolute()
    sites_csv = directory / SITES_FILE
    problems: list[InputError] = []
    camp = None
    try:
        camp = load_campaign(directory, speeds_kmh=req.speeds_kmh, check_scans=False, allow_outside=req.allow_outside)
    except CampaignError as err:
        problems.extend(getattr(err, "errors", None) or [err])
    if camp is not None:
        if points and req.smooth_window_kmh is not None:
            for site in camp.site_ids:
                tr = camp.traces[site]
                try:
                    tr.smooth_at(req.speeds_kmh, req.smooth_window_kmh)
                except DftError as exc:
                    problems.append(
                        CampaignError(
                            sites_csv,
                            "a DFT trace with samples near every speed",
                            row=camp.rows[site],
                            column="dft",
                            got=_rel(directory, tr.path),
                            hint=str(exc),
                        )
                    )
        if req.mesh_study_site is not None and req.mesh_study_site not in camp.site_ids:
            problems.append(
                ConfigProblem(
                    req.source, f"a site id of {sites_csv}", column="mesh_study.site", got=req.mesh_study_site
                )
            )
    return camp, problems


def _rel(directory: Path, path) -> str:
    try:
        return str(Path(path).relative_to(directory))
    except ValueError:
        return str(path)


# ---------------------------------------------------------------------------------------------------- campaign


def _as_row_problem(sites_csv: Path, row: int, raw: str, exc: InputError) -> CampaignError:
    """A scan problem on its ``sites.csv`` cell, keeping the scan file's own message."""
    err = CampaignError(sites_csv, "a usable scan", row=row, column="scan", got=raw, hint=str(exc))
    err.cause = exc
    return err


def _scan_rows(directory: Path, req: Requirements) -> list[tuple[int, str, Path]]:
    """``(row, scan as written, path)`` of every site row whose scan file exists (the table check names the rest)."""
    from ..campaign import inside, site_rows

    out = []
    for line, rec in site_rows(directory):
        raw = (rec.get("scan") or "").strip()
        if not raw or (not req.allow_outside and not inside(directory, raw)):
            continue
        p = Path(raw).expanduser()
        p = p if p.is_absolute() else directory / p
        if p.is_file():
            out.append((line, raw, p))
    return out


def problems(directory, req: Requirements = DEFAULT_REQUIREMENTS, level: str = "full", progress=None, workers: int = 1):
    """Every problem of a campaign at ``level``: ``(campaign or None, [InputError, ...])``.

    ``progress``: optional callable ``(n_done)`` after each scan. ``workers`` > 1 checks that many scans at a time
    in threads (decompression, MD5 and the array checks release the GIL); the problems come in row order either
    way.
    """
    if level not in LEVELS:
        raise ValueError(f"level must be one of {LEVELS}, got {level!r}")
    from ..campaign import SITES_FILE

    out = check_config(req)
    camp, table = check_table(directory, req, points=level != "table")
    out += table
    if level == "table":
        return camp, out
    directory = Path(directory).expanduser().absolute()
    sites_csv = directory / SITES_FILE
    rows = _scan_rows(directory, req)
    with ThreadPoolExecutor(max_workers=max(1, int(workers))) as pool:
        found = pool.map(lambda r: check_scan(r[2], req, level), rows)
        for checked, ((line, raw, _), scan_problems) in enumerate(zip(rows, found), start=1):
            out += [_as_row_problem(sites_csv, line, raw, exc) for exc in scan_problems]
            if progress is not None:
                progress(checked)
    return camp, out


def summary_error(directory, found: list[InputError]) -> InputError:
    """One error for ``found``: the problem itself when there is one, else a :class:`CampaignError` whose first
    line is the count and whose further lines (``"  - ..."``) are the problems (all in ``err.errors``)."""
    from ..campaign import SITES_FILE

    if len(found) == 1:  # one problem: its own message
        err = found[0]
        err.errors = list(found)
        return err
    sites_csv = Path(directory).expanduser().absolute() / SITES_FILE
    err = CampaignError(
        sites_csv,
        "a campaign without problems",
        got=f"{len(found)} problem(s)",
        hint="all listed below; fix them and run again",
    )
    err.args = (str(err) + "\n" + "\n".join(f"  - {e}" for e in found),)
    err.errors = list(found)
    return err


def check_campaign(
    directory, req: Requirements = DEFAULT_REQUIREMENTS, level: str = "full", progress=None, workers: int = 1
):
    """The validated :class:`~skidsim.campaign.Campaign`, or one error listing every problem (:func:`summary_error`).

    ``workers``: scans checked at a time (:func:`problems`)."""
    camp, found = problems(directory, req, level, progress, workers)
    if found or camp is None:
        raise summary_error(directory, found)
    return camp


def check_plan(config: dict, campaign_dir) -> list[InputError]:
    """What the workflow checks when it builds its plan: the config cross-checks and, for a user campaign
    (``campaign_dir`` not None), the ``table`` level. Returns the problems."""
    req = Requirements.from_config(config)
    if campaign_dir is None:
        return check_config(req)
    _, found = problems(campaign_dir, req, level="table")
    return found


def format_problems(found: list[InputError]) -> str:
    """The readable block printed by the workflow and the CLI: one line for one problem, else a head line with
    the count and one problem per line."""
    if len(found) == 1:
        return f"skidsim: error: {found[0]}"
    return "\n".join([f"skidsim: error: {len(found)} problems:"] + [f"  - {e}" for e in found])
