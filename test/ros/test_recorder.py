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

"""Tests of ``ring_gyro_sim.ros.recorder``: the run recorder and its writer thread."""

import numpy as np
import pytest
from ring_gyro_sim.core.params import build_config, STANDARD_GRAVITY
from ring_gyro_sim.core.simulator import Simulator
from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.recording.reader import decode, read_messages
from ring_gyro_sim.ros import conversions
from ring_gyro_sim.ros.recorder import RunRecorder


def record(path, threaded):
    config = build_config({'drive.start_on': 'rest', 'output.rate': 100000.0})
    sim = Simulator(config)
    with RunRecorder(str(path), config, sim.channel_names, threaded=threaded) as rec:
        rec.shock(1_000_000, 2000 * STANDARD_GRAVITY)
        sim.shock(2000 * STANDARD_GRAVITY, at_ns=1_000_000)
        for _ in range(12):
            samples = sim.advance(0.005)
            rec.outputs(conversions.output_blocks(samples, sim.channel_names), sim.time_ns)
            rec.drive(sim.time_ns, amplitude=0.01)
    return [(m.topic, m.log_time_ns, m.type_name, decode(m)) for m in read_messages(path)]


def test_threaded_recording_equals_the_direct_one(tmp_path):
    direct = record(tmp_path / 'direct.mcap', threaded=False)
    threaded = record(tmp_path / 'threaded.mcap', threaded=True)
    assert len(threaded) == len(direct) == 1 + 12 * 4
    for a, b in zip(direct, threaded):
        assert a[:3] == b[:3]
        if a[2] == 'std_msgs/msg/Float64MultiArray':
            assert np.array_equal(np.asarray(a[3].data), np.asarray(b[3].data))
            assert a[3].layout == b[3].layout
        else:
            assert a[3] == b[3]


def test_a_write_error_in_the_thread_reaches_the_caller(tmp_path):
    config = build_config({})
    rec = RunRecorder(str(tmp_path / 'x.mcap'), config, Simulator(config).channel_names)
    rec._write('/not/a/registered/topic', conversions.float_message(1.0), 0)
    with pytest.raises(RecordingError):
        rec.close()
    rec.close()  # idempotent once the error was reported
    assert (tmp_path / 'x.mcap').read_bytes().endswith(b'\x89MCAP0\r\n')
