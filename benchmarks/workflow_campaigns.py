"""Issue 33, item 4: the named cause of hidden-effect campaigns through the whole workflow (scans, texture, the real
FE, calibration, regression, diagnosis), several seeds per kind.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/workflow_campaigns.py WORKDIR [--seeds 8,9] [--kinds KIND,...]

The campaigns are those of ``make test-campaigns`` (tests/test_diagnosis_workflow*.py), built by the same
functions, with only the seed changed (the tests use seed 7):

* ``none``: the default generator's truth (exponential-decay law of the texture), no effect; 16 sites (8 sections
  x 2), as the test. Right: nothing named.
* ``site_column``: friction falls with ``station_ft`` (-0.03 % per ft). Right: station_ft (or its group).
* ``section_column``: the three "WMA chemical" sections of ``mix`` are 0.05 lower; 24 sites. Right: mix.
* ``categorical_speed``: the three "WMA chemical" sections of ``mix`` lose low-speed friction only, 0.21 at
  20 km/h falling to nothing at 60 km/h (the truth's section effect with ``speed_shape: low_speed``; the size of
  the rate campaigns' categorical x speed effect: sd over the 36 sites of its mean over 20-70 km/h 0.036); 36
  sites. Right: mix (any kind).
* ``temperature``: seasons 5-35 deg C, the truth's WLF shift. Right: temperature_c.
* ``drainage``: the squeeze form of macrotexture drainage (size 0.3), a texture x speed effect within sites.
  Right: an MPD column x speed.
* ``texture_speed``: the spectral generator's hysteresis growing with speed and the macro rms slope (kappa 0.8),
  with decoy columns. Right: the texture model, or a texture parameter x speed.
* ``texture_measure``: the chips generator's level set by the contact-zone microtexture (kappa 2.0), with decoy
  columns. Right: the texture model or a texture parameter between sites (the rates' score; the test asks the
  texture model).
* ``texture_speed_chips`` (not in the default list): the hysteresis effect of ``texture_speed`` on the chips
  generator.
* ``texture_measure_alone`` (not in the default list): ``texture_measure`` without the generator's random section
  factors, so that the contact-zone microtexture is the campaign's one hidden effect (the issue's design; the
  section factors are a second, section-level effect that no column carries). Right: as ``texture_measure``.
* ``section_column_36`` (not in the default list): ``section_column`` with 3 sites per section (36 sites, the
  issue's and the rate campaigns' design) instead of the test's 2; the sd over the sites of the offset is 0.022 mu.
* ``section_column_rate_size`` (not in the default list): ``section_column_36`` with the offset -0.08, sd over the
  sites 0.035 mu, the size of the rate campaigns' section-level column effect (0.037 mu on the default source,
  docs/model-criticism-measured.md, "Rates by effect kind").
* ``none_chips``, ``none_spectral`` (not in the default list): the campaigns of ``texture_speed`` /
  ``texture_measure`` without a hidden effect (the generator's own friction model of the texture, its random site
  and section factors, the decoy columns). Right: nothing named, a cause of the category ``texture model`` (the
  generators' PIARC/IFI and Rado laws are not the texture model's form), ``friction law`` (Rado's curves are not
  the exponential-decay law's form) or ``section (unexplained)`` (the random section factors are a section effect
  no column carries).
* ``texture_only_chips``, ``texture_only_spectral`` (not in the default list): the same without the generator's
  random section factors: friction depends on the texture alone (and the random site factors), the issue's null.
  Right: nothing named or a cause of the category ``texture model``, ``texture parameter`` or ``drainage`` (the
  PIARC/IFI speed constant follows MPD: a texture x speed effect) or ``friction law`` (the within-site functional
  form on measured curves that are not exponential decays, Rado's: the exponential-decay law's form, a cause in
  the model); ``section (unexplained)`` or a sites.csv column is a false naming, and so is the within-site
  functional form on exponential curves (category ``functional form``).
* ``section_column_chips``, ``site_column_chips``, ``temperature_chips``, ``categorical_speed_chips`` and the same
  with ``_spectral`` (not in the default list): the rate campaigns' effects of a sites.csv column
  (tests/diagnosis_rate_campaigns.py: traffic polishing by ``cum_traffic_msa``, the station ``station_ft``, the WLF
  shift by ``temperature_c`` at 18-22 deg C, the low-speed loss of the ``limestone`` aggregate) hidden in the
  DFT traces of the generator's campaign (36 sites, its random section factors off, the decoy columns). Right:
  that column (for the station, also its group).

Every campaign runs in its own directory ``WORKDIR/<kind>-<seed>`` with 2 cores. Prints one markdown table (kind,
seed, named top cause, right or not, its p_adjusted, the gain of its extension established at held-out sites or
speeds) and writes ``WORKDIR/workflow_campaigns.csv``. Cost: about 3 min per campaign on 2 cores (2026-11-30).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

KINDS = (
    "none",
    "site_column",
    "section_column",
    "categorical_speed",
    "temperature",
    "drainage",
    "texture_speed",
    "texture_measure",
)
#: The rate campaigns' column effects hidden in a generator's campaign (below), as ``<kind>_<generator>``, and the
#: column each reads.
COLUMN_HIDDEN = {
    "section_column": "cum_traffic_msa",
    "site_column": "station_ft",
    "temperature": "temperature_c",
    "categorical_speed": "aggregate",
}
GENERATOR_COLUMN_KINDS = tuple(f"{k}_{g}" for g in ("chips", "spectral") for k in COLUMN_HIDDEN)
#: Not in the default list (module docstring).
EXTRA_KINDS = (
    "texture_speed_chips",
    "texture_measure_alone",
    "section_column_36",
    "section_column_rate_size",
    "none_chips",
    "none_spectral",
    "texture_only_chips",
    "texture_only_spectral",
) + GENERATOR_COLUMN_KINDS


def run_kind(kind: str, seed: int, workdir: Path) -> dict:
    """Run one campaign; return ``{"causes", "gain"}`` of its diagnosis."""
    from test_diagnosis_workflow import NO_EFFECTS, run_campaign
    from test_diagnosis_workflow_effects import LOW_SPEED_MIX, SEASONS
    from test_diagnosis_workflow_texture import run_texture_campaign

    workdir.mkdir(parents=True, exist_ok=True)
    if kind == "none":
        return run_campaign(
            workdir, seed=seed, effects=NO_EFFECTS, sections="[E1, E2, E3, E4, E5, E6, C1, C2]", sites_per_section=2
        )
    if kind == "site_column":
        eff = NO_EFFECTS.replace(
            "metadata: {enabled: false}", "metadata: {enabled: true, column: station_ft, size: -0.0003, reference: 0.0}"
        )
        return run_campaign(workdir, seed=seed, effects=eff)
    if kind in ("section_column", "section_column_36", "section_column_rate_size"):
        offset = -0.08 if kind == "section_column_rate_size" else -0.05
        eff = NO_EFFECTS + f"""    section: {{enabled: true, column: mix, offsets: {{"WMA chemical": {offset}}}}}\n"""
        return run_campaign(workdir, seed=seed, effects=eff, sites_per_section=2 if kind == "section_column" else 3)
    if kind == "categorical_speed":
        return run_campaign(workdir, seed=seed, effects=LOW_SPEED_MIX)
    if kind == "temperature":
        eff = NO_EFFECTS.replace("temperature: {enabled: false}", "temperature: {enabled: true}")
        return run_campaign(workdir, seed=seed, effects=eff, synthetic_extra=SEASONS)
    if kind == "drainage":
        eff = NO_EFFECTS.replace("drainage: {enabled: false}", "drainage: {enabled: true, form: squeeze, size: 0.3}")
        return run_campaign(workdir, seed=seed, effects=eff)
    if kind == "texture_speed":
        return run_texture_campaign(workdir, "spectral", "hysteresis", 0.8, seed=seed)
    if kind == "texture_measure":
        return run_texture_campaign(workdir, "chips", "contact_micro", 2.0, seed=seed)
    if kind == "texture_measure_alone":
        return run_texture_campaign(workdir, "chips", "contact_micro", 2.0, seed=seed, section_factors=False)
    if kind == "texture_speed_chips":
        return run_texture_campaign(workdir, "chips", "hysteresis", 0.8, seed=seed)
    if kind in ("none_chips", "none_spectral"):
        return run_texture_campaign(workdir, kind.removeprefix("none_"), None, 0.0, seed=seed)
    if kind in ("texture_only_chips", "texture_only_spectral"):
        return run_texture_campaign(workdir, kind.rsplit("_", 1)[1], None, 0.0, seed=seed, section_factors=False)
    if kind in GENERATOR_COLUMN_KINDS:
        column_kind, generator = kind.rsplit("_", 1)
        return run_texture_campaign(workdir, generator, None, 0.0, seed=seed, column_kind=column_kind)
    raise ValueError(f"unknown kind {kind!r}; expected one of {KINDS + EXTRA_KINDS}")


def is_right(kind: str, top: dict | None) -> bool:
    """Whether the named cause ``top`` (None: nothing named) is the hidden one (module docstring)."""
    from skidsim.criticism.causes import MODEL_CATEGORIES

    if kind == "none":
        return top is None
    if kind in ("none_chips", "none_spectral"):  # the generator's own friction model of the texture: the texture model
        return top is None or top.get("category") in (*MODEL_CATEGORIES, "section (unexplained)")
    if kind in ("texture_only_chips", "texture_only_spectral"):  # no section factors either: a cause in the model
        return top is None or top.get("category") in (*MODEL_CATEGORIES, "texture parameter", "drainage")
    if top is None:
        return False
    var, group = str(top["variable"]), list(top.get("group") or [])
    texture_model = top.get("source") == "texture_model" or var.startswith("texture_model[")
    if kind in GENERATOR_COLUMN_KINDS:
        hidden = COLUMN_HIDDEN[kind.rsplit("_", 1)[0]]
        return var == hidden or (hidden == "station_ft" and hidden in group)
    if kind == "site_column":
        return (var == "station_ft" or "station_ft" in group) and top["level"] == "between-site"
    if kind in ("section_column", "section_column_36", "section_column_rate_size", "categorical_speed"):
        return var == "mix"
    if kind == "temperature":
        return var == "temperature_c"
    if kind == "drainage":
        return "MPD" in var.upper() and top["kind"] == "x_speed"
    if kind in ("texture_speed", "texture_speed_chips"):
        return texture_model or (top.get("source") == "texture" and top["kind"] == "x_speed")
    if kind in ("texture_measure", "texture_measure_alone"):
        return (texture_model or top.get("source") == "texture") and top["level"] == "between-site"
    raise ValueError(kind)


def gain_established(gain: dict) -> bool | None:
    """Whether the 95 % interval of the named cause's gain, in the scope the extension was judged on, excludes 0."""
    scope = gain.get("scope")
    rec = (gain.get("scopes") or {}).get(scope) if scope else None
    return None if not rec else bool(rec.get("gain_excludes_zero"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir")
    ap.add_argument("--seeds", default="8,9")
    ap.add_argument("--kinds", default=",".join(KINDS))
    a = ap.parse_args()
    import pandas as pd

    root = Path(a.workdir)
    rows = []
    for seed in (int(s) for s in a.seeds.split(",")):  # every kind once before any kind twice
        for kind in a.kinds.split(","):
            t0 = time.perf_counter()
            try:
                out = run_kind(kind, seed, root / f"{kind}-{seed}")
            except Exception as exc:  # a failed run is a row, not the end of the benchmark
                rows.append({"kind": kind, "seed": seed, "named": f"run failed: {exc}"[:200], "right": False})
                print(rows[-1], flush=True)
                continue
            causes = out["causes"]
            top = causes[0] if causes and causes[0]["significant"] else None
            label = "" if top is None else (top.get("label") or "")
            named = "nothing" if top is None else f"{top['variable']} ({top['level']}, {top['kind']})"
            rows.append(
                {
                    "kind": kind,
                    "seed": seed,
                    "named": named + (f" [{label}]" if label.startswith("section") else ""),
                    "right": is_right(kind, top),
                    "p_adjusted": None if top is None else top["p_adjusted"],
                    "gain_established": None if top is None else gain_established(out["gain"]),
                    "extension": out["gain"].get("extension"),
                    "wall_s": round(time.perf_counter() - t0, 1),
                }
            )
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(root / "workflow_campaigns.csv", index=False)
    print(df.to_markdown(index=False))


if __name__ == "__main__":
    main()
