# Copyright 2025 ring_gyro_sim developers
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
Harness of the node tests: the node in its own process, a probe node in this one.

Every test process gets its own ROS domain (``ros_domains.claim``) with discovery limited to
this machine, set here before rclpy is initialised and passed to every node process, so
parallel sessions, their workers and other machines do not see each other.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import contextlib
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import AccelStamped, Vector3Stamped
import numpy as np
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from ring_gyro_sim.core.params import PAPER_RESONATOR
from ring_gyro_sim.ros import conversions
import ros_domains
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
# isort: on

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
DOMAIN_ID = str(ros_domains.claim('node tests'))
os.environ['ROS_DOMAIN_ID'] = DOMAIN_ID
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
MATCH_TIMEOUT_S = 120.0
"""
How long a node may take to come up: imports, compiled kernels, the start state, the factory's
rate table when the cache is empty (the longest part), discovery, on a machine whose other
cores run other tests. A bound on liveness (a node that never comes up fails), not on speed:
a test that waits ends as soon as the node is there.
"""


def node_command(params_file, *ros_args):
    """
    Return the command line of the node: the installed executable or ``-m``.

    ``params_file`` None: no file (the embedded defaults), and no ``--ros-args`` unless
    ``ros_args`` are given.
    """
    exe = shutil.which('ring_gyro_node')
    head = [exe] if exe else [sys.executable, '-m', 'ring_gyro_sim.ros.node']
    args = (['--params-file', str(params_file)] if params_file is not None else []) + [
        *ros_args]
    return head + (['--ros-args', *args] if args else [])


def node_env():
    """Return the environment of a node process: this session's domain, the repo on the path."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    env['ROS_DOMAIN_ID'] = DOMAIN_ID
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    env['PYTHONUNBUFFERED'] = '1'
    return env


def params_yaml(values, node='ring_gyro', device=PAPER_RESONATOR):
    """
    Return the text of a ``--params-file`` with the flat ``values`` nested under ``node``.

    ``values`` are laid over ``device``: by default the paper's resonator, which most node
    tests run (the defaults are the gyroscope: ``device={}``).
    """
    import yaml
    tree = {}
    for name, value in {**device, **values}.items():
        *groups, leaf = name.split('.')
        branch = tree
        for group in groups:
            branch = branch.setdefault(group, {})
        branch[leaf] = value
    return yaml.safe_dump({node: {'ros__parameters': tree}}, sort_keys=True)


def process_cpu_seconds(pid):
    """Return the CPU time process ``pid`` has used so far (user + system, all threads), s."""
    with open(f'/proc/{pid}/stat', encoding='ascii') as fh:
        fields = fh.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


class NodeProcess:
    """One ``ring_gyro_node`` process; output goes to files so that no pipe can fill up."""

    def __init__(self, params_file, workdir, *ros_args, nice=0):
        """Start the node; ``nice`` < 0 raises its priority (a test that needs it on time)."""
        self.workdir = pathlib.Path(workdir)
        self.stdout_path = self.workdir / 'node.stdout'
        self.stderr_path = self.workdir / 'node.stderr'
        self._out = open(self.stdout_path, 'wb')
        self._err = open(self.stderr_path, 'wb')
        self.proc = subprocess.Popen(node_command(params_file, *ros_args), cwd=REPO_ROOT,
                                     env=node_env(), stdout=self._out, stderr=self._err,
                                     preexec_fn=(lambda: os.nice(nice)) if nice else None)

    @property
    def pid(self):
        return self.proc.pid

    def output(self):
        """Return what the node wrote so far (stdout and stderr; rcutils logs to stderr)."""
        for stream in (self._out, self._err):
            if not stream.closed:
                stream.flush()
        return (self.stdout_path.read_text(errors='replace')
                + self.stderr_path.read_text(errors='replace'))

    def wait(self, timeout):
        """Wait for the exit; return the exit code (None if still running after ``timeout``)."""
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None

    def signal(self, sig):
        self.proc.send_signal(sig)

    def rss_bytes(self):
        """Return the resident memory of the process, bytes."""
        with open(f'/proc/{self.proc.pid}/status', encoding='ascii') as fh:
            for line in fh:
                if line.startswith('VmRSS:'):
                    return int(line.split()[1]) * 1024
        raise RuntimeError('no VmRSS')

    def cpu_seconds(self):
        """Return the CPU time the process has used so far (user + system, all threads), s."""
        return process_cpu_seconds(self.proc.pid)

    def stop(self):
        """End the process if it still runs (SIGINT, then SIGKILL) and close the log files."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            if self.wait(5.0) is None:
                self.proc.kill()
                self.proc.wait()
        self._out.close()
        self._err.close()


class Block:
    """One received block: labels, data (K, C), wall time of arrival."""

    def __init__(self, msg, wall):
        self.labels, self.data = conversions.block_arrays(msg)
        self.wall = wall
        self.msg = msg

    @property
    def t(self):
        return self.data[:, 0]


