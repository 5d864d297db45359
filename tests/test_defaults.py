"""One home for every default: the frozen options dataclass of each stage.

``config/config.yaml`` (what the default run uses) and the ``default:`` entries of
``workflow/schemas/config.schema.yaml`` must give each option the value of its dataclass field default; every key of
a config section is a field of its dataclass and every field is a key of the section (or listed in
:data:`NOT_CONFIG_KEYS` with the reason). A drift fails naming the section, the key and the three values.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import re
from pathlib import Path

import pytest
import yaml

from skidsim.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "config.yaml"
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"

#: Config section (path of keys) -> the frozen dataclass holding its defaults (module, class).
SECTIONS = {
    "speeds": ("skidsim.validate", "SpeedOptions"),
    "ingest": ("skidsim.validate", "IngestOptions"),
    "texture": ("skidsim.texture", "TextureOptions"),
    "quality": ("skidsim.texture.quality", "QualityOptions"),
    "mesh": ("skidsim.reconstruct", "MeshOptions"),
    "solver": ("skidsim.solver.config", "SolverOptions"),
    "mesh_study": ("skidsim.solver.mesh_study", "MeshStudyOptions"),
    "calibration.study": ("skidsim.calibration.options", "StudyOptions"),
    "calibration.ours": ("skidsim.calibration.options", "JointOptions"),
    "calibration.identifiability": ("skidsim.calibration.options", "IdentifiabilityOptions"),
    "regression": ("skidsim.regression.options", "RegressionOptions"),
    "diagnosis": ("skidsim.criticism.options", "DiagnosisOptions"),
}

#: Config entries that are no stage's options, with the reason.
NOT_OPTIONS = {
    "campaign": "the input directory (null: the embedded synthetic campaign), not an option of a stage",
    "synthetic": "overrides of skidsim.generators.default.default_config(), whose defaults live there",
    "truth": "overrides of the synthetic campaign's truth model, whose defaults live in skidsim.generators.default",
    "calibration.methods": "which calibrations the workflow runs: a choice of targets, no library default",
}

#: Dataclass fields that are deliberately not config keys, with the reason.
NOT_CONFIG_KEYS = {
    "texture.workers": "scipy.fft threads inside one job: changes no number; the rule's thread count governs it",
}


def _load(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


def _node(tree: dict, section: str):
    for key in section.split("."):
        tree = (tree or {}).get(key)
    return tree


def _schema_properties(schema: dict, section: str) -> dict:
    node = schema
    for key in section.split("."):
        node = (node.get("properties") or {}).get(key) or {}
    return node.get("properties") or {}


def _options_class(section: str):
    module, name = SECTIONS[section]
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        pytest.fail(f"config section {section!r}: its options class {module}.{name} cannot be imported ({exc})")
    assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, f"{module}.{name} is not frozen"
    return cls


def _field_default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _plain(value):
    """Tuples as lists, recursively (YAML has only lists); numbers compare by value (20 == 20.0)."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _same(a, b) -> bool:
    a, b = _plain(a), _plain(b)
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, bool) != isinstance(b, bool):  # True == 1 in Python, not in the config
        return False
    return a == b


def _as_built(cls, name: str, value):
    """The field ``name`` of the options built from ``{name: value}`` by the class's own config reader."""
    reader = getattr(cls, "from_config", None) or getattr(cls, "from_dict", None)
    if reader is None:
        return value
    return getattr(reader({name: value}), name)


def test_every_config_entry_has_a_home():
    config = _load(CONFIG)
    homeless = []

    def walk(tree: dict, prefix: str):
        for key, value in tree.items():
            path = f"{prefix}{key}"
            if path in SECTIONS or path in NOT_OPTIONS:
                continue
            if isinstance(value, dict) and value:
                walk(value, path + ".")
            else:
                homeless.append(path)

    walk(config, "")
    assert not homeless, f"{CONFIG.name}: entries with no options dataclass (add them to SECTIONS): {homeless}"
    missing = sorted(s for s in [*SECTIONS, *NOT_OPTIONS] if _node(config, s) is None and s != "campaign")
    assert not missing, f"{CONFIG.name}: sections named in this test but not in the config: {missing}"


