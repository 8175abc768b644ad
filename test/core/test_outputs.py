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
The published output channels against brute-force references computed here.

Everything below is rebuilt from the definitions of ``doc``'s interface and physics pages,
not from the package's mode shapes or quadrature: the radial displacement
``w(theta) = sum_n q_n cos(n theta) + q_n^s sin(n theta)`` (coordinates by their published
names ``q<n>`` / ``q<n>s``); electrode k centred at ``theta_k = 2 pi k / K`` and spanning
``electrodes.span`` (``0`` = ``2 pi / K``) symmetrically; ``radial_gap``'s ``e<k>`` =
``d_g - w(theta_k)``, its ``min`` = ``d_g - max_theta w`` (200 000 angles, then a bounded
scalar maximisation around the best one); ``sense_electrodes``' ``e<k>`` =
``eps eps_0 l r_o * integral over the span of dtheta / (d_g - w)`` by ``scipy.integrate.quad``.

States: seeded random coordinates for N_R = 1..5 with and without companions, scaled so that
the largest |w| is 2 % to 90 % of the gap, for the default electrodes and for explicit,
narrower and wider spans; and states integrated by the Simulator after shocks off the grid
angles (17 and 100 deg, x and y components). The channels of a given state come from the
public :meth:`Simulator.outputs_for`; the integrated states are checked on the samples that
``advance_samples`` itself returns (what the node publishes).
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.engine.full import GAP_FLOOR_RATIO, GAP_GRID_POINTS_PER_MODE, Simulator
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.params import paper_config, STANDARD_GRAVITY
from scipy import integrate, optimize

GAP = 10e-6  # electrodes.gap default, m
EPS0 = 8.8541878128e-12  # CODATA 2018, F/m (typed here, not imported from the package)
LENGTH = 150e-6  # ring.length default (paper Table 1), m
OUTER_RADIUS = 1.5e-3 + 0.5 * (18e-6 + GAP)  # r + (h + d_g) / 2, doc/interface.md default, m
CAP_SCALE = EPS0 * LENGTH * OUTER_RADIUS  # eps = 1 by default, F / rad
# Paper Table 1 (doc/physics.md): frequencies and Q of the 1theta..5theta modes.
FREQUENCIES = [11200.0, 15800.0, 22000.0, 36300.0, 59200.0]
QUALITY = [120000.0, 64700.0, 170000.0, 80000.0, 50000.0]
# Round-off of w = sum of at most 10 terms each below d_g: a few 1e-16 d_g; 1e-13 d_g is far
# below any modelling mistake (the mutations below move the channels by > 1e-4 d_g).
ROUND_OFF = 1e-13 * GAP
# The capacitance channel's documented accuracy (kernels.output_channels): 1e-7 relative
# while the smallest gap on the electrode is at least CAP_ACCURATE_GAP.
CAP_RTOL = 1e-7
CAP_ACCURATE_GAP = 0.01 * GAP


def make_sim(n_modes, companions, **extra):
    """Return a Simulator with N_R modes of Table 1, drive off, from rest."""
    values = {'modes.frequencies': FREQUENCIES[:n_modes],
              'modes.quality_factors': QUALITY[:n_modes],
              'modes.companions': companions, 'drive.amplitude': 0.0,
              'drive.start_on': 'rest'}
    values.update(extra)
    return Simulator(paper_config(values))


def terms(names):
    """(harmonic n, is the sine companion) of each published coordinate name."""
    out = []
    for name in names:
        sine = name.endswith('s')
        out.append((int(name[1:-1] if sine else name[1:]), sine))
    return out


def w_dense(q, coords, theta):
    """w(theta) of the physics page, vectorised over theta."""
    theta = np.asarray(theta, dtype=np.float64)
    w = np.zeros_like(theta)
    for qi, (n, sine) in zip(q, coords):
        w += qi * (np.sin(n * theta) if sine else np.cos(n * theta))
    return w


def w_scalar(q, coords):
    """w(theta) as a plain Python function of one angle (for quad and minimize_scalar)."""
    pairs = [(float(qi), n, sine) for qi, (n, sine) in zip(q, coords) if qi != 0.0]

    def w(theta):
        return sum(qi * (math.sin(n * theta) if sine else math.cos(n * theta))
                   for qi, n, sine in pairs)
    return w


