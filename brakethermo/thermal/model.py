"""Batched 1D radial finite-element disc model with through-thickness layers (eq. 1–15).

State layout
------------
``N`` radial nodes times ``L`` layers, node-major: state index ``i * L + j`` is radial
node ``i``, layer ``j``; layer 0 is the face the IR sensor sees, layer ``L - 1`` touches
the mid-plane. With this ordering radial coupling has offset ``L`` and through-thickness
coupling offset 1, so the system is banded with half-bandwidth ``L`` (tridiagonal for
the paper's one-layer model, ``L = 1``).

Layers are finite volumes across the half thickness; the mid-plane is a symmetry plane
(adiabatic), so layer ``j`` stands for two mirrored slices and all energies and powers
are those of the whole disc. Slice thicknesses grow geometrically from the face towards
the mid-plane by ``layer_growth`` (1 = equal slices of ``s / (2 L)``): braking with a
poorly conducting weave makes a thin hot skin under the rubbed face, which a thin face
layer resolves with few states (:func:`layer_thicknesses`).

Discretisation choices
----------------------
* Lumped capacity matrix (row sums of the consistent axisymmetric one) and lumped face
  convection/radiation: the system stays banded with a positive diagonal and
  non-positive off-diagonals (an M-matrix), so backward Euler is monotone — no
  undershoots below ambient after a braking spike — and the LDL^T solve needs no
  pivoting. Lumping keeps second-order spatial accuracy for linear elements.
* c(T) per node, k(T) per element at the mean of its two nodes, radiation — all from the
  previous step (eq. 15). Radiation leaves both faces of the face layer; the rims only
  convect (paper, after eq. 12), with the same ``h`` as the faces.
* ``Q`` is the power entering this disc; the friction flux is integrated exactly against
  the shape functions, so the injected power is ``Q`` for any mesh (``power.py``).
* ``h`` is used as given (no clipping): a slightly negative sigma-point ``h`` keeps the
  matrix positive definite because ``M/dt`` dominates (~1e5 W/(m^2 K) per face area).

Per-member or shared matrix
---------------------------
:meth:`DiscFEModel.step` by default builds and factorises one matrix per batch member
from that member's own previous state: the exact eq. 15 for every sigma point, which is
what an unscented filter needs (and the only choice when ``h``, ``kz_ratio`` or the load
differ per member). ``shared_matrix_from=x_ref`` builds one matrix from ``x_ref`` and
solves all members with it (radiation stays per member): exact when c and k are
constant, otherwise a linearisation of the properties about ``x_ref`` — meant for linear
Kalman filters/smoothers and EKF-style use. With numba both cost about the same per
member, since the fused kernel assembles a matrix for little more than its solve.

Extension points
----------------
The power distribution (``weights``, ``power_shape`` or a per-step ``load``), ``h``
(any law, evaluated by the caller), a braking-power ``scale`` and ``kz_ratio`` are
explicit inputs; sensor lag or bias act on the output (:meth:`spot_matrix`) and are
composed outside the model. The measured face is the face *layer*; for a sensor that
should see the rubbed surface itself, :meth:`DiscFEModel.surface_temperature` adds the
half-layer temperature jump of the surface flux balance.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from brakethermo.thermal import _fe_kernels as kernels
from brakethermo.thermal._fe_kernels import KELVIN, ramp_table
from brakethermo.thermal.banded import factor_banded, solve_factored
from brakethermo.thermal.disc import DiscSpec
from brakethermo.thermal.fe import (
    conduction_factors,
    interpolation_matrix,
    nodal_areas,
    piecewise_flux_load,
    radial_nodes,
)
from brakethermo.thermal.power import crown_load, normalise_weights, shape_load

SIGMA = 5.670374419e-8  # W/(m^2 K^4), Stefan–Boltzmann


def _owned(a: np.ndarray) -> np.ndarray:
    """C-contiguous, writeable float64 (one numba signature for every caller)."""
    if a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


@dataclass(frozen=True)
class PowerTerms:
    """Heat flows of one step, W per batch member (see :meth:`DiscFEModel.power_terms`)."""

    friction: np.ndarray
    convection: np.ndarray
    radiation: np.ndarray

    @property
    def net(self) -> np.ndarray:
        """Net power into the disc, W."""
        return self.friction - self.convection - self.radiation


def layer_thicknesses(
    thickness: float, layers: int, growth: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Geometrically graded layers over the half thickness, face first.

    Layer ``j`` stands for two mirrored slices; their joint thickness is
    ``t_j = s g^j / S`` with ``S = sum_j g^j``, so ``sum t_j = s``. Between layers ``j``
    and ``j + 1`` each half conducts across the centre-to-centre distance
    ``(t_j + t_{j+1}) / 4``, so both together give ``8 a k_z / (t_j + t_{j+1})``; this
    is returned as ``n_j = 2 s / (t_j + t_{j+1})``, the count of equal layers with that
    spacing, in the closed form ``2 S / (g^j (1 + g))`` that is exactly ``L`` for equal
    layers (so ``growth = 1`` reproduces the equal-layer model bit for bit).

    Parameters
    ----------
    thickness : float — m
        Disc thickness s.
    layers : int
        Number of layers L over the half thickness.
    growth : float
        Ratio of successive slice thicknesses from the face to the mid-plane (> 0).

    Returns
    -------
    t : ndarray, shape (L,) — m
        Joint thickness of both mirrored slices of each layer.
    n_eq : ndarray, shape (L - 1,)
        Equivalent layer count of each interface; its conductance is
        ``4 n_eq a k_z / s`` (W/K for face area ``a``).
    """
    g = float(growth) ** np.arange(layers)
    S = g.sum()
    t = thickness * g / S
    n_eq = 2.0 * S / (g[:-1] * (1.0 + float(growth)))
    return t, n_eq


