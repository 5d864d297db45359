"""Internal-force kernels for the structured slider mesh.

:class:`StructuredKernel` is the production kernel. It uses the structure of
:class:`skidsim.slidermesh.SliderMesh`: all elements are the same brick, so the element stiffness is one 24 x 24
matrix ``K_e``; nodal arrays are contiguous 4-d arrays, so the 8 corner nodes of *all* elements are 8 array
slices. **Internal layout**: the solver stores nodal arrays as ``(3, nz+1, ny+1, nx+1)`` (component, k, j, i; x
fastest), the transpose of the mesh contract's ``(3, nx+1, ny+1, nz+1)``: the innermost loop then runs over the
longest edge (x, the sliding direction) and the bottom face ``[:, 0]`` is contiguous; measured 1.7x faster
gather/scatter than the ``(i, j, k)`` order on the 0.5 mm slider. :func:`to_internal` and :func:`to_mesh_layout`
convert. One force evaluation is

1. gather: 8 slice copies into an element array ``U`` of shape ``(24, nz, ny, nx)``;
2. one matrix product ``F = K_e @ U`` (BLAS dgemm, 24 x 24 times 24 x n_elements);
3. scatter: 8 slice-adds of ``F`` into the nodal force array.

No per-element Python loop, no index arrays, no general scatter (``np.add.at``). :class:`NaiveKernel` is the
general unstructured gather/scatter implementation (fancy indexing with the connectivity table and
``np.add.at``/``np.bincount``) kept as the reference the benchmark compares against.

Viscoelasticity (generalised Maxwell / Prony series on the shear modulus) is handled in element-displacement
space: for each Prony term i the element keeps a 24-vector of "relaxed displacements" ``A_i`` with
``dA_i/dt = (U - A_i)/tau_i`` (integrated exactly for piecewise-constant U). The element force is
``K_inf U + sum_i G_i k_dev (U - A_i)`` where ``K_inf = K k_vol + G_inf k_dev``. Because the strain at any point
is linear in the element displacements, this is exactly the strain-space internal-variable formulation
(viscous strains ``B A_i``), at 24 numbers per element and term.
"""

from __future__ import annotations

import numpy as np

from skidsim.slidermesh import HEX_CORNERS, SliderMesh


def to_internal(a: np.ndarray) -> np.ndarray:
    """Mesh layout ``(3, nx+1, ny+1, nz+1)`` (or without the leading 3) to the solver's ``(3, nz+1, ny+1, nx+1)``."""
    a = np.asarray(a)
    axes = (0, 3, 2, 1) if a.ndim == 4 else (2, 1, 0)
    return np.ascontiguousarray(a.transpose(axes))


