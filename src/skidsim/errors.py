"""Exceptions with messages that name the file, the field and what was expected."""

from __future__ import annotations

from pathlib import Path


class SkidsimError(Exception):
    """Base class of every error skidsim raises on purpose."""


class InputError(SkidsimError):
    """Bad user input: a file, a row, a column (field) and what was expected.

    The message reads ``<file>: row <row>, column '<column>': expected <expected>, got <got>``; the parts
    that do not apply are left out. The parts are kept as attributes for tests and tools.
    """

    def __init__(
        self,
        file: str | Path | None,
        expected: str,
        *,
        row: int | None = None,
        column: str | None = None,
        got: object = None,
        hint: str | None = None,
    ):
        self.file = None if file is None else str(file)
        self.row = row
        self.column = column
        self.expected = expected
        self.got = got
        parts = []
        where = []
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column '{column}'")
        head = self.file or "<input>"
        if where:
            head += ": " + ", ".join(where)
        parts.append(head)
        msg = f"expected {expected}"
        if got is not None:
            msg += f", got {got!r}"
        if hint:
            msg += f" ({hint})"
        super().__init__(f"{parts[0]}: {msg}")


class CampaignError(InputError):
    """Error in a campaign directory (sites.csv and the files it names)."""


class ScanFormatError(InputError):
    """A scan file that cannot be read: unknown format, bad checksum, truncated data, bad header."""


class DftError(InputError):
    """A DFT trace that cannot be used: bad header, non-numeric values, mu out of range, speeds not covered."""


class ConfigError(SkidsimError):
    """A configuration value that is inconsistent in a way the schema cannot express."""
