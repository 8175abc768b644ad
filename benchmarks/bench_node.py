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
Real-time factor of the node with the gyroscope on, as fast as it goes.

Starts ``ring_gyro_node`` on ``benchmarks/gyro.yaml`` (N_R = 3 with the companions, the
sense electronics at 200 kHz, ``~/rate`` at 1 kHz, every noise on, a 10 000 g shock at
0.5 s, ``real_time_factor: 0``), on the same file with the closed loops on
(``control.mode: rebalance``: PLL, AGC and force-to-rebalance
at 1 kHz, ``~/control`` published) and with ``gyro.enabled`` off (the resonator with its
companions: what the gyroscope adds), each for ``--duration`` simulated seconds, alternating
``--rounds`` times. It reads the node's own last line
(``... s simulated in ... s (xRTF real time)``: from the first block to the stop, start-up
excluded) and the process's CPU time (start-up included), and prints both with their ratio.
Nobody subscribes: the publishers serialise, DDS delivers to no one.

    python benchmarks/bench_node.py [--duration 5] [--rounds 2]
"""

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
LINE = re.compile(r'([0-9.]+) s simulated in ([0-9.]+) s \(x([0-9.]+) real time\)')


def node_command():
    """Return the ``ring_gyro_node`` console script next to this Python, else ``-m``."""
    exe = os.path.join(os.path.dirname(sys.executable), 'ring_gyro_node')
    return [exe] if os.path.exists(exe) else [sys.executable, '-m', 'ring_gyro_sim.ros.node']


def run_node(params: str, duration: float, domain: int):
    """Run the node once; return (rtf from its log, wall s, cpu s)."""
    log, wall, cpu = run_node_log(params, duration, domain, LINE)
    return float(LINE.findall(log)[-1][2]), wall, cpu


def run_node_log(params: str, duration: float, domain: int, line):
    """Run the node once; return (its log, wall s, cpu s); exit if ``line`` is not in it."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONPATH=os.pathsep.join([REPO, os.environ.get('PYTHONPATH', '')]))
    args = node_command() + ['--ros-args', '--params-file', params, '-p',
                             f'duration:={duration}']
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=3600,
                          check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    log = done.stdout + done.stderr
    if done.returncode != 0 or not line.search(log):
        raise SystemExit(f'node failed ({done.returncode}): {log[-2000:]}')
    return log, wall, cpu


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--duration', type=float, default=5.0)
    parser.add_argument('--rounds', type=int, default=2)
    args = parser.parse_args(argv)
    params = os.path.join(HERE, 'gyro.yaml')
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        with open(params, encoding='utf-8') as f:
            doc = yaml.safe_load(f)
        p = doc['ring_gyro']['ros__parameters']
        # the closed loops: the same file with PLL, AGC and force-to-rebalance
        p['control'] = {'mode': 'rebalance'}
        closed = os.path.join(tmp, 'closed.yaml')
        with open(closed, 'w', encoding='utf-8') as f:
            yaml.safe_dump(doc, f)
        # the resonator: the same file without the gyroscope (and so without a rate)
        del p['control']
        p['gyro']['enabled'] = False
        del p['scenario']['rate_times'], p['scenario']['rate_values']
        resonator = os.path.join(tmp, 'resonator.yaml')
        with open(resonator, 'w', encoding='utf-8') as f:
            yaml.safe_dump(doc, f)
        variants = (('gyroscope', params), ('closed loops', closed), ('resonator', resonator))
        for k in range(args.rounds):
            for j, (tag, path) in enumerate(variants):
                rtf, wall, cpu = run_node(path, args.duration, 80 + ((3 * k + j) % 5))
                print(f'round {k + 1}: {tag}: x{rtf:.3f} real time (node log), wall '
                      f'{wall:.2f} s, CPU {cpu:.2f} s for {args.duration:g} s simulated',
                      flush=True)
                if tag not in best or rtf > best[tag][0]:
                    best[tag] = (rtf, wall, cpu)
    g, c, r = best['gyroscope'], best['closed loops'], best['resonator']
    print(f'\nnode, benchmarks/gyro.yaml, real_time_factor 0, {args.duration:g} s simulated, '
          f'best of {args.rounds} (load {os.getloadavg()[0]:.2f}):')
    print(f'  gyroscope, open loop  : x{g[0]:.2f} real time (CPU incl. start-up {g[2]:.2f} s)')
    print(f'  gyroscope, closed loops: x{c[0]:.2f} real time (CPU incl. start-up {c[2]:.2f} s)')
    print(f'  gyroscope off          : x{r[0]:.2f} real time (CPU incl. start-up {r[2]:.2f} s)')
    print(f'  the gyroscope costs {100.0 * (r[0] / g[0] - 1.0):.0f} % more time per simulated '
          f'second, the closed loops {100.0 * (g[0] / c[0] - 1.0):.0f} % more than open '
          f'loop; margin over real time on one core: {c[0]:.2f}x with the loops')
    return 0


if __name__ == '__main__':
    sys.exit(main())