def reference_min_gap(q, coords):
    """d_g - max_theta w: 200 000 angles, then a bounded maximisation around the best one."""
    theta = np.linspace(0.0, 2 * np.pi, 200_000, endpoint=False)
    dense = w_dense(q, coords, theta)
    best = int(np.argmax(dense))
    w = w_scalar(q, coords)
    step = theta[1]
    bounds = (theta[best] - step, theta[best] + step)
    found = optimize.minimize_scalar(lambda x: -w(x), bounds=bounds, method='bounded',
                                     options={'xatol': 1e-14})
    return GAP - max(dense[best], -found.fun)


def reference_channels(q, coords, n_electrodes, span):
    """Centre gaps, smallest gap and capacitances of one state, brute force."""
    q = np.asarray(q, dtype=np.float64)
    centres = 2 * np.pi * np.arange(n_electrodes) / n_electrodes
    gaps = GAP - w_dense(q, coords, centres)
    w = w_scalar(q, coords)
    caps = np.empty(n_electrodes)
    for k, c in enumerate(centres):
        val, err = integrate.quad(lambda x: 1.0 / (GAP - w(x)), c - 0.5 * span, c + 0.5 * span,
                                  epsabs=0.0, epsrel=1e-13, limit=400)
        caps[k] = CAP_SCALE * val
    return gaps, reference_min_gap(q, coords), caps


def min_gap_tolerance(q, coords, n_modes):
    """
    Bound of the smallest-gap refinement's error for one state, m.

    The kernel samples w on G = GAP_GRID_POINTS_PER_MODE * N_R angles (spacing delta) and
    takes the vertex of the parabola through the best angle and its neighbours. That vertex
    lies within the three angles, where the parabola differs from w by at most
    ``|w'''| max|(x - x0)(x - x1)(x - x2)| / 6 = |w'''| delta^3 / (9 sqrt 3)``, and
    ``|w'''| <= sum n^3 |q_n|``. (This is the documented "~1e-4 of q_n": delta = 2 pi / 32
    for the highest mode gives 4.6e-4 n^3-weighted, ~1e-4 for a typical mix.)
    """
    delta = 2 * np.pi / (GAP_GRID_POINTS_PER_MODE * n_modes)
    c3 = sum(n ** 3 * abs(qi) for qi, (n, _) in zip(q, coords))
    return c3 * delta ** 3 / (9 * math.sqrt(3)) + ROUND_OFF


def random_states(rng, sim, count, w_lo=0.02, w_hi=0.9):
    """Random coordinates (mixed sizes per mode), scaled to max|w| in [w_lo, w_hi] d_g."""
    coords = terms(sim.coordinates)
    theta = np.linspace(0.0, 2 * np.pi, 20_000, endpoint=False)
    states = []
    for _ in range(count):
        q = rng.normal(size=len(coords)) * rng.uniform(0.0, 1.0, size=len(coords)) ** 2
        q *= rng.uniform(w_lo, w_hi) * GAP / np.max(np.abs(w_dense(q, coords, theta)))
        states.append(q)
    return np.array(states)


class Errors:
    """Largest error of each channel over the checked states, for the printed summary."""

    def __init__(self):
        self.gap = self.min = self.min_ratio = self.cap = 0.0
        self.cap_rows = 0

    def report(self, what):
        assert self.cap_rows > 0  # some capacitances were compared
        print(f'{what}: centre gap {self.gap / GAP:.1e} d_g, min {self.min / GAP:.1e} d_g '
              f'({self.min_ratio:.2f} of its bound), capacitance {self.cap:.1e} relative '
              f'({self.cap_rows} states)')


