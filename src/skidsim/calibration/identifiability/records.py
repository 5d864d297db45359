"""The words and the table row of a site's record: the one-line statement (:func:`statement`) and the row of
``identifiability.csv`` (:func:`table_row`).
"""

from __future__ import annotations

from collections.abc import Mapping

from skidsim.calibration.identifiability.flags import FLAGS
from skidsim.calibration.options import PARAMS


def statement(have_sigma: bool, ident: list[str], ident_c: list[str], unc: dict) -> str:
    if not have_sigma:
        return "noise not estimable from the trace (too few points): uncertainty not computed"
    parts = []
    parts.append("identified parameters: " + (", ".join(ident) if ident else "none"))
    parts.append("identified curve combinations: " + (", ".join(ident_c) if ident_c else "none"))
    weak = [d for d in unc["directions"] if not d["identified"]]
    for d in weak:
        vec = d["vector_range_units"]
        parts.append(
            "not identified: the direction "
            + " ".join(f"{vec[p]:+.2f} {p}" for p in PARAMS)
            + f" (range units; 95 % half-width {d['halfwidth_range_fraction']:.2g} of the range)"
        )
    return "; ".join(parts)


def table_row(rec: Mapping) -> dict:
    """One flat row of the campaign table ``identifiability.csv`` from a record of :func:`assess`."""
    row = {
        "site": rec["site"],
        "method": rec["method"],
        "mu_s": rec["law"]["mu_s"],
        "mu_k": rec["law"]["mu_k"],
        "alpha_s_per_m": rec["law"]["alpha"],
        "converged": bool(rec["converged"]),
        "sigma": rec["noise"]["sigma"],
        "rho1": rec["noise"]["rho1"],
        "within_noise": bool(rec["within_noise"]),
        "flags": ";".join(rec["flags"]),
        "n_flags": len(rec["flags"]),
    }
    for f in FLAGS:
        row[f] = f in rec["flags"]
    row["at_bound_params"] = ";".join(f"{d['param']}:{d['bound']}" for d in rec["at_bound"])
    for k in (
        "rmse_fe_calibration",
        "rmse_fe_validation",
        "rmse_fe_calibration_sigma",
        "rmse_fe_validation_sigma",
        "rmse_best_law_wide",
        "bound_cost_rmse",
    ):
        row[k] = rec["fit"][k]
    row["fe_miss_verify_corrected_max"] = rec["fe_misses"]["verify_corrected_max"]
    row["fe_miss_small_step_max"] = rec["fe_misses"]["small_step_max"]
    row["fe_miss_per_step_median"] = rec["fe_misses"]["miss_per_step_median"]
    row["fe_miss_validation_max"] = rec["fe_misses"]["validation_max"]
    unc = rec["uncertainty"]
    for p in PARAMS:
        pr = unc.get("params", {}).get(p, {})
        row[f"{p}_se"] = pr.get("se", float("nan"))
        row[f"{p}_lower"] = pr.get("profile_lower", float("nan"))
        row[f"{p}_upper"] = pr.get("profile_upper", float("nan"))
        row[f"{p}_open"] = ("lower" if pr.get("lower_open") else "") + ("upper" if pr.get("upper_open") else "")
        row[f"{p}_identified"] = bool(pr.get("identified", False))
    for c in ("level", "slope", "curvature"):
        cr = unc.get("combinations", {}).get(c, {})
        row[f"{c}_value"] = cr.get("value", float("nan"))
        row[f"{c}_halfwidth"] = cr.get("halfwidth", float("nan"))
    dirs = unc.get("directions") or []
    row["n_identified_directions"] = sum(bool(d["identified"]) for d in dirs)
    if dirs:
        w = dirs[0]["vector_range_units"]
        row["weakest_direction"] = " ".join(f"{w[p]:+.2f}{p}" for p in PARAMS)
        row["weakest_halfwidth_range_fraction"] = dirs[0]["halfwidth_range_fraction"]
    else:
        row["weakest_direction"] = ""
        row["weakest_halfwidth_range_fraction"] = float("nan")
    row["identified_params"] = ";".join(rec["identified_params"])
    row["identified_combinations"] = ";".join(rec["identified_combinations"])
    return row
