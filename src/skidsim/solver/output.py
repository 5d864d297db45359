"""What each member of a run reports: preload, energies at the start and the end of its slide, trace rows, and its
:class:`skidsim.solver.results.SimulationResult` (SN = mean tangential / mean normal force over the steady window)."""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from skidsim.errors import ConfigError
from skidsim.friction import kmh_to_ms
from skidsim.solver.batch import Batch
from skidsim.solver.kernel import to_mesh_layout
from skidsim.solver.model import SliderModel
from skidsim.solver.results import SimulationResult, VtuSeriesWriter, write_trace_parquet

if TYPE_CHECKING:  # the step module imports this one
    from skidsim.solver.stepping import StepOut

log = logging.getLogger("skidsim.solver")


class MemberOutput:
    """What each member (by id) reports: preload, energies at the start and the end of its slide, trace rows."""

    FLOAT_ROWS = ("ft", "fn", "a", "ff", "sl")  # time and position: :meth:`trace` (the same IEEE operations)

    def __init__(self, m: SliderModel, speeds_kmh, vtu_dirs):
        n = len(speeds_kmh)
        self.m = m
        self.v_slide = np.array([float(kmh_to_ms(s)) for s in speeds_kmh])  # m/s
        self.n_slide = np.array([max(1, int(math.ceil(m.slide_m / (v * m.dt)))) for v in self.v_slide])
        self.n_pre = np.full(n, m.n_pre_max)  # lowered when a member's preload converges
        self.every = int(m.config.trace_every)
        self.n_rec = (self.n_slide + self.every - 1) // self.every
        rows = int(self.n_rec.max())
        self.rec = {k: np.empty((n, rows)) for k in self.FLOAT_ROWS}
        self.rec_nc = np.empty((n, rows), dtype=np.int64)
        self.rec_ns = np.empty((n, rows), dtype=np.int64)
        self.preload_force, self.preload_area = np.zeros(n), np.zeros(n)
        self.state0 = {k: np.zeros(n) for k in ("kinetic", "strain", "contact", "friction_elastic")}
        self.final = {k: np.zeros(n) for k in (*self.state0, "max_pen", *Batch.ENERGY)}
        self.vtu = [None if d is None else VtuSeriesWriter(d, m.mesh) for d in vtu_dirs]
        self.any_vtu = any(w is not None for w in self.vtu)
        frames = int(m.config.vtu_frames)
        self.vtu_steps = [
            set() if w is None else set(np.unique(np.linspace(0, ns - 1, frames).round().astype(int)).tolist())
            for w, ns in zip(self.vtu, self.n_slide)
        ]

    def start_slide(self, b: Batch) -> None:
        """Start of sliding: every node gets the test speed; the energies the slide's changes are measured from."""
        ids = b.ids
        self.preload_force[ids], self.preload_area[ids] = b.fz_sum, b.area_now
        b.v[0] += b.v_slide[:, None, None]
        b.kern.force(b.u, b.fint)
        self.state0["kinetic"][ids] = b.kinetic()
        self.state0["strain"][ids] = b.kern.member_strain_energy()
        self.state0["contact"][ids] = b.pen_energy
        self.state0["friction_elastic"][ids] = b.friction_elastic()

    def record(self, b: Batch, st: StepOut, i: int) -> None:
        """Trace row of slide step ``i`` (pavement forces on the slider at step n), maximum penetration, VTU."""
        c, seg, dt = st.contact, st.seg, self.m.dt
        if b.one:
            self._record_one(b, st, i)
        else:
            if c.d_m.size:
                b.max_pen = np.maximum(b.max_pen, seg.maximum(c.d_m, 0.0))
            if i % self.every == 0:
                self._record_rows(b, st, i)
        if not self.any_vtu:
            return
        for q, j in enumerate(b.ids):
            if self.vtu[j] is not None and i in self.vtu_steps[j]:
                i0, i1 = seg.edges[q], seg.edges[q + 1]
                p = np.zeros(self.m.mass.shape)
                p[0].reshape(-1)[c.ia[i0:i1] - q * self.m.n_face] = c.normal_n[i0:i1] / b.area_bf[c.ia[i0:i1]]
                self.vtu[j].write(i * dt, self.m.mesh.coordinates, to_mesh_layout(b.u[:, :, q]), to_mesh_layout(p))

    def _record_rows(self, b: Batch, st: StepOut, i: int) -> None:
        """The trace row of slide step ``i`` of each member of a batch."""
        c, seg, sums = st.contact, st.seg, st.sums
        r, ids, rec = i // self.every, b.rows, self.rec
        rec["ft"][ids, r] = -(sums[0] + sums[3])
        rec["fn"][ids, r] = b.fz_sum
        rec["a"][ids, r] = b.area_now
        rec["ff"][ids, r] = -sums[3]
        self.rec_nc[ids, r] = seg.counts()
        self.rec_ns[ids, r] = seg.count(st.stick)
        n_sum = sums[7]
        has_n = n_sum > 0.0
        rec["sl"][ids, r] = np.divide(seg.dot(c.normal_n, st.s), n_sum, out=np.full(b.n, np.nan), where=has_n)

    def _record_one(self, b: Batch, st: StepOut, i: int) -> None:
        """:meth:`record` of a batch of one: the single run's scalar operations."""
        c, sums = st.contact, st.sums
        d = c.d_m
        if d.size:
            d_max = float(d.max())
            if d_max > b.max_pen[0]:
                b.max_pen[0] = d_max
        if i % self.every == 0:
            r, j, rec = i // self.every, int(b.ids[0]), self.rec
            fx = sums[3]
            rec["ft"][j, r] = -float(sums[0] + fx)
            rec["fn"][j, r] = st.fz
            rec["a"][j, r] = st.area
            rec["ff"][j, r] = -float(fx)
            self.rec_nc[j, r] = c.ia.size
            self.rec_ns[j, r] = np.count_nonzero(st.stick)
            n_sum = float(sums[7])
            rec["sl"][j, r] = float(np.dot(c.normal_n, st.s)) / n_sum if n_sum > 0.0 else np.nan

    def finish(self, b: Batch) -> None:
        """Energies of the members of ``b`` at the end of their slide."""
        ids, f = b.ids, self.final
        b.kern.force(b.u, b.fint)
        f["kinetic"][ids] = b.kinetic()
        f["strain"][ids] = b.kern.member_strain_energy()
        f["contact"][ids] = b.pen_energy
        f["friction_elastic"][ids] = b.friction_elastic()
        f["max_pen"][ids] = b.max_pen
        for k in Batch.ENERGY:
            f[k][ids] = b.e[k]

    def energies(self, j: int) -> dict:
        """Energy changes (J) of member ``j`` over its slide; the tangential penalty springs' stored energy is
        contact energy, the friction entry is what they dissipate."""
        f, s0 = self.final, self.state0
        d_fric_elastic = float(f["friction_elastic"][j]) - float(s0["friction_elastic"][j])
        energies = dict(
            external=float(f["external"][j]),
            kinetic=float(f["kinetic"][j]) - float(s0["kinetic"][j]),
            strain=float(f["strain"][j]) - float(s0["strain"][j]),
            contact=float(f["contact"][j]) - float(s0["contact"][j]) + d_fric_elastic,
            friction=float(f["friction"][j]) - d_fric_elastic,
            hourglass=0.0,
            damping=float(f["damping"][j]),
            viscous=float(f["viscous"][j]),
        )
        energies["residual"] = energies["external"] - sum(
            energies[k] for k in ("kinetic", "strain", "contact", "friction", "hourglass", "damping", "viscous")
        )
        return energies

    def trace(self, j: int) -> pd.DataFrame:
        n, rec = int(self.n_rec[j]), self.rec
        step = np.arange(n) * self.every  # slide step of each row
        return pd.DataFrame(
            {
                "time_s": step * self.m.dt,
                "position_mm": (self.v_slide[j] * step * self.m.dt) * 1e3,
                "tangential_n": rec["ft"][j, :n].copy(),
                "normal_n": rec["fn"][j, :n].copy(),
                "contact_area_mm2": rec["a"][j, :n] * 1e6,
                "friction_x_n": rec["ff"][j, :n].copy(),
                "contact_nodes": self.rec_nc[j, :n].copy(),
                "stick_nodes": self.rec_ns[j, :n].copy(),
                "slip_speed_ms": rec["sl"][j, :n].copy(),
            }
        )

    def result(self, j: int, speed_kmh: float, y_offset_mm: float, trace_path, wall_s: float, phase_s: dict):
        """The :class:`SimulationResult` of member ``j``: SN = window mean tangential / window mean normal force."""
        m, cfg = self.m, self.m.config
        trace = self.trace(j)
        slide = m.slide_m
        w0 = cfg.window_start_mm
        w1 = slide * 1e3 if cfg.window_end_mm is None else min(cfg.window_end_mm, slide * 1e3)
        win = (trace["position_mm"] >= w0) & (trace["position_mm"] <= w1)
        if not win.any():
            raise ConfigError(
                f"simulate: the steady window [{w0}, {w1}] mm holds no trace rows (slide {slide * 1e3:.2f} mm)"
            )
        ft = float(trace.loc[win, "tangential_n"].mean())
        fn = float(trace.loc[win, "normal_n"].mean())
        if trace_path is not None:
            write_trace_parquet(trace, trace_path)
        n_total = int(self.n_pre[j] + self.n_slide[j])
        log.info("simulate: SN %.4f (Ft %.4f N / Fn %.4f N), %d steps", ft / fn, ft, fn, n_total)
        return SimulationResult(
            sn=ft / fn,
            tangential_n=ft,
            normal_n=fn,
            n_steps=n_total,
            dt_s=m.dt,
            wall_s=wall_s,
            energies=self.energies(j),
            trace=trace,
            speed_kmh=float(speed_kmh),
            slide_length_mm=slide * 1e3,
            slide_clamped=m.clamped,
            window_mm=(float(w0), float(w1)),
            preload_steps=int(self.n_pre[j]),
            preload_contact_force_n=float(self.preload_force[j]),
            preload_contact_area_mm2=float(self.preload_area[j]) * 1e6,
            max_penetration_um=float(self.final["max_pen"][j]) * 1e6,
            n_elements=m.mesh.n_elements,
            omega_max_rad_s=m.omega,
            mean_contact_area_mm2=float(trace.loc[win, "contact_area_mm2"].mean()),
            mean_slip_speed_ms=float(trace.loc[win, "slip_speed_ms"].mean()),
            meta=dict(
                config=cfg.as_dict(),
                y_offset_mm=float(y_offset_mm),
                omega_elastic_rad_s=m.omega_el,
                rayleigh_alpha_per_s=m.alpha_r,
                rayleigh_beta_s=m.beta_r,
                slope_bound=m.slope_bound,
                element_size_m=(m.mesh.hx, m.mesh.hy, m.mesh.hz),
                phase_s=phase_s,
                batch_size=len(self.n_slide),
            ),
        )
