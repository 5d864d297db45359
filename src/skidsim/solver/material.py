"""Rubber material and the element matrices of the structured slider mesh.

Element formulation (documented choice, see docs/solver.md): **small-strain 8-node hexahedron with selective
reduced integration (SRI)**: the deviatoric stiffness is integrated with 2x2x2 Gauss points, the volumetric
stiffness with the single centre point. For linear elasticity on a parallelepiped this *is* the B-bar element
(mean dilatation). It has no spurious zero-energy (hourglass) modes, because the fully integrated deviatoric part
is rank-sufficient, so no hourglass control is needed and the hourglass energy is identically zero (it is still
reported, as 0.0 J, so that the energy table has the same columns as a C3D8R model). It avoids volumetric
locking at nu -> 0.5 through the one-point volumetric part.

Because every element of :class:`skidsim.slidermesh.SliderMesh` is the same brick, the whole internal-force
computation needs **one** 24 x 24 matrix. Degrees of freedom are ordered ``3 * a + d`` for local node ``a``
(C3D8 order, :data:`skidsim.slidermesh.HEX_CORNERS`) and component ``d`` (x, y, z).

Units: SI (Pa, kg/m^3, m, s, N).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skidsim.errors import ConfigError
from skidsim.slidermesh import HEX_CORNERS

_GP = 1.0 / np.sqrt(3.0)


@dataclass(frozen=True)
class RubberMaterial:
    """Isotropic rubber, linear elastic or viscoelastic (Prony series on the shear modulus).

    ``youngs_modulus_pa`` and ``poisson`` are the **long-term (relaxed)** elastic constants. The optional Prony
    terms ``prony_g`` (dimensionless shear-modulus fractions g_i, relative to the long-term shear modulus G_inf:
    G(t) = G_inf (1 + sum_i g_i exp(-t/tau_i))) and ``prony_tau_s`` (relaxation times tau_i in s) make the
    deviatoric response a generalised Maxwell (standard linear solid for one term). The bulk response is elastic.
    ``density_kg_m3`` in kg/m^3.
    """

    youngs_modulus_pa: float = 100e6
    poisson: float = 0.45
    density_kg_m3: float = 1200.0
    prony_g: tuple[float, ...] = ()
    prony_tau_s: tuple[float, ...] = ()

    def __post_init__(self):
        if not self.youngs_modulus_pa > 0:
            raise ConfigError(f"solver config field 'youngs_modulus_pa': expected > 0 Pa, got {self.youngs_modulus_pa}")
        if not -1.0 < self.poisson < 0.5:
            raise ConfigError(f"solver config field 'poisson': expected -1 < nu < 0.5, got {self.poisson}")
        if not self.density_kg_m3 > 0:
            raise ConfigError(f"solver config field 'density_kg_m3': expected > 0 kg/m^3, got {self.density_kg_m3}")
        if len(self.prony_g) != len(self.prony_tau_s):
            raise ConfigError(
                "solver config fields 'prony_g'/'prony_tau_s': expected equal lengths, got "
                f"{len(self.prony_g)} and {len(self.prony_tau_s)}"
            )
        if any(g < 0 for g in self.prony_g) or any(t <= 0 for t in self.prony_tau_s):
            raise ConfigError(
                "solver config fields 'prony_g'/'prony_tau_s': expected g_i >= 0 and tau_i > 0 s, got "
                f"{self.prony_g}, {self.prony_tau_s}"
            )

    @property
    def shear_modulus_pa(self) -> float:
        """Long-term shear modulus G_inf in Pa."""
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson))

    @property
    def bulk_modulus_pa(self) -> float:
        """Bulk modulus K in Pa (elastic, no relaxation)."""
        return self.youngs_modulus_pa / (3.0 * (1.0 - 2.0 * self.poisson))

    @property
    def lame_lambda_pa(self) -> float:
        return self.bulk_modulus_pa - 2.0 / 3.0 * self.shear_modulus_pa

    @property
    def branch_shear_moduli_pa(self) -> np.ndarray:
        """Shear moduli G_i = g_i * G_inf of the Maxwell branches in Pa."""
        return np.asarray(self.prony_g, dtype=float) * self.shear_modulus_pa

    @property
    def instantaneous_shear_modulus_pa(self) -> float:
        """G_0 = G_inf + sum G_i in Pa (governs the stable time step)."""
        return self.shear_modulus_pa + float(self.branch_shear_moduli_pa.sum())

    @property
    def dilatational_wave_speed_ms(self) -> float:
        """c_d = sqrt((K + 4/3 G_0) / rho) in m/s with the instantaneous shear modulus."""
        return float(
            np.sqrt((self.bulk_modulus_pa + 4.0 / 3.0 * self.instantaneous_shear_modulus_pa) / self.density_kg_m3)
        )

    @property
    def viscoelastic(self) -> bool:
        return len(self.prony_g) > 0


def _shape_gradients(hx: float, hy: float, hz: float, xi: float, eta: float, zeta: float) -> np.ndarray:
    """dN_a/dx_j at natural point (xi, eta, zeta) of an hx*hy*hz brick, shape (8, 3), 1/m."""
    s = 2.0 * HEX_CORNERS - 1.0  # (8, 3) node signs
    nx_ = 0.125 * s[:, 0] * (1 + s[:, 1] * eta) * (1 + s[:, 2] * zeta) * 2.0 / hx
    ny_ = 0.125 * s[:, 1] * (1 + s[:, 0] * xi) * (1 + s[:, 2] * zeta) * 2.0 / hy
    nz_ = 0.125 * s[:, 2] * (1 + s[:, 0] * xi) * (1 + s[:, 1] * eta) * 2.0 / hz
    return np.stack([nx_, ny_, nz_], axis=1)


def strain_matrix(dn: np.ndarray) -> np.ndarray:
    """Small-strain B (6 x 24), Voigt order xx, yy, zz, yz, xz, xy with engineering shear strains."""
    b = np.zeros((6, 24))
    for a in range(8):
        gx, gy, gz = dn[a]
        c = 3 * a
        b[0, c] = gx
        b[1, c + 1] = gy
        b[2, c + 2] = gz
        b[3, c + 1] = gz
        b[3, c + 2] = gy
        b[4, c] = gz
        b[4, c + 2] = gx
        b[5, c] = gy
        b[5, c + 1] = gx
    return b


def element_matrices(hx: float, hy: float, hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit-modulus SRI element matrices of an ``hx x hy x hz`` (m) brick.

    Returns ``(k_vol, k_dev)`` (24 x 24, units m): the element stiffness is ``K * k_vol + G * k_dev`` for bulk
    modulus K and shear modulus G in Pa. ``k_vol`` is integrated at the centre point (mean dilatation),
    ``k_dev`` with 2x2x2 Gauss points.
    """
    vol = hx * hy * hz
    m = np.array([1.0, 1, 1, 0, 0, 0])
    d_vol = np.outer(m, m)
    d_dev = np.diag([2.0, 2, 2, 1, 1, 1]) - 2.0 / 3.0 * np.outer(m, m)
    b0 = strain_matrix(_shape_gradients(hx, hy, hz, 0.0, 0.0, 0.0))
    k_vol = vol * b0.T @ d_vol @ b0
    k_dev = np.zeros((24, 24))
    for xi in (-_GP, _GP):
        for eta in (-_GP, _GP):
            for zeta in (-_GP, _GP):
                b = strain_matrix(_shape_gradients(hx, hy, hz, xi, eta, zeta))
                k_dev += (vol / 8.0) * b.T @ d_dev @ b
    return 0.5 * (k_vol + k_vol.T), 0.5 * (k_dev + k_dev.T)


