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
The averaged (slow-flow) model of the driven 2theta pair (``core.engine.averaged``, S1-S2).

Against the periodic orbits (harmonic balance, shooting), a closed form of the linear pair,
the full model (``Simulator``) and the conservation laws of (S2).
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.analysis.slow_flow import AveragedModel
from ring_gyro_sim.core import harmonic_balance
from ring_gyro_sim.core.engine.averaged import envelope_of, state_of
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro import operating_point
from ring_gyro_sim.core.params import build_config

TEN_DEG_S = math.radians(10.0)
KAPPA = 0.8
Q2 = 64700.0
OPEN_LOOP = {'modes.companions': True, 'gyro.enabled': True, 'drive.amplitude': 0.0065,
             'drive.frequency': 15800.0, 'control.mode': 'open_loop',
             'gyro.temperature': 0.0,
             'gyro.input_noise_density': 0.0, 'gyro.calibration.source': 'ideal'}
PAIR = [1, 4]   # q2, q2s among the coordinates of N_R = 3 with companions


def config(**values):
    return build_config({**OPEN_LOOP, **{k.replace('__', '.'): v for k, v in values.items()}})


def test_the_envelope_maps_invert_each_other():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(5, 2)) + 1j * rng.normal(size=(5, 2))
    phase = rng.uniform(0.0, 10.0, size=5)
    q, v = state_of(a, 1e5, phase)
    assert np.allclose(envelope_of(q, v, 1e5, phase), a, rtol=1e-14, atol=1e-14)


def test_the_steady_state_is_the_one_harmonic_balance_and_the_shooting_orbit():
    # The paper's drive on its softened upper branch (q2 = 0.39 um, 3.9 % of the gap): the
    # nonlinearity decides the amplitude (the drive is 1.4 Hz below the linear resonance,
    # 11 half-widths).
    cfg = config(drive__amplitude=0.065, drive__frequency=15798.6)
    model = AveragedModel(cfg)
    resonator = operating_point.cos_only(cfg)
    orbit = operating_point.forced_orbit(resonator, 15798.6, 0.47e-6, 0.065)
    w = model.omega
    shooting = complex(orbit.initial_state[1], -orbit.initial_state[3 + 1] / w)
    a = model.steady_state([shooting, 0.0])
    # (1) A' = 0 of (S2) is the harmonic balance of the pair with one harmonic: the same
    # equations, so the same orbit to the Newton tolerance.
    guess = harmonic_balance.HarmonicOrbit(
        frequency_hz=15798.6, amplitude_m=np.zeros(3),
        coefficients_m=np.array([[0.0, 0.0, 0.0], [0.0, a[0].real, -a[0].imag],
                                 [0.0, 0.0, 0.0]]))
    hb1 = harmonic_balance.forced_orbit(resonator, 15798.6, guess)
    one = complex(hb1.coefficients_m[1, 1], -hb1.coefficients_m[1, 2])
    assert abs(a[0] - one) < 1e-9 * abs(one)
    assert a[1] == 0.0   # a perfect ring at rest: no sine content
    # (2) Against the shooting orbit (all harmonics): the one-harmonic truncation. The 3
    # omega harmonic shifts the first harmonic's frequency by O(eps_nl^2) omega, eps_nl the
    # electrostatic frequency shift over omega at this amplitude; on the resonance the
    # response turns a frequency error d into an amplitude and phase error of at most
    # 2 Q d / omega: tolerance 2 Q eps_nl^2.
    w2 = 2.0 * math.pi * 15800.0
    amp = abs(a[0])
    w_nl = math.sqrt(w2 ** 2 - model.nonlinear(np.array([amp, 0.0]))[0].real / amp)
    eps_nl = (w2 - w_nl) / w
    tol = 2.0 * Q2 * eps_nl ** 2
    rel = abs(a[0] - shooting) / abs(shooting)
    dphase = abs(np.angle(a[0] / shooting))
    print(f'|A| {amp:.6e} m, shooting {abs(shooting):.6e} m, phase {np.angle(a[0]):.6f} rad; '
          f'difference {rel:.2e} relative, {dphase:.2e} rad (eps_nl {eps_nl:.3e}, '
          f'tolerance {tol:.2e})')
    assert 5e-5 < eps_nl < 2e-4   # the case is nonlinear: the drive is on the softened branch
    assert rel < tol and dphase < tol


