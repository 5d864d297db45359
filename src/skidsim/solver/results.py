"""Simulation result and output writers (trace parquet, VTU series)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..atomic import atomic_path, write_parquet, write_text

#: Energy table keys (J); every entry is the change over the sliding phase, see :class:`SimulationResult`.
ENERGY_KEYS = ("external", "kinetic", "strain", "contact", "friction", "hourglass", "damping", "viscous", "residual")


@dataclass
class SimulationResult:
    """Outcome of one :func:`skidsim.solver.simulate` run.

    sn: simulated skid number = ``tangential_n / normal_n`` (means over the steady window).
    tangential_n: mean resisting force in N along x (sliding direction) exerted by the pavement on the slider
        (x-components of contact-normal and friction forces, sign so that resistance is positive).
    normal_n: mean vertical force in N exerted by the pavement on the slider.
    n_steps: number of time steps (preload + slide); dt_s: time step in s; wall_s: wall time of the run in s.
    energies: J, changes over the sliding phase: ``external`` (work of the top load and the holder reaction),
        ``kinetic``, ``strain`` (stored elastic + viscoelastic branch energy), ``contact`` (penalty energy),
        ``friction`` (dissipated), ``hourglass`` (0: the SRI element has no hourglass modes), ``damping``
        (dissipated by mass-proportional damping), ``viscous`` (dissipated in the Prony branches) and
        ``residual = external - (kinetic + strain + contact + friction + hourglass + damping + viscous)``.
    trace: DataFrame (time_s from the start of sliding, position_mm = holder displacement, tangential_n,
        normal_n, contact_area_mm2 = tributary area of the bottom nodes in contact, friction_x_n, contact_nodes,
        stick_nodes, slip_speed_ms = the slip speed the friction law sees, m/s, mean over the contact nodes
        weighted by their normal force).
    mean_slip_speed_ms: window mean of the trace's ``slip_speed_ms`` (m/s): the speed at which the friction law is
        sampled, to compare with the sliding speed ``speed_kmh / 3.6``.
    """

    sn: float
    tangential_n: float
    normal_n: float
    n_steps: int
    dt_s: float
    wall_s: float
    energies: dict
    trace: pd.DataFrame
    speed_kmh: float = 0.0
    slide_length_mm: float = 0.0
    slide_clamped: bool = False
    window_mm: tuple[float, float] = (0.0, 0.0)
    preload_steps: int = 0
    preload_contact_force_n: float = 0.0
    preload_contact_area_mm2: float = 0.0
    max_penetration_um: float = 0.0
    n_elements: int = 0
    omega_max_rad_s: float = 0.0
    mean_contact_area_mm2: float = 0.0
    mean_slip_speed_ms: float = float("nan")
    meta: dict = field(default_factory=dict)

    @property
    def element_steps_per_s(self) -> float:
        """Throughput of the whole run (elements x steps / wall s), including contact and output."""
        return self.n_elements * self.n_steps / self.wall_s if self.wall_s > 0 else float("nan")

    def energy_residual_fraction(self) -> float:
        """|residual| / |external work| of the sliding phase."""
        return abs(self.energies["residual"]) / max(abs(self.energies["external"]), 1e-300)

    def summary(self) -> dict:
        """Flat dict of the scalar results (for tables and JSON)."""
        d = {
            k: getattr(self, k)
            for k in (
                "sn",
                "tangential_n",
                "normal_n",
                "n_steps",
                "dt_s",
                "wall_s",
                "speed_kmh",
                "slide_length_mm",
                "slide_clamped",
                "preload_contact_force_n",
                "max_penetration_um",
                "n_elements",
                "mean_contact_area_mm2",
                "mean_slip_speed_ms",
            )
        }
        d["window_start_mm"], d["window_end_mm"] = self.window_mm
        d.update({f"energy_{k}_j": v for k, v in self.energies.items()})
        return d


def write_trace_parquet(trace: pd.DataFrame, path: str | Path) -> Path:
    """Write the trace as parquet atomically (:mod:`skidsim.atomic`)."""
    return write_parquet(path, trace)


class VtuSeriesWriter:
    """Decimated VTU series of the slider (point data: displacement in m, contact pressure in Pa) + a .pvd index.

    Each frame is written to a temporary name and renamed; the .pvd collection is rewritten atomically after
    each frame, so a ParaView user always sees a consistent series.
    """

    def __init__(self, directory: str | Path, mesh, *, prefix: str = "slider"):
        import meshio  # noqa: F401  (fail early if missing)

        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.mesh = mesh
        self.prefix = prefix
        self.frames: list[tuple[float, str]] = []

    def write(
        self, time_s: float, coordinates_m: np.ndarray, displacement_m: np.ndarray, contact_pressure_pa: np.ndarray
    ) -> Path:
        """Write one frame; arrays in mesh layout ``(3, nx+1, ny+1, nz+1)`` / ``(nx+1, ny+1, nz+1)``."""
        import meshio

        pts = (coordinates_m + displacement_m).reshape(3, -1).T
        cells = [("hexahedron", self.mesh.connectivity)]
        m = meshio.Mesh(
            pts,
            cells,
            point_data={
                "displacement_m": displacement_m.reshape(3, -1).T.copy(),
                "contact_pressure_pa": contact_pressure_pa.reshape(-1).copy(),
            },
        )
        name = f"{self.prefix}_{len(self.frames):04d}.vtu"
        with atomic_path(self.dir / name) as tmp:
            meshio.write(tmp, m, file_format="vtu")
        self.frames.append((float(time_s), name))
        self._write_pvd()
        return self.dir / name

    def _write_pvd(self):
        lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "<Collection>"]
        lines += [f'<DataSet timestep="{t:.9g}" part="0" file="{n}"/>' for t, n in self.frames]
        lines += ["</Collection>", "</VTKFile>", ""]
        write_text(self.dir / f"{self.prefix}.pvd", "\n".join(lines))