def element_stiffness(
    material: RubberMaterial, hx: float, hy: float, hz: float, *, instantaneous: bool = True
) -> np.ndarray:
    """24 x 24 element stiffness in N/m; with the instantaneous (``G_0``) or long-term (``G_inf``) shear modulus."""
    k_vol, k_dev = element_matrices(hx, hy, hz)
    g = material.instantaneous_shear_modulus_pa if instantaneous else material.shear_modulus_pa
    return material.bulk_modulus_pa * k_vol + g * k_dev


def element_max_frequency(
    material: RubberMaterial, hx: float, hy: float, hz: float, density_scale: float = 1.0
) -> float:
    """Highest natural circular frequency (rad/s) of one free element with lumped mass.

    By the element eigenvalue inequality (Irons; Hughes, *The Finite Element Method*, thm. 9.1.1) this bounds the
    highest frequency of any assembly of such elements with lumped mass from above, so ``2 / omega`` is a
    conservative central-difference stability limit. ``density_scale`` is the mass-scaling factor.
    """
    ke = element_stiffness(material, hx, hy, hz)
    m_node = material.density_kg_m3 * density_scale * hx * hy * hz / 8.0
    lam = np.linalg.eigvalsh(ke / m_node)
    return float(np.sqrt(lam.max()))


def lumped_mass(mesh, density_kg_m3: float) -> np.ndarray:
    """Row-sum lumped nodal masses in kg, shape ``(nx+1, ny+1, nz+1)``: each element gives rho*V/8 to its corners."""
    m = np.zeros(mesh.node_shape)
    me = density_kg_m3 * mesh.hx * mesh.hy * mesh.hz / 8.0
    for di, dj, dk in HEX_CORNERS:
        m[di : di + mesh.nx, dj : dj + mesh.ny, dk : dk + mesh.nz] += me
    return m
