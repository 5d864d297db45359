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
    "predict": ("skidsim.prediction.options", "PredictOptions"),
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


# --- The command lines: every option that mirrors a library option takes the library's default ---------------------

BENCHMARKS = ROOT / "benchmarks"


def _library_options() -> dict[str, list[tuple[str, object]]]:
    """``{field name: [(owner, default), ...]}`` of every options class and generator config the command lines
    mirror (top-level keys of the generator configs)."""
    from skidsim.criticism.options import DiagnosisOptions
    from skidsim.generators import default as default_generator
    from skidsim.generators.campaign import COMMON
    from skidsim.solver.config import SolverConfig
    from skidsim.texture.mpd import MPDOptions

    classes = [SolverConfig, MPDOptions, DiagnosisOptions]
    classes += [_options_class(s) for s in SECTIONS]
    out: dict[str, list[tuple[str, object]]] = {}
    for cls in classes:
        for f in dataclasses.fields(cls):
            default = _field_default(f)
            if default is not dataclasses.MISSING:
                out.setdefault(f.name, []).append((cls.__name__, default))
    for owner, cfg in (("generators.COMMON", COMMON), ("generators.default", default_generator.default_config())):
        for key, value in cfg.items():
            if not isinstance(value, dict):
                out.setdefault(key, []).append((owner, value))
    return out


def _mirrors() -> dict[str, dict[str, object]]:
    """Options whose name is not the library field's, or whose field name has several library defaults: per
    command line, ``{dest: the library default}``. (Every other option named like a library field is compared with
    that field automatically.)"""
    from skidsim.criticism.fe_extension import DEFAULT_PRONY
    from skidsim.generators.campaign import COMMON
    from skidsim.reconstruct import MeshOptions
    from skidsim.solver.config import SolverConfig, SolverOptions
    from skidsim.solver.mesh_study import MeshStudyOptions
    from skidsim.texture import TextureOptions

    return {
        "skidsim texture": {"despeckle": TextureOptions().despeckle_method},
        "skidsim simulate": {
            "preset": SolverOptions().preset,
            "load_n": SolverConfig().load_n,
            "length_mm": MeshOptions().length_mm,
        },
        "skidsim synth": {"seed": None},  # None: each generator's own seed
        "bench_solver": {"slide_mm": SolverConfig().slide_length_mm},
        "mesh_study": {
            "sizes": list(MeshStudyOptions().sizes_mm),
            "speeds": list(MeshStudyOptions().speeds_kmh),
            "slide_mm": SolverConfig().slide_length_mm,
            "window_mm": SolverConfig().window_start_mm,
            "friction_models": [SolverConfig().friction_model],
        },
        "viscoelastic_shape": {
            "prony_g": list(DEFAULT_PRONY["prony_g"]),
            "prony_tau_s": list(DEFAULT_PRONY["prony_tau_s"]),
        },
        "independent_campaigns": {"seed": COMMON["seed"], "sites": COMMON["n_sites"]},
        "hidden_effect_capture": {"seed": COMMON["seed"], "sites": COMMON["n_sites"]},
    }


#: Options named like a library field that are the command's own choice, not a mirror of it, with the reason.
OWN_CHOICES = {
    ("bench_calibration", "seed"): "the seed of the benchmark's own draws of synthetic sites, no library option",
    ("fe_response_smoothness", "shape"): "small scans (300 x 600 points at 0.2 mm) keep one FE run to seconds",
    ("fe_response_smoothness", "spacing_mm"): "small scans (300 x 600 points at 0.2 mm), as --shape",
    ("hidden_effect_capture", "shape"): "small scans (300 x 600 points at 0.2 mm) keep the FE stage to minutes",
    ("hidden_effect_capture", "spacing_mm"): "small scans (300 x 600 points at 0.2 mm), as --shape",
    ("fe_response_smoothness", "speeds"): "the speeds the smoothness is probed at, no library option",
    ("prediction_across_campaigns", "shape"): "small scans (100 x 600 points at 0.2 mm) keep four campaigns cheap",
    ("prediction_across_campaigns", "spacing_mm"): "small scans (100 x 600 points at 0.2 mm), as --shape",
    ("prediction_across_campaigns", "model"): "a regression model's name, not the calibration's surrogate model",
    ("prediction_across_campaigns", "workers"): "worker processes of the benchmark, not scipy.fft threads",
    ("diagnosis_rates", "n_boot"): "fewer bootstrap draws per diagnosis keep campaigns x kinds x seeds affordable",
    ("bench_texture", "workers"): "the threads the benchmark times (the machine's 2 cores), a measured setting",
    ("bench_allocator", "sections"): "a small campaign (2 sections) keeps the side-by-side workflow runs to minutes",
    ("bench_allocator", "sites_per_section"): "a small campaign (2 sites per section), as --sections",
}