@pytest.mark.parametrize("section", list(SECTIONS))
def test_config_keys_are_the_fields(section):
    cls = _options_class(section)
    keys = set(_node(_load(CONFIG), section))
    fields = {f.name for f in dataclasses.fields(cls)}
    exempt = {k.rsplit(".", 1)[1] for k in NOT_CONFIG_KEYS if k.rsplit(".", 1)[0] == section}
    no_field = sorted(keys - fields)
    no_key = sorted(fields - keys - exempt)
    assert not no_field and not no_key, (
        f"{CONFIG.name} section {section!r} against {cls.__module__}.{cls.__name__}: "
        f"config keys without a field {no_field}; fields without a config key {no_key}"
    )


@pytest.mark.parametrize("section", list(SECTIONS))
def test_config_and_schema_defaults_are_the_dataclass_defaults(section):
    cls = _options_class(section)
    config = _node(_load(CONFIG), section)
    schema = _schema_properties(_load(SCHEMA), section)
    drifts = []
    for f in dataclasses.fields(cls):
        if f.name not in config:
            continue
        default = _field_default(f)
        in_config = config[f.name]
        in_schema = (schema.get(f.name) or {}).get("default", dataclasses.MISSING)
        if default is dataclasses.MISSING:
            drifts.append(f"{section}.{f.name}: the field has no default (config {in_config!r})")
            continue
        if not _same(in_config, default):
            in_config = _as_built(cls, f.name, in_config)  # a config form the class converts (start: a mapping)
        if not _same(in_config, default) or (in_schema is not dataclasses.MISSING and not _same(in_schema, default)):
            schema_text = "no default" if in_schema is dataclasses.MISSING else repr(in_schema)
            drifts.append(f"{section}.{f.name}: config {in_config!r}, {cls.__name__} {default!r}, schema {schema_text}")
    assert not drifts, "defaults drift (config.yaml / dataclass / schema):\n" + "\n".join(drifts)


def test_the_check_catches_a_drift():
    """The comparison the tests above rely on: tuples equal lists, 20 equals 20.0, a bool is not a number."""
    assert _same((20.0, 40.0), [20, 40]) and _same({"a": (1, 2)}, {"a": [1, 2]}) and _same(float("nan"), float("nan"))
    assert not _same(True, 1) and not _same(0.5, 0.05) and not _same([0.5, 50.0], [0.5, 5.0])
    assert not _same("nyquist", None)


def test_requirements_of_the_default_config_are_the_defaults():
    from skidsim.validate import Requirements

    req = Requirements.from_config(_load(CONFIG))
    assert req == Requirements()
    assert req.calibration_kmh == (20.0, 40.0, 60.0) and req.strip_length_mm == 114.3 and req.macro_mm == (0.5, 50.0)


@pytest.mark.parametrize(
    ("section", "bad", "message"),
    [
        ("speeds", {"calibration_kmh": [20, 40, 60], "typo_kmh": [10]}, "speeds: unknown key(s) ['typo_kmh']"),
        ("ingest", {"check_scans": "all"}, "ingest.check_scans: expected one of full, header, false, got 'all'"),
        ("mesh", {"gmsh_layers": 0}, "mesh.gmsh_layers: expected an integer >= 1, got 0"),
        ("mesh", {"smoothing": -1.0}, "mesh.smoothing: expected 'nyquist', null or a cutoff > 0 mm, got -1.0"),
        ("solver", {"preset": "fast"}, "solver.preset: expected one of campaign, reference, quick, got 'fast'"),
        ("mesh_study", {"speeds_kmh": []}, "mesh_study.speeds_kmh: expected at least one speed in km/h"),
    ],
)
def test_a_bad_value_names_the_section_key_and_value(section, bad, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        _options_class(section).from_dict(bad)
