"""The campaign directory: ``sites.csv`` plus the scan and DFT files it names (see ``docs/data-contract.md``).

``sites.csv`` has one row per measurement site and at least the columns :data:`REQUIRED_COLUMNS`:

* ``site``: unique id, ``^[A-Za-z0-9][A-Za-z0-9_.-]*$`` (used in file names and as a Snakemake wildcard);
* ``section``: the pavement section the site belongs to (non-empty; grouping for cross-validation);
* ``scan``: path of the texture scan (``.x3p``, ``.csv``, ``.txt``, ``.xyz`` or a SurfaceTopography format),
  relative to the campaign directory or absolute;
* ``dft``: path of the DFT trace CSV (columns ``speed_kmh``, ``mu``), relative or absolute;
* ``temperature_c``: pavement (or air) temperature during the test, degrees Celsius, a finite number in
  [-50, 80] (a guard against Fahrenheit or Kelvin entries).

Every further column is kept as site metadata (``Campaign.metadata_columns``, in file order); a metadata
column whose every non-empty value is numeric becomes float, others stay text. :func:`load_campaign` collects
**all** problems and raises one :class:`CampaignError` listing them (first line: the summary).
Row numbers are the line numbers of ``sites.csv`` (header = row 1).
"""

from __future__ import annotations

import csv
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from skidsim.dft import DftTrace, read_dft
from skidsim.errors import CampaignError, DftError, InputError
from skidsim.scans import check_scan

REQUIRED_COLUMNS = ("site", "section", "scan", "dft", "temperature_c")
SITE_ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
DEFAULT_SPEEDS_KMH = (20, 30, 40, 50, 60, 70)
TEMPERATURE_RANGE_C = (-50.0, 80.0)
SITES_FILE = "sites.csv"


@dataclass(frozen=True, eq=False)
class Campaign:
    """A validated campaign.

    Attributes
    ----------
    directory: absolute campaign directory.
    sites: one row per site, every column of sites.csv in file order; ``scan`` and ``dft`` are absolute path
        strings, ``temperature_c`` float (degrees C), ``site``/``section`` str.
    metadata_columns: the columns beyond :data:`REQUIRED_COLUMNS`, in file order.
    speeds_kmh: the DFT speeds (km/h) every trace was checked to cover.
    traces: DFT trace per site id.
    rows: line of sites.csv (header = row 1) per site id, for messages.
    """

    directory: Path
    sites: pd.DataFrame
    metadata_columns: list[str]
    speeds_kmh: tuple[float, ...] = tuple(float(v) for v in DEFAULT_SPEEDS_KMH)
    traces: dict[str, DftTrace] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)

    @property
    def site_ids(self) -> list[str]:
        """Site ids in file order."""
        return list(self.sites["site"])

    def dft_points(self, speeds_kmh=None, smooth_window_kmh: float | None = None) -> pd.DataFrame:
        """Long table ``site, speed_kmh, mu``: each site's DFT mu at each speed (km/h), sites in file order.

        Linear interpolation (:meth:`DftTrace.at`) by default; with ``smooth_window_kmh`` the local linear
        regression :meth:`DftTrace.smooth_at` within +-that many km/h.
        """
        speeds = np.asarray(self.speeds_kmh if speeds_kmh is None else speeds_kmh, dtype=float)
        frames = []
        for site in self.site_ids:
            tr = self.traces[site] if site in self.traces else read_dft(self.sites.set_index("site").at[site, "dft"])
            mu = tr.at(speeds) if smooth_window_kmh is None else tr.smooth_at(speeds, smooth_window_kmh)
            frames.append(pd.DataFrame({"site": site, "speed_kmh": speeds, "mu": mu}))
        return pd.concat(frames, ignore_index=True)


def _collected(sites_csv: Path, errors: list[InputError]) -> CampaignError:
    err = CampaignError(
        sites_csv,
        "a campaign without problems",
        got=f"{len(errors)} problem(s)",
        hint="all listed below; fix them and load again",
    )
    err.args = (str(err) + "\n" + "\n".join(f"  - {e}" for e in errors),)
    err.errors = errors
    return err


def _resolve(directory: Path, text: str) -> Path:
    p = Path(text).expanduser()
    return (p if p.is_absolute() else directory / p).resolve()


def inside(directory: Path, text: str) -> bool:
    """True when the path ``text`` of ``sites.csv`` (relative or absolute) lies inside ``directory``.

    Lexical: ``..`` components are resolved, symbolic links are not followed (a link inside the campaign is the
    user's choice)."""
    p = Path(os.path.normpath(Path(directory) / Path(text).expanduser()))
    d = Path(os.path.normpath(directory))
    return p == d or d in p.parents


def _outside(directory: Path, text: str) -> bool:
    return not inside(directory, text)