class _Parsed(Exception):
    def __init__(self, parser):
        self.parser = parser


def _benchmark_parsers(monkeypatch) -> dict[str, object]:
    """Each benchmark's parser, caught at its ``parse_args`` (nothing of the benchmark runs)."""
    import argparse
    import importlib.util
    import inspect

    def catch(self, *args, **kwargs):
        raise _Parsed(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", catch)
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    parsers = {}
    for path in sorted(BENCHMARKS.glob("*.py")):
        source = path.read_text(encoding="utf-8")
        if "argparse" not in source or not re.search(r"^def main\(", source, re.M):
            continue  # no command line (or one that runs on import): nothing to walk
        spec = importlib.util.spec_from_file_location(f"_bench_{path.stem}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        main = getattr(module, "main", None)
        if main is None:
            continue
        try:
            main([]) if inspect.signature(main).parameters else main()
        except _Parsed as caught:
            parsers[path.stem] = caught.parser
    return parsers


def _cli_parsers() -> dict[str, object]:
    import argparse

    from skidsim.cli import build_parser

    out = {}
    top = build_parser()
    for action in top._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[f"skidsim {name}"] = sub
    return out


def _drifts(parsers: dict[str, object]) -> tuple[list[str], int]:
    library = _library_options()
    mirrors = _mirrors()
    drifts, checked = [], 0
    for name, parser in sorted(parsers.items()):
        for action in parser._actions:
            dest = action.dest
            if dest in ("help",) or (name, dest) in OWN_CHOICES:
                continue
            if dest in mirrors.get(name, {}):
                expected = [("", mirrors[name][dest])]
            elif dest in library:
                expected = library[dest]
            else:
                continue
            checked += 1
            got = action.default
            if got is None:  # the command reads the library's default itself
                continue
            values = {repr(_plain(v)) for _, v in expected}
            if len(values) > 1:
                drifts.append(f"{name} --{dest}: several library defaults {expected}; name the one it mirrors")
            elif not _same(got, expected[0][1]):
                owner = expected[0][0] or "the library"
                drifts.append(f"{name} --{dest}: default {got!r}, {owner} has {expected[0][1]!r}")
    return drifts, checked


def test_benchmark_options_take_the_library_defaults(monkeypatch):
    parsers = _benchmark_parsers(monkeypatch)
    assert {"mesh_study", "bench_calibration", "independent_campaigns", "viscoelastic_shape"} <= set(parsers)
    drifts, checked = _drifts(parsers)
    assert checked >= 20
    assert drifts == [], "benchmark defaults that differ from the library's:\n" + "\n".join(drifts)


def test_cli_options_take_the_library_defaults():
    parsers = _cli_parsers()
    assert {"skidsim texture", "skidsim mpd", "skidsim simulate", "skidsim synth"} <= set(parsers)
    drifts, checked = _drifts(parsers)
    assert checked >= 10
    assert drifts == [], "skidsim defaults that differ from the library's:\n" + "\n".join(drifts)


def test_the_default_walk_catches_a_drift():
    import argparse

    p = argparse.ArgumentParser()
    p.add_argument("--friction-model", default="stick_limit")
    p.add_argument("--loss-factor", type=float, default=None)
    p.add_argument("--slide-mm", type=float, default=100.0)
    drifts, checked = _drifts({"mesh_study": p})
    assert checked == 3
    assert drifts == [
        "mesh_study --friction_model: default 'stick_limit', SolverConfig has 'penalty'",
        "mesh_study --slide_mm: default 100.0, the library has 114.3",
    ]


@pytest.mark.parametrize("generator", ["default", "chips"])
def test_synth_without_seed_uses_the_generators_own_seed(tmp_path, generator):
    import json

    from skidsim.cli import main
    from skidsim.generators import default as default_generator
    from skidsim.generators.campaign import COMMON

    out = tmp_path / "camp"
    args = ["synth", str(out), "--generator", generator, "--sites", "1", "--shape", "32", "64"]
    assert main([*args, "--spacing-mm", "0.2"]) == 0
    truth = json.loads(next((tmp_path / "camp-truth").glob("*.json")).read_text())
    seed = truth["seed"][0] if generator == "default" else truth["seed"]
    assert seed == (default_generator.default_config()["seed"] if generator == "default" else COMMON["seed"])
    assert seed in (20170117, 20261125)
