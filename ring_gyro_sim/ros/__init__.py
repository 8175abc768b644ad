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
The rclpy layer: node, parameter declaration and message conversion.

In the process of ``ring_gyro_node`` (the console script, ``ros2 run`` or ``python -m
ring_gyro_sim.ros.node``) this package, imported first, notes SIGINT and SIGTERM in
:data:`EARLY_SIGNALS` until ``node.main()`` takes them over: Ctrl-C during the slow imports
(rclpy, numpy, numba: ~0.5 s) then ends the node at once, exit code 0, without a
KeyboardInterrupt traceback. In any other process importing it changes nothing.

Modules (import from them directly, nothing else is re-exported here): ``node`` (the
simulator node and its entry point), ``parameters`` (ROS parameter declaration from the
parameter table), ``conversions`` (messages to and from the core's types), ``sinks`` (publish
and record a run), ``recorder`` (recording a run as a ROS 2 bag).
"""

# The handlers go in before anything else runs: ``signal`` (a thin wrapper of the interpreter's
# own ``_signal``, already loaded at start-up) converts its constants to enums on import, 1 ms
# idle and several under load, and a Ctrl-C landing in that import would raise
# KeyboardInterrupt in this file. ``_signal``, ``os`` and ``sys`` are loaded before any code
# of ours.
import _signal
import os
import sys

__all__ = ['EARLY_SIGNALS', 'conversions', 'node', 'parameters', 'recorder', 'sinks']

EARLY_SIGNALS = []
"""Signals received in the node's process before ``node.main()`` installed its handlers."""


def _is_node_process() -> bool:
    """Tell whether this process was started as ``ring_gyro_node``."""
    argv = getattr(sys, 'orig_argv', None) or sys.argv
    if os.path.basename(sys.argv[0] if sys.argv else '').startswith('ring_gyro_node'):
        return True
    return any(a == '-m' and b == 'ring_gyro_sim.ros.node' for a, b in zip(argv, argv[1:]))


# Also when SIGINT came in ignored (a shell's background job): the node handles both signals
# once it runs (node.main), so it must not die of one, or ignore one, before that.
if _is_node_process():
    for _signum in (_signal.SIGINT, _signal.SIGTERM):
        _signal.signal(_signum, lambda signum, frame: EARLY_SIGNALS.append(signum))
