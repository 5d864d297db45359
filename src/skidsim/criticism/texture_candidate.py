"""The texture model as a candidate cause (docs/model-criticism.md, section 2, "The texture model as a candidate
cause"), and the share of the section effect a candidate explains (the naming rule of
:func:`skidsim.criticism.ranking.rank_causes`).

A between-site residual that clusters by section is either a property of the sections that the texture does not
carry (section identity, a section-level column such as the mix or the traffic), or a misfit of the texture
model: a form that is nonlinear in a texture measure the model uses linearly (friction against MPD), or texture
measures the model leaves out. Before the first is named, the second is tested: a small, fixed set of richer
texture models (*members*), each a design built from the texture alone (3 columns but for the wide member),

* ``nonlinear in <axis>``: ``[z, z^2, z^3]`` of one texture axis ``z`` (standardised): the prediction model's own
  texture columns (as the regression used them, e.g. ``log(profile_MPD)``) and the MPD column (mm); a cubic in
  MPD also spans the IFI speed constant ``1/Sp``, ``Sp = 14.2 + 89.7 MPD`` km/h, over the campaign's range;
* ``curved in <a> and <b>``: ``[z_a z_b, z_a^2, z_b^2]`` of the first two kept axes (in practice the prediction
  model's two texture terms, e.g. ``log(profile_MPD)`` and ``log(micro_Sq)``): the second-order terms of a
  quadratic surface whose linear terms the texture model holds (a level set by microtexture times a speed
  dependence set by MPD, as in the IFI and Rado forms, is a product of the two);
* ``contact-zone microtexture``: ``[z(log(raw_Sp / raw_Sq)), z(log(micro_Sp / micro_Sq)),
  z(log micro_Sq) z(log(raw_Sp / raw_Sq))]`` where the table holds these columns: the microtexture where the slider
  touches (on the aggregate tops) rather than averaged over the scan (:func:`_contact_design`);
* ``texture PCs 1-3``: the three leading principal components of the texture table beyond the prediction
  model's columns (texture measures the model leaves out);
* ``texture PCs 1-k`` (the wide member, k from 4 to ``WIDE_PCS`` = 8): the k leading principal components of the
  texture columns beyond ``[1, the prediction model's terms]``, ``k = min(8, n_sections - 4, rank)``: a measure
  the table does not hold (the microtexture where the slider touches) shows as a direction several columns share,
  not always among the leading three (:func:`_wide_design`); of a table that holds the height and slope
  parameters of the three bands, the PCs of those, the contact zone's and MPD (:func:`wide_member_columns`),

is tested against the between-site residual (site means, ``main``) by the same nested permutations as every
covariate, and, where section identity x speed is significant between sites, against the residual's speed profiles
(``x_speed``: :func:`skidsim.criticism.texture_tests.texture_speed_tests`, a child family of that section effect).
The members of one kind are one testing unit (``main``: primary family) tested by single-step minP
(:func:`~skidsim.criticism.permutations.min_p`: each member's statistic on its own permutation scale, as the
designs differ in width): an exact permutation p-value of "no richer texture model explains the residual", and
the member with the smallest p (ties: the largest standardised statistic) says which measure or which form.

Friction mu (dimensionless), MPD mm, speeds km/h.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .adjustment import basis, lead_design, residualise

#: Prefix of the variable name of a texture-model candidate (``texture_model[<member>]``).
TEXTURE_MODEL = "texture_model"
#: Columns of the design of every member but the wide one.
MEMBER_DF = 3
#: The name of the member of the leading texture principal components (beyond the prediction model's terms).
PCS_MEMBER = f"texture PCs 1-{MEMBER_DF}"
#: At most this many leading texture PCs in the wide member (:func:`_wide_design`).
WIDE_PCS = 8
#: The wide member leaves at least this many of the sections' degrees of freedom free (k <= n_sections - this).
WIDE_SECTION_MARGIN = 4
#: The bands and the parameters (ISO 25178-2 height and hybrid) of the wide member's core columns
#: (:func:`wide_member_columns`).
WIDE_CORE_BANDS = ("raw", "macro", "micro")
WIDE_CORE_PARAMETERS = ("Sq", "Sa", "Sp", "Sv", "Ssk", "Sku", "Sdq", "Sdr")
#: The contact zone's and the profile's columns the wide member reads beside the core ones, where the table holds
#: them (:mod:`skidsim.texture.contact`; the MPD in mm).
WIDE_CORE_EXTRA = ("micro_Sq_top", "micro_Sdq_top", "profile_MPD")


@dataclass(frozen=True)
class TextureMember:
    """One richer texture model: its ``name`` (``nonlinear in <axis>``, ``texture PCs 1-3``, ...), the words a
    pavement engineer reads (``words``) and its design (n_sites, 3; the wide member n_sites, k), each column
    standardised over the sites."""

    name: str
    words: str
    design: np.ndarray

    @property
    def variable(self) -> str:
        return f"{TEXTURE_MODEL}[{self.name}]"

    @property
    def speed_words(self) -> str:
        """The words of the member tested against the speed shape of the residual (``x_speed``)."""
        w = self.words.removeprefix("friction is ")
        return f"the speed shape of friction is {w}" if w != self.words else f"the speed shape of friction follows {w}"


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


def _surface(za: np.ndarray, zb: np.ndarray) -> np.ndarray:
    """``[za zb, za^2, zb^2]`` of two standardised axes (the second-order terms of a quadratic response surface
    whose linear terms the texture model holds), each column standardised."""
    cols = [_std(c) for c in (za * zb, za**2, zb**2)]
    return np.column_stack([c if c is not None else np.zeros_like(za) for c in cols])


#: What the contact-zone member means, in words.
CONTACT_WORDS = (
    "friction follows the microtexture where the slider touches: how far the highest tops stand above the surface "
    "(raw Sp / Sq), how peaked the micro band is (micro Sp / Sq) and the micro Sq on those tops (micro Sq x raw "
    "Sp / Sq)"
)


def _column(C: pd.DataFrame, band: str, param: str) -> np.ndarray | None:
    """The positive values of the texture column ``<band>_<param>`` (or ``..._mm``; mm) of the sites, or None."""
    for name in (f"{band}_{param}", f"{band}_{param}_mm"):
        if name in C.columns:
            x = pd.to_numeric(C[name], errors="coerce").to_numpy(float)
            return x if np.isfinite(x).all() and (x > 0).all() else None
    return None


def _contact_design(C: pd.DataFrame) -> np.ndarray | None:
    """``[z(log(raw_Sp / raw_Sq)), z(log(micro_Sp / micro_Sq)), z(log micro_Sq) z(log(raw_Sp / raw_Sq))]``: the
    contact zone of a slider on the texture's tops, from the table's own columns (heights in mm): the peak-to-rms
    ratio of the whole scan (the higher the tops stand out, the smaller the share of the surface they make up),
    the same ratio of the micro band, and the micro Sq weighted by the first (microtexture on the tops rather than
    averaged over binder and aggregate). None when a column is missing or not positive."""
    cols = {(b, q): _column(C, b, q) for b in ("raw", "micro") for q in ("Sp", "Sq")}
    if any(v is None for v in cols.values()):
        return None
    peak = _std(np.log(cols["raw", "Sp"] / cols["raw", "Sq"]))
    micro_peak = _std(np.log(cols["micro", "Sp"] / cols["micro", "Sq"]))
    micro = _std(np.log(cols["micro", "Sq"]))
    on_tops = None if peak is None or micro is None else _std(micro * peak)
    if peak is None or micro_peak is None or on_tops is None:
        return None
    return np.column_stack([peak, micro_peak, on_tops])


def wide_member_columns(texture_columns) -> list[str]:
    """The texture columns the wide member reads: where ``texture_columns`` hold every core column
    ``<band>_<parameter>`` (:data:`WIDE_CORE_BANDS` x :data:`WIDE_CORE_PARAMETERS`: the heights Sq Sa Sp Sv Ssk Sku
    and the slopes Sdq Sdr of the raw, macro and micro bands), those and the ones of :data:`WIDE_CORE_EXTRA` among
    them, in the table's order; else every column.

    Why: the workflow's table holds about 120 columns, most of them families that repeat a few directions (the
    material-ratio volumes and the Sk family follow Sq, the feature and motif counts each other), and the leading
    principal components of all of them follow what many near-duplicates share, not a measure the table does not
    hold (docs/model-criticism.md, section 2, "The texture model as a candidate cause"). A table of other columns
    (a user's own, a campaign's stand-in) is read whole."""
    cols = list(texture_columns)
    core = {f"{b}_{q}" for b in WIDE_CORE_BANDS for q in WIDE_CORE_PARAMETERS}
    if not core <= set(cols):
        return cols
    return [c for c in cols if c in core or c in WIDE_CORE_EXTRA]


def _wide_design(C: pd.DataFrame, texture_columns, lead: tuple, n_sections: int) -> np.ndarray | None:
    """The wide member's design (n_sites, k): the ``k`` leading principal components of the numeric texture
    columns ``texture_columns`` of ``C`` (each standardised over the sites) taken beyond ``[1, lead columns]``
    (:func:`~skidsim.criticism.adjustment.lead_design`; ``[1]`` without lead terms), each standardised; ``k =
    min(WIDE_PCS, n_sections - WIDE_SECTION_MARGIN, rank)``; of a table that holds the core columns, those
    (:func:`wide_member_columns`). None when ``k <= MEMBER_DF`` (the PCs member holds as many) or no column is
    usable (a column with a missing value or no spread is left out)."""
    cols = wide_member_columns(c for c in texture_columns if c in C.columns)
    if not cols:
        return None
    X = C[cols].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    ok = np.isfinite(X).all(axis=0) & (X.std(axis=0) > 0)
    if not ok.any():
        return None
    X = (X[:, ok] - X[:, ok].mean(axis=0)) / X[:, ok].std(axis=0)
    L = lead_design(C, lead) if lead else None
    B = np.ones((len(C), 1)) if L is None else np.c_[np.ones(len(C)), L]
    Xb = residualise(X, B)
    U, sv, _ = np.linalg.svd(Xb, full_matrices=False)
    rank = int((sv > 1e-8 * sv[0]).sum()) if sv.size and sv[0] > 0 else 0
    k = min(WIDE_PCS, int(n_sections) - WIDE_SECTION_MARGIN, rank)
    if k <= MEMBER_DF:
        return None
    return np.column_stack([_std(U[:, j]) for j in range(k)])


def texture_members(
    site_ids,
    cov: pd.DataFrame,
    mpd: str | None,
    scores: np.ndarray,
    lead: tuple = (),
    n_lead: int = 0,
    texture_columns=(),
    n_sections: int = 0,
) -> list[TextureMember]:
    """The richer texture models of the sites ``site_ids`` (order kept).

    ``cov``: the candidate covariates (one row per site); ``mpd``: the MPD column (mm) or None; ``scores``: the
    texture model's score table of these sites (:func:`~skidsim.criticism.adjustment.texture_model_scores`: the
    prediction model's ``n_lead`` columns ``lead`` first, then texture PCs). Axes whose cubic design is almost
    the same as an earlier one's (|r| >= 0.95 of the linear columns) are dropped. ``texture_columns``: the
    numeric texture columns of ``cov`` and ``n_sections``: the number of sections of these sites, for the wide
    member (:func:`_wide_design`; none without them)."""
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
        if any(abs(float(np.corrcoef(z, k[1])[0, 1])) >= 0.95 for k in kept):
            continue
        kept.append((name, z))
        members.append(TextureMember(f"nonlinear in {name}", f"friction is a nonlinear function of {name}", _cubic(z)))
    if len(kept) >= 2:
        (a, za), (b, zb) = kept[:2]
        members.append(
            TextureMember(
                f"curved in {a} and {b}",
                f"friction is a curved function of {a} and {b} together (their squares and their product)",
                _surface(za, zb),
            )
        )
    contact = _contact_design(C)
    if contact is not None:
        members.append(TextureMember("contact-zone microtexture", CONTACT_WORDS, contact))
    pcs = np.asarray(scores, float)[:, n_lead:] if scores is not None else np.zeros((len(C), 0))
    if pcs.shape[1] >= MEMBER_DF:
        D = np.column_stack([_std(pcs[:, j]) for j in range(MEMBER_DF)])
        members.append(
            TextureMember(
                PCS_MEMBER,
                "texture measures the prediction model leaves out (the leading texture principal components)",
                D,
            )
        )
    wide = _wide_design(C, texture_columns, tuple(lead), n_sections)
    if wide is not None:
        members.append(
            TextureMember(
                f"texture PCs 1-{wide.shape[1]}",
                "many texture measures together: the leading texture principal components beyond the prediction "
                "model's texture terms (measures it leaves out, spread over several directions)",
                wide,
            )
        )
    return members


def members_of(cands, site_ids, pcs: pd.DataFrame | None, lead=()) -> list[TextureMember]:
    """The members (:func:`texture_members`) of the sites ``site_ids`` from the candidate set ``cands`` (its
    covariates, MPD column, numeric texture columns and sections), the texture model's score table ``pcs``
    (:func:`~skidsim.criticism.covariates.scores_for`) and the prediction columns ``lead``: the one construction
    that the screening tests and the extension of a texture-model cause rebuilds."""
    from .covariates import lead_count, scores_for

    scores = scores_for(site_ids, pcs, cands.covariates, cands.info)
    tex = tuple(c for c in cands.covariates.columns if cands.info[c] == ("texture", "numeric"))
    n_sections = int(cands.section_of.reindex(list(site_ids)).nunique())
    return texture_members(
        site_ids,
        cands.covariates,
        cands.mpd,
        scores,
        tuple(lead),
        lead_count(site_ids, pcs),
        texture_columns=tex,
        n_sections=n_sections,
    )


def member_basis(member: TextureMember) -> np.ndarray:
    """Orthonormal basis of the centred design of a member (rank-deficient columns dropped)."""
    return centred_basis(member.design)


def centred_basis(X: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column-centred ``X`` (n, k): QR, rank-deficient columns dropped."""
    Z = X - X.mean(axis=0)
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
    from .covariates import CandidateRoles, candidate_set
    from .extensions import TextureModelTerm
    from .residuals import level_matrix

    if cause is None or cause.source != "texture_model":
        return None
    roles = CandidateRoles() if roles is None else roles
    cands = candidate_set(sites, texture_wide, roles, 0.8)
    ids, _, _ = level_matrix(residuals, "between-site", speed_bin_kmh)
    members = members_of(cands, ids, pcs, lead)
    m = next((m for m in members if m.variable == cause.variable), None)
    if m is None:
        return None
    words = m.speed_words if cause.kind == "x_speed" else m.words
    return TextureModelTerm(
        cause.variable,
        tuple(str(s) for s in ids),
        tuple(tuple(map(float, r)) for r in m.design),
        words,
        on="slope" if cause.kind == "x_speed" else "level",
    )
