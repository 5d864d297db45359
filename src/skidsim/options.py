"""Reading a config section into a stage's frozen options dataclass: the one check every stage shares.

Each section of ``config/config.yaml`` is one frozen dataclass (docs/architecture.md, "Settings"); its field names
are the section's keys. :func:`section_items` checks a section's keys against the fields and returns them as a
dict; :func:`options_from_dict` also builds the options (lists become tuples where the default is a tuple).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields

from .errors import ConfigError


def section_items(cls, section: Mapping | None, name: str) -> dict:
    """``section`` as a dict (None: empty) after checking that every key is a field of ``cls``; otherwise
    :class:`ConfigError` naming the section ``name``, the unknown keys and the known ones."""
    if section is None:
        return {}
    if not isinstance(section, Mapping):
        raise ConfigError(f"{name}: expected a mapping of settings, got {type(section).__name__} {section!r}")
    known = sorted(f.name for f in fields(cls))
    unknown = sorted(str(k) for k in section if k not in known)
    if unknown:
        raise ConfigError(f"{name}: unknown key(s) {unknown}; expected a subset of {known}")
    return dict(section)


def options_from_dict(cls, name: str, section: Mapping | None):
    """``cls(**section)`` after :func:`section_items` (missing keys keep the defaults; a list becomes a tuple where
    the field's default is a tuple)."""
    d = section_items(cls, section, name)
    defaults = {f.name: f.default for f in fields(cls)}
    for key, value in d.items():
        if isinstance(value, list) and isinstance(defaults[key], tuple):
            d[key] = tuple(value)
    return cls(**d)
