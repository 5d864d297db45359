"""Outputs of the model criticism: residuals.parquet, causes.json, gain.json and report.md, each written
atomically (:mod:`skidsim.atomic`). Friction mu (dimensionless), speeds km/h."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import write_parquet, write_text
from .calibration_groups import GROUPS
from .causes import BEYOND_TEXTURE, Cause, explains_section_effect, name_of_test, section_effect_label
from .levels import MIN_LEVEL_SITES


def json_safe(o):
    """``o`` with NumPy scalars as Python numbers and non-finite floats as None (JSON null)."""
    if isinstance(o, dict):
        return {str(k): json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [json_safe(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def _fmt_ci(d, key):
    lo, hi = d[key + "_ci"]
    return f"{d[key]:.4f} [{lo:.4f}, {hi:.4f}]"


def _interval(iv, fmt: str = ".1f") -> str:
    """``[lo, hi]`` in the format ``fmt`` (one decimal), or ``n/a`` (missing or not finite)."""
    if not iv or not all(np.isfinite(x) for x in iv):
        return "n/a"
    return f"[{iv[0]:{fmt}}, {iv[1]:{fmt}}]"


def _fmt_group(group, n_show: int = 6) -> str:
    """A correlated group for report.md: up to ``n_show`` names and the count of the rest (causes.json has all)."""
    g = list(group)
    if len(g) <= 1:
        return ""
    return ", ".join(g[:n_show]) + (f" (+{len(g) - n_show} more)" if len(g) > n_show else "")


def _conditioned_on(top: dict, gain: dict) -> str:
    """What a texture-adjusted test conditioned on: the prediction model's columns (when the texture model chose
    them) and the number of texture principal components."""
    tm = gain.get("texture_model") or {}
    k = int(top["texture_pcs"])
    if tm.get("lead_chosen"):
        lead = tm.get("lead", [])
        return (
            f"conditional on {', '.join(lead)} (the columns of {tm.get('prediction_model')}) and "
            f"{k - len(lead)} texture principal components"
        )
    return f"conditional on {k} texture principal components"


def _texture_model_lines(gain: dict) -> list[str]:
    """One line on the texture model the between-site tests condition on and how it predicts unseen sections."""
    tm = gain.get("texture_model") or {}
    if tm.get("cv_r2_pcs") is None:
        return []
    fmt = lambda x: "n/a" if x is None else f"{x:.3f}"  # noqa: E731
    chosen = (
        f"{', '.join(tm['lead'])} (the columns of {tm.get('prediction_model')}) + {tm.get('pcs_with_lead')} PCs"
        if tm.get("lead_chosen")
        else f"{tm.get('pcs')} texture PCs"
    )
    return [
        f"Texture model of the between-site tests: {chosen}. Leave-one-section-out R^2 of the measured curves: "
        f"mean per speed {fmt(tm.get('cv_r2_mean_per_bin'))}, PCs {fmt(tm.get('cv_r2_pcs'))}, with the prediction "
        f"model's columns {fmt(tm.get('cv_r2_lead'))}.",
        "",
    ]


def _named_lines(top: dict | None, gain: dict) -> list[str]:
    """The report's opening: the named cause, its extension and (DrainageIFI) the curve forms chosen per fold."""
    if top is None:
        return [
            "**No cause named**: no candidate is significant after false-discovery control "
            "(and with positive cross-validated gain).",
            "",
        ]
    grp = _fmt_group(top["group"]) or "-"
    label = f" = {top['label']}" if top.get("label") else ""
    lines = [
        f"**Named cause: `{top['variable']}`{label}** ({top['level']}, {top['kind']}"
        + (f"; a cause of the kind *{top['category']}*" if top.get("category") else "")
        + f"); correlated group: {grp}; "
        f"effect {top['effect']:.4f} mu, cv gain {top['cv_gain']:.3f}, p = {top['p_value']:.2g}, "
        f"p_adj = {top['p_adjusted']:.2g}"
        + (f"; tested beyond the texture ({_conditioned_on(top, gain)})" if top.get("texture_pcs", -1) >= 0 else "")
        + ".",
        "",
    ]
    if top.get("explains") and not explains_section_effect(top["explains"]):
        lines += [
            f"Named as the coarser description of the significant grouping `{top['explains']}` (rule 3c of the "
            f"naming rule): that grouping splits `{top['variable']}`'s levels further only where the split cannot be "
            "established at any data (an exact permutation test within its levels cannot reach p <= fdr: it sets "
            f"apart a section or two, as section identity would); `{top['variable']}` carries "
            f"{top['section_share']:.0%} of the section effect, and its own permutation test over the sections has "
            f"p = {top['p_value']:.2g} "
            "(p_adj above fdr over the section-level columns).",
            "",
        ]
    elif str(top.get("explains", "")).endswith(BEYOND_TEXTURE):
        effect = str(top["explains"])[: -len(BEYOND_TEXTURE)]
        lines += [
            f"Named as the explanation of the significant `{effect}` effect (rule 3d of the naming rule): the "
            "measured curves hold a section effect beyond a quadratic texture model in the prediction model's terms, "
            f"and `{top['variable']}` carries {top['beyond_texture_share']:.0%} of it (exact permutation test over "
            f"the sections there p = {top['beyond_texture_p']:.2g}); of the residual's section effect, which also "
            f"holds the texture model's misfit, it carries {top['section_share']:.0%} (its own test p = "
            f"{top['p_value']:.2g}, p_adj {top['p_adjusted']:.2g}).",
            "",
        ]
    elif top.get("explains"):
        # between sites the rest is tested net of the column and the texture model's leading texture PCs
        rest_beyond = " and the texture model's leading texture PCs" if top.get("level") == "between-site" else ""
        lines += [
            f"Named as the explanation of the significant `{top['explains']}` effect (rule 3b of the naming rule): "
            f"it explains {top['section_share']:.0%} of it, its own permutation test over the sections has p = "
            f"{top['p_value']:.2g} (p_adj above fdr over the section-level columns), and no section effect is left "
            f"beyond it{rest_beyond} (p = {top['section_rest_p']:.2g}).",
            "",
        ]
    lines += [
        f"Extension applied: **{gain.get('extension')}**"
        + (f"; FE hook: {gain['fe_hook']['solver_flags']}" if gain.get("fe_hook") else "")
        + ".",
        "",
    ]
    ident = gain.get("identifiability")
    if ident and ident.get("extension") == "DrainageIFI":
        state = (
            f"identified (kappa {ident['kappa_all_sites']:.3g} over all sites, {ident['form_all_sites']} form; "
            f"MPD permuted over the sites: p {ident['perm_p']:.2g}; "
            f"95 % interval over the sections (jackknife) {_interval(ident.get('kappa_interval_95'), '.3g')})"
            if ident.get("identifiable")
            else f"not identifiable: {ident.get('why')}"
        )
        lines += [f"Drainage factor kappa of DrainageIFI: {state}.", ""]
    elif ident:
        state = (
            f"identified (T_r {ident['t_ref_c_all_sites']:.1f} deg C over all sites, permutation p "
            f"{ident['perm_p']:.2g}; median over folds {ident['t_ref_c_median']:.1f} deg C; 95 % interval over "
            f"the sections (jackknife) {_interval(ident.get('t_ref_c_interval_95'))} deg C"
            + (f"; {ident['t_ref_c_precision']}" if ident.get("t_ref_c_precision") else "")
            + ")"
            if ident.get("identifiable")
            else f"not identifiable: {ident.get('why')}"
        )
        lines += [f"WLF reference temperature of TemperatureShift from the measured curves: {state}.", ""]
    if gain.get("curve_form"):
        lines += [f"Form of the measured curves: {gain['curve_form']['reading']}.", ""]
        if gain["curve_form"].get("by_calibration"):
            lines += [f"Which sites carry the shape: {gain['curve_form']['by_calibration']['reading']}.", ""]
    own = gain.get("scopes", {}).get(gain.get("scope") or "", {})
    folds = own.get("extension", {}).get("params_per_fold", [])
    if folds and all("form" in f for f in folds):  # DrainageIFI form "auto": the curve form chosen per fold
        forms = sorted({f["form"] for f in folds})
        lines += [
            "Drainage curve form chosen on the training data, per fold: "
            + ", ".join(
                f"{fm} {sum(f['form'] == fm for f in folds)} of {len(folds)} (kappa median "
                f"{float(np.median([f['kappa'] for f in folds if f['form'] == fm])):.3g})"
                for fm in forms
            )
            + ".",
            "",
        ]
    return lines


