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
Tests of ``ring_gyro_sim.core.forces``: the electrostatic force of eqs. (18)-(26), (35), (36).

The references are independent of the package: the closed form of eq. (35) is derived here
with sympy from eq. (21) (exact integrals, exact rationals), the quadrature is checked against
a much finer trapezoidal rule written here, and the force against finite differences of the
energy. Coordinates ``x = [q_1..q_N (, q_1^s..q_N^s)]``, ``w = sum q_n cos n theta +
q_n^s sin n theta``, outward ``w`` closes the outer gap; SI units throughout.
"""

import functools
import math
import re

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from ring_gyro_sim.core import forces
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.params import paper_config
import sympy as sp

GAP = 10e-6
FREQUENCIES = [11200.0, 15800.0, 22000.0, 36300.0, 59200.0]
QUALITY_FACTORS = [120000.0, 64700.0, 170000.0, 80000.0, 50000.0]


def make_config(n_modes=3, taylor_terms=10, outer_voltage=80.0, inner_voltage=0.0, fold=True,
                companions=False, **extra):
    """Build a validated SimConfig of the paper's device with the given force model."""
    flat = {
        'modes.frequencies': FREQUENCIES[:n_modes],
        'modes.quality_factors': QUALITY_FACTORS[:n_modes],
        'modes.companions': companions,
        'electrodes.gap': GAP,
        'electrodes.taylor_terms': taylor_terms,
        'electrodes.outer_voltage': outer_voltage,
        'electrodes.inner_voltage': inner_voltage,
        'electrodes.fold_linear_stiffness': fold,
        'drive.amplitude': 0.0,
    }
    flat.update(extra)
    return paper_config(flat)


@functools.lru_cache(maxsize=None)
def make_model(**kwargs):
    """Build (once) the ForceModel of :func:`make_config`; kwargs must be hashable."""
    return forces.build_force_model(make_config(**kwargs))


def random_states(rng, n_coordinates, count, max_u):
    """States with ``max |w| <= max_u d_g`` (the sum of |q| bounds |w| everywhere)."""
    x = rng.uniform(-1.0, 1.0, size=(count, n_coordinates))
    x *= (max_u * GAP / np.abs(x).sum(axis=1))[:, None]
    return x


def displacement(x, model, theta):
    """w(theta), m, of state x (independent of the package's quadrature)."""
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    return forces.mode_shapes(model.harmonics, model.sine, theta) @ x


# ---------------------------------------------------------------------------------------------
# Eq. (35): N_R = 2, N_T = 5, derived with sympy from eq. (21).
# ---------------------------------------------------------------------------------------------

Q1, Q2 = sp.symbols('q1 q2', real=True)
A_EPS, R_O, R_I, V_O, V_I, D_G, M = sp.symbols('A_eps r_o r_i V_o V_i d_g M', positive=True)
Z = sp.symbols('z')


def circle_integral_of_power(w_of_z, k):
    """
    ``int_0^{2 pi} w^k d theta`` exactly, for w a Laurent polynomial in z = exp(i theta).

    ``int_0^{2 pi} z^m d theta`` is 2 pi for m = 0 and 0 otherwise, so the integral is 2 pi
    times the constant term of w^k; ``w`` has degree at most 2 in z and 1/z, so ``z^2 w`` is a
    polynomial and the constant term of ``w^k`` is the coefficient of ``z^(2k)`` in it.
    """
    poly = sp.Poly(sp.expand(Z ** 2 * w_of_z) ** k, Z)
    return 2 * sp.pi * poly.coeff_monomial(Z ** (2 * k))


