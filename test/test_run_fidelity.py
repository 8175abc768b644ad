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
A run on the averaged and the full model (``run.Run`` at ``integrator.fidelity``).

The blocks of an averaged stretch against those of a full-only run of the same gyroscope;
the hand-offs an input causes; a recording's hand-offs repeated by ``--from`` bit for bit.
"""

import math
import subprocess
import sys
import textwrap

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from ring_gyro_sim import offline
from ring_gyro_sim.core.errors import InputError, ParameterError
from ring_gyro_sim.core.params import build_config, STANDARD_GRAVITY
from ring_gyro_sim.recording.reader import read_handoffs
from ring_gyro_sim.run import (AmbientTemperature, AngularRate, ParameterChange, Run, Shock,
                               Sink)

HUNDRED_DEG_S = math.radians(100.0)
QUIET = {'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
         'scenario.rate_times': [0.0], 'scenario.rate_values': [HUNDRED_DEG_S]}
NS = '/ring_gyro'


def blocks_of(fidelity, seconds, **values):
    """Return (run, [Block]) of the default gyroscope, noise off, 100 deg/s, at ``fidelity``."""
    config = build_config({**QUIET, **values, 'integrator.fidelity': fidelity})
    run = Run(config, calibration=None)
    n = config.run.block_samples
    count = int(round(seconds / (n * run.period_ns * 1e-9)))
    return run, [run.advance(n) for _ in range(count)]


def joined(blocks, get):
    return np.concatenate([get(b) for b in blocks])


@pytest.fixture(scope='module')
def quiet_pair():
    """One second of the quiet gyroscope on each model."""
    return blocks_of('auto', 1.0), blocks_of('full', 1.0)


def test_a_quiet_run_is_averaged_and_its_blocks_are_the_full_models(quiet_pair):
    # The full model's first check (10 ms), the averaged model from there. Measured against
    # the full-only run after the start's loop transient (t > 0.1 s): ~/rate
    # 5.7e-6 of the reading, q 1.4e-4 of q2's amplitude (the envelope's 2 omega ripple), the
    # demodulator 1e-6 of the drive channel, the NCO 1.4e-4 Hz; the rate's variance 1e-3.
    (auto, a), (full, f) = quiet_pair
    assert auto.handoffs == [(0.0, 'full'), (pytest.approx(0.01), 'averaged')]
    assert full.handoffs == [(0.0, 'full')]
    assert auto.model == 'averaged' and auto.diagnostics().values['model'] == 'averaged'
    t = joined(a, lambda b: b.samples.t)
    assert np.array_equal(t, joined(f, lambda b: b.samples.t))
    late = t > 0.1
    rate_t = joined(a, lambda b: b.rate.t)
    settled = rate_t > 0.1
    error = joined(a, lambda b: b.rate.rate) - joined(f, lambda b: b.rate.rate)
    assert np.max(np.abs(error[settled])) < 1e-4 * HUNDRED_DEG_S
    q_a, q_f = joined(a, lambda b: b.samples.q), joined(f, lambda b: b.samples.q)
    amplitude = np.max(np.abs(q_f[:, 1]))
    assert np.max(np.abs(q_a[late] - q_f[late])) < 1e-3 * amplitude
    others = [k for k, name in enumerate(auto.channel_names['modal_displacement'])
              if name not in ('q2', 'q2s')]
    assert len(others) == 4 and np.all(q_a[t > 0.01][:, others] == 0.0)   # at rest (R1)
    d_a, d_f = joined(a, lambda b: b.demod.values), joined(f, lambda b: b.demod.values)
    drive = np.max(np.abs(d_f[:, 2]))
    assert np.max(np.abs(d_a[t > 0.5] - d_f[t > 0.5])) < 1e-5 * drive
    c_a = joined(a, lambda b: b.control.values)
    c_f = joined(f, lambda b: b.control.values)
    assert c_a.shape == c_f.shape == (999, 10)
    assert np.max(np.abs(c_a[100:, 0] - c_f[100:, 0])) < 1e-3   # Hz
    v_a, v_f = joined(a, lambda b: b.rate.variance), joined(f, lambda b: b.rate.variance)
    assert np.max(np.abs(v_a / v_f - 1.0)) < 1e-2


def test_the_averaged_blocks_channels_are_those_of_their_coordinates(quiet_pair):
    # (R1) gaps and capacitances computed from the reconstructed q as the full model computes
    # them for any coordinates (Simulator.outputs_for): the same sums, to the bit.
    (auto, a), _ = quiet_pair
    s = a[-1].samples
    ref = auto.full_model().outputs_for(s.q)
    assert np.array_equal(ref.capacitance, s.capacitance)
    assert np.array_equal(ref.gap, s.gap) and np.array_equal(ref.min_gap, s.min_gap)


class _NoChannels(Sink):
    """A sink that keeps no channel (a node nobody subscribes to that records none)."""

    needs_channels = False


def test_without_channels_the_averaged_blocks_keep_their_smallest_gap(quiet_pair):
    # (R5) The same run with a sink that keeps no channel: its averaged blocks carry no gaps
    # or capacitances, their smallest gap is that of all their samples to the bit, and
    # nothing else changes.
    (auto, a), _ = quiet_pair
    run = Run(auto.config, calibration=None, sink=_NoChannels())
    b = [run.advance(len(block)) for block in a]
    assert run.handoffs == auto.handoffs
    averaged = 0
    for x, y in zip(a, b):
        assert y.samples.least_gap() == x.samples.least_gap() == np.min(x.samples.min_gap)
        assert np.array_equal(y.rate.rate, x.rate.rate)
        assert np.array_equal(y.samples.q, x.samples.q)
        if y.samples.gap is None:
            assert y.samples.min_gap is None and y.samples.capacitance is None
            averaged += 1
    assert averaged == len(a) - 1   # the full model's first block has its channels
    assert run.stats.min_gap == auto.stats.min_gap
    assert run.summary().min_gap_m == auto.summary().min_gap_m


@pytest.mark.parametrize('motion', ['driven', 'circular', 'random'])
def test_the_smallest_gap_from_the_samples_that_can_hold_it(quiet_pair, motion):
    # (R5) against the kernel on every sample: a driven pair (8 % of the samples are
    # candidates), a circular orbit whose radius varies by 1e-8, less than the estimate's
    # error (0 to 7e-6 of the radius here: the grid and parabola decide, not the radius;
    # every sample is a candidate, and taking the largest radius alone fails), noise.
    (auto, _), _ = quiet_pair
    stretch = auto._stretch
    rng = np.random.default_rng(7)
    phase = np.linspace(0.0, 40.0 * math.pi, 2000)
    a = 2e-6
    if motion == 'driven':
        pair = np.column_stack([a * np.cos(phase), 1e-3 * a * np.sin(phase)])
    elif motion == 'circular':
        radius = a * (1.0 + 1e-8 * rng.standard_normal(phase.size))
        pair = np.column_stack([radius * np.cos(phase), radius * np.sin(phase)])
    else:
        pair = a * rng.standard_normal((2000, 2))
    q = np.zeros((pair.shape[0], auto.full_model().model.n_coordinates))
    q[:, [1, auto.config.modes.count + 1]] = pair
    every = np.min(auto.full_model().outputs_for(q).min_gap)
    assert stretch._smallest_gap(np.ascontiguousarray(pair)) == every
    assert every < auto.full_model().model.gap - 0.99 * np.max(np.hypot(pair[:, 0], pair[:, 1]))


def test_inputs_hand_to_the_full_model_and_back():
    # The full model's first 10 ms, then the averaged model (the first check). A temperature
    # step scheduled at 50 ms: the full model from the loop update at it, back
    # at the first check CHECK_S after it (60 ms). A parameter change acting now: the full
    # model at once, back 10 ms on. An angular rate: the averaged model takes it itself.
    config = build_config({**QUIET, 'integrator.fidelity': 'auto'})
    run = Run(config, calibration=None)
    n = config.run.block_samples
    run.apply(AmbientTemperature(kelvin=300.0, at_ns=50_000_000))
    for _ in range(8):
        run.advance(n)
    assert run.handoffs == [(0.0, 'full'), (pytest.approx(0.01), 'averaged'),
                            (pytest.approx(0.05), 'full'), (pytest.approx(0.06), 'averaged')]
    with pytest.raises(InputError):   # refused: changes nothing, the model included
        run.apply(AmbientTemperature(kelvin=-1.0))
    assert run.model == 'averaged'
    run.apply(ParameterChange({'gyro.bias_instability': 0.0}))
    assert run.model == 'full' and run.handoffs[-1] == (pytest.approx(0.08), 'full')
    run.advance(n)
    run.advance(n)
    assert run.model == 'averaged'
    changes = len(run.handoffs)
    run.apply(AngularRate(z=-HUNDRED_DEG_S, at_ns=run.time_ns + 5_000_000))
    block = run.advance(n)
    assert run.model == 'averaged' and len(run.handoffs) == changes
    assert np.all(block.samples.applied_rate[block.samples.t > run.time_ns * 1e-9 - 0.005
                                             + 1e-9] == -HUNDRED_DEG_S)
    assert run.diagnostics().values['model_changes'] == changes - 1


def test_averaged_refuses_a_gyroscope_it_cannot_run():
    with pytest.raises(ParameterError, match='integrator.fidelity: averaged, but'):
        Run(build_config({'control.mode': 'closed_loop', 'integrator.fidelity': 'averaged'}),
            calibration=None)
    run = Run(build_config({'control.mode': 'closed_loop'}), calibration=None)
    assert run.handoffs == [(0.0, 'full')]
    assert 'rebalance' in run.summary().extra['fidelity_reason']


def test_a_recording_holds_its_hand_offs_and_resimulates_them_bit_for_bit(tmp_path):
    # A 10 g shock at 52.5 ms (it leaves the fast modes below HAND_BACK_THRESHOLD), a
    # temperature step and a rate step: the hand-offs in the recording's metadata and the
    # summary; --from makes the same hand-offs and the same ~/rate and blocks, bit for bit.
    config = build_config({**QUIET, 'integrator.fidelity': 'auto'})
    inputs = [Shock(x=10.0 * STANDARD_GRAVITY, at_ns=52_500_000),
              AmbientTemperature(kelvin=300.0, at_ns=120_000_000),
              AngularRate(z=0.0, at_ns=150_000_000)]
    original = tmp_path / 'auto.mcap'
    summary = offline.run_offline(config, 0.2, output=str(original), progress=False,
                                  inputs=inputs)
    handoffs = read_handoffs(original)
    assert [model for _, model in handoffs] == ['full', 'averaged', 'full', 'averaged',
                                                'full', 'averaged']
    assert [t for t, _ in handoffs][:3] == [0, 10_000_000, 52_000_000]
    assert handoffs[4][0] == 120_000_000
    assert summary.extra['model_handoffs'] == [[t * 1e-9, m] for t, m in handoffs]
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert read_handoffs(again) == handoffs
    topics = [f'{NS}/rate', f'{NS}/modal_displacement', f'{NS}/demodulator', f'{NS}/control']
    a, b = decoded(original, topics), decoded(again, topics)
    assert len(a[f'{NS}/rate']) == 200
    for topic in topics:
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
    assert [m.angular_velocity.z for _, m in a[f'{NS}/rate']] == [
        m.angular_velocity.z for _, m in b[f'{NS}/rate']]
    for topic in topics[1:]:
        assert all(np.array_equal(np.array(x.data), np.array(y.data))
                   for (_, x), (_, y) in zip(a[topic], b[topic])), topic


def decoded(path, topics):
    """Return {topic: [(log_time_ns, message)]} decoded by mcap_ros2 (independent of ours)."""
    out = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(topics=topics):
            out.setdefault(channel.topic, []).append((message.log_time, msg))
    return out


LOADED = textwrap.dedent("""
    import sys
    from ring_gyro_sim.core.kernels import envelope
    from ring_gyro_sim.core.params import build_config
    from ring_gyro_sim.run import load_kernels
    config = build_config({'gyro.calibration.source': 'ideal',
                           'integrator.fidelity': sys.argv[1]})
    before = len(envelope.run_periods.signatures)
    load_kernels(config)
    print(before, len(envelope.run_periods.signatures))
""")


@pytest.mark.parametrize('fidelity, after', [('auto', 1), ('full', 0)])
def test_the_kernels_of_every_model_a_run_may_use_are_loaded_before_it(fidelity, after):
    # A fresh process: the averaged model's kernel has no signature until it first runs.
    # load_kernels (what the node calls before its clock starts) runs it when the run may
    # hand over to the averaged model, and not when the run stays on the full one.
    out = subprocess.run([sys.executable, '-c', LOADED, fidelity], capture_output=True,
                         text=True, timeout=600, check=True).stdout.split()
    assert out == ['0', str(after)]