def linear_closed_form(t, omega, w2, q, force, rate):
    """A(t) of the matched, linear pair from rest (S2 in B = A_c +- i A_s)."""
    out = np.zeros((t.size, 2), dtype=complex)
    b = []
    for sign in (1.0, -1.0):
        lam = (-w2 / (2.0 * q) - 0.5j * (omega ** 2 + rate ** 2 - w2 ** 2) / omega
               - sign * 1j * KAPPA * rate)
        b_inf = -0.5j * force / omega / -lam
        b.append(b_inf * (1.0 - np.exp(lam * t)))
    out[:, 0] = 0.5 * (b[0] + b[1])
    out[:, 1] = (b[0] - b[1]) / 2j
    return out


def test_the_linear_pair_follows_the_closed_form_and_its_time_constant():
    # A drive of 6.5e-8 m/s^2 (0.4 pm), matched modes driven at resonance, 10 deg/s from
    # t = 0, from rest. The electrostatic shift at this amplitude, eps_nl = 9e-5 (0.4 pm /
    # 0.39 um)^2 = 1e-16 of omega, moves the resonant response by 2 Q eps_nl = 1e-11: the
    # closed form holds to the integrator's tolerance (RTOL 1e-10).
    force = 6.5e-8
    cfg = config(drive__amplitude=force, drive__start_on='rest',
                 scenario__rate_times=[0.0], scenario__rate_values=[TEN_DEG_S])
    model = AveragedModel(cfg)
    s = model.run(8.0, 100.0)
    w = 2.0 * math.pi * 15800.0
    expected = linear_closed_form(s.t, w, w, Q2, force, TEN_DEG_S)
    scale = abs(expected[-1, 0])
    err = np.max(np.abs(s.envelope - expected)) / scale
    assert err < 1e-8
    # the steady sense response of doc/gyroscope.md: |q2s| / |q2| = 2 kappa Omega Q / omega
    a = model.steady_state(expected[-1], TEN_DEG_S)
    ratio = abs(a[1]) / abs(a[0])
    print(f'closed-form error {err:.1e}; |A_s|/|A_c| {ratio:.7f}, '
          f'2 kappa Omega Q / omega {2 * KAPPA * TEN_DEG_S * Q2 / w:.7f}')
    assert ratio == pytest.approx(2.0 * KAPPA * TEN_DEG_S * Q2 / w, rel=1e-6)
    # the time constant 2 Q / omega (1.303 s): at zero rate the drive rises as 1 - e^{-t/tau}
    tau = 2.0 * Q2 / w
    rest = AveragedModel(config(drive__amplitude=force, drive__start_on='rest'))
    r = rest.run(2.0 * tau, 1.0 / tau)
    final = force * Q2 / (w * w)
    assert abs(r.envelope[1, 0]) / final == pytest.approx(1.0 - math.exp(-1.0), rel=1e-7)
    assert abs(r.envelope[2, 0]) / final == pytest.approx(1.0 - math.exp(-2.0), rel=1e-7)


@pytest.mark.parametrize('q_pair', [2000.0, 1e15])
def test_without_drive_the_envelope_decays_as_the_modal_damping_alone(q_pair):
    # Drive off, a large mixed standing / travelling wave (0.3 and 0.2 um: the electrostatic
    # force is well nonlinear), 10 deg/s: the Coriolis rotation and the averaged
    # electrostatic force conserve |A_c|^2 + |A_s|^2 (module docstring), the damping
    # (isotropic here) makes it decay as exp(-omega_2 t / Q) exactly; undamped it is
    # conserved.
    cfg = config(drive__amplitude=0.0, drive__start_on='rest',
                 modes__quality_factors=[120000.0, q_pair, 170000.0],
                 scenario__rate_times=[0.0], scenario__rate_values=[TEN_DEG_S])
    model = AveragedModel(cfg)
    start = np.array([0.3e-6, 0.2e-6j])
    s = model.run(0.1, 1000.0, start=start)
    w2 = 2.0 * math.pi * 15800.0
    energy = np.sum(np.abs(s.envelope) ** 2, axis=1)
    expected = np.sum(np.abs(start) ** 2) * np.exp(-w2 * s.t / q_pair)
    assert np.max(np.abs(energy / expected - 1.0)) < 1e-8
    # and the force did act: the electrostatic softening turned the envelopes' phase
    turn = np.angle(s.envelope[-1, 0] / s.envelope[0, 0])
    print(f'Q {q_pair:g}: |A|^2 against exp(-omega t / Q) within '
          f'{np.max(np.abs(energy / expected - 1.0)):.1e}; phase of A_c turned {turn:.3f} rad')
    assert abs(turn) > 0.05


