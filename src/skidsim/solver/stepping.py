"""One central-difference step of every member of a batch, and the two phases built from it (docs/solver.md).

:func:`step` calls the internal force (kernel product, Prony update, dead load), the dashpots, the contact and
friction laws of :mod:`skidsim.solver.contact` and the update of the holder, velocities, positions and energies in
turn, on the batch's preallocated buffers. :func:`preload` (dynamic relaxation under a ramped load) and
:func:`slide` (the holder slides; a member leaves when it has slid its length) loop over it.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from skidsim.solver.batch import Batch, member_dot
from skidsim.solver.config import SolverConfig
from skidsim.solver.contact import Contact, Segments, normal_contact, penalty_step, stick_limit_friction
from skidsim.solver.model import KU_REFRESH_STEPS, SliderModel
from skidsim.solver.output import MemberOutput

log = logging.getLogger("skidsim.solver")

#: Phases of a time step timed by :func:`simulate` (``result.meta["phase_s"]``, wall s, plus ``setup_and_rest``):
#: internal force (kernel and Prony update), damping and load, contact (candidate search, surface evaluation,
#: penalty forces), friction, update (holder, velocities, positions, energy bookkeeping), output (trace rows,
#: preload check, VTU, progress).
PHASES = ("internal_force", "damping_load", "contact", "friction", "update", "output")


#: ``np.add.reduce``: what ``ndarray.sum()`` calls (the same pairwise sum), without its Python wrapper
_add = np.add.reduce


def _ramp(t, t_ramp):
    return 1.0 if t >= t_ramp else 0.5 * (1.0 - math.cos(math.pi * t / t_ramp))


@dataclass
class Phase:
    """Preload (ramped load, dashpots to the ground) or slide (dashpots to the holder frame, slide damping)."""

    sliding: bool
    c_per_s: float  # mass-proportional dashpot coefficient, 1/s
    neg_cm: np.ndarray  # -c m (kg/s), (nz+1, 1, ny+1, nx+1): broadcast over the members

    @classmethod
    def of(cls, m: SliderModel, sliding: bool) -> Phase:
        cfg = m.config
        c = (m.alpha_r if m.rayleigh else cfg.slide_damping_per_s) if sliding else cfg.preload_damping_per_s
        return cls(sliding, c, (-c * m.mass)[:, None])


@dataclass
class StepOut:
    """Contact of the step and the per-member sums that enter the trace (N, m^2): the sums of the rows of
    ``contact.rows`` (``(8,)`` for a batch of one, whose ``fz`` and ``area`` are floats, else ``(8, B)``)."""

    contact: Contact
    fric: np.ndarray
    stick: np.ndarray
    s: np.ndarray
    seg: Segments
    sums: np.ndarray  # rows: contact force x, y, z; friction x, y, z; contact area; normal force N
    fz: np.ndarray | float  # pavement force on the slider in z, N
    area: np.ndarray | float  # contact area, m^2


class Clock:
    """Wall time per phase of the step (``PHASES``) and progress reports."""

    def __init__(self, config: SolverConfig, progress):
        self.t0 = self.last_log = time.perf_counter()
        self.ph = [0.0] * len(PHASES)
        self.every_s, self.progress = config.progress_every_s, progress
        self.t = self.t0
        self._now = time.perf_counter  # bound once: lap runs 7 times a step

    def lap(self, phase: int) -> None:
        now = self._now()
        self.ph[phase] += now - self.t
        self.t = now

    def report(self, done: int, total: int) -> None:
        now = self.t
        if now - self.last_log < self.every_s:
            return
        self.last_log = now
        el = now - self.t0
        eta = el / done * (total - done)
        log.info("step %d/%d (%.0f %%), %.1f s elapsed, %.1f s left", done, total, 100.0 * done / total, el, eta)
        if self.progress is not None:
            self.progress(done, total, el, eta)


def _internal_force(m: SliderModel, b: Batch, ph: Phase, k: int, load_factor: float) -> None:
    """``f = -f_int`` (and the Rayleigh stiffness part ``-beta K v``) at u(n), the Prony update, the dead load."""
    if ph.sliding and m.incremental_ku:
        b.kern.force(b.v, b.nkv, negate=True)
        if k % KU_REFRESH_STEPS == 0:
            b.kern.force(b.u, b.nku, negate=True)
        else:
            np.multiply(b.nkv, m.dt, out=b.tmp)
            b.nku += b.tmp
        np.multiply(b.nkv, m.beta_r, out=b.f)  # the Rayleigh stiffness part -beta K v, here rather than below
        b.f += b.nku
    else:
        b.kern.force(b.u, b.f, negate=True)  # f = -f_int, bit for bit
    if b.kern.g.size:
        diss = b.kern.relax(m.dt)
        if ph.sliding:
            b.e["viscous"] += float(diss[0]) if b.one else diss
    if load_factor == 1.0:  # 1.0 * f_top is f_top: no product
        b.f_top_z += m.f_top
    else:
        b.f_top_z += load_factor * m.f_top


def _damping_force(b: Batch, ph: Phase) -> None:
    """Mass-proportional dashpots (velocity relative to the frame) and, with Prony terms, ``-beta K v``.

    Sliding: dashpots to the holder (moving with (v_slide, 0, vz_holder)), so the rigid vertical motion that follows
    the texture is not resisted; preload: to the ground (dynamic relaxation of the whole slider).
    """
    if ph.c_per_s > 0:
        fd = np.multiply(b.v, ph.neg_cm, out=b.fdamp)  # -c m (v - v_frame), frame terms on two components
        if ph.sliding:
            if b.frame_x is None:
                b.frame_x = (b.vx1 if b.one else b.v_slide[:, None, None]) * ph.neg_cm
            np.subtract(fd[0], b.frame_x, out=fd[0])
            if b.one:
                if b.vz[0] != 0.0:
                    np.subtract(fd[2], float(b.vz[0]) * ph.neg_cm, out=fd[2])
            elif b.vz.any():  # a nonzero (or NaN) vz: np.any(vz != 0) without its wrapper
                frame_z = np.multiply(b.vz[:, None, None], ph.neg_cm, out=b.fdamp_frame_z)
                np.subtract(fd[2], frame_z, out=fd[2])
        b.f += fd
    if ph.sliding and b.kern_beta is not None:  # -beta K v: rigid (frame) motion is in K's null space
        b.kern_beta.force(b.v, b.fbeta, negate=True)
        b.f += b.fbeta


def _contact_and_friction(m: SliderModel, b: Batch, clock: Clock) -> StepOut:
    """Penalty contact on the candidate nodes, then friction (stick limit or penalty with return mapping)."""
    fb, vb = b.fb, b.vb
    xyz = np.add(b.Xb, b.ub, out=b.xyz_b)  # current positions of the bottom nodes, m
    c = normal_contact(m.pavement, m.bound, xyz, b.k_pen_f, b.area_bf, m.config.contact_gap == "normal", b.all_nodes)
    ia = c.ia
    f_c = fb.take(ia, axis=1)  # the contact nodes' forces: + contact, + friction, written back once (same sums)
    f_c += c.force_n
    clock.lap(2)
    seg = Segments(ia, m.n_face, b.n, b.face_starts)
    if b.mu.shared:
        mu = b.mu.laws[0].mu
    else:

        def mu(s):
            return b.mu(s, seg)

    if m.config.friction_model == "penalty":
        fric, stick, s = penalty_step(b.ft_state, vb.take(ia, axis=1), b.k_fric_dt_f.take(ia), c, mu)
    else:
        fric, stick, s = stick_limit_friction(
            vb.take(ia, axis=1), f_c, b.inv_mb_dt.take(ia), b.mb_over_dt.take(ia), c, mu
        )
    f_c += fric
    fb[:, ia] = f_c
    if b.one:
        sums = _add(c.rows, 1)
        out = StepOut(c, fric, stick, s, seg, sums, float(sums[2] + sums[5]), float(sums[6]))
    else:
        sums = seg.sums(c.rows)
        out = StepOut(c, fric, stick, s, seg, sums, sums[2] + sums[5], sums[6])
    clock.lap(3)
    return out


def _advance(m: SliderModel, b: Batch, ph: Phase, st: StepOut) -> None:
    """Rigid holder (top x/y velocity prescribed, one common z velocity), velocities, positions, energies.

    The per-member scalars are arrays over the members, or Python floats for a batch of one (the same IEEE
    operations, without the cost of 1-element arrays).
    """
    one = b.one
    top = _add(b.f_top_xz, 2)  # net x and z forces on the top face, (2, B)
    if one:
        fx_top, fz_holder = top.ravel().tolist()
        vz_old, vx = float(b.vz[0]), b.vx1
    else:
        fx_top, fz_holder = top
        vz_old, vx = b.vz, b.v_slide
    fz_hd = -m.c_holder * vz_old if ph.sliding else (0.0 if one else np.zeros(b.n))  # holder dashpot to the ground
    vz = vz_old + m.dt * (fz_holder + fz_hd) / m.m_holder
    if ph.sliding:
        vb_old = b.vb.take(st.contact.ia, axis=1)
        dots_old = _power_dots(m, b, ph)
    np.multiply(b.f, b.dt_minv, out=b.tmp)
    b.v += b.tmp
    tv = b.top_v  # prescribed x/y velocities of the top face and the holder's vz: one assignment
    if one:
        tv[0, 0, 0, 0] = vx if ph.sliding else 0.0
        tv[2, 0, 0, 0] = vz
        b.vz[0] = vz
    else:
        tv[0, :, 0, 0] = vx if ph.sliding else 0.0
        tv[2, :, 0, 0] = vz
        b.vz = vz
    b.v_top[...] = tv
    if ph.sliding:
        _slide_energies(m, b, ph, st, vb_old, dots_old, (-fx_top, fz_hd, vz_old, vz, vx))
    np.multiply(b.v, m.dt, out=b.tmp)
    b.u += b.tmp
    c = st.contact
    if one:
        b.fz_sum[0], b.area_now[0], b.pen_energy[0] = st.fz, st.area, 0.5 * float(np.dot(c.kd_n, c.d_m))
    else:
        b.fz_sum, b.area_now, b.pen_energy = st.fz, st.area, 0.5 * st.seg.dot(c.kd_n, c.d_m)


def _power_dots(m: SliderModel, b: Batch, ph: Phase) -> tuple:
    """``f_d . v(n-1/2)`` and the stiffness-damping force's ``. v(n-1/2)`` (J/s) before the velocity update (the
    dashpots' power over the step is ``f . (v_old + v_new) / 2``: two dots, no copy of v)."""
    if ph.c_per_s > 0 and b.damp_pair is not None:
        fd_dot, nkv_dot = b.damping_dots(b.v)
        return fd_dot, m.beta_r * nkv_dot
    fd_dot = b.mdot(b.fdamp, b.v) if ph.c_per_s > 0 else 0.0
    if b.fbeta is not None:
        return fd_dot, b.mdot(b.fbeta, b.v)
    if b.nkv is not None:
        return fd_dot, m.beta_r * b.mdot(b.nkv, b.v)
    return fd_dot, 0.0


