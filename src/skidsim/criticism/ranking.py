"""The ranking that names the top cause: the rules that make a column significant as an explanation, the order by
evidence, then the parsimony rules (refinement, the naming rule of a section effect, MPD x speed within sites above its
texture clusters, the functional form below a covariate x speed) (:func:`rank_causes`, :func:`named_cause`).
"""

from __future__ import annotations

import pandas as pd

from .causes import Cause
from .options import DiagnosisOptions
from .refinement import _descriptions_at_their_groupings, order_by_refinement, refinement_descriptions
from .section_naming import beyond_texture_explanations, columns_beyond_texture, section_explanations, section_rule

DRAINAGE_FOOTPRINT_SHARE = 0.5
"""The share of a between-site texture cluster's predictive evidence (``cv_msr``) that the MPD column's own
between-site term of the same kind must carry for a within-site MPD x speed (the drainage hypothesis) to rank
above that cluster (:func:`_mpd_above_its_clusters`): drainage's footprint between sites is a function of MPD (the
IFI speed constant Sp = 14.2 + 89.7 MPD), so where MPD is not the cluster's description the cluster is not that
footprint. Measured (docs/model-criticism-measured.md, section 4): 0.81-1.06 on the residual-level drainage and
squeeze campaigns, 0.52-1.20 on the drainage rate campaigns of the default and spectral sources, -0.44 to 0.63 on
the chips texture x speed campaigns with Rado's curves (one level cluster 0.91, below a speed-slope cluster at
0.38)."""


def _describes(causes: list[Cause], mpd_col: str, cluster: Cause) -> bool:
    """Whether the MPD column's own between-site term of the cluster's kind carries at least
    :data:`DRAINAGE_FOOTPRINT_SHARE` of the cluster cause's ``cv_msr`` (True where that term was not tested)."""
    own = [c for c in causes if c.variable == mpd_col and c.level == "between-site" and c.kind == cluster.kind]
    if not own or cluster.variable == mpd_col:
        return True
    return own[0].cv_msr >= DRAINAGE_FOOTPRINT_SHARE * cluster.cv_msr


def _mpd_above_its_clusters(causes: list[Cause], mpd_col: str | None) -> None:
    """A significant MPD x speed ranks above a texture-model candidate x speed built on MPD
    (``texture_model[nonlinear in <MPD>]``, x_speed: its cubic nests the linear column, and the linear column is the
    more specific name) and, within sites, above the texture clusters that hold MPD where MPD describes them between
    sites. Within sites MPD x speed is the drainage hypothesis, whose footprint the between-site clusters are
    (drainage makes the texture model misfit the level of shallow-texture sites: the macrotexture height cluster is
    significant between sites; MPD x speed names the mechanism); it moves above each such cluster whose predictive
    evidence (``cv_msr``) the MPD column's own between-site term of the same kind carries at least
    :data:`DRAINAGE_FOOTPRINT_SHARE` of, and not past one it does not (:func:`_describes`). The MPD column itself
    between sites (level or speed slope) is that footprint too, described by MPD by definition: the within-site test
    goes above it (on the drainage rate campaigns its DrainageIFI recovers the squeeze form's kappa within sites
    and gains at held-out speeds, while the between-site column's gain at held-out sites was established in none). A
    cluster that another member describes much better than MPD (the macro rms slope of a hysteresis that grows with
    speed, while the exponential-decay law's misfit of another speed shape varies with MPD within sites) is not
    drainage's footprint.
    Between sites MPD x speed is itself a misfit of the texture model (the IFI speed constant the texture model
    misses), one description among the clusters, which keep their order by predictive evidence: on texture x speed
    campaigns the cluster's level term carries several times its ``cv_msr`` and predicts held-out sites, the
    speed-shape term does not (docs/model-criticism.md, section 2). In place."""
    if mpd_col is None:
        return
    mp = [k for k, c in enumerate(causes) if c.significant and c.variable == mpd_col and c.kind == "x_speed"]
    mp.sort(key=lambda k: causes[k].level != "within-site")  # the drainage hypothesis first, then rank order
    if not mp:
        return
    within = causes[mp[0]].level == "within-site"

    def texture_model_on_mpd(c: Cause) -> bool:
        axes = (mpd_col, f"log({mpd_col})")
        return (
            c.source == "texture_model"
            and c.kind == "x_speed"
            and c.variable in {f"texture_model[nonlinear in {a}]" for a in axes}
        )

    def footprint_on_mpd(c: Cause) -> bool:  # the MPD column itself between sites, or a texture cluster holding it
        if within and c.variable == mpd_col and c.level == "between-site":
            return True
        return within and mpd_col in c.group and c.unit is not None and str(c.unit).startswith("cluster:")

    above, barrier = [], -1
    for k in range(mp[0]):
        c = causes[k]
        if c.significant and texture_model_on_mpd(c):
            above.append(k)
        elif c.significant and footprint_on_mpd(c):
            if _describes(causes, mpd_col, c):
                above.append(k)
            else:
                barrier = k  # not drainage's footprint: MPD x speed does not go past it
    mpd = causes.pop(mp[0])
    past = [k for k in above if k > barrier]
    at = past[0] if past else mp[0]
    causes.insert(at, mpd)
    # the texture model's cubic in MPD above the barrier goes right below the linear column it nests
    nested = [causes[k] for k in above if k < barrier]
    kept = [c for c in causes if not any(c is n for n in nested)]
    k = next(i for i, c in enumerate(kept) if c is mpd) + 1
    causes[:] = kept[:k] + nested + kept[k:]