def test_a_free_standing_wave_precesses_by_bryans_factor():
    # Drive off, undamped, a 10 nm standing wave along theta = 0, 20 rad/s for 50 ms: the
    # sensor turns by 1 rad and the pattern, in the sensor frame, by -2 / (n^2 + 1) = -0.4
    # rad (doc/physics.md, Bryan's factor; the full model's test_rotation measures it).
    # In (S2) the Coriolis term is the rotation of (A_c, A_s) by -kappa Omega t, the pattern
    # angle half the modal angle: -kappa / 2 = -0.4 per radian of sensor rotation.
    cfg = config(drive__amplitude=0.0, drive__start_on='rest',
                 modes__quality_factors=[120000.0, 1e15, 170000.0],
                 scenario__rate_times=[0.0], scenario__rate_values=[20.0])
    s = AveragedModel(cfg).run(0.05, 1000.0, start=np.array([10e-9, 0.0]))
    a_c, a_s = s.envelope[-1]
    # a standing wave: both coordinates in phase (the common phase turns with the detuning)
    assert abs((a_s * np.conj(a_c)).imag) < 1e-9 * abs(a_c) ** 2
    angle = 0.5 * math.atan2((a_s * np.conj(a_c)).real, abs(a_c) ** 2)
    assert angle == pytest.approx(-0.4, abs=1e-9)


IMPERFECT = {'modes.companion_quality_factors': [120000.0, 0.9 * Q2, 170000.0],
             'modes.damping_axes': [0.0, 22.5, 0.0],
             'modes.companion_frequencies': [11200.0, 15800.005, 22000.0],
             'modes.frequency_axes': [0.0, 10.0, 0.0]}


@pytest.mark.parametrize('case', ['rate step', 'imperfect pair'])
def test_the_sense_envelope_follows_the_full_model(case):
    # Open loop, noise off, the default open-loop drive (0.0065 m/s^2 at 15 800 Hz, q2 =
    # 41 nm), started on the drive orbit; 'rate step': a step to 10 deg/s at 0.05 s;
    # 'imperfect pair': at zero rate, the damping mismatch and split of
    # doc/imperfections.md. 0.3 s of the full model (200 kHz samples) against the averaged
    # model started from the envelope of the same state.
    values = ({'scenario.rate_times': [0.05, 0.05], 'scenario.rate_values': [0.0, TEN_DEG_S]}
              if case == 'rate step' else IMPERFECT)
    cfg = build_config({**OPEN_LOOP, **values})
    start = operating_point.start_state(cfg)
    full = Simulator(cfg, start_state=start, calibration=None).advance(0.3)
    model = AveragedModel(cfg)
    w = model.omega
    a_full = envelope_of(full.q[:, PAIR], full.v[:, PAIR], w, full.drive_phase)
    a0 = envelope_of(start[0][PAIR], start[1][PAIR], w, 0.0)
    avg = model.run(0.3, cfg.run.output_rate, start=a0)
    a_avg = avg.envelope[1:]   # the full model's samples are at k / rate, k >= 1
    assert np.allclose(avg.t[1:], full.t, rtol=0.0, atol=1e-12)
    # First-order averaging is exact to O(eps) of the envelope over times O(1 / eps)
    # (module docstring, "Validity"): eps = 1 / (2 Q) = 7.7e-6 dominates here (the
    # detunings, kappa Omega / omega = 1.4e-6 and the electrostatic shift, 1e-7, are
    # smaller), so the error of A_s is below eps |A_c|: relative to the sense envelope at
    # the end of the record, eps |A_c| / |A_s|.
    eps = 1.0 / (2.0 * Q2)
    sense = abs(a_full[-1, 1])
    err_s = np.max(np.abs(a_full[:, 1] - a_avg[:, 1])) / sense
    err_c = np.max(np.abs(a_full[:, 0] - a_avg[:, 0])) / abs(a_full[-1, 0])
    err_q = np.max(np.abs(full.q[:, PAIR[1]] - avg.q[1:, 1])) / sense
    tol = eps * abs(a_full[-1, 0]) / sense
    print(f'{case}: |A_s| {sense:.4e} m at 0.3 s; largest error of A_s {err_s:.2e} of it, '
          f'of q2s {err_q:.2e}, of A_c {err_c:.2e} of |A_c| (tolerance {tol:.2e}, {eps:.1e})')
    assert sense > 1e-3 * abs(a_full[-1, 0])   # the sense mode did respond
    assert err_s < tol and err_c < eps
    # the reconstruction q = Re(A e^{i phi}) leaves out the 3 omega harmonic, of order
    # eps_nl / 12 of |A_c| (1e-8 here): the same tolerance holds for q2s itself
    assert err_q < tol


