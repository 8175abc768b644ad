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
The imperfect gyroscope's cost against the perfect one's: ``make bench-imperfect``.

``benchmarks/gyro_closed.yaml`` (the perfect ring, closed loops, force-to-rebalance) and
``benchmarks/gyro_imperfect.yaml`` (the same run on a ring with a coupled 2theta pair and the
pick-off's errors), and the imperfect file with its die warming 1 K/s (the device rebuilt
every 10 ms as core.thermal does), run through :class:`ring_gyro_sim.run.Run` in their 10 ms
blocks, in alternation in this process, the runs' construction (start state, calibration)
not timed. Printed: each one's real-time factor from process CPU time (best of the
repetitions) and the ratio of the imperfect runs' to the perfect one's; the target is a
ratio of at least 0.95 (at most 5 % slower). CPU time, not wall time, and a ratio within one
session: the host's speed drifts.
"""

import argparse
from dataclasses import replace
import os
import pathlib
import sys
import time

from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.run import Run

HERE = pathlib.Path(__file__).resolve().parent
TARGET_RATIO = 0.95


def _configs():
    perfect = load_yaml(str(HERE / 'gyro_closed.yaml'))
    imperfect = load_yaml(str(HERE / 'gyro_imperfect.yaml'))
    warming = replace(imperfect, run=replace(imperfect.run, temperature_times=(0.0, 10.0),
                                             temperature_values=(298.15, 308.15)),
                      thermal=replace(imperfect.thermal, time_constant=0.0))
    return {'perfect': perfect, 'imperfect': imperfect, 'imperfect, die +1 K/s': warming}


def _rtf_cpu(config, seconds: float) -> float:
    run = Run(config)
    blocks = int(round(seconds / config.run.block_duration))
    start = time.process_time()
    for _ in range(blocks):
        run.advance(config.run.block_samples)
    return seconds / (time.process_time() - start)


def main(argv=None) -> int:
    """Time the files in alternation; print the real-time factors and their ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=1.0, help='simulated s per run')
    parser.add_argument('--repeat', type=int, default=5, help='runs of each, alternating')
    args = parser.parse_args(argv)
    configs = _configs()
    for config in configs.values():  # compile, start states and calibrations: not timed
        _rtf_cpu(config, 0.01)
    best = {name: 0.0 for name in configs}
    for k in range(args.repeat):
        for name, config in configs.items():
            best[name] = max(best[name], _rtf_cpu(config, args.seconds))
        print(f'round {k + 1}/{args.repeat}', file=sys.stderr)
    print(f'load average {os.getloadavg()[0]:.2f}; best of {args.repeat} runs of '
          f'{args.seconds:g} s, real-time factor from CPU time')
    for name, rtf in best.items():
        ratio = rtf / best['perfect']
        verdict = '' if name == 'perfect' else (
            '  (target >= 0.95: met)' if ratio >= TARGET_RATIO else
            '  (target >= 0.95: MISSED)')
        print(f'{name:24s} rtf_cpu {rtf:7.3f}   ratio {ratio:6.3f}{verdict}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
