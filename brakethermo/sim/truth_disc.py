"""2D axisymmetric truth model of one carbon disc: finite volumes on radius x half-thickness.

The disc is rubbed on both faces, so only the half thickness ``0 <= z <= s/2`` is
modelled: ``z = 0`` is the adiabatic mid-plane, ``z = s/2`` the rubbed face. The face
exchanges heat with the air by convection and radiation; both rims by convection and
radiation. Conductivity is anisotropic: in-plane ``k(T)`` from the datasheet and
through-thickness ``k_z(T) = kz_ratio * k(T)``. Backward Euler in time with material
properties and the radiation coefficient taken from the previous step; each step is
one symmetric banded solve (LAPACK ``pbsv``).

This model is deliberately different from, and richer than, the estimator's 1D
finite-element model; it shares nothing with it except the datasheet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

SIGMA_SB = 5.670374419e-8  # W/(m^2 K^4)
KELVIN = 273.15

PropertyFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class DiscGrid:
    """Finite-volume grid of the half disc.

    Attributes
    ----------
    r_edges : ndarray, shape (nr + 1,) — m
    z_edges : ndarray, shape (nz + 1,) — m, from the mid-plane (0) to the face (s/2)
    """

    r_edges: np.ndarray
    z_edges: np.ndarray

    @property
    def nr(self) -> int:
        return self.r_edges.size - 1

    @property
    def nz(self) -> int:
        return self.z_edges.size - 1

    @property
    def r_centres(self) -> np.ndarray:
        """Radial cell centres, m."""
        return 0.5 * (self.r_edges[1:] + self.r_edges[:-1])

    @property
    def z_centres(self) -> np.ndarray:
        """Axial cell centres, m."""
        return 0.5 * (self.z_edges[1:] + self.z_edges[:-1])

    @property
    def ring_areas(self) -> np.ndarray:
        """Face area of each radial column, m^2."""
        return np.pi * np.diff(self.r_edges**2)

    @property
    def volumes(self) -> np.ndarray:
        """Cell volumes, shape (nr, nz), m^3."""
        return self.ring_areas[:, None] * np.diff(self.z_edges)[None, :]


def make_grid(
    r_int: float, r_est: float, thickness: float, nr: int = 36, nz: int = 5, growth: float = 1.5
) -> DiscGrid:
    """Grid with uniform radial cells and axial cells growing geometrically from the face.

    Parameters
    ----------
    r_int, r_est : float — m
        Inner and outer radius.
    thickness : float — m
        Full disc thickness; the grid spans half of it.
    nr, nz : int
        Number of radial and axial cells.
    growth : float
        Ratio of neighbouring axial cell thicknesses, thinnest at the face so the
        face temperature in braking is resolved.
    """
    half = 0.5 * thickness
    widths = growth ** np.arange(nz)[::-1]
    z_edges = np.concatenate([[0.0], np.cumsum(widths)]) * (half / widths.sum())
    return DiscGrid(r_edges=np.linspace(r_int, r_est, nr + 1), z_edges=z_edges)


@dataclass(frozen=True)
class Boundary:
    """Heat exchange of one time step (half disc), all arrays per radial column.

    Attributes
    ----------
    q_face : ndarray, shape (nr,) — W/m^2
        Friction heat flux entering the face.
    h_face : float — W/(m^2 K)
        Convection coefficient on the face.
    h_inner, h_outer : float — W/(m^2 K)
        Convection coefficients on the inner and outer rim.
    t_amb : float — degC
    """

    q_face: np.ndarray
    h_face: float
    h_inner: float
    h_outer: float
    t_amb: float


@dataclass(frozen=True)
class _Surfaces:
    """Exchange of the face (per radial column) and of the inner and outer rims (per
    layer) over one step: the surface node is eliminated exactly, a conductance ``g1``
    from the outermost cell centre to the surface in series with ``g2`` to the air.

    Attributes
    ----------
    g1f, g2f : ndarray, shape (nr,) — W/(m^2 K), face: cell to surface, and surface to air
        (convection plus radiation).
    hr_f : ndarray, shape (nr,) — W/(m^2 K), face radiation coefficient.
    g1i, g2i, g1o, g2o : ndarray, shape (nz,) — W/K, inner and outer rim, as for the face.
    hr_i, hr_o : ndarray, shape (nz,) — W/(m^2 K), rim radiation coefficients.
    """

    g1f: np.ndarray
    hr_f: np.ndarray
    g2f: np.ndarray
    g1i: np.ndarray
    hr_i: np.ndarray
    g2i: np.ndarray
    g1o: np.ndarray
    hr_o: np.ndarray
    g2o: np.ndarray


class TruthDisc:
    """Implicit 2D conduction in the half disc with face and rim exchange.

    Parameters
    ----------
    grid : DiscGrid
    density : float — kg/m^3
    specific_heat : callable — J/(kg K) of degC
    conductivity : callable — in-plane W/(m K) of degC
    kz_ratio : float
        Through-thickness over in-plane conductivity.
    emissivity : float
        Emissivity of faces and rims (0 switches radiation off).
    """

    def __init__(
        self,
        grid: DiscGrid,
        density: float,
        specific_heat: PropertyFn,
        conductivity: PropertyFn,
        kz_ratio: float,
        emissivity: float,
    ):
        self.grid = grid
        self.density = density
        self.specific_heat = specific_heat
        self.conductivity = conductivity
        self.kz_ratio = kz_ratio
        self.emissivity = emissivity
        nr, nz = grid.nr, grid.nz
        re, rc = grid.r_edges, grid.r_centres
        ze, zc = grid.z_edges, grid.z_centres
        dz = np.diff(ze)
        self.area = grid.ring_areas  # face area per column, m^2
        self.volume = grid.volumes
        # Geometric factors of the cylindrical resistances, R = factor / k.
        self._rad_left = np.log(re[1:-1] / rc[:-1])[:, None] / (2 * np.pi * dz)[None, :]
        self._rad_right = np.log(rc[1:] / re[1:-1])[:, None] / (2 * np.pi * dz)[None, :]
        self._ax_low = (ze[1:-1] - zc[:-1])[None, :] / self.area[:, None]
        self._ax_high = (zc[1:] - ze[1:-1])[None, :] / self.area[:, None]
        self._face_dist = ze[-1] - zc[-1]  # m, last cell centre to the face
        self._rim_in = np.log(rc[0] / re[0]) / (2 * np.pi * dz)  # per layer, R * k
        self._rim_out = np.log(re[-1] / rc[-1]) / (2 * np.pi * dz)
        self.rim_area_in = 2 * np.pi * re[0] * dz  # m^2 per layer
        self.rim_area_out = 2 * np.pi * re[-1] * dz
        self._n = nr * nz

    # Face and rim exchange through a surface node eliminated exactly:
    # conductance g1 from the cell centre to the surface in series with g2 = h + h_rad.
    @staticmethod
    def _series(g1: np.ndarray, g2: np.ndarray) -> np.ndarray:
        return g1 * g2 / (g1 + g2)

    def _h_rad(self, t_surf: np.ndarray, t_amb: float) -> np.ndarray:
        ts, ta = t_surf + KELVIN, t_amb + KELVIN
        return self.emissivity * SIGMA_SB * (ts * ts + ta * ta) * (ts + ta)

    def step(
        self,
        T: np.ndarray,
        dt: float,
        bc: Boundary,
        t_face_prev: np.ndarray,
        t_rims_prev: tuple[np.ndarray, np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray], np.ndarray]:
        """Advance one backward-Euler step.

        Parameters
        ----------
        T : ndarray, shape (nr, nz) — degC
            Cell temperatures at the start of the step.
        dt : float — s
        bc : Boundary
        t_face_prev : ndarray, shape (nr,) — degC
            Face temperature at the start of the step (lags the radiation coefficient).
        t_rims_prev : (ndarray, ndarray), shape (nz,) each — degC
            Inner and outer rim surface temperatures at the start of the step.

        Returns
        -------
        T_new : ndarray, shape (nr, nz) — degC
        t_face : ndarray, shape (nr,) — degC, face temperature at the end of the step
        t_rims : (ndarray, ndarray) — degC, rim surface temperatures at the end
        flows : ndarray, shape (5,) — J over the step, half disc:
            friction in, face convection out, face radiation out, rim convection out,
            rim radiation out.
        """
        k = self.conductivity(T)
        kz = self.kz_ratio * k
        cap = self.density * self.specific_heat(T) * self.volume / dt  # W/K
        g_rad = 1.0 / (self._rad_left / k[:-1] + self._rad_right / k[1:])  # (nr-1, nz)
        g_ax = 1.0 / (self._ax_low / kz[:, :-1] + self._ax_high / kz[:, 1:])  # (nr, nz-1)
        sx = self._surfaces(k, kz, bc, t_face_prev, t_rims_prev)
        T_new = self._solve(T, cap, g_rad, g_ax, sx, bc)
        t_face, t_rims, flows = self._surface_flows(T_new, dt, sx, bc)
        return T_new, t_face, t_rims, flows

    def _surfaces(
        self,
        k: np.ndarray,
        kz: np.ndarray,
        bc: Boundary,
        t_face_prev: np.ndarray,
        t_rims_prev: tuple[np.ndarray, np.ndarray],
    ) -> _Surfaces:
        """Conductances of the face and the rims over one step.

        Parameters
        ----------
        k, kz : ndarray, shape (nr, nz) — W/(m K), in-plane and through-thickness
            conductivity of the cells.
        bc : Boundary
        t_face_prev, t_rims_prev : as in :meth:`step` — degC, surface temperatures at the
            start of the step (the radiation coefficients are taken there).
        """
        ta = bc.t_amb
        g1f = kz[:, -1] / self._face_dist
        hr_f = self._h_rad(t_face_prev, ta)
        g1i = 1.0 / (self._rim_in / k[0])
        hr_i = self._h_rad(t_rims_prev[0], ta)
        g1o = 1.0 / (self._rim_out / k[-1])
        hr_o = self._h_rad(t_rims_prev[1], ta)
        return _Surfaces(
            g1f=g1f,
            hr_f=hr_f,
            g2f=bc.h_face + hr_f,
            g1i=g1i,
            hr_i=hr_i,
            g2i=(bc.h_inner + hr_i) * self.rim_area_in,
            g1o=g1o,
            hr_o=hr_o,
            g2o=(bc.h_outer + hr_o) * self.rim_area_out,
        )

    def _solve(
        self,
        T: np.ndarray,
        cap: np.ndarray,
        g_rad: np.ndarray,
        g_ax: np.ndarray,
        sx: _Surfaces,
        bc: Boundary,
    ) -> np.ndarray:
        """Cell temperatures at the end of the step, degC: the implicit balance assembled
        and solved as one symmetric banded system.

        Parameters
        ----------
        T : ndarray, shape (nr, nz) — degC, at the start of the step.
        cap : ndarray, shape (nr, nz) — W/K, heat capacity over the step.
        g_rad : ndarray, shape (nr - 1, nz) — W/K, between radial neighbours.
        g_ax : ndarray, shape (nr, nz - 1) — W/K, between axial neighbours.
        sx : _Surfaces
        bc : Boundary
        """
        nr, nz = T.shape
        ta = bc.t_amb
        gf = self.area * self._series(sx.g1f, sx.g2f)
        sf = self.area * sx.g1f / (sx.g1f + sx.g2f) * (bc.q_face + sx.g2f * ta)
        gi, go = self._series(sx.g1i, sx.g2i), self._series(sx.g1o, sx.g2o)

        diag = cap.copy()
        diag[:-1] += g_rad
        diag[1:] += g_rad
        diag[:, :-1] += g_ax
        diag[:, 1:] += g_ax
        diag[:, -1] += gf
        diag[0] += gi
        diag[-1] += go
        rhs = cap * T
        rhs[:, -1] += sf
        rhs[0] += gi * ta
        rhs[-1] += go * ta

        # Upper banded storage, unknown index i*nz + j: axial neighbours at +1,
        # radial neighbours at +nz.
        ab = np.zeros((nz + 1, self._n))
        ab[nz] = diag.ravel()
        up1 = np.zeros((nr, nz))
        up1[:, 1:] = -g_ax
        ab[nz - 1] = up1.ravel()
        ab[0, nz:] = -g_rad.ravel()
        _, x, info = lapack.dpbsv(ab, rhs.ravel(), lower=0, overwrite_ab=1, overwrite_b=1)
        if info != 0:
            raise FloatingPointError(f"banded solve failed (info={info})")
        return x.reshape(nr, nz)

    def _surface_flows(
        self, T_new: np.ndarray, dt: float, sx: _Surfaces, bc: Boundary
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray], np.ndarray]:
        """Face and rim temperatures at the end of the step (degC) and the step's energy
        flows (J, half disc), as returned by :meth:`step`.

        Parameters
        ----------
        T_new : ndarray, shape (nr, nz) — degC, cells at the end of the step.
        dt : float — s
        sx : _Surfaces
        bc : Boundary
        """
        ta = bc.t_amb
        t_face = (bc.q_face + sx.g2f * ta + sx.g1f * T_new[:, -1]) / (sx.g1f + sx.g2f)
        t_in = (sx.g2i * ta + sx.g1i * T_new[0]) / (sx.g1i + sx.g2i)
        t_out = (sx.g2o * ta + sx.g1o * T_new[-1]) / (sx.g1o + sx.g2o)
        conv_face = np.sum(bc.h_face * (t_face - ta) * self.area)
        rad_face = np.sum(sx.hr_f * (t_face - ta) * self.area)
        conv_rim = np.sum(bc.h_inner * self.rim_area_in * (t_in - ta)) + np.sum(
            bc.h_outer * self.rim_area_out * (t_out - ta)
        )
        rad_rim = np.sum(sx.hr_i * self.rim_area_in * (t_in - ta)) + np.sum(
            sx.hr_o * self.rim_area_out * (t_out - ta)
        )
        flows = dt * np.array(
            [np.sum(bc.q_face * self.area), conv_face, rad_face, conv_rim, rad_rim]
        )
        return t_face, (t_in, t_out), flows

    def initial_surfaces(self, T: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """Surface temperatures of a field at rest (no flux): the outermost cells."""
        return T[:, -1].copy(), (T[0].copy(), T[-1].copy())

    def mid_plane(self, T: np.ndarray) -> np.ndarray:
        """Mid-plane temperature per column, degC: ``T = a + b z^2`` through the two
        innermost cells (the mid-plane is a symmetry plane, dT/dz = 0)."""
        zc = self.grid.z_centres
        if zc.size < 2:
            return T[:, 0].copy()
        b = (T[:, 1] - T[:, 0]) / (zc[1] ** 2 - zc[0] ** 2)
        return T[:, 0] - b * zc[0] ** 2

    def enthalpy(self, T: np.ndarray, t_ref: float = 0.0) -> float:
        """Heat content of the half disc relative to ``t_ref``, J: sum of rho V int c dT.

        Integrated numerically on a fine temperature grid; independent of the stepping.
        """
        lo = min(float(T.min()), t_ref) - 1.0
        hi = max(float(T.max()), t_ref) + 1.0
        tt = np.linspace(lo, hi, 4001)
        cc = self.specific_heat(tt)
        H = np.concatenate([[0.0], np.cumsum(0.5 * (cc[1:] + cc[:-1]) * np.diff(tt))])
        h_of_T = np.interp(T, tt, H) - np.interp(t_ref, tt, H)
        return float(np.sum(self.density * self.volume * h_of_T))