def check_samples(q_rows, gap, min_gap, cap, coords, n_modes, n_electrodes, span, errors):
    """Assert every channel of every row against the reference."""
    for row in range(len(q_rows)):
        q = q_rows[row]
        ref_gap, ref_min, ref_cap = reference_channels(q, coords, n_electrodes, span)
        d_gap = np.max(np.abs(gap[row] - ref_gap))
        assert d_gap <= ROUND_OFF, (row, q, gap[row], ref_gap)
        tol = min_gap_tolerance(q, coords, n_modes)
        d_min = abs(min_gap[row] - ref_min)
        assert d_min <= tol, (row, q, min_gap[row], ref_min, tol)
        assert min_gap[row] <= np.min(gap[row]) + ROUND_OFF
        if ref_min >= CAP_ACCURATE_GAP:
            d_cap = np.max(np.abs(cap[row] / ref_cap - 1.0))
            assert d_cap <= CAP_RTOL, (row, q, cap[row], ref_cap)
            errors.cap = max(errors.cap, d_cap)
            errors.cap_rows += 1
        errors.gap = max(errors.gap, d_gap)
        errors.min = max(errors.min, d_min)
        errors.min_ratio = max(errors.min_ratio, d_min / tol)


@pytest.mark.parametrize('companions', [False, True])
@pytest.mark.parametrize('n_modes', [1, 2, 3, 4, 5])
def test_channels_of_random_states_match_brute_force(n_modes, companions):
    # A distinct, fixed seed per case: the same states on every run.
    rng = np.random.default_rng(1000 * n_modes + companions)
    sim = make_sim(n_modes, companions)
    coords = terms(sim.coordinates)
    states = random_states(rng, sim, 24)
    out = sim.outputs_for(states)
    errors = Errors()
    check_samples(states, out.gap, out.min_gap, out.capacitance, coords, n_modes, 8,
                  2 * np.pi / 8, errors)
    errors.report(f'N_R = {n_modes}, companions {companions}, 8 electrodes')


@pytest.mark.parametrize('count, span', [(3, 0.5), (1, 0.0), (2, 0.0), (12, 0.0), (8, 0.3)])
def test_electrode_count_and_span_are_honoured(count, span):
    # Explicit spans narrower than 2 pi / K, one electrode around the whole ring, and many
    # narrow ones, with the richest mode set (N_R = 5 and companions).
    rng = np.random.default_rng(77 + count)
    sim = make_sim(5, True, **{'electrodes.count': count, 'electrodes.span': span})
    coords = terms(sim.coordinates)
    states = random_states(rng, sim, 10)
    out = sim.outputs_for(states)
    errors = Errors()
    check_samples(states, out.gap, out.min_gap, out.capacitance, coords, 5, count,
                  span or 2 * np.pi / count, errors)
    errors.report(f'{count} electrodes, span {span} rad')
    assert sim.channel_names['sense_electrodes'] == [f'e{k}' for k in range(count)]


def test_channels_near_contact_match_brute_force():
    # Gaps between 0.01 d_g and 0.1 d_g: the integrand 1/(d_g - w) is sharply peaked.
    rng = np.random.default_rng(5)
    errors = Errors()
    for n_modes in (1, 3, 5):
        sim = make_sim(n_modes, True)
        states = random_states(rng, sim, 8, w_lo=0.9, w_hi=0.985)
        out = sim.outputs_for(states)
        check_samples(states, out.gap, out.min_gap, out.capacitance, terms(sim.coordinates),
                      n_modes, 8, 2 * np.pi / 8, errors)
    errors.report('gaps down to 0.01 d_g')


@pytest.mark.parametrize('n_modes, companions, angle_deg', [
    (3, True, 17.0), (5, True, 100.0), (2, True, 17.0), (3, False, 0.0)])
