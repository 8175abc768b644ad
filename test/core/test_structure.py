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

"""Tests of ring_gyro_sim.core.structure: ring and support-leg matrices (eqs. 7-17, Appendix)."""

import itertools
import math

import numpy as np
import pytest

from ring_gyro_sim.core import structure
from ring_gyro_sim.core.errors import ParameterError

# Device of section 3.1 (r, h, l, E, rho); leg values are arbitrary but of a plausible size.
RADIUS_M = 1.5e-3
THICKNESS_M = 18e-6
LENGTH_M = 150e-6
YOUNGS_PA = 150e9
DENSITY = 2330.0
RING_MASS_KG = structure.ring_mass(RADIUS_M, THICKNESS_M, LENGTH_M, DENSITY)
SECOND_MOMENT_M4 = structure.second_moment_of_area(THICKNESS_M, LENGTH_M)
K_R = 1000.0
K_T = 317.0
LEG_MASS_KG = 2.1e-9


def indices(n_modes, n):
    """Cosine and sine coordinate of mode n (1-based): core's order, cos modes then companions."""
    return [n - 1, n_modes + n - 1]


def block(matrix, n, p):
    """Return (a copy of) the 2 x 2 block of modes n (rows) and p (columns), both 1-based."""
    n_modes = matrix.shape[0] // 2
    return matrix[np.ix_(indices(n_modes, n), indices(n_modes, p))]


def set_block(matrix, n, p, value):
    """Set the 2 x 2 block of modes n (rows) and p (columns) of ``matrix`` to ``value``."""
    n_modes = matrix.shape[0] // 2
    matrix[np.ix_(indices(n_modes, n), indices(n_modes, p))] = value


def legs_couple(n, p, n_legs):
    return (n - p) % n_legs == 0 or (n + p) % n_legs == 0


def frequencies(n_modes, n_legs, angle_rad, k_r=K_R, k_t=K_T, leg_mass_kg=LEG_MASS_KG):
    return structure.natural_frequencies_hz(
        n_modes, RING_MASS_KG, YOUNGS_PA, SECOND_MOMENT_M4, RADIUS_M,
        n_legs, angle_rad, k_r, k_t, leg_mass_kg,
    )


def printed_eq15(n_legs, angle_rad, k_r):
    """Eq. (15) exactly as printed (k_r in every term), for even N_l and N_R = N_l / 2."""
    n_modes = n_legs // 2
    matrix = np.zeros((2 * n_modes, 2 * n_modes))
    for n in range(1, n_modes):
        set_block(matrix, n, n, np.eye(2) * n_legs / 2 * (k_r + k_r / n**2))
    c, s = math.cos(n_legs * angle_rad / 2), math.sin(n_legs * angle_rad / 2)
    set_block(matrix, n_modes, n_modes, [
        [n_legs * k_r * c**2 + 4 * k_r / n_legs * s**2, (n_legs * k_r - 4 * k_r / n_legs) * c * s],
        [(n_legs * k_r - 4 * k_r / n_legs) * c * s, n_legs * k_r * s**2 + 4 * k_r / n_legs * c**2],
    ])
    return matrix


# --------------------------------------------------------------------------- ring


def test_ring_mass_and_second_moment_of_device():
    assert RING_MASS_KG == pytest.approx(2330.0 * 2 * math.pi * 1.5e-3 * 18e-6 * 150e-6, rel=1e-15)
    assert RING_MASS_KG == pytest.approx(5.93e-8, rel=1e-3)
    assert SECOND_MOMENT_M4 == pytest.approx(150e-6 * (18e-6) ** 3 / 12, rel=1e-15)


def test_modal_mass_factor_and_ring_mass_matrix():
    assert structure.modal_mass_factor(1) == 1.0
    assert structure.modal_mass_factor(2) == 5 / 8
    assert structure.modal_mass_factor(10) == pytest.approx(101 / 200)
    mass = structure.ring_mass_matrix(4, 2.0)
    # Cosine coordinates of n = 1..4, then their companions (the same masses).
    expected = 2.0 * np.array([1, 5 / 8, 10 / 18, 17 / 32, 1, 5 / 8, 10 / 18, 17 / 32])
    np.testing.assert_allclose(mass, np.diag(expected), rtol=1e-15, atol=0)