@functools.lru_cache(maxsize=None)
def eq35_derivation():
    """
    -F_nl of N_R = 2, N_T = 5 from eq. (21) by Lagrange (eq. 23), and the printed eq. (35).

    Returns ``(derived, printed, alpha, beta, gamma)``: ``derived[n]`` is
    ``+dE_c/dq_n / m_n`` (the generalised electrostatic force per unit modal mass, the k >= 3
    terms only: k = 0, 1 give no force, k = 2 is K_c of eq. 26), and ``printed[n]`` the force
    terms of eq. (35) as printed, ``F_nl,n``; the claim is ``derived == -printed``.
    """
    w = Q1 * (Z + 1 / Z) / 2 + Q2 * (Z ** 2 + Z ** -2) / 2  # q1 cos(theta) + q2 cos(2 theta)
    energy = sum(A_EPS * (R_O * V_O ** 2 + (-1) ** k * R_I * V_I ** 2) / D_G ** k
                 * circle_integral_of_power(w, k) for k in range(3, 6))
    masses = (M, sp.Rational(5, 8) * M)  # m_r (n^2 + 1) / (2 n^2), eqs. (7) and (16)
    derived = tuple(sp.expand(sp.diff(energy, q) / m) for q, m in zip((Q1, Q2), masses))
    alpha = 3 * (R_I * V_I ** 2 - R_O * V_O ** 2) * A_EPS * sp.pi / (M * D_G ** 3)
    beta = 3 * (R_I * V_I ** 2 + R_O * V_O ** 2) * A_EPS * sp.pi / (M * D_G ** 4)
    gamma = 5 * alpha / (6 * D_G ** 2)
    printed = (
        alpha * Q1 * Q2 - beta * Q1 * (Q1 ** 2 + 2 * Q2 ** 2)
        + gamma * Q1 * Q2 * (4 * Q1 ** 2 + 3 * Q2 ** 2),
        sp.Rational(4, 5) * alpha * Q1 ** 2
        - sp.Rational(8, 5) * beta * Q2 * (Q2 ** 2 + 2 * Q1 ** 2)
        + sp.Rational(4, 5) * gamma * Q1 ** 2 * (2 * Q1 ** 2 + 9 * Q2 ** 2),
    )
    return derived, printed, alpha, beta, gamma


def test_circle_integral_matches_sympy_integrate():
    theta = sp.symbols('theta', real=True)
    w_theta = Q1 * sp.cos(theta) + Q2 * sp.cos(2 * theta)
    w_z = Q1 * (Z + 1 / Z) / 2 + Q2 * (Z ** 2 + Z ** -2) / 2
    for k in (3, 4):
        direct = sp.integrate(sp.expand(w_theta ** k), (theta, 0, 2 * sp.pi))
        assert sp.simplify(direct - circle_integral_of_power(w_z, k)) == 0
    # e.g. int w^3 = (3 pi / 2) q1^2 q2: the source of the alpha q1 q2 coupling.
    assert sp.simplify(circle_integral_of_power(w_z, 3)
                       - sp.Rational(3, 2) * sp.pi * Q1 ** 2 * Q2) == 0


@pytest.mark.parametrize('n', [0, 1])
def test_eq35_printed_force_is_derived_from_eq21(n):
    """Eq. (35) as printed is exact: every rational factor and the alpha, beta, gamma."""
    derived, printed, _, _, _ = eq35_derivation()
    # The paper's equations of motion carry +F_nl on the left: the generalised force of
    # eq. (23) (right-hand side) is -F_nl.
    assert sp.simplify(derived[n] + printed[n]) == 0


def test_eq35_coefficients_one_by_one():
    """Monomial by monomial, so that a typo would point at the coefficient."""
    derived, printed, alpha, beta, gamma = eq35_derivation()
    expected = {
        0: {(1, 1): alpha, (3, 0): -beta, (1, 2): -2 * beta, (3, 1): 4 * gamma,
            (1, 3): 3 * gamma},
        1: {(2, 0): sp.Rational(4, 5) * alpha, (0, 3): -sp.Rational(8, 5) * beta,
            (2, 1): -sp.Rational(16, 5) * beta, (4, 0): sp.Rational(8, 5) * gamma,
            (2, 2): sp.Rational(36, 5) * gamma},
    }
    for n in (0, 1):
        poly = sp.Poly(-derived[n], Q1, Q2)
        assert set(poly.as_dict()) == set(expected[n])
        for monomial, coefficient in expected[n].items():
            assert sp.simplify(poly.coeff_monomial(Q1 ** monomial[0] * Q2 ** monomial[1])
                               - coefficient) == 0, (n, monomial)
        assert sp.simplify(sp.expand(printed[n]) - poly.as_expr()) == 0