def site_rows(directory) -> list[tuple[int, dict[str, str]]]:
    """The data rows of ``sites.csv`` as ``(line, {column: text})`` without any check (empty list when the file
    is missing or has no header); for checks that need the raw cells even when the table has problems."""
    path = Path(directory) / SITES_FILE
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        records = [(reader.line_num, row) for row in reader]
    if not records:
        return []
    header = [c.strip() for c in records[0][1]]
    return [
        (line, dict(zip(header, (f.strip() for f in fields))))
        for line, fields in records[1:]
        if any(f.strip() for f in fields)
    ]


def load_campaign(directory, speeds_kmh=DEFAULT_SPEEDS_KMH, check_scans="header", allow_outside=True) -> Campaign:
    """Read and validate a campaign directory; return a :class:`Campaign` or raise one :class:`CampaignError`.

    ``speeds_kmh``: DFT speeds (km/h) each trace must cover. ``check_scans``: ``"header"`` (or ``True``)
    checks each scan without decoding all heights (X3P: zip, main.xml checksum, header, data sizes),
    ``"full"`` reads each scan completely, ``False`` only checks that the file exists. ``allow_outside``: accept
    scan/DFT paths that leave the campaign directory (``../``, absolute paths elsewhere); with False each is a
    problem. :mod:`skidsim.validate` adds the checks of the analysis' needs (scan contents, config).

    The raised error's message starts with a one-line summary and lists every problem as
    ``<file>: row <n>, column '<col>': expected ..., got ...``; ``err.errors`` holds them as exceptions.
    """
    if check_scans is True:
        check_scans = "header"
    if check_scans not in ("header", "full", False):
        raise ValueError(f"check_scans must be 'header', 'full' or False, got {check_scans!r}")
    speeds = tuple(float(v) for v in np.atleast_1d(speeds_kmh))
    directory = Path(directory).expanduser().resolve()
    sites_csv = directory / SITES_FILE
    header, records = _read_header(sites_csv)
    col = {name: j for j, name in enumerate(header)}
    metadata_columns = [c for c in header if c not in REQUIRED_COLUMNS]
    errors: list[InputError] = []
    rows, line_of, seen = [], [], {}
    for line, fields in records[1:]:
        if not any(f.strip() for f in fields):
            continue
        if len(fields) != len(header):
            errors.append(
                CampaignError(
                    sites_csv, f"{len(header)} fields as in the header", row=line, got=f"{len(fields)} fields"
                )
            )
            continue
        rec = {name: fields[j].strip() for name, j in col.items()}
        raw = dict(rec)  # as written, for messages
        ok = _check_site_id(sites_csv, rec["site"], line, seen, errors)
        if not rec["section"]:
            errors.append(CampaignError(sites_csv, "a section name", row=line, column="section", got=""))
        rec["temperature_c"] = _temperature(sites_csv, rec["temperature_c"], line, errors)
        for kind in ("scan", "dft"):
            rec[kind] = _file_path(sites_csv, directory, kind, rec[kind], line, allow_outside, errors)
        rows.append((rec, ok, raw))
        line_of.append(line)
    if not rows and not errors:
        errors.append(CampaignError(sites_csv, "at least one site row after the header", row=2, got="no rows"))
    traces = _check_files(sites_csv, rows, line_of, speeds, check_scans, errors)
    if errors:
        raise _collected(sites_csv, errors)
    return Campaign(
        directory=directory,
        sites=_sites_frame([rec for rec, _, _ in rows], header, metadata_columns),
        metadata_columns=metadata_columns,
        speeds_kmh=speeds,
        traces=traces,
        rows={rec["site"]: line for (rec, _, _), line in zip(rows, line_of)},
    )