def test_bad_configurations_are_refused_with_the_parameter():
    with pytest.raises(ParameterError, match='modes.companions'):
        AveragedModel(config(modes__companions=False, gyro__enabled=False))
    with pytest.raises(ParameterError, match='control.mode'):
        AveragedModel(build_config({**OPEN_LOOP, 'control.mode': 'closed_loop'}))
    model = AveragedModel(config())
    with pytest.raises(ParameterError, match='duration_s'):
        model.run(0.0, 1000.0)
    with pytest.raises(ParameterError, match='sample_rate_hz'):
        model.run(1.0, -1.0)
    with pytest.raises(ParameterError, match='shorter than one sample'):
        model.run(1e-4, 1000.0)


def test_the_compiled_averaged_force_is_the_harmonic_balance_one():
    # (S3) in closed form against harmonic_balance's AFT at 16 phases: the same first
    # harmonic of the same truncated series, so equal to round-off, up to 2.5 um (a quarter
    # of the gap) on both coordinates with arbitrary phases.
    model = AveragedModel(config(drive__amplitude=0.065, drive__frequency=15798.6))
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(20):
        a = (rng.normal(size=2) + 1j * rng.normal(size=2)) * 1e-6 * rng.uniform(0.1, 2.5)
        reference = model.nonlinear(a)
        worst = max(worst, float(np.max(np.abs(model.nonlinear_fast(a) - reference))
                                 / np.max(np.abs(reference))))
    assert worst < 1e-12


def test_the_closed_loop_averaged_gyroscope_reads_the_full_models_rate():
    # The default gyroscope (PLL, AGC, force-to-rebalance), noise off, 10 deg/s from t = 0,
    # both from the Run's start state: the rebalance readout (~/rate before calibration) at
    # every 1 kHz sample after the loops' first 50 ms within 0.1 % of the reading (the
    # must-show). Measured 3.1e-6 of the reading.
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    averaged = AveragedGyro(cfg, start).advance(0.15)
    sim = Simulator(cfg, start, calibration=None)
    full = [sim.advance_samples(2000).rate_output for _ in range(15)]
    t = np.concatenate([r.t for r in full])
    rate = np.concatenate([r.rate for r in full])
    assert np.allclose(averaged.t, t, rtol=0.0, atol=1e-12)
    late = t >= 0.05
    assert np.max(np.abs(averaged.rate[late] - rate[late])) < 1e-3 * TEN_DEG_S
    # the loops hold the drive's set-point and the sense mode at zero
    amplitude = averaged.control[-1, 2]
    assert abs(amplitude - abs(averaged.envelope[-1, 0])) < 1e-3 * amplitude
    assert abs(averaged.envelope[-1, 1]) < 1e-4 * amplitude


def test_the_closed_loop_averaged_gyroscope_refuses_an_open_loop():
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    with pytest.raises(ParameterError, match='control.mode: .* rebalance, got open_loop'):
        AveragedGyro(config())