def _share(c: dict, key: str) -> float:
    v = c.get(key)
    return float("nan") if v is None else float(v)


def _other_kind_lines(top: dict | None, clist: list[dict]) -> list[str]:
    """Rule 3e of the naming rule (:func:`skidsim.criticism.section_naming._column_beyond_texture`; a section effect
    whose ``explanation_rule`` is "3e" and ``explained_by`` the named cause's test): the named section-level column
    is also the explanation of the significant section effect of the other kind at its level, which its test of that
    kind (not significant on its own, less than half of the residual's section effect) carries beyond the texture
    model."""
    if top is None:
        return []
    name = name_of_test(top["variable"], top["level"], top["kind"])
    for S in clist:
        if not (S.get("section_id") and S.get("explanation_rule") == "3e" and S.get("explained_by") == name):
            continue
        tests = [
            x for x in clist if x["variable"] == top["variable"] and x["level"] == S["level"] and x["kind"] == S["kind"]
        ]
        tests = [t for t in tests if np.isfinite(_share(t, "beyond_texture_share"))]
        if not tests:
            continue
        x = max(tests, key=lambda t: _share(t, "beyond_texture_share"))
        return [
            f"`{top['variable']}` is also the explanation of the significant "
            f"`{section_effect_label(S['level'], S['kind'])}` effect (rule 3e of the naming rule): its test there "
            "carries "
            f"{_share(x, 'beyond_texture_share'):.0%} of that effect beyond the texture model (exact permutation "
            f"test over the sections p = {_share(x, 'beyond_texture_p'):.2g}) and {_share(x, 'section_share'):.0%} "
            "of the residual's section effect, which also holds the texture model's misfit.",
            "",
        ]
    return []