def _eq35_numeric(config):
    """Callables ``-F_nl,n(q1, q2)`` of the printed eq. (35) and the size of their terms."""
    _, printed, _, _, _ = eq35_derivation()
    e = config.electrodes
    values = {A_EPS: config.a_eps, R_O: config.outer_radius, R_I: config.inner_radius,
              V_O: e.outer_voltage, V_I: e.inner_voltage, D_G: e.gap,
              M: config.ring.mass + config.legs.count * config.legs.mass}
    out = []
    for expr in printed:
        terms = sp.Add.make_args(sp.expand(expr.subs(values)))
        force = sp.lambdify((Q1, Q2), -expr.subs(values), 'math')
        size = sp.lambdify((Q1, Q2), sum(sp.Abs(t) for t in terms), 'math')
        out.append((force, size))
    return out


@pytest.mark.parametrize('outer_voltage, inner_voltage', [
    (80.0, 50.0),   # softening, both electrodes
    (40.0, 70.0),   # hardening (r_i V_i^2 > r_o V_o^2): alpha, gamma change sign
    (80.0, 0.0),    # outer only (the paper's main runs)
])
def test_package_force_equals_eq35(outer_voltage, inner_voltage):
    config = make_config(n_modes=2, taylor_terms=5, outer_voltage=outer_voltage,
                         inner_voltage=inner_voltage, **{'legs.mass': 2e-9})
    assert config.legs.count == 8  # the paper's m_r + 8 m_l
    model = forces.build_force_model(config)
    reference = _eq35_numeric(config)
    rng = np.random.default_rng(35)
    for x in random_states(rng, 2, 200, 0.5) * rng.uniform(0.05, 1.0, size=(200, 1)):
        a = forces.nonlinear_acceleration(x, model)
        for n, (force, size) in enumerate(reference):
            assert abs(a[n] - force(*x)) <= 1e-12 * size(*x), (x, n)


def test_unfolded_force_adds_eq26_stiffness():
    """Without folding, the k = 2 term -K_c q_n / m_n (eq. 26) adds to eq. (35)."""
    folded = make_config(n_modes=2, taylor_terms=5, inner_voltage=50.0)
    unfolded = make_config(n_modes=2, taylor_terms=5, inner_voltage=50.0, fold=False)
    e = folded.electrodes
    kc = 2.0 * math.pi * folded.a_eps * (folded.outer_radius * e.outer_voltage ** 2
                                         + folded.inner_radius * e.inner_voltage ** 2) / GAP ** 2
    masses = np.array(folded.modal_masses())
    m_fold = forces.build_force_model(folded)
    m_unfold = forces.build_force_model(unfolded)
    rng = np.random.default_rng(26)
    for x in random_states(rng, 2, 50, 0.5):
        expected = forces.nonlinear_acceleration(x, m_fold) + kc * x / masses
        np.testing.assert_allclose(forces.nonlinear_acceleration(x, m_unfold), expected,
                                   rtol=1e-12, atol=1e-12 * np.abs(expected).max())


# ---------------------------------------------------------------------------------------------
# Eq. (36): symmetric electrodes r_o V_o^2 = r_i V_i^2 cancel every even power.
# ---------------------------------------------------------------------------------------------

# r_o = 4 r_i and V_i = 2 V_o: both products are the same float (scaling by 4 is exact), so
# this does not rely on any tolerance inside the package.
SYMMETRIC = {'electrodes.outer_radius': 2.0e-3, 'electrodes.inner_radius': 0.5e-3,
             'outer_voltage': 40.0, 'inner_voltage': 80.0}


def symmetric_model(n_modes, taylor_terms, companions=False):
    extra = {k: v for k, v in SYMMETRIC.items() if k.startswith('electrodes.')}
    config = make_config(n_modes=n_modes, taylor_terms=taylor_terms,
                         outer_voltage=SYMMETRIC['outer_voltage'],
                         inner_voltage=SYMMETRIC['inner_voltage'], companions=companions,
                         **extra)
    e = config.electrodes
    assert config.a_eps * config.outer_radius * e.outer_voltage ** 2 == \
        config.a_eps * config.inner_radius * e.inner_voltage ** 2
    model = forces.build_force_model(config)
    assert model.outer == model.inner
    return config, model