def test_the_pickoffs_first_harmonic_is_that_of_the_full_models_volts():
    # (S4) against the amplifiers of the full model (PickOff.clean_volts of the published
    # capacitances) along one period of q = Re(A e^{i phi}) at 3.9 % and 30 % of the gap,
    # projected on e^{-i phi} at 64 phases: the same quadrature nodes, so equal to the
    # aliasing of the harmonics 63 and 65 (below round-off) and round-off.
    from ring_gyro_sim.core import kernels
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0})
    model = AveragedGyro(cfg)
    sim = Simulator(cfg, calibration=None)
    m = model.model
    phase = 2.0 * math.pi * np.arange(64) / 64
    for a in (np.array([-0.394e-6j, 0.02e-6 + 0.01e-6j]), np.array([2.5e-6, 1.5e-6j])):
        q = np.zeros((64, 6))
        q[:, PAIR] = (a[None, :] * np.exp(1j * phase)[:, None]).real
        volts = sim.pickoff.clean_volts(sim.outputs_for(q).capacitance)
        first = 2.0 * np.mean(volts * np.exp(-1j * phase)[:, None], axis=0)  # sense, drive
        drive, sense = kernels.pickoff_harmonic(a[0], a[1], m.pb_c, m.pb_s, m.pg_drive,
                                                m.pg_sense, m.gap)
        assert abs(drive - first[1]) < 1e-11 * abs(first[1])
        assert abs(sense - first[0]) < 1e-11 * abs(first[1])


@pytest.mark.parametrize('extra', [{}, {'gyro.sense_misalignment': 0.3, 'device.seed': 3}])
def test_the_merged_angles_give_the_per_angle_force_and_pickoff(extra):
    # The closed loop's N(A) and pick-off harmonics (kernels.envelope.force_grouped,
    # pickoff_grouped: the symmetric angles merged, one D(s) per group) against the per-angle
    # sums they replace (force_harmonic, pickoff_harmonic, each tested above against AFT and
    # the full model's volts): the same sums regrouped, so equal to round-off of the sums
    # (1e-13 of the largest component: 36 and 64 terms of alternating sign at ~1e-16, and
    # the groups' keys equal to GROUP_TOLERANCE = 1e-14), on random envelopes up to 2.5 um
    # (a quarter of the gap: the pick-off's closed form beyond 0.22 of it, its series
    # below); NaN, as the per-angle sum, at and beyond contact. The default gyroscope and a
    # drawn device with its sense electrodes turned by 0.3 deg.
    from ring_gyro_sim.core import kernels
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    env = kernels.envelope
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0, **extra})
    m = AveragedGyro(cfg).model
    assert m.fgroups.shape[0] < m.fb_c.size and m.pgroups.shape[0] < m.pb_c.size
    rng = np.random.default_rng(5)
    series = 0
    worst_force = worst_pickoff = 0.0
    for _ in range(200):
        a = (rng.normal(size=2) + 1j * rng.normal(size=2)) * 1e-6 * rng.uniform(0.01, 2.5)
        reference = np.array(kernels.force_harmonic(a[0], a[1], m.fb_c, m.fb_s, m.fw_c,
                                                    m.fw_s, m.dcoef))
        fast = np.array(env.force_grouped(a[0], a[1], m.fgroups, m.dcoef))
        worst_force = max(worst_force, float(np.max(np.abs(fast - reference))
                                             / np.max(np.abs(reference))))
        reference = np.array(kernels.pickoff_harmonic(a[0], a[1], m.pb_c, m.pb_s, m.pg_drive,
                                                      m.pg_sense, m.gap))
        fast = np.array(env.pickoff_grouped(a[0], a[1], m.pgroups, m.pb_c, m.pb_s,
                                            m.pg_drive, m.pg_sense, m.gap))
        worst_pickoff = max(worst_pickoff, float(np.max(np.abs(fast - reference))
                                                 / np.max(np.abs(reference))))
        series += (abs(a[0]) + abs(a[1])) ** 2 < env.PICKOFF_SERIES_REACH * m.gap ** 2
    assert 20 < series < 180          # both branches of the pick-off
    assert worst_force < 1e-13
    assert worst_pickoff < 1e-13
    # the default drive's orbit (no sine content): the sine force zero by symmetry, to
    # the round-off of the mirror groups' sum (not exactly, as force_harmonic's member
    # order keeps it)
    n_c, n_s = env.force_grouped(-0.394e-6j, 0j, m.fgroups, m.dcoef)
    assert abs(n_s) < 1e-15 * abs(n_c) and n_c.real == 0.0
    for a in ((1.01 * m.gap + 0j, 0j), (0.75 * m.gap + 0j, 0.75 * m.gap + 0j), (0j, 1.2j * m.gap)):
        assert all(np.isnan(np.array(kernels.force_harmonic(*a, m.fb_c, m.fb_s, m.fw_c,
                                                            m.fw_s, m.dcoef))))
        assert all(np.isnan(np.array(env.force_grouped(*a, m.fgroups, m.dcoef))))