def test_channels_of_shocked_states_match_brute_force(n_modes, companions, angle_deg):
    # A 10 000 g half-sine off the electrode grid (x and y components), integrated by the
    # Simulator; every 25th sample of 2 ms (80 samples through the first swings) is checked,
    # on the samples advance_samples returns.
    peak = 10_000 * STANDARD_GRAVITY
    sim = make_sim(n_modes, companions)
    a = math.radians(angle_deg)
    sim.shock(peak * math.cos(a), peak * math.sin(a), at_ns=0)
    out = sim.advance_samples(2000)
    assert sim.status == 'running'
    rows = np.arange(0, len(out), 25)
    coords = terms(sim.coordinates)
    w_peak = max(np.max(np.abs(w_dense(q, coords, np.linspace(0, 2 * np.pi, 720))))
                 for q in out.q[rows])
    assert w_peak > 0.3 * GAP  # well into the nonlinear range
    if companions and angle_deg % 90:
        assert np.max(np.abs(out.q[:, n_modes])) > 0.1e-6  # q1s moves: the y component acts
    errors = Errors()
    check_samples(out.q[rows], out.gap[rows], out.min_gap[rows], out.capacitance[rows],
                  coords, n_modes, 8, 2 * np.pi / 8, errors)
    errors.report(f'shock at {angle_deg} deg, N_R = {n_modes}, companions {companions}')


def test_rest_and_floor_in_contact():
    sim = make_sim(3, True)
    span = 2 * np.pi / 8
    rest = sim.outputs_for(np.zeros(6))
    assert np.all(rest.gap == GAP) and rest.min_gap[0] == GAP
    assert rest.capacitance == pytest.approx(np.full((1, 8), CAP_SCALE * span / GAP),
                                             rel=1e-14)
    # q1 = 2 d_g: over all of electrode e0 (|theta| <= 22.5 deg, w >= 1.85 d_g) the ring is
    # through the electrode; the published gaps stop at 0 and the integrand at the floor
    # GAP_FLOOR_RATIO d_g (documented in core/engine/full.py), so e0 = cap_scale span / floor.
    deep = sim.outputs_for([2 * GAP, 0, 0, 0, 0, 0])
    assert deep.gap[0, 0] == 0.0 and deep.min_gap[0] == 0.0
    assert deep.capacitance[0, 0] == pytest.approx(CAP_SCALE * span / (GAP_FLOOR_RATIO * GAP),
                                                   rel=1e-12)
    # e4 at 180 deg sees the gap open to 3 d_g at its centre: no floor there.
    ref = integrate.quad(lambda x: 1 / (GAP - 2 * GAP * math.cos(x)), np.pi - span / 2,
                         np.pi + span / 2, epsrel=1e-13)[0]
    assert deep.capacitance[0, 4] == pytest.approx(CAP_SCALE * ref, rel=CAP_RTOL)
    assert deep.gap[0, 4] == pytest.approx(3 * GAP, rel=1e-15)


def test_contact_reached_by_the_simulator_gives_finite_bounded_channels():
    sim = make_sim(3, True)
    sim.shock(30_000 * STANDARD_GRAVITY * math.cos(0.3), 30_000 * STANDARD_GRAVITY
              * math.sin(0.3), at_ns=0)
    out = sim.advance_samples(1000)
    assert sim.status == 'contact'
    held = out.q[-1]
    assert np.all(out.q[-10:] == held)
    top = CAP_SCALE * (2 * np.pi / 8) / (GAP_FLOOR_RATIO * GAP)  # integrand <= 1 / floor
    for arr in (out.gap, out.min_gap, out.capacitance):
        assert np.all(np.isfinite(arr))
    assert np.all(out.gap >= 0.0) and np.all(out.min_gap >= 0.0)
    assert np.all(out.capacitance > 0.0) and np.all(out.capacitance <= top)
    # Held where it touched: the ring reaches the electrode to within the refinement bound.
    coords = terms(sim.coordinates)
    ref_min = reference_min_gap(held, coords)
    assert out.min_gap[-1] <= max(ref_min, 0.0) + min_gap_tolerance(held, coords, 3)
    assert ref_min < 0.01 * GAP


def test_outputs_for_rejects_bad_coordinates():
    sim = make_sim(2, False)
    for bad in ([1e-6], [[1e-6, 0.0, 0.0]], [math.nan, 0.0]):
        with pytest.raises(InputError, match=r'^q: expected 2 finite values'):
            sim.outputs_for(bad)
    before = sim.q.copy(), sim.time_ns
    one = sim.outputs_for([1e-6, 2e-7])
    assert len(one) == 1 and one.t[0] == 0.0 and np.all(one.v == 0.0)
    assert np.array_equal(sim.q, before[0]) and sim.time_ns == before[1]
