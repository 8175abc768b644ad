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
Recording of one run to a ROS 2 bag, shared by the node and the offline command line.

What a recording holds (interface.md, Recording):

* the output blocks (``<ns>/modal_displacement``, ``radial_gap``, ``sense_electrodes``),
  ``/diagnostics`` and, when published, ``/clock``; log time = simulation time of the last
  sample of the block (when it is complete);
* every input that reached the simulator, at the simulation time it was applied:
  ``<ns>/shock``, ``<ns>/base_acceleration`` (stamps = application times),
  ``<ns>/drive/amplitude``, ``<ns>/drive/frequency``; and, so that a run can be re-simulated,
  ``<ns>/events/reset`` (std_msgs/Empty) and ``<ns>/events/parameters`` (std_msgs/String: a
  YAML mapping of the parameters changed at run time);
* a metadata record ``ring_gyro_sim`` with the full resolved parameters (YAML), the package
  version, the git revision, the namespace and the exact initial state (JSON, repr floats).

Outputs are recorded reliable / volatile (what ``ros2 bag play`` then offers).
"""

import json
import os
import queue
import subprocess
import threading
from typing import Dict, Optional, Sequence

from ring_gyro_sim import __version__
from ring_gyro_sim.core.params import SimConfig, to_flat
from ring_gyro_sim.recording.writer import BagWriter
from ring_gyro_sim.ros import conversions
from std_msgs.msg import Empty, String
import yaml

METADATA_NAME = 'ring_gyro_sim'
BLOCK_TYPE = 'std_msgs/msg/Float64MultiArray'
INPUT_TOPICS = {
    'shock': 'geometry_msgs/msg/Vector3Stamped',
    'base_acceleration': 'geometry_msgs/msg/AccelStamped',
    'drive/amplitude': 'std_msgs/msg/Float64',
    'drive/frequency': 'std_msgs/msg/Float64',
    'events/reset': 'std_msgs/msg/Empty',
    'events/parameters': 'std_msgs/msg/String',
}


def git_revision() -> str:
    """Git revision of the package source, or 'unknown' (installed without .git)."""
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        out = subprocess.run(['git', '-C', here, 'rev-parse', 'HEAD'], capture_output=True,
                             text=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return 'unknown'
    return out.stdout.strip() if out.returncode == 0 else 'unknown'


#: Messages queued for the writer thread at most (3 per block: ~1 s of blocks at 100 Hz).
WRITE_QUEUE_DEPTH = 300


class RunRecorder:
    """
    Writes one run to ``path`` (a context manager; the file is finalised on exit).

    Parameters
    ----------
    path : str
        The ``.mcap`` file.
    config : SimConfig
        Resolved configuration (goes to the metadata record).
    channel_names : dict
        ``Simulator.channel_names``.
    namespace : str
        Topic namespace of the node, e.g. '/ring_gyro'.
    initial_state : (ndarray, ndarray), optional
        Initial coordinates and velocities (m, m/s). When None the metadata record waits
        for :meth:`start`, so that a caller can open (and so check) the file before it
        computes the start state.
    publish_clock : bool
        Also record ``/clock``.
    threaded : bool
        Serialise, compress and write in a background thread (messages keep their order; a
        write error is raised by the next call or by :meth:`close`).

    """

    def __init__(self, path: str, config: SimConfig, channel_names: Dict[str, Sequence[str]],
                 namespace: str = '/ring_gyro', initial_state=None,
                 publish_clock: bool = False, threaded: bool = True) -> None:
        self.namespace = namespace.rstrip('/') or ''
        self.channel_names = channel_names
        self._path = path
        self.writer = BagWriter(path)
        for name in conversions.OUTPUT_TOPICS:
            self.writer.add_topic(self.topic(name), BLOCK_TYPE)
        self.writer.add_topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')
        self.publish_clock = publish_clock
        if publish_clock:
            self.writer.add_topic('/clock', 'rosgraph_msgs/msg/Clock')
        for name, type_name in INPUT_TOPICS.items():
            self.writer.add_topic(self.topic(name), type_name)
        self._config = config
        self._started = False
        if initial_state is not None:
            self.start(initial_state)
        # Serialising and zstd-compressing 25 MB per simulated second (200 kHz) costs about a
        # quarter of the simulation itself; a writer thread does it while the (GIL-free)
        # kernel runs, on the second core. The bounded queue keeps memory bounded.
        self._failure: Optional[BaseException] = None
        self._queue: 'queue.Queue' = queue.Queue(maxsize=WRITE_QUEUE_DEPTH)
        self._thread: Optional[threading.Thread] = None
        if threaded:
            self._thread = threading.Thread(target=self._drain, name='ring_gyro_recorder',
                                            daemon=True)
            self._thread.start()

    def start(self, initial_state) -> None:
        """Write the metadata record with the run's initial state (q, v) (once)."""
        if self._started:
            return
        self._started = True
        self.writer.add_metadata(METADATA_NAME, {
            'parameters': yaml.safe_dump(to_flat(self._config), sort_keys=True),
            'version': __version__,
            'git_revision': git_revision(),
            'namespace': self.namespace,
            'initial_state': json.dumps({'q': [float(x) for x in initial_state[0]],
                                         'v': [float(x) for x in initial_state[1]]}),
        })

    def discard(self) -> None:
        """Close and delete the file: the run never started (no metadata, no samples)."""
        path = self._path
        try:
            self.close()
        finally:
            try:
                os.remove(path)
            except OSError:
                pass

    def topic(self, name: str) -> str:
        """Full topic name of a node-relative name."""
        return f'{self.namespace}/{name}'

    def __enter__(self) -> 'RunRecorder':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Write what is queued, then finalise the file (summary, indexes). Idempotent."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            self._thread = None
        self.writer.finish()
        self._raise_failure()

    def _write(self, topic: str, msg, t_ns: int) -> None:
        """Queue one message for the writer thread (blocks while the queue is full)."""
        self._raise_failure()
        if self._thread is None:
            self.writer.write(topic, msg, t_ns)
            return
        self._queue.put((topic, msg, t_ns))

    def _drain(self) -> None:
        """Writer thread: serialise, compress and write the queued messages in order."""
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self._failure is not None:
                continue  # keep draining so that producers never block forever
            try:
                self.writer.write(*item)
            except BaseException as exc:  # reported to the caller's thread
                self._failure = exc

    def _raise_failure(self) -> None:
        if self._failure is not None:
            failure, self._failure = self._failure, None
            raise failure

    def outputs(self, blocks: Dict[str, object], t_ns: int) -> None:
        """Record the block messages of one chunk, logged at its last sample time ``t_ns``."""
        for name, msg in blocks.items():
            self._write(self.topic(name), msg, t_ns)

    def diagnostics(self, msg, t_ns: int) -> None:
        """Record a /diagnostics message."""
        self._write('/diagnostics', msg, t_ns)

    def clock(self, t_ns: int) -> None:
        """Record /clock at ``t_ns`` (only when the run publishes it)."""
        if self.publish_clock:
            self._write('/clock', conversions.clock_message(t_ns), t_ns)

    def shock(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Record a shock applied at ``at_ns``."""
        self._write(self.topic('shock'), conversions.shock_message(at_ns, x, y), at_ns)

    def base_acceleration(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Record a base-acceleration sample applied at ``at_ns``."""
        self._write(self.topic('base_acceleration'),
                    conversions.base_acceleration_message(at_ns, x, y), at_ns)

    def drive(self, at_ns: int, amplitude: Optional[float] = None,
              frequency_hz: Optional[float] = None) -> None:
        """Record a drive change applied at ``at_ns``."""
        if amplitude is not None:
            self._write(self.topic('drive/amplitude'),
                        conversions.float_message(amplitude), at_ns)
        if frequency_hz is not None:
            self._write(self.topic('drive/frequency'),
                        conversions.float_message(frequency_hz), at_ns)

    def reset(self, at_ns: int) -> None:
        """Record a reset applied at ``at_ns``."""
        self._write(self.topic('events/reset'), Empty(), at_ns)

    def parameters(self, at_ns: int, changed: Dict[str, object]) -> None:
        """Record parameters changed at run time, applied at ``at_ns``."""
        self._write(self.topic('events/parameters'),
                    String(data=yaml.safe_dump(dict(changed), sort_keys=True)), at_ns)