def _slide_energies(m: SliderModel, b: Batch, ph: Phase, st: StepOut, vb_old, dots_old, holder) -> None:
    """Energies (J) of the sliding step: external work, friction, dashpots and stiffness damping (trapezoidal in
    the velocities ``vb_old`` / ``b.v`` before / after the update); ``holder``: ``(react_x N, fz_hd N, vz_old m/s,
    vz m/s, vx m/s)``, the reaction in x, the holder dashpot force and the holder's velocities."""
    react_x, fz_hd, vz_old, vz, vx = holder
    fd_dot_v_old, fb_dot_v_old = dots_old
    h = 0.5 * m.dt
    e = b.e
    vz_sum = vz_old + vz
    e["external"] += h * (-m.config.load_n * vz_sum + react_x * 2.0 * vx)
    e["damping"] -= h * fz_hd * vz_sum
    e["friction"] -= h * (member_dot if b.one else st.seg.dot)(st.fric, vb_old + b.vb.take(st.contact.ia, axis=1))
    paired = ph.c_per_s > 0 and b.damp_pair is not None
    if paired:
        fd_dot_v, nkv_dot_v = b.damping_dots(b.v)
    if ph.c_per_s > 0:
        # dashpots between each node and the frame (vx, 0, vz_old): they dissipate c m |w|^2 (w = velocity
        # relative to the frame, >= 0), the holder feeds them f_d . v_frame
        if b.one:
            fdx, fdz = _add(b.fdamp_xz, 1).tolist()
        else:
            fdx, fdz = np.add.reduce(b.fdamp[::2], axis=(1, 3, 4))  # per-member sums of x and z, one call
        fd_frame = 2.0 * (vx * fdx + vz_old * fdz)
        e["damping"] -= h * (fd_dot_v_old + (fd_dot_v if paired else b.mdot(b.fdamp, b.v)) - fd_frame)
        e["external"] += h * fd_frame
    if b.fbeta is not None:
        e["damping"] -= h * (fb_dot_v_old + b.mdot(b.fbeta, b.v))
    elif b.nkv is not None:  # the Rayleigh stiffness part -beta K v(n-1/2) is beta * nkv
        e["damping"] -= h * (fb_dot_v_old + m.beta_r * (nkv_dot_v if paired else b.mdot(b.nkv, b.v)))