def test_the_closed_loop_averaged_gyroscope_follows_a_rate_ramp_as_the_full_model():
    # The rate profile's slope enters (S5) through kappa Omega' and the Coriolis term: a
    # ramp 0 -> 20 deg/s from 20 to 120 ms, noise off, from the Run's start state. The
    # readout at every 1 kHz sample within 0.1 % of the final reading (the must-show's
    # tolerance), the ramp included. Measured 1.5e-5.
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    final = math.radians(20.0)
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'scenario.rate_times': [0.0, 0.02, 0.12],
                        'scenario.rate_values': [0.0, 0.0, final]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    averaged = AveragedGyro(cfg, start).advance(0.2)
    sim = Simulator(cfg, start, calibration=None)
    rate = np.concatenate([sim.advance_samples(2000).rate_output.rate for _ in range(20)])
    assert np.max(np.abs(averaged.rate - rate)) < 1e-3 * final
    assert abs(averaged.rate[-1] - final) < 2e-2 * final   # it reads the rate (filter lag)


def test_the_closed_loop_averaged_gyroscope_takes_a_rate_step_as_the_full_model():
    # The must-show's step: 0 -> 100 deg/s over a 10 s run, the step between two loop updates
    # (at 1.00037 s), noise off, from the Run's start state. RK4 steps are cut at the rate
    # profile's knots and take the left limit at their end (S6): without it the step leaked
    # a sixth of a period's Coriolis rotation into the period before and the reading was
    # 1.8 % off after its time constant. After the first time constant (the full model's
    # reading reaching 1 - 1/e of the step, 11.6 ms) within 0.1 % of the reading at every
    # 1 kHz sample. Measured 5.4e-4 right after the time constant (the full model's C2 fit
    # over the period the Coriolis force steps in, against the mean envelope), 3.1e-6 from
    # 0.1 s after the step on.
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    final, at = math.radians(100.0), 1.00037
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'scenario.rate_times': [0.0, at, at],
                        'scenario.rate_values': [0.0, 0.0, final]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    averaged = AveragedGyro(cfg, start).advance(10.0)
    sim = Simulator(cfg, start, calibration=None)
    rate = np.concatenate([sim.advance_samples(20000).rate_output.rate for _ in range(100)])
    t = averaged.t
    assert np.max(np.abs(averaged.rate[t < at])) < 1e-9 * final   # nothing before the step
    rise = t[np.argmax(rate >= (1.0 - math.exp(-1.0)) * final)]
    assert at + 0.005 < rise < at + 0.05        # the reading's time constant, ~10 ms
    after = t >= rise
    error = np.abs(averaged.rate[after] - rate[after]) / np.abs(rate[after])
    assert np.max(error) < 1e-3
    assert np.max(error[t[after] >= at + 0.1]) < 1e-5   # settled: the constant-rate agreement


