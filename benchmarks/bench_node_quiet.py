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
The node's share of a core at real time in a quiet stretch, per model (issue 25).

Starts ``ring_gyro_node`` with the default parameters (the closed-loop gyroscope, every noise
on, ``real_time_factor: 1``) at ``integrator.fidelity: auto`` (the averaged model throughout:
nothing fast acts) and ``full``, each for a short and a long ``duration``, and prints the CPU
time per simulated second from the difference of the two (start-up, imports and the start
orbit cancel): the share of a core the running node takes; and the node's own figure
(its last line: CPU time over wall time from the first block to the stop). Nobody
subscribes to the block topics; the node records nothing (``record.path`` empty). Ratios
in one session.

    python benchmarks/bench_node_quiet.py [--short 5] [--long 25] [--rounds 1]
"""

import argparse
import os
import re
import sys
import tempfile

import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_node import run_node_log  # noqa: E402 I100 - the other benchmark's runner


SHARE = re.compile(r'real time\), ([0-9.]+) % of a core')


def run_node(params: str, duration: float, domain: int):
    """Run the node once; return (its own share of a core in %, wall s, cpu s)."""
    log, wall, cpu = run_node_log(params, duration, domain, SHARE)
    return float(SHARE.findall(log)[-1]), wall, cpu


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--short', type=float, default=5.0)
    parser.add_argument('--long', type=float, default=25.0)
    parser.add_argument('--rounds', type=int, default=1)
    args = parser.parse_args(argv)
    share, own = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for j, fidelity in enumerate(('auto', 'full')):
                path = os.path.join(tmp, f'{fidelity}.yaml')
                with open(path, 'w', encoding='utf-8') as f:
                    yaml.safe_dump({'/**': {'ros__parameters': {
                        'real_time_factor': 1.0, 'integrator': {'fidelity': fidelity}}}}, f)
                cpu = []
                for i, duration in enumerate((args.short, args.long)):
                    node, wall, seconds = run_node(path, duration, 85 + (4 * k + 2 * j + i) % 10)
                    cpu.append(seconds)
                    print(f'round {k + 1}: {fidelity}: {duration:g} s at real time, wall '
                          f'{wall:.2f} s, CPU {seconds:.2f} s, the node says {node:.1f} % of '
                          f'a core', flush=True)
                own[fidelity] = min(own.get(fidelity, node), node)
                value = (cpu[1] - cpu[0]) / (args.long - args.short)
                share[fidelity] = min(share.get(fidelity, value), value)
    a, f = share['auto'], share['full']
    print(f'\nnode at real time, default gyroscope, quiet (best of {args.rounds}, load '
          f'{os.getloadavg()[0]:.2f}):')
    print(f'  auto (averaged): {100.0 * a:6.2f} % of a core (the node: {own["auto"]:.1f} %)')
    print(f'  full           : {100.0 * f:6.2f} % of a core (the node: {own["full"]:.1f} %)   '
          f'ratio full / auto {f / a:.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
