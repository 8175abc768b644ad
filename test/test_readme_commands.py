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
The README's commands work as written.

Every command line of the README's ``sh`` blocks is either run here, in README order, from a
directory holding a copy of ``config/`` (as a user runs it from the repository's top,
``.venv`` activated), or listed in :data:`NOT_RUN` with the reason: a command added to the
README fails :func:`test_every_readme_command_is_run_or_says_why_not` until it is placed.
The executables are the ones beside this interpreter (``.venv/bin``, what
``source .venv/bin/activate`` puts on PATH).
"""

import os
from pathlib import Path
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time

import pytest
import ros_domains

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent

NOT_RUN = {
    'make run': 'the node for 8 s paced: test/ros runs the node; make is the setup',
    'make test': 'this suite',
    'make test-ci': 'this suite with the end-to-end runs (this test is one of them)',
    'source .venv/bin/activate': 'the shell setting up PATH (this test calls .venv/bin)',
    'ring_gyro calibrate': '~70 s of shooting (test/analysis/test_nnm.py calibrates)',
    'ring_gyro report --out out/report --quick': '~1 min on 2 cores (test/analysis, sweep)',
    'ring_gyro report --out out/report': '~20 min (make test-all: the slow paper cases)',
    'ring_gyro sweep config/sweep_case4.yaml --out out/case4': 'six 30 s cases '
    '(test/sweep/test_case4.py runs its short form)',
    'ring_gyro characterize config/default.yaml --out out/datasheet': '~10 min '
    '(test/test_characterize.py runs --quick)',
}
"""Commands not run here, by their text in the README, and why."""

WAIT_S = 120.0
"""Longest a command may take here (the slowest measured ~10 s)."""


def readme_commands():
    """Return the command lines of the README's ``sh`` blocks, comments stripped, in order."""
    text = (REPO / 'README.md').read_text(encoding='utf-8')
    commands = []
    for block in re.findall(r'```sh\n(.*?)```', text, flags=re.S):
        for line in block.splitlines():
            line = re.sub(r'\s+#.*$', '', line).strip()
            if line and not line.startswith('#'):
                commands.append(line)
    return commands


def test_every_readme_command_is_run_or_says_why_not():
    commands = readme_commands()
    assert 'ring_gyro_node' in commands and len(commands) >= 15
    assert not [c for c in commands if c.startswith(('ring_gyro', 'make', 'source')) is False]
    assert set(NOT_RUN) <= set(commands), set(NOT_RUN) - set(commands)


def _env():
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(ros_domains.claim('README commands'))
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['PATH'] = os.pathsep.join([str(BIN), env.get('PATH', '')])
    env['PYTHONUNBUFFERED'] = '1'
    return env


def _argv(command):
    words = shlex.split(command)
    exe = BIN / words[0]
    assert exe.is_file(), f'{exe}: not installed (pip install -e .)'
    return [str(exe)] + words[1:]


def _run(command, cwd, env):
    """Run a command to its end; return its output. A live node is stopped with SIGINT."""
    live = command == 'ring_gyro_node'  # runs until shut down
    with open(cwd / 'log.txt', 'w+b') as log:
        proc = subprocess.Popen(_argv(command), cwd=cwd, env=env, stdout=log,
                                stderr=subprocess.STDOUT)
        try:
            if live:
                end = time.monotonic() + WAIT_S
                while b'simulating' not in (cwd / 'log.txt').read_bytes():
                    assert proc.poll() is None and time.monotonic() < end, \
                        (cwd / 'log.txt').read_text()
                    time.sleep(0.2)
                time.sleep(2.0)
                proc.send_signal(signal.SIGINT)
            code = proc.wait(timeout=WAIT_S)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        log.seek(0)
        output = log.read().decode(errors='replace')
    assert code == 0, f'{command}: exit {code}\n{output[-3000:]}'
    return output


@pytest.mark.ci
def test_the_readme_commands_run_as_written(tmp_path):
    shutil.copytree(REPO / 'config', tmp_path / 'config')
    env = _env()
    ran = []
    for command in readme_commands():
        if command in NOT_RUN:
            continue
        if command.startswith('ring_gyro recover out/killed.mcap'):
            # a killed recording: the first two thirds of one (every completed chunk kept)
            data = (tmp_path / 'out' / 'run.mcap').read_bytes()
            (tmp_path / 'out' / 'killed.mcap').write_bytes(data[:2 * len(data) // 3])
        output = _run(command, tmp_path, env)
        ran.append(command)
        if command == 'ring_gyro_node':
            assert 'q2s' in output and 'stopped' in output  # the gyroscope, ended by Ctrl-C
        if '__node:=gyro_left' in command:
            assert '[gyro_left]' in output and 'duration reached: 5.000000 s' in output
    assert (tmp_path / 'out' / 'run' / 'rate.png').is_file()
    assert (tmp_path / 'out' / 'again.mcap').is_file()
    assert (tmp_path / 'out' / 'backbone.png').is_file()
    print(f'{len(ran)} README commands run')
    assert len(ran) >= 10


@pytest.mark.ci
def test_the_readme_example_output_is_what_the_demo_simulates():
    # The simulated part of the example (after the wall time and the core's share, which
    # depend on the machine) is the demo's summary as printed, to its last digit: the demo's
    # parameters run offline, unpaced and unrecorded, give the same numbers as the node.
    from ring_gyro_sim.core.params import build_config, to_flat
    from ring_gyro_sim.paramfile import load_yaml
    from ring_gyro_sim.run import Run
    text = (REPO / 'README.md').read_text(encoding='utf-8')
    block = re.search(r'```\n(\[INFO\].*?)```', text, flags=re.S).group(1)
    line = ' '.join(block.split())
    example = re.search(r'duration reached: .*? of a core; (.*); recorded to out/demo\.mcap',
                        line).group(1)
    flat = to_flat(load_yaml(str(REPO / 'config' / 'demo.yaml')))
    config = build_config({**flat, 'record.path': '', 'real_time_factor': 0.0})
    run = Run(config)
    block_samples = int(round(config.run.block_duration * config.run.output_rate))
    total = int(round(config.run.duration * config.run.output_rate))
    while run.sample_index < total and run.running:
        run.advance(min(block_samples, total - run.sample_index))
    assert example == run.summary_text()
