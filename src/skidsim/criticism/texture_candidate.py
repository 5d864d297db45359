"""The texture model as a candidate cause (docs/model-criticism.md, section 2, "The texture model as a candidate
cause"), and the share of the section effect a candidate explains (the naming rule of
:func:`skidsim.criticism.causes.rank_causes`).

A between-site residual that clusters by section is either a property of the sections that the texture does not
carry (section identity, a section-level column such as the mix or the traffic), or a misfit of the texture
model: a form that is nonlinear in a texture measure the model uses linearly (friction against MPD), or texture
measures the model leaves out. Before the first is named, the second is tested: a small, fixed set of richer
texture models (*members*), each a 3-column design built from the texture alone,

* ``nonlinear in <axis>``: ``[z, z^2, z^3]`` of one texture axis ``z`` (standardised): the prediction model's own
  texture columns (as the regression used them, e.g. ``log(profile_MPD)``) and the MPD column (mm); a cubic in
  MPD also spans the IFI speed constant ``1/Sp``, ``Sp = 14.2 + 89.7 MPD`` km/h, over the campaign's range;
* ``texture PCs 1-3``: the three leading principal components of the texture table beyond the prediction
  model's columns (texture measures the model leaves out),

is tested against the between-site residual (site means, ``main``) by the same nested permutations as every
covariate. The members are one testing unit (primary family) tested by their max-statistic (all members have
3 columns, so their sums of squares share one scale): an exact permutation p-value of "no richer texture model
explains the residual", and the member with the largest statistic says which measure or which form.

Friction mu (dimensionless), MPD mm, speeds km/h.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .adjustment import basis, lead_design

#: Prefix of the variable name of a texture-model candidate (``texture_model[<member>]``).
TEXTURE_MODEL = "texture_model"
#: Columns of every member's design (one scale for the max-statistic).
MEMBER_DF = 3


@dataclass(frozen=True)
class TextureMember:
    """One richer texture model: its ``name`` (``nonlinear in <axis>`` or ``texture PCs 1-3``), the words a
    pavement engineer reads (``words``) and its design (n_sites, 3), each column standardised over the sites."""

    name: str
    words: str
    design: np.ndarray

    @property
    def variable(self) -> str:
        return f"{TEXTURE_MODEL}[{self.name}]"


def is_texture_model(variable: str) -> bool:
    """Whether a cause's variable is a texture-model candidate."""
    return str(variable).startswith(TEXTURE_MODEL + "[")


def _std(x: np.ndarray) -> np.ndarray | None:
    x = np.asarray(x, float)
    sd = x.std()
    return None if not np.isfinite(x).all() or sd <= 0 else (x - x.mean()) / sd


def _cubic(z: np.ndarray) -> np.ndarray:
    """``[z, z^2, z^3]`` of a standardised axis, each column standardised."""
    cols = [_std(z**p) for p in (1, 2, 3)]
    return np.column_stack([c if c is not None else np.zeros_like(z) for c in cols])


def texture_members(
    site_ids, cov: pd.DataFrame, mpd: str | None, scores: np.ndarray, lead: tuple = (), n_lead: int = 0
) -> list[TextureMember]:
    """The richer texture models of the sites ``site_ids`` (order kept).

    ``cov``: the candidate covariates (one row per site); ``mpd``: the MPD column (mm) or None; ``scores``: the
    texture model's score table of these sites (:func:`~skidsim.criticism.adjustment.texture_model_scores`: the
    prediction model's ``n_lead`` columns ``lead`` first, then texture PCs). Axes whose cubic design is almost
    the same as an earlier one's (|r| >= 0.95 of the linear columns) are dropped."""
    C = cov.loc[list(site_ids)]
    axes = []
    if lead:
        L = lead_design(C, lead)
        if L is not None:
            axes += [(str(t), L[:, j]) for j, t in enumerate(lead)]
    if mpd is not None and mpd in C.columns:
        z = _std(C[mpd].to_numpy(float))
        if z is not None:
            axes.append((mpd, z))
    members, kept = [], []
    for name, z in axes:
        if any(abs(float(np.corrcoef(z, k)[0, 1])) >= 0.95 for k in kept):
            continue
        kept.append(z)
        members.append(TextureMember(f"nonlinear in {name}", f"friction is a nonlinear function of {name}", _cubic(z)))
    pcs = np.asarray(scores, float)[:, n_lead:] if scores is not None else np.zeros((len(C), 0))
    if pcs.shape[1] >= MEMBER_DF:
        D = np.column_stack([_std(pcs[:, j]) for j in range(MEMBER_DF)])
        members.append(
            TextureMember(
                f"texture PCs 1-{MEMBER_DF}",
                "texture measures the prediction model leaves out (the leading texture principal components)",
                D,
            )
        )
    return members