def _enthalpy_table(temp_c: np.ndarray, c: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``e(T) = int_0^T c dT`` (J/kg) for a c table linear between points, constant outside.

    With ``c`` written as ramps (:func:`ramp_table`) each ramp integrates in closed form.
    """
    x0, slope, width, c0 = ramp_table(temp_c, c)

    def ramp_integral(t: np.ndarray) -> np.ndarray:
        u = np.asarray(t, dtype=float)[..., None] - x0
        inside = np.clip(u, 0.0, width)
        return (slope * (0.5 * inside**2 + width * np.maximum(u - width, 0.0))).sum(axis=-1)

    return lambda t: c0 * np.asarray(t, dtype=float) + ramp_integral(t) - ramp_integral(0.0)


class DiscFEModel:
    """Batched backward-Euler 1D-FE disc model (eq. 15), one matrix per batch member.

    Parameters
    ----------
    disc : DiscSpec
        Datasheet (geometry, ``rho``, ``c(T)``, ``k(T)``, emissivity, pad crowns).
    n_nodes : int
        Radial nodes N (>= 2; the paper uses 10 and 51).
    layers : int
        Through-thickness layers L over the half thickness (1 = the paper's model).
    layer_growth : float
        Ratio of successive layer thicknesses from the face towards the mid-plane
        (1 = equal layers; e.g. 2.5 with L = 4 gives a face layer ~4 % of the half
        thickness to resolve the hot skin under braking). See :func:`layer_thicknesses`.
    weights : sequence of 3 float
        Pad-crown weights w_1..w_3 (eq. 6–8), normalised to conserve power.
    power_shape : ndarray (N,) or callable, optional
        Replaces the crown distribution: nodal shares of ``Q`` (normalised to sum 1) or a
        radial flux shape ``f(r_m)`` integrated by :func:`power.shape_load`.
    kz_ratio : float
        Multiplier of the through-thickness conductivity (``L > 1`` only); a batch can
        override it per member in :meth:`step` (e.g. an identified parameter).
    k_z : float, optional — W/(m K)
        Constant through-thickness conductivity; by default it is the in-plane ``k(T)``
        (carbon–carbon is orthotropic, so the ratio is a real unknown).
    dt : float — s
        Time step (0.1 s = the 10 Hz grid).
    use_numba : bool or None
        Banded kernel: numba (``None``), or force numba / numpy.
    """

    def __init__(
        self,
        disc: DiscSpec,
        n_nodes: int = 10,
        layers: int = 1,
        *,
        weights: Sequence[float] = (1.0, 1.0, 1.0),
        power_shape: np.ndarray | Callable[[np.ndarray], np.ndarray] | None = None,
        kz_ratio: float = 1.0,
        k_z: float | None = None,
        dt: float = 0.1,
        use_numba: bool | None = None,
        layer_growth: float = 1.0,
    ) -> None:
        if n_nodes < 2 or layers < 1:
            raise ValueError("need n_nodes >= 2 and layers >= 1")
        if dt <= 0 or kz_ratio <= 0 or (k_z is not None and k_z <= 0):
            raise ValueError("dt, kz_ratio and k_z must be > 0")
        if not (np.isfinite(layer_growth) and layer_growth > 0):
            raise ValueError(f"layer_growth must be finite and > 0, got {layer_growth}")
        self.disc = disc
        self.n_nodes = int(n_nodes)
        self.layers = int(layers)
        self.n_state = self.n_nodes * self.layers
        self.dt = float(dt)
        self.kz_ratio = float(kz_ratio)
        self.layer_growth = float(layer_growth)
        self.use_numba = True if use_numba is None else bool(use_numba)
        self.radii = radial_nodes(disc.r_int, disc.r_est, self.n_nodes)
        self.face_index = np.arange(self.n_nodes) * self.layers

        # normalised crown weights (eq. 8); NaN when a power_shape replaces the crowns
        self.weights: np.ndarray
        if power_shape is None:
            self.weights = normalise_weights(weights, disc.crown_edges)
            self.load = crown_load(self.radii, disc.crown_edges, self.weights)
        elif callable(power_shape):
            self.weights = np.full(3, np.nan)
            self.load = shape_load(self.radii, power_shape)
        else:
            b = np.asarray(power_shape, dtype=float)
            if b.shape != (self.n_nodes,) or np.any(b < 0) or b.sum() <= 0:
                raise ValueError(f"power_shape must be {self.n_nodes} shares >= 0")
            self.weights = np.full(3, np.nan)
            self.load = b / b.sum()

        N, L, s = self.n_nodes, self.layers, disc.thickness
        a = nodal_areas(self.radii)
        self._face_area = a  # lumped area of one face per node, m^2
        t_layer, n_eq = layer_thicknesses(s, L, self.layer_growth)
        self.layer_thickness = t_layer  # (L,) m, both mirrored slices of each layer
        self._c_tab = (np.asarray(disc.c_temp_c, float), np.asarray(disc.c_value, float))
        self._k_tab = (np.asarray(disc.k_temp_c, float), np.asarray(disc.k_value, float))
        self._z_tab = self._k_tab if k_z is None else (np.zeros(1), np.full(1, float(k_z)))
        # Geometric factors that the step multiplies by material properties or h.
        self._cap_geo = disc.density * a[:, None] * t_layer  # (N, L): times c -> J/K
        # (N - 1, L): times k -> W/K
        self._cond_geo = t_layer * conduction_factors(self.radii)[:, None]
        # (N, L - 1): two interfaces (mirrored halves); times k_z -> W/K
        self._z_geo = 4.0 * n_eq * a[:, None] / s
        area = np.zeros((N, L))
        area[:, 0] = 2.0 * a  # both faces (eq. 3)
        area[0, :] += 2.0 * np.pi * self.radii[0] * t_layer  # inner rim (eq. 11)
        area[-1, :] += 2.0 * np.pi * self.radii[-1] * t_layer  # outer rim (eq. 12)
        self._area = area  # times h -> W/K
        self._rad_geo = 2.0 * a * SIGMA * disc.emissivity  # (N,), both faces (eq. 4)
        self._enthalpy = _enthalpy_table(*self._c_tab)
        self._kernel_args = (
            N, L, self.dt, self._cap_geo.ravel().copy(), self._cond_geo.ravel().copy(),
            self._z_geo.ravel().copy(), area.ravel().copy(), self._rad_geo,
            ramp_table(*self._c_tab), ramp_table(*self._k_tab), ramp_table(*self._z_tab),
        )  # fmt: skip

    def fingerprint(self) -> str:
        """A digest of everything the model steps with: mesh, time step, geometric
        factors, property tables (k_z included), node radii, crown edges and weights and
        the k_z ratio. Two models of one fingerprint step every state alike."""
        digest = hashlib.blake2b(digest_size=16)
        _feed(digest, (self._kernel_args, self.radii, self.disc.crown_edges,
                       tuple(self.weights), self.kz_ratio, self.use_numba))
        return digest.hexdigest()

    @property
    def kernel_geometry(self) -> tuple[Any, ...]:
        """What the compiled step takes after its per-member arrays (``step_nb``'s
        ``*geometry``: mesh sizes, time step, geometric factors, property tables), for
        compiled loops built on it elsewhere (:mod:`brakethermo.models._disc_kernels`)."""
        return self._kernel_args

    # ------------------------------------------------------------------ helpers
    def _batch(self, T: np.ndarray) -> tuple[np.ndarray, bool]:
        T = np.asarray(T, dtype=float)
        single = T.ndim == 1
        T2 = T[None, :] if single else T
        if T2.ndim != 2 or T2.shape[1] != self.n_state:
            raise ValueError(f"T must have shape (B, {self.n_state}), got {T.shape}")
        return T2, single

    @staticmethod
    def _per_member(x: float | np.ndarray, B: int) -> np.ndarray:
        """``x`` as a fresh or owned, writeable, C-contiguous float64 array of shape (B,).

        Writeable and contiguous so that numba sees one array type on every call (a
        read-only broadcast view would trigger a second compilation).
        """
        a = np.asarray(x, dtype=np.float64)
        if a.ndim == 0:
            return np.full(B, float(a))
        if a.shape != (B,):
            a = np.broadcast_to(a, (B,))
        if not (a.flags.c_contiguous and a.flags.writeable):
            a = a.copy()
        return a

    def _member_inputs(
        self,
        B: int,
        q: float | np.ndarray,
        h: float | np.ndarray,
        scale: float | np.ndarray,
        kz_ratio: float | np.ndarray | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The step's ``h``, ``kz_ratio`` and braking power per member (arguments as
        :meth:`step`; ``kz_ratio=None`` takes the model's).

        Returns
        -------
        h_b : ndarray, shape (B,) — W/(m^2 K)
        kz : ndarray, shape (B,) — dimensionless
        Qs : ndarray, shape (B,) — W, ``q * scale``
        """
        h_b = self._per_member(h, B)
        kz = self._per_member(self.kz_ratio if kz_ratio is None else kz_ratio, B)
        return h_b, kz, self._per_member(q, B) * self._per_member(scale, B)

    def initial_state(self, t_c: float) -> np.ndarray:
        """Uniform temperature ``t_c`` (degC) at every node, shape (n_state,)."""
        return np.full(self.n_state, float(t_c))

    def spot_matrix(self, radii: Sequence[float] | np.ndarray) -> np.ndarray:
        """Measurement matrix of face temperatures at ``radii`` (m), shape (m, n_state).

        Linear interpolation between the two face nodes around each radius (eq. 53).
        """
        H = np.zeros((np.size(radii), self.n_state))
        H[:, self.face_index] = interpolation_matrix(self.radii, radii)
        return H

    def surface_temperature(
        self,
        T: np.ndarray,
        q: float | np.ndarray,
        h: float | np.ndarray,
        t_amb: float | np.ndarray,
        scale: float | np.ndarray = 1.0,
        *,
        kz_ratio: float | np.ndarray | None = None,
        load: np.ndarray | None = None,
    ) -> np.ndarray:
        """Temperature of the rubbed surface at each radial node, degC, shape (B, N).

        The face layer's state is the mean over its slice (depth ``d_0 = t_0 / 2``, which
        is ``s / (2 L)`` for equal layers); the surface itself sits half a slice further
        out, where friction heat enters. The flux balance at the surface, linear in
        ``T_s`` except for radiation (taken at the face-layer temperature, as in eq. 15),
        ``k_z (T_s - T_face) / (d_0 / 2) = phi_fric - h (T_s - T_amb) - phi_rad``
        gives ``T_s``; ``phi_fric = Q w_i / (2 a_i)`` per face. Under braking this is
        hotter than the face layer by ~``phi d_0 / (2 k_z)`` — several K for the default
        conductivity, tens of K for a poorly conducting weave — and equal to it at rest
        in still air. Arguments as :meth:`step`; an optional measurement model for
        sensors that see the surface (``spot_matrix`` interpolates face-layer states).
        """
        T2, single = self._batch(T)
        B, N, L = T2.shape[0], self.n_nodes, self.layers
        T_face = T2.reshape(B, N, L)[:, :, 0]
        half_depth = 0.25 * self.layer_thickness[0]  # d_0 / 2: both slices are 2 d_0
        ta = self._per_member(t_amb, B)[:, None]
        h_b, kz, Qs = (x[:, None] for x in self._member_inputs(B, q, h, scale, kz_ratio))
        a_face = self._face_area
        phi_fric = Qs * self._load_rows(load, B) / (2.0 * a_face)
        phi_rad = self._radiation(T_face, ta[:, 0]) / (2.0 * a_face)
        R = half_depth / (kz * np.interp(T_face, *self._z_tab))
        T_s = T_face + R * (phi_fric - h_b * (T_face - ta) - phi_rad) / (1.0 + h_b * R)
        return T_s[0] if single else T_s

    def capacity(self, T: np.ndarray) -> np.ndarray:
        """Lumped heat capacity of each state at temperature ``T`` (degC), J/K."""
        T2, single = self._batch(T)
        C = self._cap_geo * np.interp(T2.reshape(-1, self.n_nodes, self.layers), *self._c_tab)
        C = C.reshape(T2.shape)
        return C[0] if single else C

    def energy(self, T: np.ndarray) -> np.ndarray | float:
        """Heat stored relative to a disc at 0 degC, ``sum rho V_i int_0^T_i c dT``, J."""
        T2, single = self._batch(T)
        e = self._enthalpy(T2).reshape(-1, self.n_nodes, self.layers)
        E = (self._cap_geo * e).sum(axis=(1, 2))
        return float(E[0]) if single else E

    # ---------------------------------------------------------------- assembly
    def _conductances(
        self, T3: np.ndarray, kz_ratio: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Radial ``G_r`` (B, N-1, L) and through-thickness ``G_z`` (B, N, L-1), W/K."""
        k_r = np.interp(0.5 * (T3[:, :-1] + T3[:, 1:]), *self._k_tab)
        G_r = k_r * self._cond_geo
        if self.layers == 1:
            return G_r, None
        k_z = np.interp(0.5 * (T3[:, :, :-1] + T3[:, :, 1:]), *self._z_tab)
        return G_r, kz_ratio[:, None, None] * k_z * self._z_geo

    def crown_basis(self) -> np.ndarray:
        """Nodal load of each pad crown alone, shape (3, N), per W of ``Q``.

        For crown weights ``w`` satisfying eq. 8 the load is ``w @ crown_basis()``, so a
        filter with the weights in its state can form one load row per sigma point and
        pass it to :meth:`step` as ``load``.
        """
        edges = self.disc.crown_edges
        flux = 1.0 / (np.pi * (edges[-1] ** 2 - edges[0] ** 2))
        return np.stack([piecewise_flux_load(self.radii, edges, flux * e) for e in np.eye(3)])

    def _load_rows(self, load: np.ndarray | None, B: int) -> np.ndarray:
        """Nodal shares of ``Q`` as (1, N) or (B, N) rows."""
        if load is None:
            return self.load[None, :]
        rows = np.asarray(load, dtype=np.float64)
        rows = rows[None, :] if rows.ndim == 1 else rows
        if rows.shape not in ((1, self.n_nodes), (B, self.n_nodes)):
            raise ValueError(f"load must have shape ({self.n_nodes},) or ({B}, {self.n_nodes})")
        return _owned(rows)

    def _rhs(
        self,
        T3: np.ndarray,
        Mdt: np.ndarray,
        h_b: np.ndarray,
        ta: np.ndarray,
        Qs: np.ndarray,
        load: np.ndarray,
    ) -> np.ndarray:
        """``M/dt T + p`` (eq. 15): convection to ambient, friction and lagged radiation."""
        p = (h_b[:, None, None] * self._area) * ta[:, None, None]
        p[:, :, 0] += Qs[:, None] * load - self._radiation(T3[:, :, 0], ta)
        return (Mdt * T3 + p).reshape(T3.shape[0], self.n_state)

    def system(
        self,
        T: np.ndarray,
        q: float | np.ndarray,
        h: float | np.ndarray,
        t_amb: float | np.ndarray,
        scale: float | np.ndarray = 1.0,
        kz_ratio: float | np.ndarray | None = None,
        load: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Banded system of eq. 15 for each batch member (arguments as :meth:`step`).

        Returns
        -------
        ab : ndarray, shape (B, L + 1, n_state)
            ``M/dt + A_cond + A_conv`` at the previous state, lower band storage
            (:mod:`brakethermo.thermal.banded`).
        rhs : ndarray, shape (B, n_state) — W
            ``M/dt T_{k-1} + p_{k-1}``.
        """
        T2, _ = self._batch(T)
        B = T2.shape[0]
        h_b, kz, Qs = self._member_inputs(B, q, h, scale, kz_ratio)
        T3 = T2.reshape(B, self.n_nodes, self.layers)
        ab, Mdt = self._matrix(T3, h_b, kz)
        rhs = self._rhs(T3, Mdt, h_b, self._per_member(t_amb, B), Qs, self._load_rows(load, B))
        return ab, rhs

    def _matrix(
        self, T3: np.ndarray, h_b: np.ndarray, kz: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``M/dt + A_cond + A_conv`` in band storage, and ``M/dt`` as (B, N, L)."""
        B, N, L, n = T3.shape[0], self.n_nodes, self.layers, self.n_state
        Mdt = self._cap_geo * np.interp(T3, *self._c_tab) / self.dt  # eq. 15
        G_r, G_z = self._conductances(T3, kz)

        diag = Mdt + h_b[:, None, None] * self._area  # A_conv lumped (eq. 3, 11, 12)
        diag[:, :-1] += G_r
        diag[:, 1:] += G_r
        ab = np.zeros((B, L + 1, n))
        ab[:, L, : (N - 1) * L] = -G_r.reshape(B, -1)
        if G_z is not None:
            diag[:, :, :-1] += G_z
            diag[:, :, 1:] += G_z
            off1 = np.zeros((B, N, L))
            off1[:, :, :-1] = -G_z
            ab[:, 1, :] = off1.reshape(B, n)
        ab[:, 0, :] = diag.reshape(B, n)
        return ab, Mdt

    def _radiation(self, T_face: np.ndarray, t_amb: np.ndarray) -> np.ndarray:
        """Radiated power per face node, W (eq. 4, lagged one step)."""
        return self._rad_geo * ((T_face + KELVIN) ** 4 - (t_amb[:, None] + KELVIN) ** 4)

    # -------------------------------------------------------------------- step
    def step(
        self,
        T: np.ndarray,
        q: float | np.ndarray,
        h: float | np.ndarray,
        t_amb: float | np.ndarray,
        scale: float | np.ndarray = 1.0,
        *,
        kz_ratio: float | np.ndarray | None = None,
        load: np.ndarray | None = None,
        shared_matrix_from: np.ndarray | None = None,
    ) -> np.ndarray:
        """Advance every batch member by one backward-Euler step (eq. 15).

        Parameters
        ----------
        T : ndarray, shape (B, n_state) or (n_state,) — degC
            Temperatures at step k-1.
        q : float or ndarray (B,) — W
            Braking power into this disc over the step.
        h : float or ndarray (B,) — W/(m^2 K)
            Convection coefficient (faces and rims).
        t_amb : float or ndarray (B,) — degC
            Ambient temperature.
        scale : float or ndarray (B,) — dimensionless
            Braking-power scale factor (e.g. a filter's friction-coefficient state).
        kz_ratio : float or ndarray (B,), optional
            Through-thickness conductivity multiplier; defaults to the model's.
        load : ndarray (N,) or (B, N), optional — dimensionless
            Nodal shares of ``Q`` on the face layer (sum 1 to conserve power); defaults to
            the model's crown distribution. See :meth:`crown_basis`.
        shared_matrix_from : ndarray (n_state,), optional — degC
            Build ``M``, ``A_cond`` from this one state and factorise once for all
            members (``h`` and ``kz_ratio`` must then be common); radiation stays per
            member. Exact when c and k are constant, an approximation otherwise.

        Returns
        -------
        ndarray, same shape as ``T`` — degC
        """
        T2, single = self._batch(T)
        B = T2.shape[0]
        h_b, kz, Qs = self._member_inputs(B, q, h, scale, kz_ratio)
        ta = self._per_member(t_amb, B)
        rows = self._load_rows(load, B)
        if shared_matrix_from is not None:
            if np.any(h_b != h_b[0]) or np.any(kz != kz[0]):
                raise ValueError("shared_matrix_from needs one h and kz_ratio for all members")
            Tm = np.asarray(shared_matrix_from, dtype=np.float64).reshape(1, self.n_state)
        else:
            Tm = T2
        if self.use_numba:
            Bm = Tm.shape[0]
            args = (_owned(T2), _owned(Tm), Qs, ta, h_b[:Bm].copy(), kz[:Bm].copy(), rows)
            out = kernels.step_nb(*args, *self._kernel_args)
        else:
            N, L, Bm = self.n_nodes, self.layers, Tm.shape[0]
            ab, Mdt = self._matrix(Tm.reshape(Bm, N, L), h_b[:Bm], kz[:Bm])
            rhs = self._rhs(T2.reshape(B, N, L), Mdt, h_b, ta, Qs, rows)
            out = solve_factored(factor_banded(ab, use_numba=False), rhs, use_numba=False)
        return out[0] if single else out

    def run_readout(
        self,
        T0: np.ndarray,
        q: np.ndarray,
        h: np.ndarray,
        t_amb: np.ndarray,
        kz_ratio: np.ndarray,
        loads: np.ndarray,
        zone: np.ndarray,
        H: np.ndarray,
        feedback: tuple[np.ndarray, np.ndarray, float, np.ndarray] | None = None,
    ) -> np.ndarray:
        """Open loop of B members through K steps, only a readout ``H T`` kept per step.

        The same steps as :meth:`step` called K times (one compiled loop instead).

        Parameters
        ----------
        T0 : ndarray (B, n_state) — degC
        q : ndarray (K, B) — W, braking power per member and step (scale applied)
        h : ndarray (K, B) — W/(m^2 K)
        t_amb : ndarray (K,) — degC
        kz_ratio : ndarray (B,)
        loads : ndarray (Z, B, N) — nodal shares of ``q`` (see :meth:`step`'s ``load``)
        zone : ndarray (K,) of int — which of the Z loads each step uses
        H : ndarray (m, n_state) — readout (e.g. face temperatures at the spots)
        feedback : tuple of (ndarray (B,), ndarray (B,), float, ndarray of int), optional
            A braking power that follows the temperature it makes (a friction
            coefficient μ(T)): ``(gain, centre, span, at)`` scales member b's power by
            ``1 + gain_b clip((T_c - centre_b)/span, -1, 1)``, ``T_c`` (degC) the mean
            of the state entries ``at`` before the step.

        Returns
        -------
        ndarray, shape (K + 1, B, m) — row 0 from ``T0``
        """
        T0 = _owned(np.atleast_2d(T0))
        B, K = T0.shape[0], len(zone)
        ta = _owned(np.broadcast_to(np.asarray(t_amb, float)[:K, None], (K, B)))
        gain, centre, span, at = feedback or (np.zeros(B), np.zeros(B), 1.0, np.arange(1))
        fb = np.column_stack([self._per_member(gain, B), self._per_member(centre, B),
                              np.full(B, float(span))])
        if not self.use_numba:
            out = np.empty((K + 1, B, H.shape[0]))
            T = T0
            out[0] = T @ H.T
            for k in range(K):
                x = np.clip((T[:, at].mean(axis=1) - fb[:, 1]) / fb[:, 2], -1.0, 1.0)
                T = self.step(T, q[k], h[k], ta[k], 1.0 + fb[:, 0] * x, kz_ratio=kz_ratio,
                              load=loads[zone[k]])
                out[k + 1] = T @ H.T
            return out
        return kernels.run_nb(T0, _owned(q), ta, _owned(h), self._per_member(kz_ratio, B),
                              _owned(loads), np.ascontiguousarray(zone, dtype=np.int64),
                              _owned(np.asarray(H, float).T), fb,
                              np.ascontiguousarray(at, dtype=np.int64), *self._kernel_args)

    def open_loop(
        self,
        T0: np.ndarray,
        q: np.ndarray,
        h: np.ndarray,
        t_amb: np.ndarray,
        scale: float | np.ndarray = 1.0,
    ) -> np.ndarray:
        """Open-loop simulation (the 1D-FE baseline).

        Parameters
        ----------
        T0 : ndarray (n_state,) — degC
        q, h, t_amb : ndarray (K,) — W, W/(m^2 K), degC
            Inputs of steps 1..K (step k uses the inputs at k-1, eq. 15).
        scale : float or ndarray (K,)
            Braking-power scale per step.

        Returns
        -------
        ndarray, shape (K + 1, n_state) — degC, row 0 = ``T0``
        """
        q = np.asarray(q, dtype=float)
        K = q.size
        h = np.broadcast_to(np.asarray(h, dtype=float), (K,))
        t_amb = np.broadcast_to(np.asarray(t_amb, dtype=float), (K,))
        scale = np.broadcast_to(np.asarray(scale, dtype=float), (K,))
        out = np.empty((K + 1, self.n_state))
        out[0] = T0
        for k in range(K):
            out[k + 1] = self.step(out[k], q[k], h[k], t_amb[k], scale[k])
        return out

    def power_terms(
        self,
        T_prev: np.ndarray,
        T_new: np.ndarray,
        q: float | np.ndarray,
        h: float | np.ndarray,
        t_amb: float | np.ndarray,
        scale: float | np.ndarray = 1.0,
        load: np.ndarray | None = None,
    ) -> PowerTerms:
        """Heat flows of the step ``T_prev -> T_new`` as the scheme computes them, W.

        Convection uses ``T_new`` (implicit), radiation and friction ``T_prev`` inputs, so
        ``sum(capacity(T_prev) (T_new - T_prev)) = dt * net`` to round-off.
        """
        P2, _ = self._batch(T_prev)
        N2, _ = self._batch(T_new)
        B = P2.shape[0]
        ta = self._per_member(t_amb, B)
        h_b = self._per_member(h, B)
        theta = N2.reshape(B, self.n_nodes, self.layers) - ta[:, None, None]
        conv = h_b * (self._area * theta).sum(axis=(1, 2))
        rad = self._radiation(P2.reshape(B, self.n_nodes, self.layers)[:, :, 0], ta).sum(axis=1)
        shares = self._load_rows(load, B).sum(axis=1)
        fric = self._per_member(q, B) * self._per_member(scale, B) * shares
        return PowerTerms(friction=fric, convection=conv, radiation=rad)


def _feed(digest: Any, value: Any) -> None:
    """Feed ``value`` (numbers, strings, arrays and tuples of them) into ``digest``."""
    if isinstance(value, tuple | list):
        digest.update(b"(%d" % len(value))
        for v in value:
            _feed(digest, v)
    elif isinstance(value, np.ndarray):
        digest.update(f"{value.dtype}{value.shape}".encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    else:
        digest.update(repr(value).encode())