def step(m: SliderModel, b: Batch, ph: Phase, k: int, load_factor: float, clock: Clock) -> StepOut:
    """One central-difference step of every member of ``b`` (``k``: step index within the phase)."""
    clock.lap(5)
    _internal_force(m, b, ph, k, load_factor)
    clock.lap(0)
    _damping_force(b, ph)
    clock.lap(1)
    st = _contact_and_friction(m, b, clock)
    _advance(m, b, ph, st)
    clock.lap(4)
    return st


# ---- the two phases -------------------------------------------------------------------------------------------------


def preload(m: SliderModel, b: Batch, out: MemberOutput, clock: Clock) -> Batch:
    """Dynamic relaxation under the ramped load; a member leaves when its contact force is within tolerance of the
    load at two checks in a row (or after ``n_pre_max`` steps). Returns the preloaded members, in order."""
    ph = Phase.of(m, sliding=False)
    cfg = m.config
    done = []
    n_total = m.n_pre_max + int(out.n_slide.max())
    for k in range(m.n_pre_max):
        step(m, b, ph, k, _ramp(k * m.dt, m.t_ramp), clock)
        check = k >= m.n_ramp and (k - m.n_ramp) % m.n_check == 0
        clock.lap(5)
        clock.report(k + 1, n_total)
        if not check and k + 1 < m.n_pre_max:
            continue
        leave = np.full(b.n, k + 1 == m.n_pre_max)
        if check:
            ok = np.abs(b.fz_sum - cfg.load_n) <= cfg.preload_tolerance * cfg.load_n
            leave |= ok & b.prev_ok & (k + 1 < m.n_pre_max)
            b.prev_ok = ok
        if leave.any():
            out.n_pre[b.ids[leave]] = k + 1
            done.append(b.take(leave))
            if leave.all():
                break
            b = b.take(~leave)
    return Batch.concat(done)


