# Copyright 2026 ring_gyro_sim developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Linear mechanical model of the supported ring: mass and stiffness matrices (eqs. 7-17).

The ring is thin and inextensible (radial displacement w = -du/dtheta) and is described by the
Ritz expansion of eqs. (2)-(4) with N_R pairs of generalised coordinates.

Conventions
-----------
Coordinate ordering
    Every matrix of this module is ``(2 N_R, 2 N_R)`` and acts on the coordinates in the order
    of the whole core (the simulator's ``q1 .. qN, q1s .. qNs``): the cosine coordinates, then
    their sine companions::

        Lambda = [q_1^(1), q_2^(1), ..., q_N^(1), q_1^(2), q_2^(2), ..., q_N^(2)]

    (the paper's eq. 4 interleaves them; the matrices are the same up to this permutation), so
    mode ``n`` (1-based) owns the zero-based rows and columns ``n - 1`` (the cosine coordinate
    q_n^(1)) and ``N_R + n - 1`` (the sine companion q_n^(2)); :func:`mode_indices` gives them.
Shape functions
    ``Psi^T(theta)`` of eq. (3) is ``(2, 2 N_R)``: the radial row holds
    ``[cos n theta]`` then ``[sin n theta]`` and the tangential row
    ``[-(1/n) sin n theta]`` then ``[(1/n) cos n theta]``, so that
    ``[w, u]^T = Psi^T(theta) Lambda``.
Support legs
    ``N_l`` identical legs sit at ``theta_j = 2 j pi / N_l + alpha``, ``j = 1 .. N_l``; each is a
    radial spring ``k_r``, a tangential spring ``k_t`` and a point mass ``m_l`` (eqs. 12-17).
    Modes ``n`` and ``p`` couple through the legs iff ``(n - p) / N_l`` or ``(n + p) / N_l`` is
    an integer (Appendix).
Base
    The hub is fixed: the ring-centre coupling blocks ``M_br`` (eq. 9) and ``M_bl`` (eq. 17) are
    not part of these matrices; the base (shock) excitation is applied elsewhere as a force.
Units
    SI throughout: m, kg, Pa, N/m, rad; frequencies in Hz only where the name says ``_hz``.
"""

import math

import numpy as np
from ring_gyro_sim.core.errors import ParameterError
import scipy.linalg

__all__ = ['ring_mass', 'second_moment_of_area', 'modal_mass_factor', 'gyroscopic_coefficient',
           'bryan_factor', 'mode_indices',
           'ring_mass_matrix', 'ring_stiffness_matrix', 'leg_stiffness_matrix',
           'leg_stiffness_matrix_closed_form', 'leg_mass_matrix', 'couples_different_modes',
           'coupling_pattern', 'natural_frequencies_hz', 'pair_matrices']

# Entries smaller than this fraction of the largest |entry| count as zero (round-off of sums).
_RELATIVE_ZERO = 1e-12

# Generic, incommensurate leg stiffnesses used to reveal the structural sparsity of K_l: their
# ratio is irrational, so k_r - k_t / (n p) never vanishes for integer n and p.
_GENERIC_RADIAL_STIFFNESS = 1.0
_GENERIC_TANGENTIAL_STIFFNESS = math.sqrt(2.0)


# --------------------------------------------------------------------------- validation


def _check_positive_int(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f'{name} must be an integer, got {value!r}')
    if value < 1:
        raise ParameterError(f'{name} must be >= 1, got {value}')
    return int(value)


def _check_float(value, name, *, positive=False, nonnegative=False):
    if isinstance(value, bool):
        raise ParameterError(f'{name} must be a real number, got {value!r}')
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f'{name} must be a real number, got {value!r}') from None
    if not math.isfinite(number):
        raise ParameterError(f'{name} must be finite, got {number}')
    if positive and number <= 0.0:
        raise ParameterError(f'{name} must be > 0, got {number}')
    if nonnegative and number < 0.0:
        raise ParameterError(f'{name} must be >= 0, got {number}')
    return number


# --------------------------------------------------------------------------- ring properties


def ring_mass(radius_m, thickness_m, length_m, density_kg_m3):
    """
    Physical mass of the ring, m_r = rho 2 pi r h l.

    Parameters
    ----------
    radius_m : float
        Mean radius r of the ring (m), > 0.
    thickness_m : float
        Radial thickness h (m), > 0.
    length_m : float
        Axial length l (m), > 0.
    density_kg_m3 : float
        Material density rho (kg/m^3), > 0.

    Returns
    -------
    float
        Ring mass m_r (kg).

    Raises
    ------
    ParameterError
        If an argument is not a finite positive number.

    """
    radius = _check_float(radius_m, 'radius_m', positive=True)
    thickness = _check_float(thickness_m, 'thickness_m', positive=True)
    length = _check_float(length_m, 'length_m', positive=True)
    density = _check_float(density_kg_m3, 'density_kg_m3', positive=True)
    return density * 2.0 * math.pi * radius * thickness * length


def second_moment_of_area(thickness_m, length_m):
    """
    In-plane second moment of area of the ring cross-section, I = l h^3 / 12.

    The bending axis is parallel to the ring axis, so the radial thickness is cubed. E I is the
    in-plane flexural rigidity of eq. (10).

    Parameters
    ----------
    thickness_m : float
        Radial thickness h (m), > 0.
    length_m : float
        Axial length l (m), > 0.

    Returns
    -------
    float
        Second moment of area I (m^4).

    Raises
    ------
    ParameterError
        If an argument is not a finite positive number.

    """
    thickness = _check_float(thickness_m, 'thickness_m', positive=True)
    length = _check_float(length_m, 'length_m', positive=True)
    return length * thickness**3 / 12.0


def modal_mass_factor(n):
    """
    Generalised mass of the n-theta mode per unit ring mass, (n^2 + 1) / (2 n^2) (eq. 7).

    Parameters
    ----------
    n : int
        Mode number (number of nodal diameters), >= 1. n = 1 is the rigid-body translation.

    Returns
    -------
    float
        Dimensionless factor; 1 for n = 1, 5/8 for n = 2, tending to 1/2.

    Raises
    ------
    ParameterError
        If ``n`` is not an integer >= 1.

    """
    n = _check_positive_int(n, 'n')
    return (n * n + 1) / (2.0 * n * n)


def gyroscopic_coefficient(n):
    """
    Coriolis coefficient kappa_n = 2 n / (n^2 + 1) of the n-theta pair of a thin ring.

    Derivation (the rotating sensor frame, angular rate Omega(t) about the ring's axis z).
    The velocity of a ring point in the inertial frame is ``r' + Omega e_z x r`` with
    ``r = (R + w) e_r + u e_theta`` and ``r'`` its rate in the sensor frame, so the kinetic
    energy per unit length ``rho A / 2 |r' + Omega e_z x r|^2`` holds, besides the relative
    term of eq. (7),

    (G1)  the gyroscopic term ``rho A Omega ((R + w) u' - u w')``, and
    (G2)  the centrifugal term ``rho A Omega^2 / 2 ((R + w)^2 + u^2)``.

    With eq. (3) (``w = q_c cos n theta + q_s sin n theta``,
    ``u = -(q_c / n) sin n theta + (q_s / n) cos n theta``) and
    ``int_0^{2 pi} R dtheta``: the terms linear in w and u vanish for n >= 1, and

    (G3)  ``T_G = c_n Omega (q_c q_s' - q_s q_c')``, ``c_n = 2 pi rho A R / n``;
    (G4)  ``T_C = (M_n / 2) Omega^2 (q_c^2 + q_s^2)``, ``M_n = pi rho A R (1 + 1/n^2)``
          (the generalised mass of eq. 7: ``m_r (n^2 + 1) / (2 n^2)``).

    Lagrange's equations of ``T_G + T_C`` add to the modal equations (per unit ``M_n``)

    (G5)  ``q_c'' = ... + 2 kappa_n Omega q_s' + kappa_n Omega' q_s + Omega^2 q_c``
    (G6)  ``q_s'' = ... - 2 kappa_n Omega q_c' - kappa_n Omega' q_c + Omega^2 q_s``

    with ``kappa_n = c_n / M_n = 2 n / (n^2 + 1)``: 1 for the rigid 1theta translation, 0.8
    for 2theta. The legs' point masses (eqs. 16-17) enter the modal masses smeared over the
    ring (``SimConfig.modal_masses``: ``(m_r + N_l m_l)(n^2 + 1)/(2 n^2)``); a point mass
    adds to (G3) and to ``M_n`` in the same ratio ``2 n / (n^2 + 1)`` (its u and w are
    those of the ring point it sits on), so kappa_n holds with them. (Leg positions that
    couple different pairs, ``(n +- p) / N_l`` integer, would add off-pair gyroscopic terms
    of order ``m_l / m_r``; the modal model keeps the pairs uncoupled, as its masses do.)

    A free vibration then precesses: in complex form ``z = q_c + i q_s``,
    ``z'' + 2 i kappa Omega z' + omega^2 z = 0`` has the roots ``+-omega - kappa Omega``
    (to first order), so a standing wave ``z = a e^{-i kappa Omega t} cos(omega t)`` has its
    antinode at ``theta = -(kappa / n) Omega t``: it turns by :func:`bryan_factor` times the
    sensor's rotation angle, backwards (in the inertial frame it lags the case by
    ``1 - kappa / n``).

    Parameters
    ----------
    n : int
        Mode number, >= 1.

    Returns
    -------
    float

    """
    n = _check_positive_int(n, 'n')
    return 2.0 * n / (n * n + 1.0)


def bryan_factor(n):
    """
    Angular gain of the n-theta standing wave, kappa_n / n = 2 / (n^2 + 1) (0.4 for n = 2).

    In the sensor frame the pattern turns by ``-bryan_factor(n)`` times the sensor's rotation
    angle (:func:`gyroscopic_coefficient`).
    """
    return gyroscopic_coefficient(n) / _check_positive_int(n, 'n')


def mode_indices(n_modes, n):
    """
    Rows (and columns) of mode ``n`` in the matrices of this module: ``[n - 1, N_R + n - 1]``.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n : int
        Mode number, 1 <= n <= N_R.

    Returns
    -------
    list of int
        The cosine coordinate's index, then its sine companion's.

    Raises
    ------
    ParameterError
        If an argument is not an integer in range.

    """
    n_modes = _check_positive_int(n_modes, 'n_modes')
    n = _check_positive_int(n, 'n')
    if n > n_modes:
        raise ParameterError(f'n must be <= n_modes = {n_modes}, got {n}')
    return [n - 1, n_modes + n - 1]


def _mode_numbers(n_modes):
    """Mode number n of every coordinate, as floats: ``[1 .. N_R, 1 .. N_R]``."""
    return np.tile(np.arange(1, n_modes + 1, dtype=float), 2)


def ring_mass_matrix(n_modes, ring_mass_kg):
    """
    Ring mass matrix M_r of eqs. (7)-(8), without the ring-centre coupling M_br.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    ring_mass_kg : float
        Physical ring mass m_r (kg), > 0 (see :func:`ring_mass`).

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` diagonal matrix (kg); entries ``n-1`` and ``N_R+n-1`` equal
        ``m_r (n^2 + 1) / (2 n^2)``.

    Raises
    ------
    ParameterError
        If ``n_modes`` is not an integer >= 1 or ``ring_mass_kg`` not finite and > 0.

    """
    n_modes = _check_positive_int(n_modes, 'n_modes')
    mass = _check_float(ring_mass_kg, 'ring_mass_kg', positive=True)
    n = _mode_numbers(n_modes)
    return np.diag(mass * (n * n + 1.0) / (2.0 * n * n))


def ring_stiffness_matrix(n_modes, youngs_modulus_pa, second_moment_m4, radius_m):
    """
    Ring stiffness matrix K_r of eq. (11), from the strain energy of eq. (10).

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    youngs_modulus_pa : float
        Young's modulus E (Pa), > 0.
    second_moment_m4 : float
        In-plane second moment of area I (m^4), > 0 (see :func:`second_moment_of_area`).
    radius_m : float
        Mean ring radius r (m), > 0.

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` diagonal matrix (N/m); entries ``n-1`` and ``N_R+n-1`` equal
        ``E I pi (n^2 - 1)^2 / r^3``, zero for the rigid-body mode n = 1.

    Raises
    ------
    ParameterError
        If ``n_modes`` is not an integer >= 1 or a material/geometry value is not finite and > 0.

    """
    n_modes = _check_positive_int(n_modes, 'n_modes')
    modulus = _check_float(youngs_modulus_pa, 'youngs_modulus_pa', positive=True)
    second_moment = _check_float(second_moment_m4, 'second_moment_m4', positive=True)
    radius = _check_float(radius_m, 'radius_m', positive=True)
    n = _mode_numbers(n_modes)
    return np.diag(modulus * second_moment * math.pi * (n * n - 1.0) ** 2 / radius**3)


# --------------------------------------------------------------------------- support legs


def _psi_transpose(theta_rad, n_modes):
    """Psi^T(theta) of eq. (3): ``(2, 2 N_R)``, radial row then tangential row."""
    n = np.arange(1, n_modes + 1, dtype=float)
    cos_n = np.cos(n * theta_rad)
    sin_n = np.sin(n * theta_rad)
    psi_t = np.empty((2, 2 * n_modes))
    psi_t[0, :n_modes] = cos_n
    psi_t[0, n_modes:] = sin_n
    psi_t[1, :n_modes] = -sin_n / n
    psi_t[1, n_modes:] = cos_n / n
    return psi_t


def _check_leg_geometry(n_modes, n_legs, angle_rad):
    return (
        _check_positive_int(n_modes, 'n_modes'),
        _check_positive_int(n_legs, 'n_legs'),
        _check_float(angle_rad, 'angle_rad'),
    )


def leg_stiffness_matrix(n_modes, n_legs, angle_rad, radial_stiffness, tangential_stiffness):
    """
    Total support-leg stiffness matrix K_l by direct summation of eq. (13) over the legs.

    ``K_l = sum_{j=1}^{N_l} Psi(theta_j) diag(k_r, k_t) Psi^T(theta_j)`` with
    ``theta_j = 2 j pi / N_l + alpha`` (eqs. 12-13). This is the reference implementation;
    :func:`leg_stiffness_matrix_closed_form` gives the same matrix with exact zeros.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n_legs : int
        Number of identical, uniformly spaced support legs N_l, >= 1.
    angle_rad : float
        Angular position alpha of the last leg (j = N_l) in the reference frame (rad).
    radial_stiffness : float
        Radial stiffness k_r of one leg (N/m), >= 0.
    tangential_stiffness : float
        Tangential stiffness k_t of one leg (N/m), >= 0.

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` symmetric positive semi-definite matrix (N/m), ordered as the module
        docstring says. Structural zeros carry round-off of order ``N_l`` machine epsilons.

    Raises
    ------
    ParameterError
        If an argument is out of range (see above).

    """
    n_modes, n_legs, angle = _check_leg_geometry(n_modes, n_legs, angle_rad)
    k_r = _check_float(radial_stiffness, 'radial_stiffness', nonnegative=True)
    k_t = _check_float(tangential_stiffness, 'tangential_stiffness', nonnegative=True)
    leg = np.diag([k_r, k_t])
    total = np.zeros((2 * n_modes, 2 * n_modes))
    for j in range(1, n_legs + 1):
        psi_t = _psi_transpose(2.0 * j * math.pi / n_legs + angle, n_modes)
        total += psi_t.T @ leg @ psi_t
    return total


def _leg_sums(n, p, n_legs, angle):
    """
    Sum a_cc, a_ss, a_cs and a_sc over the legs (eqs. 39-45 and the Appendix table).

    Returns ``(S_cc, S_ss, S_cs, S_sc)``; all four are zero unless ``(n - p) / N_l`` or
    ``(n + p) / N_l`` is an integer. The printed table stops before the a_sc row; it follows from
    ``sin A cos B = [sin(A + B) + sin(A - B)] / 2`` and eq. (44) like the other three.
    """
    minus = (n - p) % n_legs == 0
    plus = (n + p) % n_legs == 0
    half = 0.5 * n_legs
    if minus and plus:
        # Intersection of the two diagonals: both halves of the product formulae survive.
        c_n, s_n = math.cos(n * angle), math.sin(n * angle)
        c_p, s_p = math.cos(p * angle), math.sin(p * angle)
        # Products grouped so that S_cs(n, n) == S_sc(n, n) exactly.
        return (n_legs * (c_n * c_p), n_legs * (s_n * s_p), n_legs * (c_n * s_p),
                n_legs * (s_n * c_p))
    if minus:
        # 'Positive' diagonals: only the (n - p) harmonic survives.
        c, s = math.cos((n - p) * angle), math.sin((n - p) * angle)
        return (half * c, half * c, -half * s, half * s)
    if plus:
        # 'Negative' diagonals: only the (n + p) harmonic survives.
        c, s = math.cos((n + p) * angle), math.sin((n + p) * angle)
        return (half * c, -half * c, half * s, half * s)
    return (0.0, 0.0, 0.0, 0.0)


def _closed_form(n_modes, n_legs, angle, radial, tangential):
    """Assemble the Appendix blocks (eq. 38 summed over j) for the two spring weights."""
    total = np.zeros((2 * n_modes, 2 * n_modes))
    for n in range(1, n_modes + 1):
        # Upper blocks only, mirrored below: the matrix is then exactly symmetric.
        for p in range(n, n_modes + 1):
            s_cc, s_ss, s_cs, s_sc = _leg_sums(n, p, n_legs, angle)
            # Eq. (38) as printed has k_r in the 1/(n p) terms: a typo. Those terms come from the
            # tangential row of Psi^T, so they carry k_t: the direct sum of eq. (13) shows it, and
            # the text of eq. (16), replacing 'k_r and k_t' by m_l, presumes k_t is there.
            tan = tangential / (n * p)
            rows = np.ix_(mode_indices(n_modes, n), mode_indices(n_modes, p))
            cols = np.ix_(mode_indices(n_modes, p), mode_indices(n_modes, n))
            total[rows] = [
                [radial * s_cc + tan * s_ss, radial * s_cs - tan * s_sc],
                [radial * s_sc - tan * s_cs, radial * s_ss + tan * s_cc],
            ]
            total[cols] = total[rows].T
    return total


def leg_stiffness_matrix_closed_form(
    n_modes, n_legs, angle_rad, radial_stiffness, tangential_stiffness
):
    """
    Total support-leg stiffness matrix K_l from the Appendix closed form (eqs. 37-45).

    Block ``(n, p)`` (rows and columns :func:`mode_indices` of n and p) is eq. (38) summed over
    the legs, with the sums of a_cc, a_ss, a_cs and a_sc taken from the Appendix table: non-zero
    only on the 'positive diagonals' ``(n - p) / N_l`` integer, the 'negative diagonals'
    ``(n + p) / N_l`` integer, and their intersections. Equals :func:`leg_stiffness_matrix`
    to round-off, with exact zeros elsewhere.

    Eqs. (15) and (38) as printed carry k_r in the tangential ``1/(n p)`` terms; the tangential
    stiffness k_t belongs there and is used here (see the module tests for the demonstration).

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n_legs : int
        Number of identical, uniformly spaced support legs N_l, >= 1.
    angle_rad : float
        Angular position alpha of the last leg (j = N_l) in the reference frame (rad).
    radial_stiffness : float
        Radial stiffness k_r of one leg (N/m), >= 0.
    tangential_stiffness : float
        Tangential stiffness k_t of one leg (N/m), >= 0.

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` symmetric positive semi-definite matrix (N/m).

    Raises
    ------
    ParameterError
        If an argument is out of range (see above).

    Notes
    -----
    For ``n < N_l / 2`` the blocks are diagonal with equal entries ``(N_l / 2)(k_r + k_t / n^2)``
    (eq. 15, corrected); the ``n = N_l / 2`` block is
    ``[[N_l k_r c^2 + (4 k_t / N_l) s^2, (N_l k_r - 4 k_t / N_l) c s], [..., N_l k_r s^2 +
    (4 k_t / N_l) c^2]]`` with ``c, s = cos, sin(N_l alpha / 2)``.

    """
    n_modes, n_legs, angle = _check_leg_geometry(n_modes, n_legs, angle_rad)
    k_r = _check_float(radial_stiffness, 'radial_stiffness', nonnegative=True)
    k_t = _check_float(tangential_stiffness, 'tangential_stiffness', nonnegative=True)
    return _closed_form(n_modes, n_legs, angle, k_r, k_t)


def leg_mass_matrix(n_modes, n_legs, angle_rad, leg_mass_kg):
    """
    Total support-leg mass matrix M_l of eq. (16), without the ring-centre coupling M_bl.

    Same structure as K_l with both k_r and k_t replaced by the point mass m_l of one leg
    (each leg moves radially and tangentially with the ring at its attachment point).

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n_legs : int
        Number of identical, uniformly spaced support legs N_l, >= 1.
    angle_rad : float
        Angular position alpha of the last leg (j = N_l) in the reference frame (rad).
    leg_mass_kg : float
        Point mass m_l of one leg (kg), >= 0.

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` symmetric positive semi-definite matrix (kg). For ``n < N_l / 2`` the
        diagonal entries are ``N_l m_l (n^2 + 1) / (2 n^2)``.

    Raises
    ------
    ParameterError
        If an argument is out of range (see above).

    """
    n_modes, n_legs, angle = _check_leg_geometry(n_modes, n_legs, angle_rad)
    mass = _check_float(leg_mass_kg, 'leg_mass_kg', nonnegative=True)
    return _closed_form(n_modes, n_legs, angle, mass, mass)


def couples_different_modes(n_modes, n_legs):
    """
    Whether the legs can couple two different modes n != p <= N_R (Appendix).

    True iff some ``1 <= p < n <= N_R`` has ``(n - p) / N_l`` or ``(n + p) / N_l`` integer. This
    depends on N_R and N_l only; for special angles or stiffness ratios the coupling entries may
    still happen to vanish.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n_legs : int
        Number of support legs N_l, >= 1.

    Returns
    -------
    bool
        True when K_l and M_l are not block diagonal in 2 x 2 blocks (generically).

    Raises
    ------
    ParameterError
        If an argument is not an integer >= 1.

    """
    n_modes = _check_positive_int(n_modes, 'n_modes')
    n_legs = _check_positive_int(n_legs, 'n_legs')
    return any(
        (n - p) % n_legs == 0 or (n + p) % n_legs == 0
        for n in range(2, n_modes + 1)
        for p in range(1, n)
    )


def coupling_pattern(n_modes, n_legs, angle_rad):
    """
    Non-zero pattern of K_l for generic, unequal leg stiffnesses (Fig. 2).

    K_l is computed by direct summation (:func:`leg_stiffness_matrix`) with k_r = 1 and
    k_t = sqrt(2) N/m (an irrational ratio, so no entry cancels by accident); an entry counts as
    non-zero when its magnitude exceeds 1e-12 times the largest one. The pattern depends on
    alpha: at special angles (e.g. alpha = 0) some entries of the coupled blocks vanish.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    n_legs : int
        Number of support legs N_l, >= 1.
    angle_rad : float
        Angular position alpha of the last leg (rad).

    Returns
    -------
    numpy.ndarray
        ``(2 N_R, 2 N_R)`` boolean array, True where K_l is non-zero.

    Raises
    ------
    ParameterError
        If an argument is out of range (see above).

    """
    stiffness = leg_stiffness_matrix(
        n_modes, n_legs, angle_rad, _GENERIC_RADIAL_STIFFNESS, _GENERIC_TANGENTIAL_STIFFNESS
    )
    magnitude = np.abs(stiffness)
    return magnitude > _RELATIVE_ZERO * magnitude.max()


# --------------------------------------------------------------------------- frequencies


def natural_frequencies_hz(
    n_modes,
    ring_mass_kg,
    youngs_modulus_pa,
    second_moment_m4,
    radius_m,
    n_legs,
    angle_rad,
    radial_stiffness,
    tangential_stiffness,
    leg_mass_kg,
):
    """
    Linear natural frequencies of the supported ring on a fixed hub.

    Solves the generalised eigenproblem ``(K_r + K_l) x = omega^2 (M_r + M_l) x``
    (eqs. 7, 11, 13, 16). The ring-centre blocks M_br and M_bl (eqs. 9, 17) are left out: the
    base is the fixed hub. Electrostatic stiffness is not included.

    Ordering of the result:

    - If the legs couple no two different modes (``couples_different_modes(n_modes, n_legs)``
      is False, which for ``N_l >= 3`` means ``N_R <= N_l / 2``), each 2 x 2 block is solved
      alone and the result is ordered as the coordinates: entry ``n-1`` for the cosine
      coordinate of mode n, entry ``N_R+n-1`` for its sine companion. When a pair splits
      (2n / N_l integer) and alpha rotates the mode shapes, each frequency goes to the
      coordinate its mode shape is closer to (at alpha = 0 the assignment is exact: the cosine
      slot is the mode aligned with the legs).
    - Otherwise (``couples_different_modes`` True) the coordinates are mixed and no frequency
      belongs to one of them: the eigenfrequencies sorted ascending are taken in consecutive
      pairs (the ring's modes come in pairs), the lower of pair k in slot ``k`` and the upper
      in slot ``N_R + k``; ``numpy.sort`` of the result is the spectrum.

    Parameters
    ----------
    n_modes : int
        Ritz order N_R, >= 1.
    ring_mass_kg : float
        Physical ring mass m_r (kg), > 0.
    youngs_modulus_pa : float
        Young's modulus E (Pa), > 0.
    second_moment_m4 : float
        In-plane second moment of area I (m^4), > 0.
    radius_m : float
        Mean ring radius r (m), > 0.
    n_legs : int
        Number of support legs N_l, >= 1 (a free ring: set the leg stiffnesses and mass to 0).
    angle_rad : float
        Angular position alpha of the last leg (rad).
    radial_stiffness : float
        Radial stiffness k_r of one leg (N/m), >= 0.
    tangential_stiffness : float
        Tangential stiffness k_t of one leg (N/m), >= 0.
    leg_mass_kg : float
        Point mass m_l of one leg (kg), >= 0.

    Returns
    -------
    numpy.ndarray
        ``(2 N_R,)`` natural frequencies (Hz), cosine slots then companion slots as described
        above. A free ring has a zero frequency for the rigid-body mode n = 1.

    Raises
    ------
    ParameterError
        If an argument is out of range (see above).

    """
    stiffness = ring_stiffness_matrix(n_modes, youngs_modulus_pa, second_moment_m4, radius_m)
    stiffness += leg_stiffness_matrix_closed_form(
        n_modes, n_legs, angle_rad, radial_stiffness, tangential_stiffness
    )
    mass = ring_mass_matrix(n_modes, ring_mass_kg) + leg_mass_matrix(
        n_modes, n_legs, angle_rad, leg_mass_kg
    )
    if couples_different_modes(n_modes, n_legs):
        spectrum = scipy.linalg.eigh(stiffness, mass, eigvals_only=True)
        omega_sq = np.concatenate([spectrum[0::2], spectrum[1::2]])
    else:
        omega_sq = np.empty(2 * n_modes)
        for n in range(1, n_modes + 1):
            block = mode_indices(n_modes, n)
            values, vectors = scipy.linalg.eigh(stiffness[np.ix_(block, block)],
                                                mass[np.ix_(block, block)])
            # The lower mode takes the slot of the coordinate it is mostly made of.
            lower_is_cosine = abs(vectors[0, 0]) >= abs(vectors[1, 0])
            omega_sq[block] = values if lower_is_cosine else values[::-1]
    # K is positive semi-definite by construction: clip round-off below zero (free n = 1 mode).
    omega_sq = np.clip(omega_sq, 0.0, None)
    return np.sqrt(omega_sq) / (2.0 * math.pi)


def pair_matrices(n, omega_x, omega_y, q_x, q_y, frequency_axis_deg=0.0, damping_axis_deg=0.0):
    r"""
    Stiffness and damping of an imperfect mode pair, per unit modal mass (P1-P4).

    A ring whose mass or stiffness is not uniform (etching, anchors) has, for each n-theta
    pair, two orthogonal principal axes of stiffness and two of damping, which need not
    coincide with the electrodes (theta = 0) nor with each other.

    (P1) A principal axis at ring angle ``theta_0``: the radial pattern
    ``w = a cos(n (theta - theta_0))`` is, in the pair's coordinates of eq. (2),
    ``q_n = a cos(n theta_0)``, ``q_n^s = a sin(n theta_0)``: the modal direction
    ``e(theta_0) = (cos n theta_0, sin n theta_0)``. The axis 90/n deg further on the ring is
    ``(-sin n theta_0, cos n theta_0)``, orthogonal in modal space.

    (P2) With ``omega_x`` along ``e(theta_w)`` and ``omega_y`` 90/n deg further on, the
    stiffness per unit modal mass (both coordinates of a pair have the same modal mass,
    eq. 7) is ``K = R(n theta_w) diag(omega_x^2, omega_y^2) R(n theta_w)^T``,
    ``R(phi) = [[cos phi, -sin phi], [sin phi, cos phi]]``::

        K_cc = (w_x^2 + w_y^2)/2 + (w_x^2 - w_y^2)/2 cos(2 n theta_w)
        K_ss = (w_x^2 + w_y^2)/2 - (w_x^2 - w_y^2)/2 cos(2 n theta_w)
        K_cs = K_sc = (w_x^2 - w_y^2)/2 sin(2 n theta_w)                              (P2)

    (P3) Likewise the damping, ``C = R(n theta_t) diag(c_x, c_y) R(n theta_t)^T`` with
    ``c = omega / Q`` (the ``2 zeta omega`` of eq. 28): ``c_x = omega_x / Q_x``,
    ``c_y = omega_y / Q_y``, ``C_cs = (c_x - c_y)/2 sin(2 n theta_t)``.

    (P4) Axes at 0 (or 90/n deg with the values swapped) give diagonal matrices: the
    coordinates of eq. (2) with their own frequencies and Q, as without imperfection; an
    isotropic pair (equal values) has no principal axis at all. The open-loop consequences
    (doc/imperfections.md): with the drive ``q_n = X sin(omega t)`` at match, the sense
    coordinate is forced by ``-(2 kappa Omega + C_sc) q_n' - K_sc q_n``: the damping term
    acts as a rate ``C_sc / (2 kappa)`` (a zero-rate output, in phase with the Coriolis
    force) and the stiffness term, 90 deg from it, as a quadrature ``K_sc / (2 kappa omega)``
    in rate units.

    Parameters
    ----------
    n : int
        n of the n-theta pair.
    omega_x, omega_y : float
        Principal angular frequencies, rad/s (``modes.frequencies``,
        ``modes.companion_frequencies``).
    q_x, q_y : float
        Principal quality factors (``modes.quality_factors``,
        ``modes.companion_quality_factors``).
    frequency_axis_deg, damping_axis_deg : float
        Ring angles ``theta_w``, ``theta_t`` of the axes of ``omega_x`` and ``q_x``, deg.

    Returns
    -------
    (ndarray, ndarray)
        ``K`` ((rad/s)^2) and ``C`` (1/s), each 2x2 over ``(q_n, q_n^s)``.

    """
    def rotated(x, y, axis_deg):
        phi = n * math.radians(axis_deg)
        c, s = math.cos(phi), math.sin(phi)
        rot = np.array([[c, -s], [s, c]])
        return rot @ np.diag([x, y]) @ rot.T

    stiffness = rotated(omega_x * omega_x, omega_y * omega_y, frequency_axis_deg)
    damping = rotated(omega_x / q_x, omega_y / q_y, damping_axis_deg)
    return stiffness, damping