def to_mesh_layout(a: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_internal`."""
    return to_internal(a)


def corner_slices(mesh: SliderMesh) -> list[tuple]:
    """The 8 slices (internal layout, leading component axis) that pick each local corner of all elements."""
    nx, ny, nz = mesh.nx, mesh.ny, mesh.nz
    return [(slice(None), slice(dk, dk + nz), slice(dj, dj + ny), slice(di, di + nx)) for di, dj, dk in HEX_CORNERS]


class StructuredKernel:
    """f_int = K u on a structured mesh of identical bricks, by slicing (see module docstring).

    **Padded flat layout** (bit-identical to the 4-d slicing, 2-3x faster gather and scatter): element
    ``(k, j, i)`` gets the column ``(k (ny+1) + j) (nx+1) + i``, its node 0's flat node index. Corner ``c`` of
    every element is then node ``column + o_c`` with one constant offset ``o_c``, so the 8 gathers and the 8
    scatter-adds are contiguous 1-d slabs of each component (no 4-d strided iteration). The columns with
    ``j = ny`` or ``i = nx`` are dummy elements (5.7 % extra columns on the 0.5 mm slider): their gathered
    displacements are zeroed, so they carry zero force and energy.

    Parameters
    ----------
    mesh: the slider mesh.
    k_elastic: 24 x 24 element stiffness (N/m) of the elastic (long-term) part.
    k_dev_unit: 24 x 24 unit-shear-modulus deviatoric element matrix (m), needed with Prony terms.
    branch_g_pa: shear moduli G_i (Pa) of the Maxwell branches.
    branch_tau_s: relaxation times tau_i (s).
    batch: number of sliders (members) stored side by side. **Batched layout** ``(3, nz+1, B, ny+1, nx+1)``:
        the member axis sits between the layers and the rows, so each layer is ``B`` copies of the
        ``(ny+1, nx+1)`` face and the bottom and top faces of all members stay contiguous. It is the padded flat
        layout above with the layer stride ``B (ny+1)(nx+1)``: the same 8 slabs and one dgemm for all members,
        whose columns do not mix (each member's forces are those of a single-member kernel, bit for bit, with
        OpenBLAS: tested). ``batch = 1`` is the single-slider layout.
    """

    def __init__(
        self,
        mesh: SliderMesh,
        k_elastic: np.ndarray,
        *,
        k_dev_unit: np.ndarray | None = None,
        branch_g_pa=(),
        branch_tau_s=(),
        batch: int = 1,
    ):
        self.mesh = mesh
        self.batch = b = int(batch)
        self.k = np.ascontiguousarray(k_elastic, dtype=float)
        nx, ny, nz = mesh.nx, mesh.ny, mesh.nz
        self.slices = corner_slices(mesh)
        sy, sf = nx + 1, (nx + 1) * (ny + 1)
        sz = b * sf  # layer stride: B faces
        self.offsets = [dk * sz + dj * sy + di for di, dj, dk in HEX_CORNERS]
        self.n_nodes = (nz + 1) * sz
        self.n_cols = nz * sz  # padded element columns (real + dummy)
        # slab length: up to the last real element (the slab of the farthest corner then ends at the last node)
        self.n_slab = (nz - 1) * sz + (b - 1) * sf + (ny - 1) * sy + nx
        self.ue = np.zeros((24, self.n_cols))
        self._ue4 = self.ue.reshape(24, nz * b, ny + 1, nx + 1)
        self.fe = np.empty((24, self.n_cols))
        n = self.n_slab  # per-corner views of the element buffers and the dummy columns, made once
        self._ue_corners = [(self.ue[3 * c : 3 * c + 3, :n], o) for c, o in enumerate(self.offsets)]
        self._fe_corners = [(self.fe[3 * c : 3 * c + 3, :n], o) for c, o in enumerate(self.offsets)]
        self._dummies = (self._ue4[:, :, ny, :], self._ue4[:, :, :, nx])
        self.g = np.asarray(branch_g_pa, dtype=float)
        self.tau = np.asarray(branch_tau_s, dtype=float)
        self.k_dev = None if k_dev_unit is None else np.ascontiguousarray(k_dev_unit, dtype=float)
        self.a = [np.zeros((24, self.n_cols)) for _ in self.g]  # relaxed element displacements per term
        self._tmp = np.empty((24, self.n_cols)) if len(self.g) else None
        self._ftmp = np.empty((24, self.n_cols)) if len(self.g) else None
        self._k_neg = None
        self.branch_energy = np.zeros((len(self.g), b))  # J per term and member, at the last call
        if len(self.g) and self.k_dev is None:
            raise ValueError("Prony terms need k_dev_unit")

    def gather(self, u: np.ndarray) -> np.ndarray:
        """Element displacement array ``(24, n_cols)`` in the padded layout (dummy columns 0; the kernel's buffer)."""
        uf = u.reshape(3, self.n_nodes)
        n = self.n_slab
        for dst, o in self._ue_corners:
            dst[...] = uf[:, o : o + n]
        for dummy in self._dummies:  # dummy columns (j = ny, i = nx); the tail beyond n_slab
            dummy.fill(0.0)  # is such a column and stays 0 from the allocation
        return self.ue

    def scatter(self, fe: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Add element forces ``(24, n_cols)`` (padded layout, dummies 0) to the nodal array ``out`` (zeroed first)."""
        of = out.reshape(3, self.n_nodes)
        n = self.n_slab
        corners = (
            self._fe_corners if fe is self.fe else [(fe[3 * c : 3 * c + 3, :n], o) for c, o in enumerate(self.offsets)]
        )
        of[:, :n] = corners[0][0]  # corner 0 (offset 0) is assigned, the rest zeroed
        of[:, n:] = 0.0
        add = np.add
        for src, o in corners[1:]:
            dst = of[:, o : o + n]
            add(dst, src, out=dst)
        return out

    def real_columns(self, a: np.ndarray) -> np.ndarray:
        """The real elements' columns of a padded ``(24, n_cols)`` array as ``(24, nz, ny, nx)`` (``batch`` 1) or
        ``(24, nz, B, ny, nx)``."""
        nx, ny, nz = self.mesh.nx, self.mesh.ny, self.mesh.nz
        if self.batch == 1:
            return a.reshape(24, nz, ny + 1, nx + 1)[:, :, :ny, :nx]
        return a.reshape(24, nz, self.batch, ny + 1, nx + 1)[:, :, :, :ny, :nx]

    def member_dot(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per-member ``a . b`` (``batch``,) of two padded element arrays ``(24, n_cols)``; ``np.vdot`` for one."""
        if self.batch == 1:
            return np.array([np.vdot(a, b)])
        shape = (24 * self.mesh.nz, self.batch, -1)
        return np.einsum("kbs,kbs->b", a.reshape(shape), b.reshape(shape))

    def take(self, members) -> StructuredKernel:
        """A kernel for the members ``members`` (indices along the batch axis), with their Prony history."""
        members = np.asarray(members, dtype=np.intp)
        new = StructuredKernel(
            self.mesh,
            self.k,
            k_dev_unit=self.k_dev,
            branch_g_pa=self.g,
            branch_tau_s=self.tau,
            batch=members.size,
        )
        shape = (24, self.mesh.nz, self.batch, -1)
        for a_new, a in zip(new.a, self.a):
            a_new[...] = a.reshape(shape)[:, :, members].reshape(a_new.shape)
        return new

    @staticmethod
    def concat(kernels: list[StructuredKernel]) -> StructuredKernel:
        """One kernel for the members of ``kernels`` side by side (in that order), with their Prony history."""
        k0 = kernels[0]
        new = StructuredKernel(
            k0.mesh,
            k0.k,
            k_dev_unit=k0.k_dev,
            branch_g_pa=k0.g,
            branch_tau_s=k0.tau,
            batch=sum(k.batch for k in kernels),
        )
        for i, a_new in enumerate(new.a):
            parts = [k.a[i].reshape(24, k.mesh.nz, k.batch, -1) for k in kernels]
            a_new[...] = np.concatenate(parts, axis=2).reshape(a_new.shape)
        return new

    def force(self, u: np.ndarray, out: np.ndarray, *, negate: bool = False) -> np.ndarray:
        """Internal nodal forces (N) of nodal displacements ``u`` (m), internal layout ``(3, nz+1, ny+1, nx+1)``.

        ``negate=True`` returns ``-f_int`` (the force the elements exert on the nodes) bit for bit, at no extra
        cost: the negated matrices are used (IEEE rounding is sign-symmetric), which saves the solver a full
        array pass per step.
        """
        if not (out.flags.c_contiguous and u.flags.c_contiguous):
            raise ValueError("StructuredKernel.force: u and out must be C-contiguous (3, nz+1, [B,] ny+1, nx+1) arrays")
        ue = self.gather(u)
        if negate:
            if self._k_neg is None:
                self._k_neg = -self.k
            np.matmul(self._k_neg, ue, out=self.fe)
        else:
            np.matmul(self.k, ue, out=self.fe)
        if len(self.g):
            for i, gi in enumerate(self.g):
                np.subtract(ue, self.a[i], out=self._tmp)
                np.matmul(self.k_dev, self._tmp, out=self._ftmp)
                self.branch_energy[i] = 0.5 * gi * self.member_dot(self._tmp, self._ftmp)
                self._ftmp *= -gi if negate else gi
                self.fe += self._ftmp
        return self.scatter(self.fe, out)

    def strain_energy(self) -> float:
        """Stored energy (J) at the displacements of the last :meth:`force` call: ``U.K_inf.U/2 + sum_i E_i``
        (the sum over the members of a batch; :meth:`member_strain_energy` per member)."""
        return float(self.member_strain_energy().sum())

    def member_strain_energy(self) -> np.ndarray:
        """Stored energy (J) of each member (``batch``,) at the displacements of the last :meth:`force` call."""
        ue = self.ue
        fe = np.matmul(self.k, ue)
        return 0.5 * self.member_dot(ue, fe) + self.branch_energy.sum(axis=0)

    def relax(self, dt_s: float) -> np.ndarray:
        """Advance the Prony internal variables over ``dt_s`` (exact for constant element displacements).

        Must be called after :meth:`force` (it uses the element displacements gathered there). Returns the
        energy (J) dissipated in the branches over the step per member (``batch``,), ``sum_i beta_i * 2 * E_i`` with
        ``beta_i = 1 - exp(-dt/tau_i)`` and ``E_i`` the branch energy: the exact dissipation of the update.
        """
        if not len(self.g):
            return np.zeros(self.batch)
        ue = self.ue
        diss = np.zeros(self.batch)
        for i, tau in enumerate(self.tau):
            beta = -np.expm1(-dt_s / tau)
            # A_i += beta (U - A_i); the branch energy drops from E to (1-beta)^2 E: dissipated (1-(1-beta)^2) E
            np.subtract(ue, self.a[i], out=self._tmp)
            self._tmp *= beta
            self.a[i] += self._tmp
            diss += (1.0 - (1.0 - beta) ** 2) * self.branch_energy[i]
        return diss

    def reset_history(self, u: np.ndarray) -> None:
        """Set the relaxed displacements to the current ones (a fully relaxed state)."""
        ue = self.gather(u)
        for a in self.a:
            a[...] = ue


class NaiveKernel:
    """General unstructured gather/scatter with the connectivity table (the benchmark's baseline).

    ``scatter`` is ``"add_at"`` (``np.add.at``) or ``"bincount"`` (``np.bincount`` with weights, the usual fast
    NumPy idiom for a general scatter). Elastic only.
    """

    def __init__(self, mesh: SliderMesh, k_elastic: np.ndarray, scatter: str = "bincount"):
        self.mesh = mesh
        self.k = np.asarray(k_elastic, dtype=float)
        nx, ny, nz = mesh.nx, mesh.ny, mesh.nz
        k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
        # flat node ids in the internal (k, j, i) layout, element table (n_el, 8) in C3D8 corner order
        self.conn = np.stack(
            [((k.ravel() + dk) * (ny + 1) + j.ravel() + dj) * (nx + 1) + i.ravel() + di for di, dj, dk in HEX_CORNERS],
            axis=1,
        )
        self.n_nodes = mesh.n_nodes
        self.mode = scatter
        # flat dof index 3*node + d for component-first layout: d * n_nodes + node
        self.dof = (np.arange(3)[None, None, :] * self.n_nodes + self.conn[:, :, None]).reshape(-1, 24)
        if scatter not in ("add_at", "bincount"):
            raise ValueError(f"scatter must be 'add_at' or 'bincount', got {scatter!r}")

    def force(self, u: np.ndarray, out: np.ndarray) -> np.ndarray:
        uf = u.reshape(-1)
        ue = uf[self.dof]  # gather (n_el, 24)
        fe = ue @ self.k.T  # (n_el, 24)
        if self.mode == "add_at":
            of = np.zeros(3 * self.n_nodes)
            np.add.at(of, self.dof, fe)
        else:
            of = np.bincount(self.dof.ravel(), weights=fe.ravel(), minlength=3 * self.n_nodes)
        out[...] = of.reshape(out.shape)
        return out
