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
Tests of run.py, the one run path.

When inputs act, what is refused and counted, reset, the order the sink sees things in, the
diagnostics keys, and the bounded cost of pending inputs.
"""

import math
import time

import numpy as np
import pytest
from ring_gyro_sim import run as run_mod
from ring_gyro_sim.core.engine import full as simulator
from ring_gyro_sim.core.errors import InputError, ParameterError
from ring_gyro_sim.core.params import build_config, paper_config, STANDARD_GRAVITY
from ring_gyro_sim.run import (AngularRate, BaseAcceleration, DriveAmplitude, ParameterChange,
                               Reset, Run, Shock, Sink)

REST = {'drive.amplitude': 0.0, 'drive.start_on': 'rest'}
GYRO = {'drive.start_on': 'rest', 'modes.companions': True, 'gyro.enabled': True,
        'output.rate': 20000.0}
GYRO_BLOCK = 200  # samples of one 10 ms block at 20 kHz
BLOCK = 2000  # samples of one 10 ms block at 200 kHz
PEAK = 2000 * STANDARD_GRAVITY


class Collect(Sink):
    """A sink that keeps what it is given, in order."""

    def __init__(self):
        self.calls = []

    def start(self, state):
        self.calls.append(('start', 0, state))

    def input(self, event):
        self.calls.append(('input', event.at_ns, event))

    def block(self, block):
        self.calls.append(('block', block.end_ns, block))

    def diagnostics(self, diag):
        self.calls.append(('diagnostics', diag.t_ns, diag))


def rest_run(sink=None, **extra):
    return Run(paper_config({**REST, **extra}), sink=sink)


def test_a_stamp_beyond_the_horizon_is_refused_counted_and_changes_nothing():
    run = rest_run(**{'inputs.horizon': 1.0})
    with pytest.raises(InputError, match=r'inputs\.horizon'):
        run.apply(BaseAcceleration(x=100.0, at_ns=2_145_916_800 * 10 ** 9))  # 2038
    with pytest.raises(InputError, match=r'inputs\.horizon'):
        run.apply(Shock(x=PEAK, at_ns=1_000_000_001))
    assert run.rejected['base_acceleration'] == 1 and run.rejected['shock'] == 1
    assert run.pending_inputs == 0 and run.pending_shocks == 0
    # The topic is not locked: a normal sample now is taken ("stamps must increase" would
    # have refused it had the 2038 one been kept).
    assert run.apply(BaseAcceleration(x=100.0, at_ns=1_000_000)) == 1_000_000
    # At the horizon itself it is still taken.
    assert run.apply(Shock(x=PEAK, at_ns=1_000_000_000)) == 1_000_000_000


def test_late_and_past_stamps():
    run = Run(paper_config(REST), late_tolerance_ns=BLOCK * 5000)
    run.advance(3 * BLOCK)
    now = run.time_ns
    assert run.apply(Shock(x=PEAK, at_ns=now - BLOCK * 5000)) == now  # late: acts now
    with pytest.raises(InputError, match='in the past'):
        run.apply(Shock(x=PEAK, at_ns=now - BLOCK * 5000 - 1))
    assert run.rejected['shock'] == 1 and run.accepted['shock'] == 1


def test_non_finite_components_are_refused_z_is_otherwise_ignored():
    run = rest_run()
    for bad in (Shock(x=math.nan), Shock(x=1.0, z=math.inf),
                BaseAcceleration(x=1.0, y=-math.inf)):
        with pytest.raises(InputError, match='not finite'):
            run.apply(bad)
    assert sum(run.rejected.values()) == 3
    run.apply(Shock(x=0.0, z=5.0))  # out of plane: not modelled, accepted
    assert run.accepted['shock'] == 1


def test_reset_discards_everything_pending():
    sink = Collect()
    run = rest_run(sink, **{'scenario.shock_times': [0.05], 'scenario.shock_peaks': [PEAK]})
    run.apply(Shock(x=PEAK, at_ns=30_000_000))
    run.apply(BaseAcceleration(x=500.0, at_ns=20_000_000))
    run.apply(BaseAcceleration(x=500.0, at_ns=40_000_000))
    assert run.pending_shocks == 2 and run.pending_inputs == 4
    run.advance(BLOCK)
    run.apply(Reset())
    assert run.pending_shocks == 0 and run.pending_inputs == 0
    # A profile may start again at any stamp after the reset.
    run.apply(BaseAcceleration(x=0.0, at_ns=15_000_000))
    for _ in range(6):
        block = run.advance(BLOCK)
        assert np.all(block.samples.q == 0.0)  # no shock, no profile acted after the reset
    # What the reset discarded was never handed to the sink (it never acted).
    inputs = [c[2] for c in sink.calls if c[0] == 'input']
    assert [type(e).__name__ for e in inputs] == ['Reset', 'BaseAcceleration']


def test_without_reset_the_same_inputs_move_the_ring():
    """Control for the test above: the pending inputs do act when nothing discards them."""
    run = rest_run(**{'scenario.shock_times': [0.05], 'scenario.shock_peaks': [PEAK]})
    run.apply(Shock(x=PEAK, at_ns=30_000_000))
    peaks = [np.max(np.abs(run.advance(BLOCK).samples.q)) for _ in range(7)]
    assert peaks[0] == 0.0 and max(peaks) > 1e-7


def test_the_sink_sees_inputs_in_log_time_order_before_their_block():
    sink = Collect()
    run = rest_run(sink, **{'scenario.shock_times': [0.025], 'scenario.shock_peaks': [PEAK]})
    run.apply(DriveAmplitude(0.0))
    run.apply(Shock(x=PEAK, at_ns=12_345_678))
    run.apply(ParameterChange({'electrodes.outer_voltage': 70.0}))
    for _ in range(3):
        run.advance(BLOCK)
    run.diagnostics()
    times = [c[1] for c in sink.calls]
    assert times == sorted(times)
    kinds = [(c[0], c[1]) for c in sink.calls]
    assert kinds.index(('input', 12_345_678)) == kinds.index(('block', 20_000_000)) - 1
    assert ('input', 25_000_000) in kinds and kinds[0][0] == 'start'


def test_diagnostics_have_the_same_keys_whatever_happened():
    quiet = rest_run()
    quiet.advance(BLOCK)
    busy = rest_run()
    busy.advance(BLOCK)
    with pytest.raises(InputError):
        busy.apply(Shock(x=math.nan))
    with pytest.raises(ParameterError):
        busy.apply(ParameterChange({'electrodes.gap': -1.0}))
    a, b = quiet.diagnostics(), busy.diagnostics()
    assert list(a.values) == list(b.values)
    assert b.values['rejected_inputs'] == 2 and b.values['rejected_parameter_changes'] == 1
    assert a.level == b.level == 'OK'


def test_pending_limits_are_refused_with_the_reason(monkeypatch):
    monkeypatch.setattr(run_mod, 'MAX_PENDING_SHOCKS', 3)
    run = rest_run()
    for k in range(3):
        run.apply(Shock(x=1.0, at_ns=(k + 1) * 1_000_000))
    with pytest.raises(InputError, match='3 shocks are already pending'):
        run.apply(Shock(x=1.0, at_ns=5_000_000))


def test_a_flood_of_future_samples_does_not_reach_the_kernel():
    """The stretch handed to the kernel holds the samples it can use, not all pending ones."""
    run = rest_run()
    for k in range(100_000):
        run.apply(BaseAcceleration(x=1.0, at_ns=(k + 1) * 10_000))  # 1 s of 100 kHz samples
    sim = run.full_model()
    t, x, _ = sim._profile_arrays(0.0, BLOCK * sim.period_s)
    assert 0 < t.size <= BLOCK * sim.period_s / 10e-6 + 4
    run.advance(BLOCK)
    t, _, _ = sim._profile_arrays(sim.time_s, sim.time_s + BLOCK * sim.period_s)
    assert t[0] <= sim.time_s and t.size <= BLOCK * sim.period_s / 10e-6 + 4


def test_a_huge_value_is_summarised_in_exponent_form():
    assert run_mod.format_number(1.7e308) == '1.7000e+308'
    assert run_mod.format_number(1.7e302, 1e6) == '1.7000e+308'
    assert run_mod.format_number(5.7465e-6, 1e6) == '5.7465'


def test_at_most_max_shocks_per_block_are_accepted_between_blocks():
    run = rest_run()
    for k in range(run_mod.MAX_SHOCKS_PER_BLOCK):
        run.apply(Shock(x=1.0, at_ns=(k + 1) * 100_000))
    with pytest.raises(InputError, match='since the last block'):
        run.apply(Shock(x=1.0, at_ns=5_000_000))
    run.advance(BLOCK)
    run.apply(Shock(x=1.0, at_ns=15_000_000))  # a new block: taken again
    assert run.rejected['shock'] == 1
    assert run.accepted['shock'] == run_mod.MAX_SHOCKS_PER_BLOCK + 1


def test_shock_refusal_says_when_every_shock_would_be_refused():
    # What the node relies on to take a flood's excess undecoded: shock_refusal() is None
    # exactly while apply() could accept a valid shock, else apply()'s reason, and
    # refuse_shocks() counts as apply() does.
    run = rest_run()
    for k in range(run_mod.MAX_SHOCKS_PER_BLOCK):
        assert run.shock_refusal() is None
        run.apply(Shock(x=1.0, at_ns=(k + 1) * 100_000))
    reason = run.shock_refusal()
    with pytest.raises(InputError) as refused:
        run.apply(Shock(x=1.0, at_ns=5_000_000))
    assert str(refused.value) == reason
    run.refuse_shocks(41)
    assert run.rejected['shock'] == 42
    assert run.accepted['shock'] == run_mod.MAX_SHOCKS_PER_BLOCK
    run.advance(BLOCK)
    assert run.shock_refusal() is None


def acted_rates(sink):
    """Return the (at_ns, z) of the angular rates the sink was given, in order."""
    return [(c[1], c[2].z) for c in sink.calls if c[0] == 'input'
            and isinstance(c[2], AngularRate)]


def test_a_rate_replaced_before_it_acts_never_reaches_the_sink():
    # A rate stamped ahead, then one stamped before it: the second replaces the first (and the
    # scheduled knot at 30 ms) in the profile, so neither ever acts and neither is recorded.
    sink = Collect()
    run = Run(paper_config({**GYRO, 'scenario.rate_times': [0.0, 0.03],
                            'scenario.rate_values': [0.0, 0.2]}), sink=sink)
    run.apply(AngularRate(z=0.5, at_ns=25_000_000))
    run.apply(AngularRate(z=0.1, at_ns=15_000_000))
    assert run.pending_inputs == 1
    applied = []
    for _ in range(4):
        block = run.advance(GYRO_BLOCK)
        applied.append(block.samples.applied_rate)
    assert acted_rates(sink) == [(0, 0.0), (15_000_000, 0.1)]
    assert np.all(np.concatenate(applied)[300:] == 0.1)  # what acted from 15 ms on


def test_a_reset_keeps_the_rates_pending_and_records_them_when_they_act():
    # The rate profile is the motion of the case: a reset does not discard it (Simulator.reset)
    # and a rate accepted before a reset acts after it, so it is recorded when it acts.
    sink = Collect()
    run = Run(paper_config(GYRO), sink=sink)
    run.advance(GYRO_BLOCK)
    run.apply(AngularRate(z=0.3, at_ns=25_000_000))
    run.apply(Reset())
    assert run.pending_inputs == 1
    rates = np.concatenate([run.advance(GYRO_BLOCK).samples.applied_rate for _ in range(3)])
    assert rates[-1] == 0.3
    assert acted_rates(sink) == [(25_000_000, 0.3)]


def test_pending_rates_are_bounded_refused_with_the_reason_and_replaceable(monkeypatch):
    monkeypatch.setattr(run_mod, 'MAX_PENDING_RATES', 3, raising=False)
    run = Run(paper_config(GYRO))
    for k in range(3):
        run.apply(AngularRate(z=0.1, at_ns=(k + 1) * 1_000_000))
    with pytest.raises(InputError, match='3 angular rates are already pending'):
        run.apply(AngularRate(z=0.1, at_ns=5_000_000))
    assert run.rejected['angular_rate'] == 1 and run.pending_inputs == 3
    # One stamped before the last held replaces it (and all after it): always taken.
    run.apply(AngularRate(z=0.2, at_ns=2_500_000))
    assert run.pending_inputs == 3 and run.accepted['angular_rate'] == 4
    run.advance(GYRO_BLOCK)  # every one acted: room again
    run.apply(AngularRate(z=0.3, at_ns=15_000_000))
    assert run.diagnostics().values['accepted_angular_rate'] == 5


def test_the_cost_of_a_rate_does_not_grow_with_the_rates_pending(monkeypatch):
    # A flood of rates stamped ahead must cost each message a bounded time (the profile read
    # whole for every one costs 49 us each with 1 000 pending, 245 us with 8 000).
    monkeypatch.setattr(run_mod, 'MAX_PENDING_RATES', 8000, raising=False)

    def cost(pending):
        run = Run(paper_config(GYRO))
        last = 100_000_000 + (pending - 1) * 10_000
        for k in range(pending):
            run.apply(AngularRate(z=0.1 * (k % 3), at_ns=100_000_000 + k * 10_000))
        best = math.inf
        for _ in range(5):  # the best of 5: the host's load only ever adds
            t0 = time.perf_counter()
            for _ in range(100):
                last -= 1  # replaces the last one held: as many stay pending
                run.apply(AngularRate(z=0.2, at_ns=last))
            best = min(best, (time.perf_counter() - t0) / 100)
        assert run.pending_inputs == pending
        return best
    few, many = cost(10), cost(8000)
    print(f'\n{few * 1e6:.1f} us per rate with 10 pending, {many * 1e6:.1f} us with 8 000')
    assert many < 2.0 * few + 10e-6


def test_rates_beyond_the_range_of_the_model_are_refused_with_the_reason():
    # 1e6 and 1e308 rad/s, accepted, would end in contact or failure.
    run = Run(paper_config(GYRO))
    for rate in (1e6, -1e308, 703.72):
        with pytest.raises(InputError, match=r'angular_rate\.z: .* beyond the range of the '
                           r'model, \|Omega\| <= 703\.7 rad/s'):
            run.apply(AngularRate(z=rate))
    assert run.rejected['angular_rate'] == 3 and run.pending_inputs == 0
    limit = run.config.max_input_rate()
    assert limit == pytest.approx(0.01 * 2 * math.pi * 11200.0)  # 703.7 rad/s, 40 320 deg/s
    run.apply(AngularRate(z=-limit))  # the range itself is taken
    block = run.advance(GYRO_BLOCK)
    assert run.running and block.samples.applied_rate[-1] == -limit
    with pytest.raises(ParameterError, match=r'scenario\.rate_values: 1e\+06 rad/s is beyond'):
        build_config({'scenario.rate_times': [0.0], 'scenario.rate_values': [1e6]})


def test_a_contact_right_after_a_reset_names_what_is_in_force():
    # A reset that cannot help says why: the drive that put the ring into contact is still in
    # force when the reset acts, and the ring is back in contact 10 us later.
    run = rest_run()
    run.apply(DriveAmplitude(1e5))
    run.advance(BLOCK)
    first = run.diagnostics()
    assert first.level == 'ERROR' and first.message.endswith('(~/reset recovers)')
    run.apply(Reset())
    run.advance(BLOCK)
    text = run.diagnostics().message
    assert 'after the reset at t = 0.010000 s: a reset does not help' in text, text
    assert 'drive 100000 m/s^2 at 15798.6 Hz' in text and '~/reset recovers' not in text
    assert run.failure_text() == text
    # Without the drive a reset recovers for good (the control).
    run.apply(DriveAmplitude(0.0))
    run.apply(Reset())
    for _ in range(20):
        run.advance(BLOCK)
    assert run.running and run.failure_text() == '' and run.relapse() is None


def test_accelerations_beyond_the_physical_bound_are_refused_with_the_reason():
    # A 1.7e308 shock would hold the ring at 3e292 m with non-finite gaps. Beyond 10^6 g an
    # input is refused.
    run = rest_run()
    bound = 9.80665e6
    for event in (Shock(x=1.7e308), Shock(x=0.8 * bound, y=0.8 * bound),
                  BaseAcceleration(x=-2.0 * bound, at_ns=1000), DriveAmplitude(1e9)):
        with pytest.raises(InputError, match=r'beyond the physical bound of 9\.80665e\+06 '
                                             r'm/s\^2'):
            run.apply(event)
    assert sum(run.rejected.values()) == 4 and run.pending_shocks == 0
    run.apply(Shock(x=bound))  # the bound itself: contact, with finite numbers
    blocks = [run.advance(BLOCK) for _ in range(3)]
    assert all(b is not None and np.all(np.isfinite(b.samples.q)) for b in blocks)
    assert not run.running and np.max(np.abs(run.full_model().q)) < 2.0 * 10e-6
    for name, value in (('scenario.shock_peaks', [1.7e308]), ('drive.amplitude', -1e8),
                        ('control.drive_limit', 1e8)):
        flat = {name: value, 'scenario.shock_times': [0.0] if 'shock' in name else []}
        with pytest.raises(ParameterError, match=rf'{name}: must be .*10\^6 g'):
            build_config(flat)


def test_the_closed_loop_refuses_an_unbiased_pick_off_at_start_and_at_run_time():
    # electrodes.outer_voltage 0 with the closed loop would divide by zero in the loops
    # (drive_amplitude_m = inf, status still running).
    closed = {'drive.start_on': 'rest', 'output.rate': 20000.0}
    reason = (r'electrodes\.outer_voltage: must not be 0 with control\.mode: rebalance: the '
              r'loops read the drive through the pick-off')
    with pytest.raises(ParameterError, match=reason):
        build_config({**closed, 'electrodes.outer_voltage': 0.0})
    run = Run(build_config(closed))
    run.advance(GYRO_BLOCK)
    with pytest.raises(ParameterError, match=reason):
        run.apply(ParameterChange({'electrodes.outer_voltage': 0.0}))
    assert run.rejected['events/parameters'] == 1
    assert run.config.electrodes.outer_voltage == 78.0
    block = run.advance(GYRO_BLOCK)
    assert run.running and np.all(np.isfinite(block.control.values))
    # A pick-off biased on its own reads the drive without V_o (the control).
    build_config({**closed, 'electrodes.outer_voltage': 0.0, 'gyro.bias_voltage': 5.0})


def all_finite(block):
    """Tell whether every value of a block is finite (samples and the electronics)."""
    s = block.samples
    arrays = [s.q, s.v, s.gap, s.min_gap, s.capacitance]
    arrays += [a for a in (s.control, s.drive_phase, s.applied_rate) if a is not None]
    if block.rate is not None:
        arrays += [block.rate.rate, block.rate.quadrature, block.demod.values]
    if block.control is not None:
        arrays.append(block.control.values)
    return all(np.all(np.isfinite(a)) for a in arrays)


def test_a_non_finite_value_is_a_failure_and_every_block_goes_out(monkeypatch):
    # The 1.7e308 shock (let through here: its bound is the first line of defence) holds the
    # ring at 3e292 m with non-finite gaps: the run fails at once, holds the ring at rest and
    # goes on, every block published.
    monkeypatch.setattr(simulator, 'MAX_ACCELERATION', math.inf)
    sink = Collect()
    run = rest_run(sink)
    run.advance(BLOCK)
    run.apply(Shock(x=1.7e308, at_ns=12_345_678))
    blocks = [run.advance(BLOCK) for _ in range(4)]
    assert all(b is not None and all_finite(b) for b in blocks)
    sim = run.full_model()
    assert sim.status == 'failed' and sim.nonfinite_failures == 1
    assert sim.message.startswith('non-finite') and 't = 0.01234' in sim.message
    diag = run.diagnostics()
    assert diag.level == 'ERROR' and diag.values['nonfinite_failures'] == 1
    assert np.all(blocks[0].samples.q[2 * BLOCK // 10:] == 0.0)  # held at rest from then on
    assert np.all(blocks[-1].samples.min_gap == 10e-6)
    ends = [c[1] for c in sink.calls if c[0] == 'block']
    assert ends == [(k + 1) * 10_000_000 for k in range(5)]  # no hole
    run.apply(Reset())
    run.apply(Shock(x=PEAK))
    block = run.advance(BLOCK)
    assert run.running and np.max(np.abs(block.samples.q)) > 1e-7


def test_loops_that_overflow_fail_the_run_with_finite_outputs():
    # A denormal bias (1e-320 V, not 0: refused) makes the loops' measured amplitude overflow
    # at their first update (1 ms): the closed-loop gyroscope's every output stays finite.
    run = Run(build_config({'drive.start_on': 'rest', 'output.rate': 20000.0,
                            'electrodes.outer_voltage': 1e-320}))
    blocks = [run.advance(GYRO_BLOCK) for _ in range(3)]
    assert all(b is not None and all_finite(b) for b in blocks)
    sim = run.full_model()
    assert sim.status == 'failed' and 'non-finite loop state' in sim.message
    assert run.full_model().contact_time_s == pytest.approx(1.05e-3)
    assert len(blocks[-1].rate.rate) == 10 and len(blocks[-1].control) == 10


def test_a_shock_into_the_stops_runs_on_and_counts_the_impacts():
    # With stops at 0.6 d_g a 30 000 g shock bounces the ring instead of
    # ending the run in contact; the impacts are on /diagnostics and in the summary.
    run = rest_run(**{'stops.gap': 6e-6})
    run.advance(BLOCK)
    run.apply(Shock(x=30000.0 * STANDARD_GRAVITY))
    blocks = [run.advance(BLOCK) for _ in range(3)]
    assert all(b is not None and all_finite(b) for b in blocks)
    assert run.running and run.full_model().status == 'running'
    impacts = run.diagnostics().values['stop_impacts']
    assert impacts == run.full_model().impacts > 0
    summary = run.summary()
    assert summary.status == 'finished' and summary.extra['stop_impacts'] == impacts
    assert f'{impacts} impacts on the stops' in run.summary_text()
    # without stops the diagnostics still carry the key, at 0
    assert rest_run().diagnostics().values['stop_impacts'] == 0
