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
The node's share of a core at real time in a quiet stretch, per model.

Starts ``ring_gyro_node`` with the default parameters (the closed-loop gyroscope, every noise
on, ``real_time_factor: 1``) at ``integrator.fidelity: auto`` (the averaged model throughout:
nothing fast acts) and ``full``, each for a short and a long ``duration``, and prints the CPU
time per simulated second from the difference of the two (start-up, imports and the start
orbit cancel): the share of a core the running node takes; and the node's own figure
(its last line: CPU time over wall time from the first block to the stop). Nobody
subscribes to the block topics; the node records nothing (``record.path`` empty). Ratios
in one session.

And the floor under that share on this host: a bare rclpy node in this process that does the
node's ROS side with nothing simulated (:func:`floor_share`), and the CPU cost of one
wake-up from a sleep (:func:`wake_up_cost`): what no simulation, however fast, takes away
from the node at the interface's pacing (one ``~/rate`` message per sample at
``gyro.output_rate``, at most two together).

    python benchmarks/bench_node_quiet.py [--short 5] [--long 25] [--rounds 1] [--floor 10]
"""

import argparse
import os
import re
import sys
import tempfile
import time

import yaml

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_node import run_node_log  # noqa: E402 I100 - the other benchmark's runner


SHARE = re.compile(r'real time\), ([0-9.]+) % of a core')


def run_node(params: str, duration: float, domain: int):
    """Run the node once; return (its own share of a core in %, wall s, cpu s)."""
    log, wall, cpu = run_node_log(params, duration, domain, SHARE)
    return float(SHARE.findall(log)[-1]), wall, cpu


def wake_up_cost(period_s: float, seconds: float) -> float:
    """Return the CPU time of one wake-up from ``time.sleep`` at ``period_s``, s."""
    t0 = time.monotonic()
    c0 = time.process_time()
    due, count = t0, 0
    while due - t0 < seconds:
        due += period_s
        count += 1
        delay = due - time.monotonic()
        if delay > 0.0:
            time.sleep(delay)
    return (time.process_time() - c0) / count


def floor_share(seconds: float, domain: int) -> float:
    """
    Return the share of a core a bare rclpy node takes doing the paced node's ROS side.

    What ``ring_gyro_node`` does at its defaults besides simulating (``ros/node.py``,
    "Pacing"): ``spin_once`` turns of a ``SingleThreadedExecutor`` whose timer ticks every
    100 ms; in each tick it sleeps until each pair of ``~/rate`` messages is due (1 000
    ``sensor_msgs/Imu`` a second, two at a time) and publishes them, and ``/clock`` once a
    10 ms block. Nothing simulated, the messages serialised once before (the cheapest
    publish rclpy has), nobody subscribed: a lower bound of the node's share.
    """
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu

    rclpy.init()
    try:
        node = rclpy.create_node('floor')
        rate = node.create_publisher(Imu, '~/rate', 10)
        clock = node.create_publisher(Clock, '/clock', 10)
        imu, tick = serialize_message(Imu()), serialize_message(Clock())
        start = time.monotonic()
        state = {'due': start, 'sent': 0}

        def on_tick():
            end = time.monotonic() + 0.1 - 0.0005
            while state['due'] + 0.002 < end:
                state['due'] += 0.002
                delay = state['due'] - time.monotonic()
                if delay > 0.0:
                    time.sleep(delay)
                rate.publish(imu)
                rate.publish(imu)
                state['sent'] += 2
                if state['sent'] % 10 == 0:
                    clock.publish(tick)

        node.create_timer(0.1, on_tick)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        c0 = time.process_time()
        while time.monotonic() - start < seconds:
            executor.spin_once(timeout_sec=0.1)
        share = (time.process_time() - c0) / (time.monotonic() - start)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.shutdown()
    return share


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--short', type=float, default=5.0)
    parser.add_argument('--long', type=float, default=25.0)
    parser.add_argument('--rounds', type=int, default=1)
    parser.add_argument('--floor', type=float, default=10.0,
                        help='seconds of the bare rclpy floor (0: skip it)')
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
    if args.floor > 0.0:
        wake = [wake_up_cost(p, args.floor / 2.0) for p in (0.002, 0.01)]
        floor = floor_share(args.floor, 95)
        print(f'  floor          : {100.0 * floor:6.2f} % of a core (a bare rclpy node: '
              f'1 000 ~/rate a second two at a time, /clock, 10 executor turns a second; '
              f'nothing simulated)   ratio auto / floor {a / floor:.1f}')
        print(f'  a wake-up from time.sleep costs {1e6 * wake[0]:.0f} us of CPU at 500 a '
              f'second, {1e6 * wake[1]:.0f} us at 100 a second')
    return 0


if __name__ == '__main__':
    sys.exit(main())