def member_basis(member: TextureMember) -> np.ndarray:
    """Orthonormal basis of the centred design of a member (rank-deficient columns dropped)."""
    Z = member.design - member.design.mean(axis=0)
    q, r = np.linalg.qr(Z)
    keep = np.abs(np.diag(r)) > 1e-9 * max(1.0, np.abs(r).max())
    return q[:, keep]


# ----------------------------------------------------------------------------------------------------------------
# share of the section effect
# ----------------------------------------------------------------------------------------------------------------


def section_ss(Y: np.ndarray, sections: np.ndarray) -> float:
    """Between-section sum of squares of the column-centred ``Y`` (n_sites, S): ``sum_g n_g |mean_g Y|^2`` (mu^2)."""
    Yc = Y - Y.mean(axis=0)
    out = 0.0
    for g in np.unique(sections):
        m = Yc[sections == g].mean(axis=0)
        out += float((sections == g).sum()) * float(m @ m)
    return out


def section_share(Q: np.ndarray, Y: np.ndarray, sections: np.ndarray) -> float:
    """Share of the section effect of ``Y`` (n_sites, S) that a candidate with orthonormal centred basis ``Q``
    explains: ``1 - SS_sec((I - Q Q') Y) / SS_sec(Y)`` (NaN without a section effect). For a section-level column
    (its basis lies in the span of the section indicators) it is ``T_column / T_section``, the fraction of the
    between-section sum of squares the column carries; 1 for section identity itself."""
    ss = section_ss(Y, sections)
    if not ss > 0 or Q.shape[1] == 0:
        return float("nan") if not ss > 0 else 0.0
    R = Y - Q @ (Q.T @ Y)
    return float(min(max(1.0 - section_ss(R, sections) / ss, 0.0), 1.0))


def categorical_basis(values) -> np.ndarray:
    """Orthonormal basis of a categorical column (for the section share of section identity)."""
    return basis(pd.Series(np.asarray(values)), "categorical")


def texture_model_term(cause, residuals, sites, texture_wide, pcs, lead=(), roles=None, speed_bin_kmh: float = 10.0):
    """The :class:`~skidsim.criticism.extensions.TextureModelTerm` of a texture-model cause: the member's design
    over the between-site sites, rebuilt exactly as the screening built it (same score table ``pcs``, same
    prediction columns ``lead``, same MPD column). None when the cause is not a texture-model candidate."""
    from .covariates import CandidateRoles, candidate_set, scores_for
    from .extensions import TextureModelTerm
    from .residuals import level_matrix

    if cause is None or cause.source != "texture_model":
        return None
    roles = CandidateRoles() if roles is None else roles
    cands = candidate_set(sites, texture_wide, roles, 0.8)
    ids, _, _ = level_matrix(residuals, "between-site", speed_bin_kmh)
    scores = scores_for(ids, pcs, cands.covariates, cands.info)
    n_lead = int(pcs.attrs.get("n_lead", 0)) if pcs is not None and set(pcs.index) == set(ids) else 0
    members = texture_members(ids, cands.covariates, cands.mpd, scores, tuple(lead), n_lead)
    m = next((m for m in members if m.variable == cause.variable), None)
    if m is None:
        return None
    return TextureModelTerm(
        cause.variable, tuple(str(s) for s in ids), tuple(tuple(map(float, r)) for r in m.design), m.words
    )
