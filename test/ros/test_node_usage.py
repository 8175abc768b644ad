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

"""``ring_gyro_node -h`` prints its usage and does not start the node."""

from pathlib import Path
import subprocess
import sys

import pytest
import rclpy
from ring_gyro_sim.ros import node

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize('flag', ['-h', '--help'])
def test_help_prints_the_usage_without_starting_rclpy(monkeypatch, capsys, flag):
    def no_init(*args, **kwargs):
        raise AssertionError('rclpy.init called for --help')
    monkeypatch.setattr(rclpy, 'init', no_init)
    assert node.main(['ring_gyro_node', flag]) == 0
    out = capsys.readouterr().out
    assert out.startswith('usage: ring_gyro_node ') and '--params-file FILE' in out
    assert '-r __node:=NAME' in out and 'doc/interface.md' in out


def test_help_among_the_ros_arguments_is_not_ours():
    assert node.asks_for_help(['n', '--ros-args', '-p', 'duration:=1.0', '--', '-h'])
    assert not node.asks_for_help(['n', '--ros-args', '--help'])  # rcl's, not the node's
    assert not node.asks_for_help(['n', '--ros-args', '--params-file', 'f.yaml'])


def test_the_executable_answers_help_at_once():
    # before: `ring_gyro_node --help` started the simulation and ran until Ctrl-C
    result = subprocess.run([sys.executable, '-m', 'ring_gyro_sim.ros.node', '--help'],
                            env={'PYTHONPATH': str(REPO), 'PATH': '/usr/bin:/bin'},
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith('usage: ring_gyro_node') and result.stderr == ''