def test_ring_stiffness_is_zero_for_rigid_body_mode():
    stiffness = structure.ring_stiffness_matrix(3, YOUNGS_PA, SECOND_MOMENT_M4, RADIUS_M)
    assert stiffness.shape == (6, 6)
    assert np.count_nonzero(stiffness - np.diag(np.diag(stiffness))) == 0
    assert stiffness[0, 0] == 0.0 and stiffness[3, 3] == 0.0  # n = 1: q1 and q1s
    unit = YOUNGS_PA * SECOND_MOMENT_M4 * math.pi / RADIUS_M**3
    np.testing.assert_allclose(np.diag(stiffness)[[1, 2, 4, 5]], unit * np.array([9, 64, 9, 64]),
                               rtol=1e-14)


def test_free_ring_frequencies_match_the_classical_formula():
    # f_n = sqrt(E I / (rho A r^4)) n (n^2 - 1) / sqrt(n^2 + 1) / (2 pi) for a free thin ring.
    scale = math.sqrt(YOUNGS_PA * SECOND_MOMENT_M4
                      / (DENSITY * THICKNESS_M * LENGTH_M * RADIUS_M**4)) / (2 * math.pi)
    n = np.tile(np.arange(1, 7), 2)
    expected = scale * n * (n**2 - 1) / np.sqrt(n**2 + 1)
    # N_R = 6 < N_l = 16 / 2: coordinate order; N_l = 3: coupled path, consecutive pairs of the
    # sorted spectrum (the free ring's pairs are degenerate and increase with n: both agree).
    for n_legs in (16, 3):
        freq = frequencies(6, n_legs, 0.4, k_r=0.0, k_t=0.0, leg_mass_kg=0.0)
        np.testing.assert_allclose(freq, expected, rtol=1e-12, atol=1e-9)
    assert expected[1] == pytest.approx(7.9e3, rel=0.01)  # bare 2theta: the legs add the rest


def paper_interleaved_leg_stiffness(n_modes, n_legs, angle, k_r, k_t):
    """Eq. (13) summed directly on the paper's interleaved vector (eq. 4), written out here."""
    total = np.zeros((2 * n_modes, 2 * n_modes))
    for j in range(1, n_legs + 1):
        theta = 2 * j * math.pi / n_legs + angle
        psi_t = np.zeros((2, 2 * n_modes))
        for n in range(1, n_modes + 1):
            c, s = math.cos(n * theta), math.sin(n * theta)
            psi_t[:, 2 * n - 2] = [c, -s / n]  # q_n^(1), eq. (3)
            psi_t[:, 2 * n - 1] = [s, c / n]  # q_n^(2)
        total += psi_t.T @ np.diag([k_r, k_t]) @ psi_t
    return total


@pytest.mark.parametrize(('n_modes', 'n_legs', 'angle'), [(4, 8, 0.3), (11, 9, 0.3), (5, 3, -1.1)])
def test_matrices_are_the_papers_in_the_core_coordinate_order(n_modes, n_legs, angle):
    """The paper interleaves q_n^(1), q_n^(2) (eq. 4); core orders cos modes, then companions."""
    order = [2 * n for n in range(n_modes)] + [2 * n + 1 for n in range(n_modes)]
    paper = paper_interleaved_leg_stiffness(n_modes, n_legs, angle, K_R, K_T)
    expected = paper[np.ix_(order, order)]
    for matrix in (structure.leg_stiffness_matrix(n_modes, n_legs, angle, K_R, K_T),
                   structure.leg_stiffness_matrix_closed_form(n_modes, n_legs, angle, K_R, K_T)):
        np.testing.assert_allclose(matrix, expected, rtol=0, atol=1e-12 * np.abs(paper).max())
    assert [structure.mode_indices(n_modes, n) for n in (1, n_modes)] == [
        [0, n_modes], [n_modes - 1, 2 * n_modes - 1]]


def test_mode_indices_refuses_a_mode_beyond_the_ritz_order():
    with pytest.raises(ParameterError, match='^n must be <= n_modes'):
        structure.mode_indices(3, 4)


# --------------------------------------------------------------------------- closed form


