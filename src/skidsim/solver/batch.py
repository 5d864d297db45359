"""The state of the members of a batch, stepped together (docs/solver.md, "Step loop and batched runs").

Nodal arrays ``(3, nz+1, B, ny+1, nx+1)`` (the kernel's batched layout,
:class:`skidsim.solver.kernel.StructuredKernel`), the bottom faces as flat views ``(3, B * n_face)`` (the contact
laws' layout, :mod:`skidsim.solver.contact`), one entry per member in the 1-d arrays. A member that finishes its
preload or its slide leaves the batch (:meth:`Batch.take`); members that differ only in their test speed share one
preload (:meth:`Batch.spread`).
"""

from __future__ import annotations

import numpy as np

from skidsim.solver.contact import FrictionCoefficient
from skidsim.solver.kernel import StructuredKernel
from skidsim.solver.model import SliderModel, build_kernel


class Batch:
    """State of the members stepped together. Nodal arrays ``(3, nz+1, B, ny+1, nx+1)`` (the kernel's batched
    layout), the bottom faces as flat views ``(3, B * n_face)``, one entry per member in the 1-d arrays."""

    NODAL = ("u", "v", "nku", "nkv")  # carried nodal state (f, tmp, fdamp, fbeta, fint are per-step scratch)
    MEMBER = ("ids", "v_slide", "vz", "fz_sum", "area_now", "pen_energy", "prev_ok", "max_pen")
    ENERGY = ("external", "friction", "damping", "viscous")

    def __init__(self, m: SliderModel, ids, v_slide, laws):
        self.m, self.n = m, len(ids)
        shape = (3, m.mesh.nz + 1, self.n, m.mesh.ny + 1, m.mesh.nx + 1)
        self.u, self.v = np.zeros(shape), np.zeros(shape)
        self.nku = np.zeros(shape) if m.incremental_ku else None  # -K u(n), N
        self.nkv = np.zeros(shape) if m.incremental_ku else None  # -K v(n-1/2), N/s
        self.ft_state = np.zeros((3, self.n * m.n_face))  # penalty friction: tangential force per bottom node, N
        self.ids, self.v_slide, self.laws = np.asarray(ids), np.asarray(v_slide, dtype=float), list(laws)
        for name in self.MEMBER[2:]:
            setattr(self, name, np.zeros(self.n))
        self.prev_ok = np.zeros(self.n, dtype=bool)  # the last preload check was within tolerance
        self.e = {k: np.zeros(self.n) for k in self.ENERGY}  # J, accumulated over the slide (floats for one member)
        self.kern = build_kernel(m.mesh, m.material, batch=self.n)
        self._derive()

    def _derive(self) -> None:
        """Scratch arrays, bottom-face views and the per-node constants tiled over the members."""
        m, n = self.m, self.n
        shape = self.u.shape
        self.f, self.tmp, self.fdamp, self.fint = (np.zeros(shape) for _ in range(4))
        self.damp_pair = None  # batch with -K v: the dashpot forces and -K v side by side, (2, *shape)
        if self.nkv is not None and n > 1:
            self.damp_pair = np.zeros((2, *shape))
            self.damp_pair[1] = self.nkv
            self.fdamp, self.nkv = self.damp_pair
        self.kern_beta = None  # stiffness-proportional damping with Prony terms: its own product, N s/m
        if m.rayleigh and not m.incremental_ku:
            self.kern_beta = StructuredKernel(m.mesh, m.beta_r * m.k_inf, batch=n)
        self.fbeta = np.zeros(shape) if self.kern_beta is not None else None
        self.mu = FrictionCoefficient(self.laws)
        self.ub, self.vb, self.fb = (a[:, 0].reshape(3, -1) for a in (self.u, self.v, self.f))
        self.f_top_z = self.f[2, -1]  # views made once: dead load, holder forces, top velocities, dashpot sums
        self.f_top_xz = self.f[::2, -1].reshape(2, n, -1)
        self.fdamp_xz = self.fdamp[::2].reshape(2, -1) if n == 1 else None
        self.fdamp_frame_z = None if n == 1 else np.empty(shape[1:])  # a batch's dashpot frame term in z, N
        self.v_top = self.v[:, -1]
        self.top_v = np.zeros((3, n, 1, 1))  # m/s: (vx, 0, vz) per member
        self.frame_x = None  # sliding: -c m vx (N), the dashpots' frame term in x (made at the first slide step)
        assert np.shares_memory(self.ub, self.u) and np.shares_memory(self.fb, self.f)
        self.Xb = np.tile(m.X[:, 0].reshape(3, -1), (1, n))
        self.xyz_b = np.empty_like(self.Xb)
        self.k_pen_f = np.tile(m.k_pen.ravel(), n)
        self.k_fric_f = np.tile(m.k_fric.ravel(), n)
        self.k_fric_dt_f = self.k_fric_f * m.dt  # N s/m: the tangential penalty on a velocity over one step
        m_bf = np.tile(m.mass[0].ravel(), n)
        self.inv_mb_dt, self.mb_over_dt = m.dt / m_bf, m_bf / m.dt
        self.area_bf = np.tile(m.area_b.ravel(), n)
        self.all_nodes = np.arange(n * m.n_face)
        self.face_starts = np.arange(n + 1) * m.n_face  # first flat bottom node of each member, and the end
        lo = int(self.ids[0])  # rows of the members in the output's per-member arrays: a slice when contiguous
        contiguous = np.array_equal(self.ids, np.arange(lo, lo + n))
        self.rows = slice(lo, lo + n) if contiguous else self.ids
        self.dt_minv = m.dt * (1.0 / m.mass)[:, None]
        # per-member reductions: Python floats for a batch of one (the single run's IEEE operations, without the
        # cost of 1-element arrays), arrays over the members otherwise
        self.one = n == 1
        if self.one:
            self.e = {k: float(np.atleast_1d(v)[0]) for k, v in self.e.items()}
            self.vx1 = float(self.v_slide[0])
            self.mdot = member_dot
        else:
            self.mdot = self._mdot

    def _assemble(self, parts, kern) -> Batch:
        new = object.__new__(Batch)
        new.m, new.kern = self.m, kern
        for name in self.NODAL:
            arrs = [getattr(p, name) for p in parts]
            setattr(new, name, None if arrs[0] is None else np.ascontiguousarray(np.concatenate(arrs, axis=2)))
        new.n = new.u.shape[2]
        new.ft_state = np.concatenate([p.ft_state.reshape(3, p.n, -1) for p in parts], axis=1).reshape(3, -1)
        for name in self.MEMBER:
            setattr(new, name, np.concatenate([getattr(p, name) for p in parts]))
        new.e = {k: np.concatenate([np.atleast_1d(p.e[k]) for p in parts]) for k in self.ENERGY}
        new.laws = [law for p in parts for law in p.laws]
        new._derive()
        return new

    def take(self, sel) -> Batch:
        """The batch of the members selected by the boolean mask ``sel`` (self if all)."""
        idx = np.flatnonzero(sel)
        if idx.size == self.n:
            return self
        return self._pick(idx)

    def _pick(self, idx: np.ndarray, **member) -> Batch:
        """The batch of the members ``idx`` (indices, repeats allowed), their state copied; ``member`` replaces
        per-member entries of the copies (``ids``, ``v_slide``)."""
        part = object.__new__(Batch)
        part.n, part.laws = idx.size, [self.laws[i] for i in idx]
        for name in self.NODAL:
            a = getattr(self, name)
            setattr(part, name, None if a is None else a[:, :, idx])
        part.ft_state = self.ft_state.reshape(3, self.n, -1)[:, idx].reshape(3, -1)
        for name in self.MEMBER:
            setattr(part, name, getattr(self, name)[idx])
        for name, value in member.items():
            setattr(part, name, np.asarray(value))
        part.e = {k: np.atleast_1d(v)[idx] for k, v in self.e.items()}
        return self._assemble([part], self.kern.take(idx))

    def spread(self, source: np.ndarray, ids: np.ndarray, v_slide: np.ndarray) -> Batch:
        """Members ``ids`` (test speeds ``v_slide``, m/s), each a copy of this batch's member ``source[i]``: the
        preload of members that differ only in their test speed is one preload (see :func:`preload_shared`)."""
        return self._pick(np.asarray(source, dtype=np.intp), ids=ids, v_slide=v_slide)

    @staticmethod
    def concat(batches: list[Batch]) -> Batch:
        """One batch of the members of ``batches``, in order of their ids."""
        batches = sorted(batches, key=lambda p: int(p.ids[0]))
        if len(batches) == 1:
            return batches[0]
        return batches[0]._assemble(batches, StructuredKernel.concat([p.kern for p in batches]))

    def _mdot(self, a: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Per-member ``a . c`` of two nodal arrays (``self.mdot``; a float, ``np.vdot``, for one member)."""
        s = (a.shape[0] * a.shape[1], self.n, -1)
        return np.einsum("kbj,kbj->b", a.reshape(s), c.reshape(s))

    def damping_dots(self, v: np.ndarray) -> np.ndarray:
        """Per-member ``f_d . v`` and ``(-K v_old) . v`` (2, B) in one pass (``damp_pair``; a batch with -K v)."""
        k = 3 * self.u.shape[1]
        return np.einsum("pkbj,kbj->pb", self.damp_pair.reshape(2, k, self.n, -1), v.reshape(k, self.n, -1))

    def kinetic(self) -> np.ndarray:
        w = (self.v * self.v).sum(axis=0)
        if self.n == 1:
            return np.array([0.5 * np.vdot(self.m.mass, w)])
        nz1 = w.shape[0]
        return 0.5 * np.einsum("kbj,kj->b", w.reshape(nz1, self.n, -1), self.m.mass.reshape(nz1, -1))

    def friction_elastic(self) -> np.ndarray:
        """Energy (J) stored in the tangential penalty springs of each member (0 with the stick limit)."""
        if self.m.config.friction_model != "penalty":
            return np.zeros(self.n)
        ft = self.ft_state
        return 0.5 * ((ft * ft).sum(axis=0) / self.k_fric_f).reshape(self.n, -1).sum(axis=1)


def member_dot(a: np.ndarray, c: np.ndarray) -> float:
    """``a . c`` of a batch of one (``Batch.mdot``)."""
    return float(np.vdot(a, c))