def _read_header(sites_csv: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """The header of ``sites.csv`` (stripped names) and every record as ``(line, fields)``; raises one
    :class:`CampaignError` listing every problem of the header."""
    if not sites_csv.is_file():
        raise CampaignError(sites_csv, f"a {SITES_FILE} file in the campaign directory", got="no such file")
    with open(sites_csv, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        records = [(reader.line_num, row) for row in reader]
    if not records:
        raise CampaignError(
            sites_csv, f"a header row with columns {', '.join(REQUIRED_COLUMNS)}", row=1, got="an empty file"
        )
    header = [c.strip() for c in records[0][1]]
    errors: list[InputError] = []
    for j, name in enumerate(header):
        if not name:
            errors.append(CampaignError(sites_csv, "a non-empty column name", row=1, column=f"#{j + 1}"))
        elif header.index(name) != j:
            errors.append(CampaignError(sites_csv, "unique column names", row=1, column=name, got="a duplicate"))
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        errors.append(
            CampaignError(
                sites_csv,
                f"required columns {', '.join(REQUIRED_COLUMNS)}",
                row=1,
                got=",".join(header),
                hint=f"missing {', '.join(missing)}",
            )
        )
    if errors:
        raise _collected(sites_csv, errors)
    return header, records


def _check_site_id(sites_csv: Path, site: str, line: int, seen: dict[str, int], errors: list) -> bool:
    """True for a valid site id not used before (case-insensitive; recorded in ``seen``), else a problem appended."""
    if not site:
        errors.append(CampaignError(sites_csv, "a site id", row=line, column="site", got=""))
        return False
    if not SITE_ID_PATTERN.match(site):
        errors.append(
            CampaignError(
                sites_csv,
                "a site id of letters, digits, '_', '.', '-' starting with a "
                "letter or digit (used in file names and workflow wildcards)",
                row=line,
                column="site",
                got=site,
            )
        )
        return False
    if site.lower() in seen:
        errors.append(
            CampaignError(
                sites_csv,
                "a unique site id (case-insensitive: ids become file names)",
                row=line,
                column="site",
                got=site,
                hint=f"already used in row {seen[site.lower()]}",
            )
        )
        return False
    seen[site.lower()] = line
    return True


def _temperature(sites_csv: Path, t: str, line: int, errors: list) -> float:
    """The ``temperature_c`` cell as a number (NaN when it is none; problems appended)."""
    try:
        tc = float(t)
    except ValueError:
        errors.append(CampaignError(sites_csv, "a number (degrees C)", row=line, column="temperature_c", got=t))
        return math.nan
    if not math.isfinite(tc):
        errors.append(CampaignError(sites_csv, "a finite number (degrees C)", row=line, column="temperature_c", got=t))
    elif not (TEMPERATURE_RANGE_C[0] <= tc <= TEMPERATURE_RANGE_C[1]):
        errors.append(
            CampaignError(
                sites_csv,
                f"a temperature between {TEMPERATURE_RANGE_C[0]:g} and {TEMPERATURE_RANGE_C[1]:g} degrees C",
                row=line,
                column="temperature_c",
                got=tc,
                hint="Fahrenheit or Kelvin?",
            )
        )
    return tc


def _file_path(sites_csv: Path, directory: Path, kind: str, text: str, line: int, allow_outside: bool, errors) -> str:
    """The resolved path of the ``scan`` or ``dft`` cell ``text`` ("" when empty; problems appended)."""
    if not text:
        errors.append(CampaignError(sites_csv, f"a path to the {kind} file", row=line, column=kind, got=""))
        return ""
    p = _resolve(directory, text)
    if not allow_outside and _outside(directory, text):
        errors.append(
            CampaignError(
                sites_csv,
                f"a {kind} path inside the campaign directory {directory} "
                "(config ingest.allow_outside_campaign: true, or skidsim validate "
                "--allow-outside, accepts others)",
                row=line,
                column=kind,
                got=text,
            )
        )
    elif not p.is_file():
        errors.append(
            CampaignError(sites_csv, f"an existing {kind} file", row=line, column=kind, got=text, hint=f"no file {p}")
        )
    return str(p)


def _check_files(sites_csv: Path, rows, line_of, speeds, check_scans, errors: list) -> dict[str, DftTrace]:
    """Each row's scan (at ``check_scans``) and DFT trace (read, covering ``speeds``); the traces of the rows with
    a valid site id by site (problems appended)."""
    traces: dict[str, DftTrace] = {}
    for (rec, ok, raw), line in zip(rows, line_of):
        scan, dft = Path(rec["scan"]) if rec["scan"] else None, Path(rec["dft"]) if rec["dft"] else None
        if scan is not None and check_scans and scan.is_file():
            try:
                check_scan(scan, level=check_scans)
            except InputError as exc:
                errors.append(
                    CampaignError(sites_csv, "a readable scan", row=line, column="scan", got=raw["scan"], hint=str(exc))
                )
        if dft is not None and dft.is_file():
            try:
                tr = read_dft(dft)
            except DftError as exc:
                errors.append(
                    CampaignError(sites_csv, "a valid DFT trace", row=line, column="dft", got=raw["dft"], hint=str(exc))
                )
                continue
            if not tr.covers(speeds):
                lo, hi = tr.range_kmh
                need = [v for v in speeds if not lo <= v <= hi]
                errors.append(
                    CampaignError(
                        sites_csv,
                        f"a DFT trace covering {min(speeds):g}-{max(speeds):g} km/h",
                        row=line,
                        column="dft",
                        got=raw["dft"],
                        hint=f"{dft} spans {lo:g}-{hi:g} km/h, missing {', '.join(f'{v:g}' for v in need)} km/h",
                    )
                )
                continue
            if ok:
                traces[rec["site"]] = tr
    return traces


def _sites_frame(records: list[dict], header: list[str], metadata_columns: list[str]) -> pd.DataFrame:
    """The site table: text columns as str, ``temperature_c`` float, a metadata column float when every non-empty
    cell is a number (empty cells NaN), else text."""
    sites = pd.DataFrame(records, columns=header)
    for c in ("site", "section", "scan", "dft"):
        sites[c] = sites[c].astype(object).astype(str)
    sites["temperature_c"] = sites["temperature_c"].astype(float)
    for c in metadata_columns:
        vals = sites[c].astype(str)
        nonempty = vals[vals != ""]
        num = pd.to_numeric(nonempty, errors="coerce")
        if len(nonempty) and not num.isna().any():
            sites[c] = pd.to_numeric(vals.where(vals != "", None), errors="coerce").astype(float)
        else:
            sites[c] = vals.astype(object)
    return sites