def test_eq36_printed_form():
    config, model = symmetric_model(2, 5)
    assert np.all(model.energy_poly[1::2] == 0.0)  # no odd k: no even power of q in the force
    _, _, _, beta, _ = eq35_derivation()
    e = config.electrodes
    b = float(beta.subs({A_EPS: config.a_eps, R_O: config.outer_radius,
                         R_I: config.inner_radius, V_O: e.outer_voltage, V_I: e.inner_voltage,
                         D_G: GAP, M: config.ring.mass}))
    rng = np.random.default_rng(36)
    for q1, q2 in random_states(rng, 2, 100, 0.5):
        a = forces.nonlinear_acceleration(np.array([q1, q2]), model)
        expected = (b * q1 * (q1 ** 2 + 2 * q2 ** 2), 1.6 * b * q2 * (q2 ** 2 + 2 * q1 ** 2))
        scale = b * (abs(q1) + abs(q2)) ** 3 * 5
        assert abs(a[0] - expected[0]) <= 1e-12 * scale
        assert abs(a[1] - expected[1]) <= 1e-12 * scale


def test_eq36_no_force_on_q2_from_q1_alone():
    _, model = symmetric_model(2, 5)
    for q1 in np.linspace(-0.9, 0.9, 37) * GAP:
        a = forces.nonlinear_acceleration(np.array([q1, 0.0]), model)
        assert a[1] == 0.0
        assert q1 == 0.0 or a[0] != 0.0


@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('companions', [False, True])
def test_eq36_odd_harmonics_never_drive_even_ones(taylor_terms, companions):
    """N_R = 3: states of odd harmonics only (q1, 0, q3) give exactly 0.0 on every even one."""
    _, model = symmetric_model(3, taylor_terms, companions)
    even = model.harmonics % 2 == 0
    rng = np.random.default_rng(360)
    for x in random_states(rng, model.n_coordinates, 100, 0.9):
        x[even] = 0.0
        a = forces.nonlinear_acceleration(x, model)
        assert np.all(a[even] == 0.0), a
        assert np.all(a[~even] != 0.0)


@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('companions', [False, True])
def test_eq36_force_is_odd(taylor_terms, companions):
    _, model = symmetric_model(3, taylor_terms, companions)
    rng = np.random.default_rng(361)
    for x in random_states(rng, model.n_coordinates, 100, 0.9):
        a = forces.nonlinear_acceleration(x, model)
        assert np.array_equal(forces.nonlinear_acceleration(-x, model), -a)


def test_asymmetric_electrodes_do_couple_q1_to_q2():
    """The control of the eq. (36) tests: with r_o V_o^2 != r_i V_i^2, q1 alone drives q2."""
    model = make_model(n_modes=3, inner_voltage=50.0)
    a = forces.nonlinear_acceleration(np.array([0.3 * GAP, 0.0, 0.0]), model)
    assert a[1] != 0.0


# ---------------------------------------------------------------------------------------------
# Force = -grad(potential) = +grad(E_c), Jacobian, Taylor convergence, quadrature.
# ---------------------------------------------------------------------------------------------

def central_gradient(f, x, step):
    grad = np.empty_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        grad[i] = (f(x + e) - f(x - e)) / (2.0 * step)
    return grad


@pytest.mark.parametrize('fold', [True, False])
@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('companions', [False, True])
@pytest.mark.parametrize('n_modes', [3, 5])
def test_force_is_gradient_of_energy(n_modes, companions, taylor_terms, inner_voltage, fold):
    model = make_model(n_modes=n_modes, companions=companions, taylor_terms=taylor_terms,
                       inner_voltage=inner_voltage, fold=fold)
    rng = np.random.default_rng(23)
    for x in random_states(rng, model.n_coordinates, 5, 0.6):
        force = forces.nonlinear_acceleration(x, model) * model.masses
        grad = central_gradient(lambda y: forces.electrostatic_energy(y, model), x, 1e-4 * GAP)
        np.testing.assert_allclose(force, grad, rtol=1e-6, atol=1e-6 * np.abs(grad).max())


@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('companions', [False, True])
def test_jacobian_matches_finite_differences(companions, taylor_terms, inner_voltage):
    model = make_model(n_modes=3, companions=companions, taylor_terms=taylor_terms,
                       inner_voltage=inner_voltage)
    rng = np.random.default_rng(24)
    step = 1e-5 * GAP
    for x in random_states(rng, model.n_coordinates, 5, 0.6):
        jac = forces.jacobian(x, model)
        fd = np.empty_like(jac)
        for j in range(x.size):
            e = np.zeros_like(x)
            e[j] = step
            fd[:, j] = (forces.nonlinear_acceleration(x + e, model)
                        - forces.nonlinear_acceleration(x - e, model)) / (2.0 * step)
        np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@pytest.mark.parametrize('state', [(0.5, 0.0, 0.0), (0.3, 0.15, 0.05), (0.2, -0.2, 0.1)])