def _gain_lines(gain: dict) -> list[str]:
    """The table of held-out gains per scope and the reference comparisons below it."""
    lines = [
        "## Gain on held-out data (bootstrap over sites)",
        "",
        "| scope | sites | points | RMSE before | RMSE after | RMSE gain | R2 before | R2 after |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, d in gain.get("scopes", {}).items():
        lines.append(
            f"| {name} | {d['n_sites']} | {d['n_points']} | {_fmt_ci(d, 'rmse_before')} | "
            f"{_fmt_ci(d, 'rmse_after')} | {_fmt_ci(d, 'rmse_gain')} | {_fmt_ci(d, 'r2_before')} | "
            f"{_fmt_ci(d, 'r2_after')} |"
        )
    for name, d in gain.get("scopes", {}).items():
        o = d.get("over_shared_level")
        if o is not None and gain.get("extension"):
            lines += [
                "",
                f"{name}: against a campaign-wide level offset of the texture model alone (RMSE "
                f"{o['rmse_before']:.4f}), the extension's RMSE gain is {_fmt_ci(o, 'rmse_gain')} "
                "(what the named variable itself adds).",
            ]
        o = d.get("over_texture_refit")
        if o is not None and gain.get("extension"):
            lines += [
                "",
                f"{name}: against the same refit on the texture PCs without the named variable (RMSE "
                f"{o['rmse_before']:.4f}), the RMSE gain is {_fmt_ci(o, 'rmse_gain')}.",
            ]
    return lines


def _candidate_lines(clist: list[dict], top_n: int) -> list[str]:
    lines = [
        "",
        f"## Candidates (top {top_n} of {len(clist)}, ranked by evidence)",
        "",
        "Kind `main*` / `x_speed*`: tested beyond the texture (texture-adjusted test).",
        "",
        "| rank | variable | level | kind | effect (mu) | cv gain | p | p adj | significant | group |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in clist[:top_n]:
        kind = c["kind"] + ("*" if c.get("texture_pcs", -1) >= 0 else "")
        lines.append(
            f"| {c['rank']} | {c['variable']} | {c['level']} | {kind} | {c['effect']:.4f} | "
            f"{c['cv_gain']:.3f} | {c['p_value']:.2g} | {c['p_adjusted']:.2g} | {c['significant']} | "
            f"{_fmt_group(c['group'])} |"
        )
    return lines


def _figure_lines(figures: dict | None, out: Path) -> list[str]:
    if not figures:
        return []
    lines = ["", "## Figures", ""]
    for cap, fp in figures.items():
        lines += [f"![{cap}]({os.path.relpath(Path(fp), out)})", "", f"*{cap}*", ""]
    return lines


def _untested_lines(untested: dict | None) -> list[str]:
    if not untested:
        return []
    lines = ["", "## Columns not tested as causes (sites.csv, texture table)", ""]
    return lines + [f"* `{c}`: {why}" for c, why in untested.items()]


def _left_out_lines(left_out: dict | None, n_tested: int | None = None) -> list[str]:
    """The sites the within-site tests left out (``within_site_sites: settled``), per group, with why; with
    ``n_tested`` (gain.json ``within_site_sites_tested``) how many sites the within-site tests kept, and, below
    :data:`~skidsim.criticism.levels.MIN_LEVEL_SITES`, that the within-site level was not screened."""
    if not left_out:
        return []
    parts = [f"{len(v)} where {GROUPS[k]} ({', '.join(v)})" for k, v in left_out.items()]
    kept = "the" if n_tested is None else f"the {n_tested}"
    lines = [
        f"Within-site tests on {kept} sites the calibration settled inside its bounds; left out: "
        + "; ".join(parts)
        + " (results/calibration/identifiability.csv says why, site by site)."
    ]
    if n_tested is not None and n_tested < MIN_LEVEL_SITES:
        lines[0] += (
            f" **The within-site level was not screened**: it needs at least {MIN_LEVEL_SITES} sites; no cause "
            "within sites (a speed shape the calibrated law misses at its own site) could be named."
        )
    return lines + [""]


def report_markdown(
    clist: list[dict], gain: dict, figures: dict | None, out: Path, top_n: int = 15, untested: dict | None = None
) -> str:
    """The text of report.md: named cause, gains, the top ``top_n`` candidates, the sites.csv columns not tested
    (``untested``: {column: why}), figures (paths relative to ``out``)."""
    top = clist[0] if clist and clist[0]["significant"] else None
    lines = ["# Model criticism", ""] + _named_lines(top, gain) + _other_kind_lines(top, clist)
    lines += _left_out_lines(gain.get("within_site_left_out"), gain.get("within_site_sites_tested"))
    lines += _gain_lines(gain) + _texture_model_lines(gain)
    lines += _candidate_lines(clist, top_n) + _untested_lines(untested)
    return "\n".join(lines + _figure_lines(figures, out)) + "\n"


def write_outputs(
    out_dir,
    residuals: pd.DataFrame,
    causes: list,
    gain: dict,
    figures: dict | None = None,
    *,
    top_n: int = 15,
    untested: dict | None = None,
) -> dict:
    """Write residuals.parquet, causes.json, gain.json and report.md to ``out_dir`` (each atomically).

    ``figures``: {caption: path of an existing PNG}; embedded in report.md with paths relative to ``out_dir``.
    ``untested``: the sites.csv columns not tested as causes, {column: why}
    (:func:`skidsim.criticism.covariates.untested_columns`), listed in report.md. Returns {name: path}."""
    out = Path(out_dir)
    clist = [c.as_dict() if isinstance(c, Cause) else dict(c) for c in causes]
    for rank, c in enumerate(clist, 1):
        c["rank"] = rank
    paths = {
        "residuals": write_parquet(out / "residuals.parquet", residuals),
        "causes": write_text(out / "causes.json", json.dumps(json_safe(clist), indent=2) + "\n"),
        "gain": write_text(out / "gain.json", json.dumps(json_safe(gain), indent=2) + "\n"),
    }
    paths["report"] = write_text(out / "report.md", report_markdown(clist, gain, figures, out, top_n, untested))
    return paths