def _same_preload(laws) -> np.ndarray:
    """For each member, the first member with an equal friction law (``==``, or the same object)."""
    return np.array([next(i for i in range(j + 1) if laws[i] is law or laws[i] == law) for j, law in enumerate(laws)])


def preload_shared(m: SliderModel, b: Batch, out: MemberOutput, clock: Clock) -> Batch:
    """:func:`preload` of the members with distinct friction laws only; the others get a copy of their twin's state.

    The preload does not depend on the test speed: the slider is pressed onto the pavement at rest (the speed is
    given at the start of the slide, :meth:`MemberOutput.start_slide`), and every member steps bit for bit as a single
    run (the batch tests), so members with equal laws preload to the same bits. A calibration batch (one law,
    three speeds) preloads once instead of three times, a validation batch of two laws at six speeds twice
    instead of twelve times.
    """
    first = _same_preload(b.laws)
    distinct = first == np.arange(b.n)
    if distinct.all():
        return preload(m, b, out, clock)
    done = preload(m, b.take(distinct), out, clock)  # members in id order: the distinct ids
    out.n_pre[b.ids] = out.n_pre[b.ids[first]]
    pos = np.searchsorted(done.ids, b.ids[first])
    return done.spread(pos, b.ids, b.v_slide)


def slide(m: SliderModel, b: Batch, out: MemberOutput, clock: Clock) -> None:
    """Every node gets the test speed in x, the holder slides; a member leaves when it has slid its length."""
    log.info(
        "preload: contact force %s N (load %.4f N) after %s steps",
        np.array2string(b.fz_sum, precision=4),
        m.config.load_n,
        out.n_pre[b.ids],
    )
    out.start_slide(b)
    ph = Phase.of(m, sliding=True)
    n_done = int(out.n_pre.max())
    n_slide = out.n_slide[b.ids]
    n_total, next_leave = n_done + int(n_slide.max()), int(n_slide.min())  # the longest slide leaves last
    for i in range(int(n_slide.max())):
        st = step(m, b, ph, i, 1.0, clock)
        out.record(b, st, i)
        clock.lap(5)
        clock.report(n_done + i + 1, n_total)
        if i + 1 < next_leave:
            continue
        leave = n_slide == i + 1
        out.finish(b.take(leave))
        if leave.all():
            break
        b = b.take(~leave)
        n_slide = out.n_slide[b.ids]
        next_leave = int(n_slide.min())