def test_taylor_series_converges_geometrically(state, inner_voltage):
    """|w| < d_g: the N_T error falls like u_max^N_T towards the untruncated force."""
    x = np.array(state) * GAP
    u_max = np.abs(displacement(x, make_model(), np.linspace(0, 2 * np.pi, 3601))).max() / GAP
    assert u_max == pytest.approx(0.5, abs=1e-3)
    exact = forces.nonlinear_acceleration(x, make_model(taylor_terms=0,
                                                        inner_voltage=inner_voltage))
    errors = {}
    for n_t in (10, 20, 30):
        a = forces.nonlinear_acceleration(x, make_model(taylor_terms=n_t,
                                                        inner_voltage=inner_voltage))
        errors[n_t] = np.linalg.norm(a - exact) / np.linalg.norm(exact)
    assert errors[10] > errors[20] > errors[30]
    for lo, hi in ((10, 20), (20, 30)):
        rate = (errors[hi] / errors[lo]) ** (1.0 / (hi - lo))  # per Taylor term
        assert 0.9 * u_max < rate < 1.1 * u_max, (lo, hi, rate)
    assert errors[30] < 1e-6


@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@pytest.mark.parametrize('companions', [False, True])
def test_quadrature_is_exact(companions, inner_voltage):
    """N_T = 10, N_R = 3: the package equals a 10x finer trapezoidal rule written here."""
    config = make_config(n_modes=3, taylor_terms=10, inner_voltage=inner_voltage,
                         companions=companions)
    model = forces.build_force_model(config)
    assert model.m_points >= 10 * 3 + 1  # degree of u^(N_T - 1) cos(n theta) is <= N_T N_R
    e = config.electrodes
    c = [config.a_eps * (config.outer_radius * e.outer_voltage ** 2
                         + (-1) ** k * config.inner_radius * e.inner_voltage ** 2)
         for k in range(11)]
    n_fine = 10 * model.m_points
    theta = 2.0 * np.pi * np.arange(n_fine) / n_fine
    shapes = forces.mode_shapes(model.harmonics, model.sine, theta)
    masses = np.array([(n * n + 1.0) / (2.0 * n * n) for n in model.harmonics]) * config.ring.mass
    rng = np.random.default_rng(13)
    for x in random_states(rng, model.n_coordinates, 20, 0.9):
        u = shapes @ x / GAP
        dedw = sum(k * c[k] * u ** (k - 1) for k in range(3, 11)) / GAP  # P(u), N/rad
        reference = (2.0 * np.pi / n_fine) * (shapes.T @ dedw) / masses
        np.testing.assert_allclose(forces.nonlinear_acceleration(x, model), reference,
                                   rtol=0, atol=1e-13 * np.abs(reference).max())


# ---------------------------------------------------------------------------------------------
# Range: contact and the radius of convergence of the series.
# ---------------------------------------------------------------------------------------------

def angle_in_message(message):
    match = re.search(r'theta = (-?[0-9.]+) deg', message)
    assert match, message
    return math.radians(float(match.group(1)))


@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('companions, state', [
    (False, (0.7, 0.4, 0.0)),                  # theta = 0
    (False, (-0.7, 0.4, 0.0)),                 # theta = 180 deg
    (False, (0.72, -0.54, -0.42)),             # around 63 deg, three modes
    (False, (0.2, 0.1, 0.75)),                 # theta = 0, through q3
    (True, (0.0, -0.4, 0.0, -0.7, 0.0, 0.0)),  # theta = 270 deg, through q1^s
    (True, (0.354, 0.0, 0.0, 0.354, 0.7, 0.0)),  # theta = 45 deg, through q1^s and q2^s
])
def test_outer_contact_raises_and_names_the_angle(companions, state, taylor_terms,
                                                  inner_voltage):
    """Max w >= d_g somewhere (and min w > -d_g, so that nothing else is out of range)."""
    model = make_model(companions=companions, taylor_terms=taylor_terms,
                       inner_voltage=inner_voltage)
    x = np.array(state) * GAP
    assert displacement(x, model, np.linspace(0.0, 2.0 * np.pi, 36001)).min() > -0.95 * GAP
    with pytest.raises(SimulationError, match='outer electrode contact') as info:
        forces.nonlinear_acceleration(x, model)
    theta = angle_in_message(str(info.value))
    assert displacement(x, model, theta)[0] >= GAP * (1.0 - 1e-3), str(info.value)