class Probe(Node):
    """A test node: subscribes to the outputs, publishes inputs, calls the services."""

    def __init__(self, target='/ring_gyro', topics=conversions.OUTPUT_TOPICS):
        super().__init__(f'probe_{os.getpid()}_{random.randrange(1 << 30)}')
        self.target = target
        self.blocks = {name: [] for name in topics}
        self.diagnostics = []
        self.subs = [self.create_subscription(
            Float64MultiArray, f'{target}/{name}',
            lambda msg, name=name: self.blocks[name].append(Block(msg, time.monotonic())), 200)
            for name in topics]
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 50)
        self.clock = []
        self.create_subscription(ClockMsg, '/clock', lambda msg: self.clock.append(
            conversions.stamp_to_ns(msg.clock)), 200)
        self.shock_pub = self.create_publisher(Vector3Stamped, f'{target}/shock', 100)
        self.accel_pub = self.create_publisher(AccelStamped, f'{target}/base_acceleration', 10)
        self.amplitude_pub = self.create_publisher(Float64, f'{target}/drive/amplitude', 10)
        self.frequency_pub = self.create_publisher(Float64, f'{target}/drive/frequency', 10)
        self.set_client = self.create_client(SetParameters, f'{target}/set_parameters')
        self.get_client = self.create_client(GetParameters, f'{target}/get_parameters')
        self.reset_client = self.create_client(Trigger, f'{target}/reset')
        self.describe_client = self.create_client(DescribeParameters,
                                                  f'{target}/describe_parameters')
        self.executor_ = SingleThreadedExecutor()
        self.executor_.add_node(self)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            self.diagnostics.append((time.monotonic(), status, values))

    def spin_until(self, predicate, timeout, what='condition'):
        """Spin until ``predicate()`` is true; fail the test after ``timeout`` s."""
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > end:
                pytest.fail(f'timed out after {timeout} s waiting for {what}')
            self.executor_.spin_once(timeout_sec=0.02)

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor_.spin_once(timeout_sec=0.02)

    def wait_connected(self, timeout=MATCH_TIMEOUT_S):
        """Wait until blocks arrive and every input and service is matched."""
        first = next(iter(self.blocks))
        publishers = (self.shock_pub, self.accel_pub, self.amplitude_pub, self.frequency_pub)
        clients = (self.set_client, self.get_client, self.reset_client)

        def connected():
            return (len(self.blocks[first]) >= 2
                    and all(p.get_subscription_count() > 0 for p in publishers)
                    and all(c.service_is_ready() for c in clients))
        self.spin_until(connected, timeout, 'the node to be up and matched')

    def last_time_ns(self, topic='modal_displacement'):
        """Return the simulation time (ns) of the last sample received (the node's 'now')."""
        return int(round(self.blocks[topic][-1].t[-1] * 1e9))

    def wait_sim_time(self, t_ns, timeout, topic='modal_displacement'):
        self.spin_until(lambda: self.blocks[topic] and self.last_time_ns(topic) >= t_ns,
                        timeout, f'simulation time {t_ns * 1e-9:.6f} s')

    def call(self, client, request, timeout=10.0):
        future = client.call_async(request)
        self.spin_until(future.done, timeout, f'a response of {client.srv_name}')
        return future.result()

    def remote_set(self, *params, timeout=10.0):
        """Set ``(name, value)`` pairs through the node's set_parameters service."""
        request = SetParameters.Request()
        request.parameters = [Parameter(name, value=value).to_parameter_msg()
                              for name, value in params]
        return self.call(self.set_client, request, timeout).results

    def remote_get(self, name, timeout=10.0):
        request = GetParameters.Request(names=[name])
        value = self.call(self.get_client, request, timeout).values[0]
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=value)).value

    def remote_describe(self, *names, timeout=10.0):
        request = DescribeParameters.Request(names=list(names))
        return self.call(self.describe_client, request, timeout).descriptors

    def reset(self, timeout=10.0):
        return self.call(self.reset_client, Trigger.Request(), timeout)

    def shock(self, x, y=0.0, at_ns=0, z=0.0):
        msg = Vector3Stamped()
        msg.header.stamp = conversions.ns_to_stamp(at_ns)
        msg.vector.x, msg.vector.y, msg.vector.z = float(x), float(y), float(z)
        self.shock_pub.publish(msg)

    def latest_diagnostics(self, after_wall=0.0):
        """Return the values of the last ring_gyro status received after ``after_wall``."""
        for wall, status, values in reversed(self.diagnostics):
            if wall >= after_wall and status.name.endswith(': simulator'):
                return values
        return None

    def stacked(self, topic, since_t_s=-np.inf):
        """Return (labels, data) of all blocks of ``topic`` received, stacked."""
        blocks = [b for b in self.blocks[topic] if b.t[-1] >= since_t_s]
        return blocks[0].labels, np.concatenate([b.data for b in blocks])


def start_node(workdir, values, *ros_args, node='ring_gyro', nice=0):
    """Write ``values`` as a params file in ``workdir`` and start a node process on it."""
    path = pathlib.Path(workdir) / 'params.yaml'
    path.write_text(params_yaml(values, node), encoding='utf-8')
    return NodeProcess(path, workdir, *ros_args, nice=nice)


@contextlib.contextmanager
def connected(node, make_probe=Probe, tail=3000):
    """
    Yield a probe (``make_probe()``) connected to a started node process.

    On the way out, also on a failure: the probe destroyed, the node stopped and the last
    ``tail`` characters of its log printed (pytest shows them with a failure).
    """
    probe = None
    try:
        probe = make_probe()
        probe.wait_connected()
        yield probe
    finally:
        if probe is not None:
            probe.destroy_node()
        node.stop()
        print(node.output()[-tail:])
