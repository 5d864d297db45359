"""Contact laws of one explicit step, on the bottom-face nodes of a batch of sliders (SI units).

The solver (:class:`skidsim.solver.batch.Batch`) stores the bottom faces of the ``B`` members of a batch as one flat
node set of ``B * n_face`` nodes (member ``b``'s node ``j`` is ``b * n_face + j``); every law here works node by
node on that set, so a batch of one is the single run, bit for bit. Contact nodes come in increasing index order,
hence grouped by member (:class:`Segments`).

* :func:`normal_contact`: penalty on the vertical penetration (option: the normal gap), evaluated on candidates;
* :func:`stick_limit_friction`: Coulomb ``mu(s) N`` capped by the force that stops the node within the step;
* :func:`penalty_step`: elastic stick with a tangential penalty and a return mapping
  (:func:`skidsim.solver.contact_friction.penalty_friction`);
* :class:`FrictionCoefficient`: ``mu(s)`` of each contact node with its member's friction law.

The step's cost is NumPy's per-call overhead, not arithmetic (a few contact nodes per step): the normal contact and
the penalty friction of at most :data:`SCALAR_MAX_NODES` contact nodes are computed node by node in Python floats
(the array paths' IEEE operations in the same order, so the same bits; tested against them), and the contact and
friction forces, the areas and the normal forces share one ``(8, n)`` buffer (:attr:`Contact.rows`) whose
per-member sums are one reduction.

The slide damping (Rayleigh or mass-proportional) acts on the whole slider and lives with the internal force in
:mod:`skidsim.solver.stepping`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from skidsim.friction import ExponentialDecay
from skidsim.solver.contact_friction import _TINY, penalty_friction


@dataclass
class Contact:
    """The bottom nodes in contact at one step.

    ia: flat node indices in contact (increasing); d_m: vertical penetration ``z_surface - z`` (m, > 0);
    gx, gy: surface slopes there; kd_n: ``k d`` (vertical gap) or ``k d / (1 + |grad z|^2)`` (normal gap) (N);
    force_n: (3, n) penalty force on the nodes (N), ``kd (-gx, -gy, 1)``; normal_n: magnitude N of the normal
    force (N); normal: (3, n) unit surface normals ``(nx, ny, nz)``; rows: (8, n) the buffer that holds
    force_n (rows 0-2), the friction force (3-5, written by the friction law: :attr:`friction_out`), the nodes'
    tributary areas (6, m^2) and normal_n (7), so that the per-member sums of the trace are one reduction.
    """

    ia: np.ndarray
    d_m: np.ndarray
    gx: np.ndarray
    gy: np.ndarray
    kd_n: np.ndarray
    force_n: np.ndarray
    normal_n: np.ndarray
    normal: np.ndarray
    rows: np.ndarray

    @property
    def friction_out(self) -> np.ndarray:
        """Rows 3-5 of :attr:`rows`: where the friction law writes the friction force (3, n), N."""
        return self.rows[3:6]


#: Contact sets of at most this many nodes take the scalar paths of the normal contact and the penalty friction:
#: Python floats node by node, the same IEEE operations in the same order as the array paths (so the same bits),
#: cheaper than their ~50 NumPy calls on the handful of nodes a slider usually touches with (3-4 on average on a
#: 0.5 mm heightfield with the campaign preset).
SCALAR_MAX_NODES = 16


def normal_contact(
    pavement, bound, xyz_m, k_pen_n_per_m, area_m2, normal_gap: bool, all_nodes, scalar_max: int = SCALAR_MAX_NODES
) -> Contact:
    """Penalty contact of the bottom nodes at ``xyz_m`` ``(3, n_nodes)`` (m) on the rigid ``pavement``.

    Only the candidates are evaluated: nodes below the per-cell upper bound of the surface (``bound``, a
    :class:`skidsim.solver.surfaces.SurfaceBound`, or None: every node); a node above it cannot penetrate (exact).
    ``k_pen_n_per_m`` (N/m) and ``area_m2`` (tributary areas, m^2) per node (flat). Up to ``scalar_max`` contact
    nodes the forces are computed node by node in Python floats (:func:`_contact_scalar`, the same bits).
    """
    if bound is None:
        cand = all_nodes
        zg = np.array(pavement.evaluate(xyz_m[0], xyz_m[1]), dtype=float).reshape(3, -1)
    else:
        cand, zg = bound.surface_at_candidates(xyz_m)
    np.subtract(zg[0], xyz_m[2].take(cand), out=zg[0])  # z_surface - z
    act = zg[0] > 0.0
    ia = cand[act]
    dg = zg.compress(act, axis=1)  # [d, gx, gy], C-contiguous rows (np.dot of d below)
    if ia.size <= scalar_max:
        return _contact_scalar(ia, dg, k_pen_n_per_m, area_m2, normal_gap)
    d, g = dg[0], dg[1:]
    rows = np.empty((8, ia.size))
    kd = np.multiply(k_pen_n_per_m.take(ia), d, out=rows[2])
    g2 = g * g
    den = 1.0 + g2[0]  # 1 + |grad z|^2
    den += g2[1]
    if normal_gap:  # k d_n along the normal: vertical component k d / (1 + |grad z|^2)
        kd /= den
    neg_g = np.negative(g)
    np.multiply(kd, neg_g, out=rows[0:2])  # kd (-gx, -gy): -(kd gx) bit for bit
    np.take(area_m2, ia, out=rows[6])
    n_len = np.sqrt(den)
    np.multiply(kd, n_len, out=rows[7])
    normal = np.empty((3, ia.size))
    np.divide(neg_g, n_len, out=normal[0:2])
    np.divide(1.0, n_len, out=normal[2])
    return Contact(ia, d, g[0], g[1], kd, rows[0:3], rows[7], normal, rows)


def _contact_scalar(ia, dg, k_pen_n_per_m, area_m2, normal_gap: bool) -> Contact:
    """:func:`normal_contact`'s forces for the contact nodes ``ia`` with ``dg = [d, gx, gy]`` ``(3, n)``, node by
    node in Python floats: each value gets the IEEE operations of the array path in the same order."""
    fx, fy, kds, nn, nx, ny, nz = [], [], [], [], [], [], []
    for k, d, gx, gy in zip(k_pen_n_per_m.take(ia).tolist(), *dg.tolist()):
        kd = k * d
        den = 1.0 + gx * gx + gy * gy
        if normal_gap:
            kd /= den
        n_len = math.sqrt(den)
        fx.append(kd * -gx)
        fy.append(kd * -gy)
        kds.append(kd)
        nn.append(kd * n_len)
        nx.append(-gx / n_len)
        ny.append(-gy / n_len)
        nz.append(1.0 / n_len)
    n = ia.size
    rows = np.empty((8, n))
    rows[0:3] = (fx, fy, kds)
    rows[7] = nn
    np.take(area_m2, ia, out=rows[6])
    normal = np.array((nx, ny, nz)).reshape(3, n)
    return Contact(ia, dg[0], dg[1], dg[2], rows[2], rows[0:3], rows[7], normal, rows)


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
            return self.mu_k.take(m) + self.d_mu.take(m) * np.exp(self.neg_alpha.take(m) * np.abs(s_ms))
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

    def __init__(self, ia: np.ndarray, n_face: int, n_members: int, starts: np.ndarray | None = None):
        """``starts``: the first flat node of each member and the end, ``arange(n_members + 1) * n_face`` (made
        here if not given)."""
        self.n, self._ia, self._n_face = n_members, ia, n_face
        if n_members > 1:
            starts = np.arange(n_members + 1) * n_face if starts is None else starts
            self.edges = np.searchsorted(ia, starts)
        else:
            self.edges = [0, ia.size]

    @cached_property
    def member(self) -> np.ndarray:
        """Member index of each contact node."""
        return self._ia // self._n_face

    def bounds(self):
        """``(i0, i1)`` of each member: its contact nodes are ``ia[i0:i1]``."""
        e = self.edges.tolist() if self.n > 1 else self.edges
        return zip(e[:-1], e[1:])

    def sums(self, rows: np.ndarray) -> np.ndarray:
        """Per-member sums ``(k, B)`` of the rows of ``rows`` ``(k, n)`` (NumPy's ``sum`` of each slice)."""
        if self.n == 1:
            return rows.sum(axis=1)[:, None]
        out = np.zeros((rows.shape[0], self.n))
        for b, (i0, i1) in enumerate(self.bounds()):
            if i1 > i0:
                np.add.reduce(rows[:, i0:i1], 1, out=out[:, b])
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
        return np.array([self._ia.size]) if self.n == 1 else self.edges[1:] - self.edges[:-1]

    def maximum(self, a: np.ndarray, initial: float) -> np.ndarray:
        """Per-member maximum of ``a`` (n,), ``initial`` where a member has no entry."""
        if self.n == 1:
            return np.array([max(initial, float(a.max()))]) if a.size else np.array([initial])
        out = np.full(self.n, initial)
        if a.size:  # one reduceat over the members with entries: a maximum is exact, so the same bits
            starts, ends = self.edges[:-1], self.edges[1:]
            some = ends > starts
            out[some] = np.maximum(np.maximum.reduceat(a, starts[some]), initial)
        return out


def stick_limit_friction(vt_ms, f_n, inv_m_dt, m_over_dt, c: Contact, mu):
    """Coulomb friction ``mu(s) N`` capped by the stick limit ``m |v_t,trial| / dt`` (the first releases' law).

    vt_ms, f_n: (3, n) velocities (m/s) and forces (N, without friction) of the contact nodes; inv_m_dt
    (``dt / m``, s/kg) and m_over_dt (kg/s) per node; ``mu`` a callable ``mu(s)`` of the trial tangential speed.
    Returns ``(friction force (3, n) N, held-by-the-limit mask, s m/s)``.
    """
    vt = f_n * inv_m_dt
    vt += vt_ms  # trial velocity without friction
    vt -= _normal_part(vt, c.normal) * c.normal
    s = _add(vt * vt, 0)
    np.sqrt(s, out=s)
    mu_n = mu(s) * c.normal_n
    stick_lim = m_over_dt * s
    fmag = np.minimum(mu_n, stick_lim)
    pos = s > 0.0
    scale = np.where(pos, -fmag / np.where(pos, s, 1.0), 0.0)
    return np.multiply(vt, scale, out=c.friction_out), stick_lim < mu_n, s


def penalty_step(ft_state_n, vt_ms, k_t_dt, c: Contact, mu, scalar_max: int = SCALAR_MAX_NODES):
    """Penalty friction with a return mapping onto ``mu(s) N`` for the contact nodes ``c.ia``.

    ft_state_n: (3, n_nodes) tangential forces (N) of the last step, updated in place (nodes out of contact lose
    theirs); vt_ms: (3, n) velocities (m/s) of the contact nodes over the step, ``k_t_dt`` (N s/m) per contact
    node: ``k_t dt v`` is the elastic predictor on the step's displacement; ``s`` the node's tangential speed.
    Returns ``(friction force (3, n) N, stick mask, s m/s)``. Up to ``scalar_max`` nodes node by node in Python
    floats (:func:`_penalty_scalar`, the same bits).
    """
    if c.ia.size <= scalar_max:
        fric, stuck, s = _penalty_scalar(ft_state_n.take(c.ia, axis=1), vt_ms, k_t_dt, c, mu)
        ft_state_n.fill(0.0)
        ft_state_n[:, c.ia] = fric
        return fric, stuck, s
    vn = _normal_part(vt_ms, c.normal)
    s = _add(vt_ms * vt_ms, 0)
    vn *= vn
    s -= vn
    np.maximum(s, 0.0, out=s)
    np.sqrt(s, out=s)
    mu_n = mu(s) * c.normal_n
    fric, stuck = penalty_friction(ft_state_n.take(c.ia, axis=1), vt_ms, k_t_dt, mu_n, c.normal, out=c.friction_out)
    ft_state_n.fill(0.0)
    ft_state_n[:, c.ia] = fric
    return fric, stuck, s


def _penalty_scalar(f_old_n, vt_ms, k_t_dt, c: Contact, mu):
    """:func:`penalty_step`'s law (slip speed, elastic predictor, projection, return mapping) node by node in Python
    floats; ``f_old_n`` (3, n) N the contact nodes' previous tangential forces. The comparisons are written so that
    a NaN takes the branch ``np.maximum`` / ``np.minimum`` give it."""
    normal = c.normal.tolist()
    s_l = []
    for a0, a1, a2, n0, n1, n2 in zip(*vt_ms.tolist(), *normal):
        vn = a0 * n0 + a1 * n1 + a2 * n2
        ss = a0 * a0 + a1 * a1 + a2 * a2 - vn * vn
        s_l.append(math.sqrt(0.0 if ss < 0.0 else ss))
    s = np.array(s_l)
    limits = (mu(s) * c.normal_n).tolist()
    f0, f1, f2, stick = [], [], [], []
    cols = zip(*f_old_n.tolist(), *vt_ms.tolist(), k_t_dt.tolist(), *normal, limits)
    for o0, o1, o2, a0, a1, a2, k, n0, n1, n2, lim in cols:
        t0, t1, t2 = o0 - k * a0, o1 - k * a1, o2 - k * a2  # elastic predictor
        an = t0 * n0 + t1 * n1 + t2 * n2
        t0, t1, t2 = t0 - an * n0, t1 - an * n1, t2 - an * n2  # tangential part
        mag = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        stick.append(mag <= lim)
        scale = lim / (_TINY if mag < _TINY else mag)
        if scale >= 1.0:  # min(1, limit / |f|)
            scale = 1.0
        f0.append(t0 * scale)
        f1.append(t1 * scale)
        f2.append(t2 * scale)
    fric = c.friction_out
    fric[...] = (f0, f1, f2)
    return fric, np.array(stick, dtype=bool), s


def _normal_part(a: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``a . n`` (n,) of vectors ``a`` (3, n) and unit normals ``normal`` (3, n): ``a_x n_x + a_y n_y + a_z n_z`` in
    that order (new array)."""
    p = a * normal
    an = np.add(p[0], p[1])
    an += p[2]
    return an


#: ``np.add.reduce``: what ``ndarray.sum()`` calls (the same sums), without its Python wrapper
_add = np.add.reduce