# u(0) = -1.1 (inner gap closed at theta = 0), max u = 0.65 < 1.
INWARD = np.array([-0.5, -0.6, 0.0]) * GAP


def test_inner_contact_with_inner_electrode():
    for taylor_terms in (10, 0):
        model = make_model(taylor_terms=taylor_terms, inner_voltage=50.0)
        with pytest.raises(SimulationError, match='inner') as info:
            forces.nonlinear_acceleration(INWARD, model)
        assert displacement(INWARD, model, angle_in_message(str(info.value)))[0] <= -GAP


def test_series_out_of_range_without_inner_electrode():
    """No inner electrode: w <= -d_g is no contact, but the Taylor series has diverged."""
    model = make_model(taylor_terms=10, inner_voltage=0.0)
    with pytest.raises(SimulationError, match='Taylor series') as info:
        forces.nonlinear_acceleration(INWARD, model)
    assert 'contact' not in str(info.value)
    assert displacement(INWARD, model, angle_in_message(str(info.value)))[0] <= -GAP


def test_untruncated_force_without_inner_electrode_accepts_w_below_minus_gap():
    model = make_model(taylor_terms=0, inner_voltage=0.0)
    a = forces.nonlinear_acceleration(INWARD, model)
    assert np.all(np.isfinite(a))


def test_untruncated_force_without_inner_electrode_at_w_equal_minus_gap():
    model = make_model(taylor_terms=0, inner_voltage=0.0)
    x = np.array([-0.5, -0.5, 0.0]) * GAP  # u(0) = -1 exactly, max u = 0.5625
    a = forces.nonlinear_acceleration(x, model)
    assert np.all(np.isfinite(a))


def test_invalid_state_shape_and_value():
    model = make_model()
    with pytest.raises(ValueError, match='shape'):
        forces.nonlinear_acceleration(np.zeros(2), model)
    with pytest.raises(ValueError, match='finite'):
        forces.nonlinear_acceleration(np.array([np.nan, 0.0, 0.0]), model)


# ---------------------------------------------------------------------------------------------
# The ring's symmetry theta -> theta + pi, as a property.
# ---------------------------------------------------------------------------------------------

COORDINATE = st.floats(min_value=-0.3, max_value=0.3, allow_nan=False, allow_subnormal=False)


@pytest.mark.parametrize('taylor_terms', [10, 0])
@pytest.mark.parametrize('inner_voltage', [0.0, 50.0])
@settings(max_examples=40, deadline=None)
@given(q=st.tuples(COORDINATE, COORDINATE, COORDINATE))
def test_half_turn_symmetry(q, inner_voltage, taylor_terms):
    """w(theta + pi) with (q1, q2, q3) is w(theta) with (-q1, q2, -q3): a1, a3 flip, a2 stays."""
    model = make_model(inner_voltage=inner_voltage, taylor_terms=taylor_terms)
    x = np.array(q) * GAP
    flip = np.array([-1.0, 1.0, -1.0])
    a = forces.nonlinear_acceleration(x, model)
    assert np.array_equal(forces.nonlinear_acceleration(flip * x, model), flip * a)


@settings(max_examples=40, deadline=None)
@given(q=st.tuples(*[st.floats(min_value=-0.15, max_value=0.15, allow_nan=False,
                               allow_subnormal=False)] * 6))
def test_half_turn_symmetry_with_companions(q):
    """sin(n (theta + pi)) = (-1)^n sin(n theta): the odd companions flip as well."""
    model = make_model(inner_voltage=50.0, companions=True)
    x = np.array(q) * GAP
    flip = np.array([-1.0, 1.0, -1.0, -1.0, 1.0, -1.0])
    a = forces.nonlinear_acceleration(x, model)
    assert np.array_equal(forces.nonlinear_acceleration(flip * x, model), flip * a)
