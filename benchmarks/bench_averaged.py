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
The averaged model's speed against the full model's: ``make bench-averaged``.

One open-loop case for both: ``benchmarks/gyro.yaml``'s operating point (N_R = 3 with the
companions, 0.0065 m/s^2 at 15 800 Hz, 10 deg/s from t = 0) without its shock and with the
noise off (the open-loop averaged model has neither), started on the drive orbit. The full model
runs through :class:`ring_gyro_sim.run.Run` in its 10 ms blocks (integration, outputs and
the sense chain at 200 kHz); the averaged model (``core.engine.averaged``) from the envelope of the
same start state, its samples at 1 kHz (the rate output's rate, 100 s) and at 200 kHz (the
block topics' rate, q2 and q2s reconstructed, as long as the full model's record: the
samples are made in one piece, and their arrays, not the model, set that cost). In
alternation in this process, the construction (start state, compilation) not timed;
printed: simulated seconds per CPU second of each, best of the repetitions, and the ratios.
CPU time, not wall time: the host is shared (``make bench-averaged`` runs it with one
OpenBLAS thread: the dense output's matrix products otherwise count idle threads). The
averaged model computes less (the pair's envelopes only: no sense chain, no q1, q3): the
open-loop ratio is not the closed loop's (below).

The closed loop (``--closed``, run by default after the open loop): the default gyroscope
(``config/default.yaml``: PLL, AGC, force-to-rebalance, the factory calibration) with the
noise off at a constant 10 deg/s, through ``Run`` and through ``core.engine.averaged.AveragedGyro``
(its ``~/rate`` samples at ``gyro.output_rate``, 1 kHz, with the same held calibration),
both from the Run's start state; printed likewise, with the largest difference of the two
``~/rate`` records over the full model's stretch after its first 50 ms, relative to the
reading. The averaged model is timed again with the default gyroscope's noises on (S9, S10).
"""

import argparse
import math
import os
import sys
import time

import numpy as np
from ring_gyro_sim.analysis.slow_flow import AveragedModel
from ring_gyro_sim.core.engine.averaged import AveragedGyro, envelope_of
from ring_gyro_sim.core.gyro import operating_point
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.run import Run

CASE = {'modes.companions': True, 'gyro.enabled': True, 'drive.amplitude': 0.0065,
        'drive.frequency': 15800.0, 'drive.start_on': 'upper_branch',
        'control.mode': 'open_loop',
        'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
        'gyro.calibration.source': 'ideal', 'real_time_factor': 0.0,
        'scenario.rate_times': [0.0], 'scenario.rate_values': [math.radians(10.0)]}
PAIR = [1, 4]
CLOSED = {'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0, 'real_time_factor': 0.0,
          'scenario.rate_times': [0.0], 'scenario.rate_values': [math.radians(10.0)]}
NOISE_KEYS = ('gyro.temperature', 'gyro.input_noise_density')


def _full(config, seconds: float) -> float:
    run = Run(config)
    blocks = int(round(seconds / config.run.block_duration))
    start = time.process_time()
    for _ in range(blocks):
        run.advance(config.run.block_samples)
    return seconds / (time.process_time() - start)


def _averaged(config, start, seconds: float, sample_rate: float) -> float:
    model = AveragedModel(config)
    begin = time.process_time()
    model.run(seconds, sample_rate, start=start)
    return seconds / (time.process_time() - begin)


def _full_closed(run, seconds: float):
    blocks = int(round(seconds / run.config.run.block_duration))
    t, rate = [], []
    start = time.process_time()
    for _ in range(blocks):
        samples = run.advance(run.config.run.block_samples)
        t.append(samples.rate.t)
        rate.append(samples.rate.rate)
    return seconds / (time.process_time() - start), np.concatenate(t), np.concatenate(rate)


def _averaged_closed(config, start, calibration, seconds: float):
    model = AveragedGyro(config, start, calibration=calibration)
    begin = time.process_time()
    out = model.advance(seconds)
    return seconds / (time.process_time() - begin), out


def closed(args) -> None:
    """Time the closed-loop default gyroscope in both models; print speeds, ratio, agreement."""
    config = build_config(CLOSED)
    run = Run(config)                        # the factory calibration: not timed
    start = run.start_state
    calibration = run.calibration
    _averaged_closed(config, start, calibration, 0.01)   # compile: not timed
    run.advance(config.run.block_samples)
    full = averaged = averaged_noisy = 0.0
    worst = 0.0
    # the default gyroscope as configured: its noises on (S9, S10), at the same rate
    noisy = build_config({k: v for k, v in CLOSED.items() if not k.startswith(NOISE_KEYS)})
    for k in range(args.repeat):
        run = Run(config, start_state=start, calibration=calibration)
        rtf, t, rate = _full_closed(run, args.seconds)
        full = max(full, rtf)
        rtf, _ = _averaged_closed(config, start, calibration, args.averaged_seconds)
        averaged = max(averaged, rtf)
        rtf, _ = _averaged_closed(noisy, start, calibration, args.averaged_seconds)
        averaged_noisy = max(averaged_noisy, rtf)
        _, out = _averaged_closed(config, start, calibration, args.seconds)
        late = t >= 0.05
        worst = float(np.max(np.abs(out.rate[:t.size][late] - rate[late])
                             / np.abs(rate[late])))
        print(f'closed loop round {k + 1}/{args.repeat}', file=sys.stderr)
    print(f'closed loop, default gyroscope, 10 deg/s, noise off: load average '
          f'{os.getloadavg()[0]:.2f}; best of {args.repeat}; simulated s per CPU s')
    print(f'{"full (Run, 200 kHz)":28s} rtf_cpu {full:10.2f}')
    print(f'{"averaged, ~/rate at 1 kHz":28s} rtf_cpu {averaged:10.2f}   ratio to full '
          f'{averaged / full:8.1f}   {1e6 / (config.control.rate * averaged):.2f} us per '
          f'loop period')
    print(f'{"averaged, noises on":28s} rtf_cpu {averaged_noisy:10.2f}   ratio to full '
          f'{averaged_noisy / full:8.1f}   {1e6 / (config.control.rate * averaged_noisy):.2f} '
          f'us per loop period')
    print(f'~/rate, averaged against full after 50 ms: largest difference {worst:.2e} of '
          f'the reading')


def main(argv=None) -> int:
    """Time both models in alternation; print their speeds and the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=1.0, help='simulated s of the full')
    parser.add_argument('--averaged-seconds', type=float, default=100.0,
                        help='simulated s of the averaged model')
    parser.add_argument('--repeat', type=int, default=3, help='runs of each, alternating')
    parser.add_argument('--closed-only', action='store_true',
                        help='only the closed-loop default gyroscope')
    args = parser.parse_args(argv)
    if args.closed_only:
        closed(args)
        return 0
    config = build_config(CASE)
    q, v = operating_point.start_state(config)
    w = 2.0 * math.pi * config.drive.frequency
    start = envelope_of(q[PAIR], v[PAIR], w, 0.0)
    _full(config, 0.01)                      # compile: not timed
    _averaged(config, start, 0.1, 1000.0)
    rows = {'full (Run, 200 kHz)': 0.0, 'averaged, 1 kHz samples': 0.0,
            'averaged, 200 kHz samples': 0.0}
    for k in range(args.repeat):
        rows['full (Run, 200 kHz)'] = max(rows['full (Run, 200 kHz)'],
                                          _full(config, args.seconds))
        rows['averaged, 1 kHz samples'] = max(
            rows['averaged, 1 kHz samples'],
            _averaged(config, start, args.averaged_seconds, 1000.0))
        rows['averaged, 200 kHz samples'] = max(
            rows['averaged, 200 kHz samples'],
            _averaged(config, start, args.seconds, 200000.0))
        print(f'round {k + 1}/{args.repeat}', file=sys.stderr)
    print(f'load average {os.getloadavg()[0]:.2f}; best of {args.repeat}; simulated seconds '
          f'per CPU second (full and averaged at 200 kHz: {args.seconds:g} s, averaged at '
          f'1 kHz: {args.averaged_seconds:g} s)')
    full = rows['full (Run, 200 kHz)']
    for name, rtf in rows.items():
        print(f'{name:28s} rtf_cpu {rtf:10.2f}   ratio to full {rtf / full:8.1f}')
    closed(args)
    return 0


if __name__ == '__main__':
    sys.exit(main())