def _shape_below_its_covariate(causes: list[Cause]) -> None:
    """Hierarchy of within-site shapes: where the functional form and a covariate x speed are both significant
    within sites, the shape's amplitude follows the covariate and the shared shape is its mean over the sites; the
    covariate names the mechanism (its model, shared profile + covariate x profile, nests the functional form's),
    so the functional form ranks right below the first such cause. In place."""
    ff = [k for k, c in enumerate(causes) if c.significant and c.kind == "functional_form" and c.level == "within-site"]
    xs = [k for k, c in enumerate(causes) if c.significant and c.kind == "x_speed" and c.level == "within-site"]
    if ff and xs and ff[0] < xs[0]:
        causes.insert(xs[0], causes.pop(ff[0]))


def _tie(x: float) -> float:
    """``x`` to 10 significant digits: an affine copy of a column (the texture stage's ETD = 1.1 MPD) gets the same
    statistics up to rounding in the last bits, which should not decide the order."""
    return float(f"{x:.10g}")


def _rank_key(c: Cause, mpd_col: str | None) -> tuple:
    """The ranking's sort key (:func:`rank_causes`): significant first, then cv_msr (significant) or p_adjusted,
    then z; on ties (to 10 digits) the MPD column first."""
    return (not c.significant, _tie(-c.cv_msr) if c.significant else c.p_adjusted, _tie(-c.z), c.variable != mpd_col)


def rank_causes(causes: list[Cause], cov: pd.DataFrame, mpd_col: str | None, fdr: float | None = None) -> list[Cause]:
    """Rules 3b, 3d and 3c of the naming rule of a section effect first (:func:`section_explanations`,
    :func:`beyond_texture_explanations`, :func:`refinement_descriptions`, at ``fdr``; None: the default of
    :class:`~skidsim.criticism.options.DiagnosisOptions`); then
    significant causes first, among them by ``cv_msr`` (predictive evidence), the rest by ``p_adjusted``, then
    ``z``, and on ties (to 10 significant digits) the MPD column ``mpd_col`` first (a texture table also holds its
    affine copies, e.g. ETD); then the parsimony rules: :func:`order_by_refinement`, the naming rule of a section effect
    (:func:`section_rule`), MPD x speed within sites above the texture clusters holding MPD
    (:func:`_mpd_above_its_clusters`), the within-site functional form below a significant within-site covariate x
    speed."""
    if fdr is None:
        fdr = DiagnosisOptions().fdr
    causes = section_explanations(causes, fdr)
    causes = beyond_texture_explanations(causes, fdr)
    causes = columns_beyond_texture(causes, fdr)
    causes = refinement_descriptions(causes, cov, fdr)
    causes = sorted(causes, key=lambda c: _rank_key(c, mpd_col))
    _descriptions_at_their_groupings(causes)
    causes = order_by_refinement(causes, cov)
    causes = section_rule(causes, fdr=fdr)
    _mpd_above_its_clusters(causes, mpd_col)
    _shape_below_its_covariate(causes)
    return causes


def named_cause(causes: list[Cause]) -> Cause | None:
    """The top significant cause, or None."""
    return causes[0] if causes and causes[0].significant else None
