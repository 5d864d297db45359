"""Contact laws of one explicit step, on the bottom-face nodes of a batch of sliders (SI units).

The solver (:mod:`skidsim.solver.explicit`) stores the bottom faces of the ``B`` members of a batch as one flat
node set of ``B * n_face`` nodes (member ``b``'s node ``j`` is ``b * n_face + j``); every law here works node by
node on that set, so a batch of one is the single run, bit for bit. Contact nodes come in increasing index order,
hence grouped by member (:class:`Segments`).

* :func:`normal_contact`: penalty on the vertical penetration (option: the normal gap), evaluated on candidates;
* :func:`stick_limit_friction`: Coulomb ``mu(s) N`` capped by the force that stops the node within the step;
* :func:`penalty_step`: elastic stick with a tangential penalty and a return mapping
  (:func:`skidsim.solver.contact_friction.penalty_friction`);
* :class:`FrictionCoefficient`: ``mu(s)`` of each contact node with its member's friction law.

The slide damping (Rayleigh or mass-proportional) acts on the whole slider and lives with the internal force in
:mod:`skidsim.solver.explicit`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from skidsim.friction import ExponentialDecay
from skidsim.solver.contact_friction import penalty_friction


@dataclass
class Contact:
    """The bottom nodes in contact at one step.

    ia: flat node indices in contact (increasing); d_m: vertical penetration ``z_surface - z`` (m, > 0);
    gx, gy: surface slopes there; kd_n: ``k d`` (vertical gap) or ``k d / (1 + |grad z|^2)`` (normal gap) (N);
    force_n: (3, n) penalty force on the nodes (N), ``kd (-gx, -gy, 1)``; normal_n: magnitude N of the normal
    force (N); normal: unit surface normals ``(nx, ny, nz)``.
    """

    ia: np.ndarray
    d_m: np.ndarray
    gx: np.ndarray
    gy: np.ndarray
    kd_n: np.ndarray
    force_n: np.ndarray
    normal_n: np.ndarray
    normal: tuple[np.ndarray, np.ndarray, np.ndarray]


def normal_contact(pavement, bound, xb_m, yb_m, zb_m, k_pen_n_per_m, normal_gap: bool, all_nodes) -> Contact:
    """Penalty contact of the bottom nodes at ``(xb_m, yb_m, zb_m)`` (m, flat) on the rigid ``pavement``.

    Only the candidates are evaluated: nodes below the per-cell upper bound of the surface (``bound``, a
    :class:`skidsim.solver.surfaces.SurfaceBound`, or None: every node); a node above it cannot penetrate (exact).
    ``k_pen_n_per_m`` (flat, N/m) is the penalty stiffness per node.
    """
    cand = all_nodes if bound is None else bound.candidates(xb_m, yb_m, zb_m)
    if cand.size:
        zs, gx, gy = pavement.evaluate(xb_m[cand], yb_m[cand])
        d = zs - zb_m[cand]
        act = d > 0.0
        ia = cand[act]
        d = d[act]
        gx = gx[act]
        gy = gy[act]
    else:
        ia = cand
        d = gx = gy = np.zeros(0)
    kd = k_pen_n_per_m[ia] * d
    if normal_gap:  # k d_n along the normal: vertical component k d / (1 + |grad z|^2)
        kd /= 1.0 + gx * gx + gy * gy
    fcn = np.empty((3, ia.size))
    np.multiply(kd, gx, out=fcn[0])
    np.negative(fcn[0], out=fcn[0])
    np.multiply(kd, gy, out=fcn[1])
    np.negative(fcn[1], out=fcn[1])
    fcn[2] = kd
    n_len = np.sqrt(1.0 + gx * gx + gy * gy)
    return Contact(ia, d, gx, gy, kd, fcn, kd * n_len, (-gx / n_len, -gy / n_len, 1.0 / n_len))


class FrictionCoefficient:
    """``mu(s)`` of each contact node (``s`` in m/s) with the friction law of its member.

    One call of the law when every member has the same law; the :class:`ExponentialDecay` formula with per-node
    parameters when the members' laws are all exponential (the same operations in the same order as
    :meth:`ExponentialDecay.mu`, so bit for bit); otherwise one call per member.
    """

    def __init__(self, laws):
        self.laws = list(laws)
        first = self.laws[0]
        self.shared = all(law is first or law == first for law in self.laws)
        self.exponential = not self.shared and all(type(law) is ExponentialDecay for law in self.laws)
        if self.exponential:
            self.mu_k = np.array([law.mu_k for law in self.laws])
            self.d_mu = np.array([law.mu_s - law.mu_k for law in self.laws])
            self.neg_alpha = np.array([-law.alpha for law in self.laws])

    def __call__(self, s_ms: np.ndarray, seg: Segments) -> np.ndarray:
        if self.shared:
            return self.laws[0].mu(s_ms)
        if self.exponential:
            m = seg.member
            return self.mu_k[m] + self.d_mu[m] * np.exp(self.neg_alpha[m] * np.abs(s_ms))
        out = np.empty(s_ms.size)
        for b, (i0, i1) in enumerate(seg.bounds()):
            if i1 > i0:
                out[i0:i1] = self.laws[b].mu(s_ms[i0:i1])
        return out


class Segments:
    """The contact nodes ``ia`` (flat, increasing) grouped by member: per-member sums, dots, counts and maxima.

    With one member every reduction is the plain NumPy one (``sum``, ``np.vdot``, ``np.dot``), so a batch of one
    reproduces the single run bit for bit. Sums that enter SN (forces, contact area) are NumPy's pairwise ``sum``
    over each member's slice in every case; diagnostics and energies of larger batches use ``np.bincount``.
    """

    def __init__(self, ia: np.ndarray, n_face: int, n_members: int):
        self.n, self._ia, self._n_face = n_members, ia, n_face
        self.edges = np.searchsorted(ia, np.arange(n_members + 1) * n_face) if n_members > 1 else [0, ia.size]

    @cached_property
    def member(self) -> np.ndarray:
        """Member index of each contact node."""
        return self._ia // self._n_face

    def bounds(self):
        return zip(self.edges[:-1], self.edges[1:])

    def sums(self, rows: np.ndarray) -> np.ndarray:
        """Per-member sums ``(k, B)`` of the rows of ``rows`` ``(k, n)`` (NumPy's ``sum`` of each slice)."""
        if self.n == 1:
            return rows.sum(axis=1)[:, None]
        out = np.zeros((rows.shape[0], self.n))
        for b, (i0, i1) in enumerate(self.bounds()):
            if i1 > i0:
                out[:, b] = rows[:, i0:i1].sum(axis=1)
        return out

    def dot(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per-member ``a . b`` of ``(3, n)`` or ``(n,)`` arrays."""
        if self.n == 1:
            return np.array([np.vdot(a, b) if a.ndim > 1 else np.dot(a, b)])
        w = a * b
        if w.ndim > 1:
            w = w.sum(axis=0)
        return np.bincount(self.member, weights=w, minlength=self.n)

    def count(self, mask: np.ndarray) -> np.ndarray:
        """Per-member number of ``True`` entries of ``mask`` (n,)."""
        if self.n == 1:
            return np.array([np.count_nonzero(mask)])
        return np.bincount(self.member[mask], minlength=self.n)

    def counts(self) -> np.ndarray:
        """Number of contact nodes of each member."""
        return np.array([self._ia.size]) if self.n == 1 else np.diff(self.edges)

    def maximum(self, a: np.ndarray, initial: float) -> np.ndarray:
        """Per-member maximum of ``a`` (n,), ``initial`` where a member has no entry."""
        if self.n == 1:
            return np.array([max(initial, float(a.max()))]) if a.size else np.array([initial])
        out = np.full(self.n, initial)
        np.maximum.at(out, self.member, a)
        return out


def stick_limit_friction(vt_ms, f_n, inv_m_dt, m_over_dt, c: Contact, mu):
    """Coulomb friction ``mu(s) N`` capped by the stick limit ``m |v_t,trial| / dt`` (the first releases' law).

    vt_ms, f_n: (3, n) velocities (m/s) and forces (N, without friction) of the contact nodes; inv_m_dt
    (``dt / m``, s/kg) and m_over_dt (kg/s) per node; ``mu`` a callable ``mu(s)`` of the trial tangential speed.
    Returns ``(friction force (3, n) N, held-by-the-limit mask, s m/s)``.
    """
    nxh, nyh, nzh = c.normal
    vt = vt_ms + f_n * inv_m_dt  # trial velocity without friction
    vn = vt[0] * nxh + vt[1] * nyh + vt[2] * nzh
    vt[0] -= vn * nxh
    vt[1] -= vn * nyh
    vt[2] -= vn * nzh
    s = np.sqrt((vt * vt).sum(axis=0))
    mu_n = mu(s) * c.normal_n
    stick_lim = m_over_dt * s
    fmag = np.minimum(mu_n, stick_lim)
    scale = np.where(s > 0.0, -fmag / np.where(s > 0.0, s, 1.0), 0.0)
    return vt * scale, stick_lim < mu_n, s


def penalty_step(ft_state_n, vt_ms, k_t_dt, c: Contact, mu):
    """Penalty friction with a return mapping onto ``mu(s) N`` for the contact nodes ``c.ia``.

    ft_state_n: (3, n_nodes) tangential forces (N) of the last step, updated in place (nodes out of contact lose
    theirs); vt_ms: (3, n) velocities (m/s) of the contact nodes over the step, ``k_t_dt`` (N s/m) per contact
    node: ``k_t dt v`` is the elastic predictor on the step's displacement; ``s`` the node's tangential speed.
    Returns ``(friction force (3, n) N, stick mask, s m/s)``.
    """
    nxh, nyh, nzh = c.normal
    vn = vt_ms[0] * nxh + vt_ms[1] * nyh + vt_ms[2] * nzh
    s = np.sqrt(np.maximum((vt_ms * vt_ms).sum(axis=0) - vn * vn, 0.0))
    mu_n = mu(s) * c.normal_n
    fric, stuck = penalty_friction(ft_state_n[:, c.ia], vt_ms, k_t_dt, mu_n, c.normal)
    ft_state_n.fill(0.0)
    ft_state_n[:, c.ia] = fric
    return fric, stuck, s
