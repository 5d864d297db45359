"""False-discovery rate of the model-criticism screening on null campaigns, and detection rates of hidden effects.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/diagnosis_null_rate.py --seeds 100-129 --trace-step 4
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/diagnosis_null_rate.py --effects --seeds 0-10 --trace-step 4

Campaigns come from tests/diagnosis_campaigns.py through a campaign directory (write_campaign / read_campaign, as
tests/test_diagnosis.py does); the screening sees only the campaign tables, the truth is used only to score.
Null mode prints, per seed, whether anything is named (and what: variable, level, kind, p, p_adjusted, cv_gain)
and the rate of seeds naming something. Effect mode prints, per effect and seed, the named cause and whether it
is the hidden variable (or its group), and the detection rate per effect. Screening seed = campaign seed minus
the first seed of the range (as the slow null test does); ``--trace-step 0``: no trace points (6 speeds per site).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from diagnosis_campaigns import read_campaign, write_campaign

from skidsim import criticism as cr


def seed_range(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def screen(tmp: Path, seed: int, effect, trace_step: float, screen_seed: int, **kw):
    d = tmp / f"c_{effect}_{seed}"
    truth = write_campaign(d, seed=seed, effect=effect, trace_step_kmh=trace_step)
    t = read_campaign(d)
    res = cr.build_residuals(t["sites"], t["measured"], t["simulated"], t["predicted"])
    causes = cr.screen_candidates(res, t["sites"], t["texture"], cr.DiagnosisOptions(seed=screen_seed, **kw))
    return causes, truth


def describe(c) -> str:
    return (
        f"{c.variable} ({c.level}, {c.kind}, {c.family}) p={c.p_value:.2g} p_adj={c.p_adjusted:.2g} "
        f"cv_gain={c.cv_gain:.3f}"
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-129", help="campaign seeds, e.g. 100-129 or 0-10,20")
    ap.add_argument("--trace-step", type=float, default=4.0, help="DFT trace step, km/h (0: no trace)")
    ap.add_argument(
        "--effects", action="store_true", help="hidden-effect mode (temperature, drainage, squeeze, wear, mix)"
    )
    ap.add_argument("--only", default="temperature,drainage,squeeze,wear,mix", help="effects for --effects")
    ap.add_argument("--n-permutations", type=int, default=None, help="default: auto")
    args = ap.parse_args(argv)
    seeds = seed_range(args.seeds)
    kw = {"n_permutations": args.n_permutations}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if not args.effects:
            named = 0
            for s in seeds:
                causes, _ = screen(tmp, s, None, args.trace_step, s - seeds[0], **kw)
                top = cr.named_cause(causes)
                named += top is not None
                sig = [c for c in causes if c.significant]
                print(
                    f"seed {s}: "
                    + ("nothing named" if top is None else f"NAMED {describe(top)}; {len(sig)} significant")
                    + f"; best p_adj {causes[0].p_adjusted:.2g} ({causes[0].variable}, {causes[0].level}, "
                    f"{causes[0].kind})",
                    flush=True,
                )
            print(
                f"null, trace step {args.trace_step:g} km/h: named something in {named} / {len(seeds)} seeds "
                f"({100.0 * named / len(seeds):.1f} %); wall {time.perf_counter() - t0:.0f} s"
            )
            return
        rates = {}
        for eff in args.only.split(","):
            hit = 0
            for s in seeds:
                causes, truth = screen(tmp, s, eff, args.trace_step, s, **kw)
                top = cr.named_cause(causes)
                ok = top is not None and (top.variable == truth["variable"] or truth["variable"] in top.group)
                hit += ok
                print(
                    f"{eff} seed {s}: {'HIT ' if ok else 'miss'} "
                    + ("nothing named" if top is None else describe(top)),
                    flush=True,
                )
            rates[eff] = hit
        for eff, hit in rates.items():
            print(f"{eff}: hidden variable named in {hit} / {len(seeds)} seeds (trace step {args.trace_step:g} km/h)")
        print(f"wall {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