CLOSED_FORM_CASES = [
    (n_modes, n_legs, angle, k_r, k_t)
    for n_legs in range(1, 13)
    for n_modes in sorted({1, max(1, n_legs // 2), n_legs // 2 + 1, n_legs, 2 * n_legs + 1})
    for angle in (0.0, 0.3, -1.1, 2.5)
    for k_r, k_t in ((1000.0, 317.0), (2.5, 40.0))
]


@pytest.mark.parametrize(('n_modes', 'n_legs', 'angle', 'k_r', 'k_t'), CLOSED_FORM_CASES)
def test_direct_sum_equals_closed_form(n_modes, n_legs, angle, k_r, k_t):
    direct = structure.leg_stiffness_matrix(n_modes, n_legs, angle, k_r, k_t)
    closed = structure.leg_stiffness_matrix_closed_form(n_modes, n_legs, angle, k_r, k_t)
    scale = np.abs(direct).max()
    np.testing.assert_allclose(closed, direct, rtol=0, atol=1e-12 * scale)
    np.testing.assert_array_equal(closed, closed.T)


def test_closed_form_cases_cover_the_special_blocks():
    kinds = set()
    for n_modes, n_legs, *_ in CLOSED_FORM_CASES:
        for n, p in itertools.product(range(1, n_modes + 1), repeat=2):
            minus, plus = (n - p) % n_legs == 0, (n + p) % n_legs == 0
            if n == p and 2 * n == n_legs:
                kinds.add('n = N_l / 2')
            if n != p and n + p == n_legs:
                kinds.add('n + p = N_l')
            if n != p and minus and not plus:
                kinds.add('positive diagonal, n != p')
            if n != p and minus and plus:
                kinds.add('intersection, n != p')
    assert kinds == {'n = N_l / 2', 'n + p = N_l', 'positive diagonal, n != p',
                     'intersection, n != p'}


@pytest.mark.parametrize(('n_modes', 'n_legs', 'angle'), [(11, 9, 0.3), (9, 4, -0.7), (5, 8, 0.0)])
def test_leg_mass_matrix_is_the_direct_sum_with_both_springs_replaced_by_the_mass(
    n_modes, n_legs, angle
):
    direct = structure.leg_stiffness_matrix(n_modes, n_legs, angle, LEG_MASS_KG, LEG_MASS_KG)
    mass = structure.leg_mass_matrix(n_modes, n_legs, angle, LEG_MASS_KG)
    np.testing.assert_allclose(mass, direct, rtol=0, atol=1e-12 * np.abs(direct).max())


def test_printed_eq15_has_k_r_where_k_t_belongs():
    n_legs, angle = 8, 0.2
    direct = structure.leg_stiffness_matrix(n_legs // 2, n_legs, angle, 1000.0, 300.0)
    printed = printed_eq15(n_legs, angle, 1000.0)
    # n = 1: printed (N_l / 2)(k_r + k_r) = 8000, direct (N_l / 2)(k_r + k_t) = 5200 N/m.
    assert printed[0, 0] == pytest.approx(8000.0)
    assert direct[0, 0] == pytest.approx(5200.0)
    assert np.abs(printed - direct).max() == pytest.approx(2800.0)
    # With the tangential terms given k_t the printed form is right.
    corrected = printed_eq15(n_legs, angle, 1000.0)
    for n in range(1, n_legs // 2):
        set_block(corrected, n, n, np.eye(2) * n_legs / 2 * (1000.0 + 300.0 / n**2))
    c, s = math.cos(n_legs * angle / 2), math.sin(n_legs * angle / 2)
    k_r, k_t = 1000.0, 300.0
    set_block(corrected, 4, 4, [
        [n_legs * k_r * c**2 + 4 * k_t / n_legs * s**2, (n_legs * k_r - 4 * k_t / n_legs) * c * s],
        [(n_legs * k_r - 4 * k_t / n_legs) * c * s, n_legs * k_r * s**2 + 4 * k_t / n_legs * c**2],
    ])
    np.testing.assert_allclose(corrected, direct, rtol=0, atol=1e-9)


@pytest.mark.parametrize(('n_legs', 'angle'), [(8, 0.2), (8, 0.0), (6, -1.3), (2, 0.7)])
def test_printed_eq15_is_right_when_k_t_equals_k_r(n_legs, angle):
    direct = structure.leg_stiffness_matrix(n_legs // 2, n_legs, angle, 1000.0, 1000.0)
    np.testing.assert_allclose(printed_eq15(n_legs, angle, 1000.0), direct, rtol=0, atol=1e-9)
    different = structure.leg_stiffness_matrix(n_legs // 2, n_legs, angle, 1000.0, 300.0)
    assert np.abs(printed_eq15(n_legs, angle, 1000.0) - different).max() > 100.0


@pytest.mark.parametrize('n_legs', [3, 4, 8, 9, 16])
@pytest.mark.parametrize('angle', [0.0, 0.41])
def test_uncoupled_diagonal_entries(n_legs, angle):
    n_modes = (n_legs - 1) // 2  # every n < N_l / 2
    stiffness = structure.leg_stiffness_matrix(n_modes, n_legs, angle, K_R, K_T)
    mass = structure.leg_mass_matrix(n_modes, n_legs, angle, LEG_MASS_KG)
    n = np.tile(np.arange(1, n_modes + 1), 2)
    np.testing.assert_allclose(
        stiffness, np.diag(n_legs / 2 * (K_R + K_T / n**2)), rtol=0, atol=1e-12 * K_R * n_legs)
    np.testing.assert_allclose(
        mass, np.diag(n_legs * LEG_MASS_KG * (n**2 + 1) / (2 * n**2)), rtol=1e-13, atol=0)


# --------------------------------------------------------------------------- coupling pattern


def expected_pattern(n_modes, n_legs):
    """Entry pattern implied by the Appendix for a generic angle and generic k_r != k_t."""
    pattern = np.zeros((2 * n_modes, 2 * n_modes), dtype=bool)
    for n, p in itertools.product(range(1, n_modes + 1), repeat=2):
        if n == p and (2 * n) % n_legs != 0:
            set_block(pattern, n, p, np.eye(2, dtype=bool))  # equal pair, no off-diagonal
        elif legs_couple(n, p, n_legs):
            set_block(pattern, n, p, True)
    return pattern


def test_fig2_pattern():
    n_modes, n_legs, angle = 11, 9, 0.3
    pattern = structure.coupling_pattern(n_modes, n_legs, angle)
    assert pattern.dtype == bool and pattern.shape == (22, 22)
    np.testing.assert_array_equal(pattern, pattern.T)
    for n, p in ((1, 8), (4, 5), (2, 11)):
        assert block(pattern, n, p).all(), (n, p)
    assert not block(pattern, 1, 2).any()
    assert not block(pattern, 3, 5).any()
    stiffness = structure.leg_stiffness_matrix(n_modes, n_legs, angle, K_R, K_T)
    split = block(stiffness, 9, 9)
    assert abs(split[0, 1]) > 1.0
    assert abs(split[0, 0] - split[1, 1]) > 1.0
    for n in (1, 2, 5, 8, 11):
        equal = block(stiffness, n, n)
        assert equal[0, 0] == pytest.approx(equal[1, 1], rel=1e-12)
        assert abs(equal[0, 1]) < 1e-12 * equal[0, 0]
    np.testing.assert_array_equal(pattern, expected_pattern(n_modes, n_legs))


@pytest.mark.parametrize(('n_modes', 'n_legs'), [(11, 9), (12, 8), (9, 4), (7, 3), (5, 1), (6, 2)])
def test_pattern_follows_the_n_plus_minus_p_rule(n_modes, n_legs):
    pattern = structure.coupling_pattern(n_modes, n_legs, 0.37)
    np.testing.assert_array_equal(pattern, expected_pattern(n_modes, n_legs))


def test_split_block_at_zero_angle_is_diagonal_but_unequal():
    # Eq. (15) at alpha = 0: off-diagonal terms vanish, the diagonal terms differ.
    stiffness = structure.leg_stiffness_matrix_closed_form(4, 8, 0.0, K_R, K_T)
    np.testing.assert_array_equal(stiffness, np.diag(np.diag(stiffness)))
    assert block(stiffness, 4, 4)[0, 0] == pytest.approx(8 * K_R)
    assert block(stiffness, 4, 4)[1, 1] == pytest.approx(4 * K_T / 8)


@pytest.mark.parametrize(('n_modes', 'n_legs', 'diagonal'), [
    (3, 8, True), (4, 8, False), (4, 9, True), (5, 9, False), (2, 5, True), (3, 5, False),
    (1, 3, True), (1, 2, False), (1, 1, False), (7, 16, True), (8, 16, False),
])
def test_leg_stiffness_is_diagonal_iff_ritz_order_below_half_the_legs(n_modes, n_legs, diagonal):
    assert (n_modes < n_legs / 2) == diagonal
    pattern = structure.coupling_pattern(n_modes, n_legs, 0.3)
    assert (np.count_nonzero(pattern & ~np.eye(2 * n_modes, dtype=bool)) == 0) == diagonal


@pytest.mark.parametrize('n_legs', range(1, 13))
def test_couples_different_modes_agrees_with_the_pattern(n_legs):
    for n_modes in range(1, 2 * n_legs + 2):
        pattern = structure.coupling_pattern(n_modes, n_legs, 0.3)
        off_block = pattern.copy()
        for n in range(1, n_modes + 1):
            set_block(off_block, n, n, False)
        assert structure.couples_different_modes(n_modes, n_legs) == off_block.any()


# --------------------------------------------------------------------------- frequencies


def test_eight_legs_split_the_4theta_pair_not_the_2theta_pair():
    freq = frequencies(4, 8, 0.0)
    assert freq[1] == pytest.approx(freq[5], rel=1e-13)  # 2theta (q2, q2s): degenerate
    assert abs(freq[3] - freq[7]) > 0.05 * freq[3]  # 4theta (q4, q4s): split
    # At alpha = 0 the cosine 4theta shape has its antinodes on the legs: radial springs.
    k_ring = YOUNGS_PA * SECOND_MOMENT_M4 * math.pi * 15**2 / RADIUS_M**3
    m_ring = RING_MASS_KG * 17 / 32
    aligned = math.sqrt((k_ring + 8 * K_R) / (m_ring + 8 * LEG_MASS_KG)) / (2 * math.pi)
    across = math.sqrt((k_ring + 4 * K_T / 8) / (m_ring + 4 * LEG_MASS_KG / 8)) / (2 * math.pi)
    assert freq[3] == pytest.approx(aligned, rel=1e-12)
    assert freq[7] == pytest.approx(across, rel=1e-12)


def test_split_pair_slots_follow_the_mode_shapes():
    base = frequencies(4, 8, 0.0)
    # Rotating the legs by pi / 8 puts them on the nodes of cos 4 theta: the slots swap.
    rotated = frequencies(4, 8, math.pi / 8)
    pair = [3, 7]  # q4, q4s
    others = [0, 1, 2, 4, 5, 6]
    np.testing.assert_allclose(rotated[pair], base[pair][::-1], rtol=1e-12)
    np.testing.assert_allclose(frequencies(4, 8, 0.05)[pair], base[pair], rtol=1e-12)
    np.testing.assert_allclose(rotated[others], base[others], rtol=1e-12)


@pytest.mark.parametrize('n_legs', range(1, 13))
@pytest.mark.parametrize('angle', [0.0, 0.37])
def test_pair_splits_iff_2n_over_n_legs_is_integer(n_legs, angle):
    n_modes = max(1, n_legs // 2)
    assert not structure.couples_different_modes(n_modes, n_legs)
    freq = frequencies(n_modes, n_legs, angle)
    for n in range(1, n_modes + 1):
        cos, sin = freq[indices(n_modes, n)]
        relative_gap = abs(cos - sin) / cos
        if (2 * n) % n_legs == 0:
            assert relative_gap > 1e-4, n
        else:
            assert relative_gap < 1e-12, n


@pytest.mark.parametrize(('n_modes', 'n_legs'), [(9, 4), (7, 3), (12, 8), (11, 9), (6, 2)])
def test_coupled_spectrum_splitting_and_rotation_invariance(n_modes, n_legs):
    assert structure.couples_different_modes(n_modes, n_legs)
    slots = frequencies(n_modes, n_legs, 0.37)
    freq = np.sort(slots)
    # Coupled: consecutive pairs of the sorted spectrum, the lower in the cosine slots.
    np.testing.assert_array_equal(slots, np.concatenate([freq[0::2], freq[1::2]]))
    # Groups of equal frequencies: pairs for the 2-dimensional classes, singles for the modes
    # with 2n / N_l integer (one single per coordinate).
    sizes = [1]
    for previous, value in zip(freq[:-1], freq[1:]):
        if value - previous <= 1e-9 * value:
            sizes[-1] += 1
        else:
            sizes.append(1)
    expected_singles = 2 * sum(1 for n in range(1, n_modes + 1) if (2 * n) % n_legs == 0)
    assert sizes.count(1) == expected_singles
    assert sizes.count(2) == (2 * n_modes - expected_singles) // 2
    # Rotating the legs rotates the modes, not the spectrum.
    np.testing.assert_allclose(np.sort(frequencies(n_modes, n_legs, -1.2)), freq, rtol=1e-11)


# --------------------------------------------------------------------------- validation


@pytest.mark.parametrize(('call', 'name'), [
    (lambda: structure.ring_mass(0.0, 1e-5, 1e-4, 2330.0), 'radius_m'),
    (lambda: structure.ring_mass(1e-3, -1e-5, 1e-4, 2330.0), 'thickness_m'),
    (lambda: structure.second_moment_of_area(1e-5, float('nan')), 'length_m'),
    (lambda: structure.modal_mass_factor(0), 'n'),
    (lambda: structure.ring_mass_matrix(2.0, 1.0), 'n_modes'),
    (lambda: structure.ring_mass_matrix(True, 1.0), 'n_modes'),
    (lambda: structure.ring_mass_matrix(2, 0.0), 'ring_mass_kg'),
    (lambda: structure.ring_stiffness_matrix(2, 'x', 1.0, 1.0), 'youngs_modulus_pa'),
    (lambda: structure.leg_stiffness_matrix(2, 0, 0.0, 1.0, 1.0), 'n_legs'),
    (lambda: structure.leg_stiffness_matrix(2, 8, float('inf'), 1.0, 1.0), 'angle_rad'),
    (lambda: structure.leg_stiffness_matrix_closed_form(2, 8, 0.0, -1.0, 1.0),
     'radial_stiffness'),
    (lambda: structure.leg_stiffness_matrix_closed_form(2, 8, 0.0, 1.0, -1.0),
     'tangential_stiffness'),
    (lambda: structure.leg_mass_matrix(2, 8, 0.0, -1e-9), 'leg_mass_kg'),
    (lambda: structure.coupling_pattern(0, 8, 0.0), 'n_modes'),
    (lambda: frequencies(3, 8, 0.0, leg_mass_kg=-1.0), 'leg_mass_kg'),
])
def test_invalid_arguments_raise_parameter_error_naming_them(call, name):
    with pytest.raises(ParameterError, match=f'^{name} must'):
        call()
    assert issubclass(ParameterError, ValueError)


def test_numpy_integers_are_accepted():
    np.testing.assert_array_equal(
        structure.leg_mass_matrix(np.int64(3), np.int32(8), 0.1, 1e-9),
        structure.leg_mass_matrix(3, 8, 0.1, 1e-9),
    )


# ----------------------------------------------------------------------------- imperfect pairs
def test_pair_matrices_follow_their_principal_axes():
    n, wx, wy, qx, qy = 2, 2 * math.pi * 15800.0, 2 * math.pi * 15801.0, 6e4, 5e4
    k, c = structure.pair_matrices(n, wx, wy, qx, qy, 10.0, 22.5)
    # (P2) eigenvectors along (cos n theta, sin n theta), eigenvalues the principal values
    for matrix, values, axis in ((k, (wx * wx, wy * wy), 10.0), (c, (wx / qx, wy / qy), 22.5)):
        phi = n * math.radians(axis)
        ex = np.array([math.cos(phi), math.sin(phi)])
        ey = np.array([-math.sin(phi), math.cos(phi)])
        np.testing.assert_allclose(matrix @ ex, values[0] * ex, rtol=1e-13)
        np.testing.assert_allclose(matrix @ ey, values[1] * ey, rtol=1e-13)
    assert k[0, 1] == pytest.approx((wx * wx - wy * wy) / 2 * math.sin(4 * math.radians(10.0)))
    assert c[0, 1] == pytest.approx((wx / qx - wy / qy) / 2 * math.sin(4 * math.radians(22.5)))
    # (P4) axes turned by 90/n deg with the principal values swapped: the same pair
    k2, c2 = structure.pair_matrices(n, wy, wx, qy, qx, 10.0 + 45.0, 22.5 + 45.0)
    np.testing.assert_allclose(k2, k, rtol=1e-12)
    np.testing.assert_allclose(c2, c, rtol=1e-12)
    # axes at 0: diagonal, exactly the coordinates' own values
    k0, c0 = structure.pair_matrices(n, wx, wy, qx, qy)
    assert k0[0, 1] == c0[0, 1] == 0.0 and k0[0, 0] == wx * wx and c0[1, 1] == wy / qy