def test_the_imperfect_averaged_gyroscope_follows_a_temperature_ramp_as_the_full_model():
    # The must-show: an imperfect ring (5 % damping mismatch on axes at 22.5 deg, a 20 mHz
    # split at 10 deg: its bias is -0.0252 rad/s) under a 20 K ramp of the ambient over 2 s,
    # the die behind it by 0.2 s, noise off. The averaged model follows the die as the full
    # model does (S12: every 10 ms, the device rebuilt each 0.01 K) and turns its frame with
    # the frequencies: with the frame held at drive.frequency the averaging's error
    # (omega - omega_frame) / omega = 6e-4 at 20 K made the bias change 0.98 % off. The bias
    # change (the rebalance readout at zero rate, 2.8-3 s against 0.3-0.5 s) within 1 % of
    # the full model's, and within the averaging's O(1 / (2 Q)) of the bias (with the frame
    # held: 1.6e-5 rad/s, 40 times that). Measured 2.2e-6 of the change.
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    t_ref = 298.15
    cfg = build_config({
        'modes.companion_frequencies': [11200.0, 15800.02, 22000.0],
        'modes.companion_quality_factors': [120000.0, 0.95 * 64700.0, 170000.0],
        'modes.frequency_axes': [0.0, 10.0, 0.0], 'modes.damping_axes': [0.0, 22.5, 0.0],
        'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
        'thermal.time_constant': 0.2, 'scenario.temperature_times': [0.0, 0.5, 2.5],
        'scenario.temperature_values': [t_ref, t_ref, t_ref + 20.0]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    model = AveragedGyro(cfg, start)
    averaged = model.advance(3.0)
    assert model.device_temperature > t_ref + 19.0     # it followed the die
    sim = Simulator(cfg, start, calibration=None)
    rate = np.concatenate([sim.advance_samples(2000).rate_output.rate for _ in range(300)])
    t = averaged.t
    before, after = (t > 0.3) & (t <= 0.5), t > 2.8

    def change(r):
        return np.mean(r[after]) - np.mean(r[before])
    full_change = change(rate)
    assert abs(full_change) > 0.05 * abs(np.mean(rate[before]))   # the ramp moves the bias
    error = abs(change(averaged.rate) - full_change)
    assert error < 1e-2 * abs(full_change)
    # and within first-order averaging's error, eps = 1 / (2 Q) of the bias at each end
    assert error < 2.0 * (1.0 / (2.0 * Q2)) * abs(np.mean(rate[before]))
    print(f'bias change: full {full_change:.6e}, averaged off by {error / abs(full_change):.2e}')


def test_the_averaged_gyroscope_continues_a_running_full_model():
    # (S13) the hand-off to the averaged model: from a full model at a loop update (0.3 s
    # at 10 deg/s, noise off) the averaged one takes the pair's state (its envelopes at the
    # NCO's phase now), the loops' state after their last update, the output filter's and
    # the die's. Its first ~/rate sample is the full model's (the filter state carries it:
    # round-off), and every later one within 0.1 % of the reading of the full model run
    # on (the must-show's tolerance). Measured 2.6e-13, then at most 1.2e-5 (the exact
    # envelope's 2 omega ripple, which averaging drops, relaxing).
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    full = Simulator(cfg, start, calibration=None)
    for _ in range(30):
        full.advance_samples(2000)
    q, v = full.q.copy(), full.v.copy()
    averaged = AveragedGyro(cfg, simulator=full)
    assert np.array_equal(full.q, q) and np.array_equal(full.v, v)   # it only reads
    assert averaged.time_s == pytest.approx(0.3, abs=1e-12)
    rate = averaged.advance(0.3).rate
    reference = np.concatenate([full.advance_samples(2000).rate_output.rate
                                for _ in range(30)])
    assert abs(rate[0] - reference[0]) < 1e-9 * TEN_DEG_S
    assert np.max(np.abs(rate - reference)) < 1e-3 * TEN_DEG_S
    full.advance_samples(7)
    with pytest.raises(ParameterError, match='simulator: the hand-off is at a loop update'):
        AveragedGyro(cfg, simulator=full)


def test_the_averaged_noises_follow_the_die():
    # (S9, S10 at S12's die) the force noise's density 2 k_B T_n C / m with the device's
    # T_n and C at the die temperature (T4, T5), the pick-off's output density with its
    # feedback capacitance (T6), as the full model rebuilds them: after a 20 K step of the
    # ambient (the die at once) the scales are those of the device at 318.15 K.
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    from ring_gyro_sim.core.params import BOLTZMANN
    cfg = build_config({'thermal.time_constant': 0.0,
                        'scenario.temperature_times': [0.0, 0.005, 0.005],
                        'scenario.temperature_values': [298.15, 298.15, 318.15]})
    model = AveragedGyro(cfg)
    cold = model.force_noise_factor @ model.force_noise_factor.T
    model.advance(0.02)
    assert model.device_temperature == 318.15
    hot_device = thermal.device_at(cfg, 318.15)
    _, damping = hot_device.modes.pair_matrices(2)
    expected = (4.0 * BOLTZMANN * hot_device.gyro.temperature * damping
                / (hot_device.modal_masses()[1] * model.model.period))
    hot = model.force_noise_factor @ model.force_noise_factor.T
    assert np.allclose(hot, expected, rtol=1e-12, atol=0.0)
    assert not np.allclose(hot, cold, rtol=1e-3, atol=0.0)
    sim = Simulator(hot_device, calibration=None)
    density = np.asarray(sim.pickoff.output_noise_density)[[1, 0]]
    assert np.allclose(model.pickoff_noise_std,
                       density * math.sqrt(cfg.run.output_rate / model.model.window),
                       rtol=1e-12, atol=0.0)


def test_a_full_model_goes_on_from_the_averaged_one():
    # (S14) the hand-back: a full model handed to the averaged one at 0.3 s (S13), which
    # runs 0.3 s, then the same full model resumes from the averaged state (the pair from
    # its envelopes, the other modes at rest, the loops, the filters, the die, the flicker)
    # and runs 0.3 s more. Against a full-only run: ~/rate within 1e-3 of the reading
    # (the must-show's) at every sample after the hand-back, and the demodulator (its
    # low-pass restarted in its periodic steady state, the 2 omega products included: at the
    # constant alone it rang 1.2e-3 of the drive channel 5 ms on) within 1e-4 of the drive
    # channel. Measured 6.2e-6 and 7.2e-6 (the loops' own difference after 0.6 s).
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    from ring_gyro_sim.core.errors import InputError
    from ring_gyro_sim.core.params import STANDARD_GRAVITY
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    reference, handed = (Simulator(cfg, start, calibration=None) for _ in range(2))
    for _ in range(30):
        reference.advance_samples(2000)
        handed.advance_samples(2000)
    averaged = AveragedGyro(cfg, simulator=handed)
    averaged.advance(0.3)
    for _ in range(30):
        reference.advance_samples(2000)
    state = averaged.export_state()
    refused = Simulator(cfg, start, calibration=None)
    refused.shock(1000.0 * STANDARD_GRAVITY, at_ns=100_000_000)   # in the skipped stretch
    with pytest.raises(InputError, match='import_state: an input, a shock'):
        refused.import_state(state)
    handed.import_state(state)
    assert handed.time_s == pytest.approx(0.6, abs=1e-12)
    full = [reference.advance_samples(2000) for _ in range(30)]
    back = [handed.advance_samples(2000) for _ in range(30)]
    rate = np.concatenate([b.rate_output.rate for b in back])
    expected = np.concatenate([f.rate_output.rate for f in full])
    assert np.max(np.abs(rate - expected)) < 1e-3 * TEN_DEG_S
    demod = np.concatenate([b.demod.values for b in back])
    expected = np.concatenate([f.demod.values for f in full])
    drive = np.max(np.abs(expected[:, 2:]))
    assert np.max(np.abs(demod - expected)) < 1e-4 * drive


def test_the_averaged_rate_goes_through_the_output_word():
    # (E15) the output word last, as the full model's sense chain: at 10 deg/s with a full
    # scale of 0.1 rad/s and a resolution of 1e-4 rad/s, every sample a whole number of the
    # resolution within the range, those the rounded reading would put beyond it read the
    # full scale and are flagged (and counted); the full model reads the same words (the
    # readings 3e-6 apart round alike but where one falls within 3e-6 of a half step).
    from ring_gyro_sim.core import thermal
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    cfg = build_config({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
                        'gyro.range': 0.1, 'gyro.resolution': 1e-4,
                        'scenario.rate_times': [0.0, 0.05],
                        'scenario.rate_values': [0.0, TEN_DEG_S]})
    start = operating_point.start_state(thermal.start_state_device(cfg))
    model = AveragedGyro(cfg, start)
    out = model.advance(0.2)
    words = out.rate / 1e-4
    assert np.allclose(words, np.round(words), rtol=0.0, atol=1e-6)
    assert np.max(np.abs(out.rate)) <= 0.1
    assert out.saturated is not None and out.saturated.any() and not out.saturated.all()
    assert np.all(np.abs(out.rate[out.saturated]) == 0.1)
    assert model.saturated_samples == int(np.count_nonzero(out.saturated))
    sim = Simulator(cfg, start, calibration=None)
    full = [sim.advance_samples(2000).rate_output for _ in range(20)]
    assert np.array_equal(np.concatenate([f.saturated for f in full]), out.saturated)
