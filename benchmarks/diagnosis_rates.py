"""Rates of the model criticism by effect kind and texture source (issue 33, item 4: "Rates, not anecdotes").

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/diagnosis_rates.py --seeds 0-19 --jobs 2 \
        [--generators default,chips,spectral] [--kinds none,section_column,...] [--n-permutations 4999] \
        [--n-boot 200] [--screen-only] [--beyond-size MU] [--out results/diagnosis_rates] [--cache DIR] [--designs N] \
        [--texture-share S] [--fdr Q] [--cluster-rho R] [--trace-from KMH] [--temperature-range LO,HI]
        [--table harness|workflow] [--friction-model piarc|rado|penn_state]

Campaigns: tests/diagnosis_rate_campaigns.py (36 sites, 12 sections; the FE replaced by a per-site calibration of
the exponential-decay law, the texture model by a physics2@dft-like least squares on log MPD and log micro Sq; the
texture of chips and spectral from the generators' own surfaces, cached per design in ``--cache``: the harness's 27
columns, or with ``--table workflow`` every column of the workflow's texture table, about 120; the DFT traces
from ``--trace-from``, 20 km/h by default, up to 80 km/h; the sections' temperatures in ``--temperature-range``,
18-22 deg C by default; ``--friction-model``: the chips and spectral campaigns' friction-speed model in place of
the generator's own, PIARC/IFI for chips and Rado for spectral, with the same random draws). Per generator
x kind x seed the whole diagnosis (:func:`skidsim.criticism.diagnose`, ``DiagnosisOptions(seed=seed, n_boot=...,
n_permutations=...)``) sees only the campaign tables; the truth is used only to score:

* ``named_top``: the named cause (first, significant) is the hidden variable or holds it in its group; for
  ``texture_speed`` also the texture model (a texture-model candidate, ``texture_model[...]``); for
  ``texture_measure`` (the driving measure is not in the table) the texture model or a texture parameter
  (``source`` in texture / texture_model); for ``drainage`` (profile_MPD) the MPD column at either level, a
  texture cluster holding it, or a texture-model member in MPD (``texture_model[... log(profile_MPD) ...]``: the
  texture model's form in MPD, which the IFI speed constant sets). For ``none`` the column is empty, except on the
  robustness sources
  ``<generator>+sectionlatent`` (the generator's random section factors kept: a hidden section-level effect that
  nothing in the tables carries), where the right answer is ``section (unexplained)`` and the false-naming columns
  are empty. The plain ``chips`` / ``spectral`` sources hide one effect per campaign (no section factors);
* ``false_category``: the named cause's ``category`` (:attr:`skidsim.criticism.Cause.category`) is not ``texture
  model`` (a texture parameter between sites is reported as the texture model's misfit in that measure, the MPD
  column x speed between sites as the IFI speed constant it misses); ``false_model``: nor ``friction law``
  (``skidsim.criticism.causes.MODEL_CATEGORIES``; the within-site functional form where the measured curves are
  not exponential decays: the exponential-decay law's form, a cause in the model as the texture model is);
  ``false_named``: the named cause is not a texture-model candidate (``texture_model[...]``); ``false_any``: some
  significant cause other than a texture-model candidate (any rank); ``false_nontexture``: the named cause is
  neither the texture model nor a texture parameter (within sites too); ``section_unexplained``: the named cause
  is section identity labelled ``section (unexplained)``;
* ``gain_established``: where named, the gain interval at held-out sites excludes 0 (``gain.json``'s
  held_out_sites scope; a within-site cause's scope is held-out speeds, recorded in ``gain_scope``);
* the physical extension (whole diagnosis only, :func:`physical_record`): the chosen ``extension``, the RMSE gains
  of the physical one and of the generic term in the cause's scope, and for TemperatureShift its ``t_ref_c`` (deg C,
  all sites; where the curves are not exponential also ``t_ref_c_stretched``, read with their own stretched form)
  and whether gain.json calls it identified and pinned within 5 deg C, and the verdict of
  ``curve_shape`` on the measured curves (issue 33, item 3; the rate campaigns' WLF truth is t_ref 20 deg C, C1
  8.86, C2 101.6 K).

Prints a markdown table (per generator x kind: the median effect size, sd over sites of the effect's mean over
20-70 km/h in mu, n seeds, named-top share, false naming share for none, gain
established share among named) and writes ``<out>/rates.csv`` (one row per campaign), ``<out>/table.md`` and
``<out>/rates.png`` (the right answers and the gains as heatmaps, ``skidsim.plotting.diagnosis.plot_naming_rates``;
``--figure-only CSV ...`` draws it from stored tables, e.g. a ``--screen-only`` run and a whole-diagnosis run).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pandas as pd

from skidsim.generators.friction_models import MODELS as FRICTION_MODELS

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from diagnosis_rate_campaigns import (  # noqa: E402 (tests/ on the path first)
    KINDS,
    N_DESIGNS,
    SECTION_LATENT,
    TABLES,
    design_of,
    generator_of,
)


def seed_range(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def is_texture_model(c) -> bool:
    return getattr(c, "source", "") == "texture_model" or str(c.variable).startswith("texture_model[")


def is_texture(c) -> bool:
    return getattr(c, "source", "") in ("texture", "texture_model") or is_texture_model(c)


def is_section_unexplained(c) -> bool:
    return c is not None and "unexplained" in (getattr(c, "label", "") or "")


def hit(c, truth: dict) -> bool:
    """Whether the named cause ``c`` is the hidden variable (module docstring)."""
    if c is None:
        return False
    kind, hidden = truth["kind"], truth["variable"]
    if kind == "none" and truth["source"].endswith(SECTION_LATENT):
        return is_section_unexplained(c)  # the generator's random section factors are the hidden effect
    if kind == "texture_measure":
        return is_texture(c)
    if kind == "texture_speed" and is_texture_model(c):
        return True
    if kind == "drainage" and is_texture_model(c):  # the texture model's form in MPD: the IFI speed constant
        return hidden in str(c.variable)
    return hidden is not None and (c.variable == hidden or hidden in (c.group or ()))


def label(c) -> str:
    if c is None:
        return ""
    lab = getattr(c, "label", "") or ""
    name = lab if "unexplained" in lab else c.variable
    return f"{name} ({c.level}, {c.kind})"


def physical_record(gain: dict) -> dict:
    """What a whole diagnosis's gain.json says of the physical extension (issue 33, item 3): the extension chosen,
    the RMSE gains in the cause's own scope of TemperatureShift / DrainageIFI (``physical_gain``) and of the generic
    term (``generic_gain``; mu, NaN where not evaluated), and TemperatureShift's reference temperature fitted on all
    sites (``t_ref_c``, deg C; ``t_ref_c_stretched``: read with the curves' own stretched form where they are not
    exponential, gain.json ``stretched_reading``), whether it is identified and pinned within 5 deg C
    (``identifiability``) and
    whether the measured curves are exponential decays of speed (``curve_shape``), or DrainageIFI's kappa. Empty
    values where the named cause has no physical extension or nothing is named."""
    out = {
        "extension": gain.get("extension", ""),
        "physical_gain": float("nan"),
        "generic_gain": float("nan"),
        "t_ref_c": float("nan"),
        "t_ref_c_stretched": float("nan"),
        "t_ref_identifiable": None,
        "t_ref_pinned": None,
        "kappa": float("nan"),
        "curves_exponential": None,
        "stretch_exponent": float("nan"),
    }
    scope = gain.get("scope")
    for scopes in [gain.get("scopes")] + [a["scopes"] for a in gain.get("alternatives") or []]:
        own = (scopes or {}).get(scope) or {}
        if "rmse_gain" in own:  # the extension's own record (gain._ext_describe) says whether it is physical
            out["physical_gain" if own["extension"]["physical"] else "generic_gain"] = float(own["rmse_gain"])
    ident = gain.get("identifiability") or {}
    if ident.get("parameter") == "t_ref_c":
        out["t_ref_c"] = float(ident["t_ref_c_all_sites"])
        out["t_ref_identifiable"] = bool(ident["identifiable"])
        out["t_ref_pinned"] = bool(ident.get("t_ref_c_pinned"))
        stretched = ident.get("stretched_reading")
        if stretched:
            out["t_ref_c_stretched"] = float(stretched["t_ref_c"])
        shape = ident.get("curve_shape")
        if shape is not None:
            out["curves_exponential"] = bool(shape["exponential"])
            out["stretch_exponent"] = float(shape["stretch_exponent"])
    elif "kappa_all_sites" in ident:
        out["kappa"] = float(ident["kappa_all_sites"])
    return out


def run_one(args: tuple) -> dict:
    """One campaign: generate, diagnose, score."""
    import os

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from diagnosis_rate_campaigns import make_rate_campaign, rate_inputs, screen_rate_campaign

    from skidsim import criticism as cr
    from skidsim.criticism import DiagnosisOptions
    from skidsim.criticism.causes import MODEL_CATEGORIES

    source, kind, seed, n_perm, n_boot, cache, screen_only, beyond, n_designs, overrides, campaign = args
    t0 = time.perf_counter()
    t, truth = make_rate_campaign(source, kind, seed, cache_dir=cache, n_designs=n_designs, **campaign)
    if beyond is not None and kind != "none":  # rescale: the part beyond the texture model's terms has sd `beyond`
        size = beyond / truth["effect_sd_beyond_texture_model_mu"]
        t, truth = make_rate_campaign(source, kind, seed, cache_dir=cache, size=size, n_designs=n_designs, **campaign)
    opts = DiagnosisOptions(seed=seed, n_permutations=n_perm, n_boot=n_boot, **overrides)
    if screen_only:  # the screening of cr.diagnose, without the extension and its gain
        causes = screen_rate_campaign(t, opts)
        gain, top = {}, cr.named_cause(causes)
    else:
        r = cr.diagnose(rate_inputs(t), opts)
        causes, gain, top = r.causes, r.gain, r.named
    sig = [c for c in causes if c.significant]
    latent = source.endswith(SECTION_LATENT)
    scope = gain.get("scope")
    sites_scope = (gain.get("scopes") or {}).get("held_out_sites") or {}
    own = (gain.get("scopes") or {}).get(scope) or {}
    gain_sites = bool(sites_scope.get("gain_excludes_zero")) if (top is not None and gain) else None
    return {
        "generator": source,
        "kind": kind,
        "seed": seed,
        "design": design_of(seed, n_designs) if generator_of(source) != "default" else seed,
        "hidden": truth["variable"],
        "effect_sd_mu": truth["effect_sd_mu"],
        "effect_rms_mu": truth["effect_rms_mu"],
        "effect_sd_beyond_texture_model_mu": truth["effect_sd_beyond_texture_model_mu"],
        "size": truth["size"],
        "friction_model": truth["friction_model"],
        "named": label(top),
        "named_variable": top.variable if top is not None else "",
        "named_source": getattr(top, "source", "") if top is not None else "",
        "named_p_adjusted": top.p_adjusted if top is not None else float("nan"),
        "named_top": hit(top, truth) if (kind != "none" or latent) else None,
        "named_category": top.category if top is not None else "",
        "false_category": top is not None and top.category != "texture model" if not latent else None,
        "false_model": top is not None and top.category not in MODEL_CATEGORIES if not latent else None,
        "false_named": top is not None and not is_texture_model(top) if not latent else None,
        "false_any": any(not is_texture_model(c) for c in sig) if not latent else None,
        "false_nontexture": top is not None and not is_texture(top) if not latent else None,
        "texture_model_named": top is not None and is_texture_model(top),
        "section_unexplained": is_section_unexplained(top),
        "named_label": (getattr(top, "label", "") or "") if top is not None else "",
        "n_significant": len(sig),
        "gain_scope": scope if top is not None else "",
        "gain_established": gain_sites,
        "gain_established_own_scope": bool(own.get("gain_excludes_zero")) if (top is not None and gain) else None,
        "gain_sites_ci_low": (sites_scope.get("rmse_gain_ci") or [float("nan")])[0] if top is not None else None,
        **(physical_record(gain) if (top is not None and gain) else {}),
        "n_permutations": causes[0].n_permutations if causes else 0,
        "wall_s": time.perf_counter() - t0,
    }


def texture_of_design(job: tuple) -> None:
    """Compute (or find) the cached texture table of one (generator, design, cache) job."""
    import os

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from diagnosis_rate_campaigns import generator_texture

    generator_texture(*job)


def mapped(fn, items: list, jobs: int):
    """``fn`` over ``items`` in order: in ``jobs`` worker processes when ``jobs`` > 1, else in this one."""
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            yield from ex.map(fn, items)
    else:
        yield from map(fn, items)


def share(x) -> str:
    from skidsim.plotting.diagnosis import scored_bools

    x = scored_bools(x)
    return f"{sum(x)} / {len(x)}" if x else "-"


def table(df: pd.DataFrame) -> str:
    lines = [
        "| generator | kind | effect size (mu, median; beyond the texture model's terms) | seeds "
        "| hidden variable named top "
        "| null: named top other than the texture model, by category "
        "(texture-model candidates only; other than a texture cause; any significant other than a texture-model "
        "candidate) "
        "| gain at held-out sites established, where named | named instead (most often) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (g, k), d in df.groupby(["generator", "kind"], sort=False):
        if k == "none" and g.endswith(SECTION_LATENT):  # the section factors are the hidden effect
            named_top, false = share(d["named_top"]) + " (section (unexplained))", "-"
        elif k == "none":
            named_top = "-"
            false = (
                f"{share(d['false_category'])} ({share(d['false_named'])}; {share(d['false_nontexture'])}; "
                f"{share(d['false_any'])})"
            )
            tm = int(d["texture_model_named"].sum())
            if tm:
                false += f" (texture model named in {tm})"
            law = int((d["named_category"] == "friction law").sum())
            if law:
                false += f" (the friction law's form named in {law})"
            su = int(d["section_unexplained"].sum())
            if su:
                false += f" (section (unexplained) in {su})"
        else:
            named_top = share(d["named_top"])
            false = "-"
        named = d[d["named"] != ""]
        gain = share(named["gain_established"]) if len(named) else "-"
        miss = d[(d["named_top"] != True) & (d["named"] != "")]  # noqa: E712 (None for none)
        size = (
            f"{d['effect_sd_mu'].median():.3f} ({d['effect_sd_beyond_texture_model_mu'].median():.3f})"
            if k != "none"
            else "-"
        )
        other = miss["named"].value_counts()
        inst = "; ".join(f"{v} x{c}" for v, c in other.head(2).items())
        n_nothing = int((d["named"] == "").sum())
        if n_nothing and k != "none":
            inst = (inst + "; " if inst else "") + f"nothing x{n_nothing}"
        lines.append(f"| {g} | {k} | {size} | {len(d)} | {named_top} | {false} | {gain} | {inst} |")
    return "\n".join(lines)


def merge_rates(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """One row per (generator, kind, seed) from several rates.csv tables (e.g. ``--screen-only`` over every cell and
    the whole diagnosis over the cells with a gain): the first table's row, with ``gain_established`` from the
    first table that measured it. The named causes must agree (the screening is the diagnosis's first step)."""
    key = ["generator", "kind", "seed"]
    merged = tables[0].drop_duplicates(key).set_index(key)
    merged["gain_established"] = merged["gain_established"].astype(object)  # a screening's column is all NaN
    for t in tables[1:]:
        t = t.drop_duplicates(key).set_index(key)
        both = merged.index.intersection(t.index)
        differ = both[(merged.loc[both, "named"].fillna("") != t.loc[both, "named"].fillna("")).to_numpy()]
        if len(differ):
            raise SystemExit(f"merge_rates: the named causes differ in {len(differ)} campaigns, e.g. {differ[0]}")
        gain = t.loc[both, "gain_established"]
        fill = merged.loc[both, "gain_established"].isna() & gain.notna()
        merged.loc[both[fill.to_numpy()], "gain_established"] = gain[fill]
        merged = pd.concat([merged, t.loc[t.index.difference(merged.index)]])
    return merged.reset_index()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-19")
    ap.add_argument("--generators", default="default,chips,spectral")
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--n-permutations", type=int, default=None, help="default: auto (DiagnosisOptions)")
    ap.add_argument("--n-boot", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument(
        "--screen-only", action="store_true", help="the screening only (named causes; no extension, no gain)"
    )
    ap.add_argument(
        "--beyond-size",
        type=float,
        default=None,
        metavar="MU",
        help="scale each campaign's effect so that its part beyond the texture model's terms has this sd (mu)",
    )
    ap.add_argument("--out", default=str(ROOT / "results" / "diagnosis_rates"))
    ap.add_argument("--cache", default=str(ROOT / "results" / "diagnosis_rates" / "texture_cache"))
    ap.add_argument(
        "--designs",
        type=int,
        default=N_DESIGNS,
        help=f"texture designs of the chips and spectral sources, seed s using design s %% N (default {N_DESIGNS}); "
        "0: a design per seed",
    )
    ap.add_argument(
        "--texture-share",
        type=float,
        default=None,
        metavar="S",
        help="DiagnosisOptions.texture_share: the texture clusters' own share of fdr, taken from the secondary "
        "family's (default: DiagnosisOptions' own, under which they stay secondary units)",
    )
    ap.add_argument(
        "--table",
        choices=TABLES,
        default="harness",
        help="the chips and spectral texture tables: the harness's 27 columns (default) or every column of the "
        "workflow's texture table (about 120: tests/diagnosis_rate_campaigns.py::workflow_table_of_surface)",
    )
    ap.add_argument(
        "--cluster-rho",
        type=float,
        default=None,
        metavar="R",
        help="DiagnosisOptions.cluster_rho: |Spearman rho| of every pair of texture columns in one testing unit "
        "(default: DiagnosisOptions' own)",
    )
    ap.add_argument(
        "--fdr",
        type=float,
        default=None,
        metavar="Q",
        help="DiagnosisOptions.fdr: the false-discovery rate across candidate causes, which bounds the share of null "
        "campaigns with a false name (default: DiagnosisOptions' own)",
    )
    ap.add_argument(
        "--trace-from",
        type=float,
        default=20.0,
        metavar="KMH",
        help="the DFT trace's lowest speed in km/h (default 20: no point below the simulated speeds; e.g. 5 for a "
        "spin-down trace's low speeds, which the WLF shift of a temperature cause is read from)",
    )
    ap.add_argument(
        "--temperature-range",
        default=None,
        metavar="LO,HI",
        help="range of the sections' temperatures in deg C (default 18,22: tests/diagnosis_rate_campaigns.py)",
    )
    ap.add_argument(
        "--friction-model",
        default=None,
        choices=FRICTION_MODELS,
        help="the chips and spectral campaigns' friction-speed model (skidsim.generators.friction_models) in place of "
        "the generator's own (chips: piarc, spectral: rado); not for the default source, whose law is its own",
    )
    ap.add_argument(
        "--figure-only",
        nargs="+",
        default=None,
        metavar="CSV",
        help="run nothing: draw <out>/rates.png from these rates.csv files (merge_rates)",
    )
    a = ap.parse_args(argv)
    if a.figure_only:
        from skidsim.plotting.diagnosis import plot_naming_rates

        Path(a.out).mkdir(parents=True, exist_ok=True)
        print(plot_naming_rates(merge_rates([pd.read_csv(f) for f in a.figure_only]), Path(a.out) / "rates.png"))
        return
    seeds = seed_range(a.seeds)
    gens = [g for g in a.generators.split(",") if g]
    kinds = [k for k in a.kinds.split(",") if k]
    for k in kinds:
        if k not in KINDS:
            ap.error(f"--kinds: unknown {k!r}; expected some of {','.join(KINDS)}")
    if a.friction_model is not None and "default" in gens:
        ap.error("--friction-model: the default source has a law of its own; give --generators chips,spectral")
    if a.designs < 0:
        ap.error(f"--designs: expected 0 (a design per seed) or a positive count, got {a.designs}")
    t0 = time.perf_counter()
    designs = [  # the texture tables first (cached): the campaigns only read them
        (g, d, a.cache, None, a.table)
        for g in sorted({generator_of(g) for g in gens} - {"default"})
        for d in sorted({design_of(s, a.designs) for s in seeds})
    ]
    for _ in mapped(texture_of_design, designs, a.jobs):
        pass
    # DiagnosisOptions fields set on the command line; the others keep the dataclass's defaults (their one home)
    overrides = {
        f: v
        for f, v in (("texture_share", a.texture_share), ("fdr", a.fdr), ("cluster_rho", a.cluster_rho))
        if v is not None
    }
    campaign = {"trace_from_kmh": a.trace_from, "texture_table": a.table}
    if a.friction_model is not None:
        campaign["friction_model"] = a.friction_model
    if a.temperature_range is not None:
        lo, _, hi = a.temperature_range.partition(",")
        campaign["temperature_section_c"] = (float(lo), float(hi))
    jobs = [
        (g, k, s, a.n_permutations, a.n_boot, a.cache, a.screen_only, a.beyond_size, a.designs, overrides, campaign)
        for g in gens
        for k in kinds
        for s in seeds
    ]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)

    def record(r):  # one row per campaign, the CSV rewritten after each (an interrupted run keeps its rows)
        rows.append(r)
        pd.DataFrame(rows).to_csv(out / "rates.csv", index=False)
        print(
            f"{r['generator']} {r['kind']} seed {r['seed']}: {r['named'] or 'nothing'} "
            f"(hit {r['named_top']}, gain {r['gain_established']}, {r['wall_s']:.1f} s)",
            flush=True,
        )

    rows = []
    for r in mapped(run_one, jobs, a.jobs):
        record(r)
    df = pd.DataFrame(rows)
    md = table(df)
    (out / "table.md").write_text(md + "\n")
    print(md)
    from skidsim.plotting.diagnosis import plot_naming_rates

    plot_naming_rates(df, out / "rates.png")
    print(
        f"{len(df)} campaigns, wall {time.perf_counter() - t0:.0f} s, median {df['wall_s'].median():.1f} s per "
        f"campaign (one process), permutations {int(df['n_permutations'].median())}"
    )


if __name__ == "__main__":
    main()
