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
Memory of a long-running node: whether the RSS of ``ring_gyro_node`` stays flat.

Starts a real ``ring_gyro_node`` in its own process, configured like ``config/demo.yaml``
(drive on, upper branch, paced at ``real_time_factor`` 1, recording to a temporary file, by
default every sample of the block topics: ``record.decimation`` 1, the recording that grows
fastest) but without an end (``duration: 0``), waits until it runs (its start-up log line)
and a warm-up after that, then reads ``VmRSS`` from ``/proc/<pid>/status`` every
``--interval`` seconds for ``--minutes``. It prints the least-squares slope of RSS against
time (kB/s, kB as /proc gives them: 1024 bytes), the growth from the first to the last sample
and the verdict against the target: flat within 5 MB over 10 minutes, i.e. a
slope below 5 * 1024 kB / 600 s = 8.5 kB/s and a measured growth below 5 MB scaled to the run
length.

The node gets a ROS domain of its own (random 215-232, outside Linux's ephemeral ports) and
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, as the node tests do, so that it neither
disturbs nor is disturbed by other sessions. The repository of this file is put first on the
node's ``PYTHONPATH``.

Usage::

    python benchmarks/bench_memory.py                  # 10 min after a 60 s warm-up
    python benchmarks/bench_memory.py --minutes 1 --warmup 20 --json
"""

import argparse
from dataclasses import asdict, dataclass
import json
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import List, Optional, Tuple

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
TARGET_KB = 5 * 1024
"""Growth allowed over ``TARGET_S`` (the target: flat within 5 MB over 10 minutes), kB."""
TARGET_S = 600.0
"""The time over which ``TARGET_KB`` is allowed, s."""
MAX_SLOPE_KB_S = TARGET_KB / TARGET_S
"""The slope that reaches ``TARGET_KB`` in ``TARGET_S``: 8.53 kB/s."""
STARTED_MARKER = 'simulating '
"""Start of the node's log line once its start state is computed and its timers run."""
START_TIMEOUT_S = 120.0
"""Start-up allowed (imports, compiled kernels, upper-branch orbit), generously."""

PARAMS = """\
ring_gyro:
  ros__parameters:
    drive:
      amplitude: 0.065
      frequency: 15798.6
      start_on: upper_branch
    real_time_factor: 1.0
    duration: 0.0
    output:
      rate: {rate!r}
      block_duration: 0.01
    record:
      path: '{record}'
      decimation: {decimation}
    scenario:
      shock_times: [0.5]
      shock_peaks: [98066.5]
"""
"""demo.yaml with no end (duration 0) and the recording in a temporary directory."""


@dataclass
class MemoryResult:
    """What one measurement found (times in s from the first sample, RSS in kB)."""

    times_s: List[float]
    rss_kb: List[int]
    slope_kb_s: float
    growth_kb: int
    warmup_s: float
    node_exit: Optional[int]

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample, s."""
        return self.times_s[-1] - self.times_s[0] if self.times_s else 0.0

    @property
    def flat(self) -> bool:
        """Whether the slope and the growth (scaled to the run) meet the 5 MB / 10 min target."""
        allowed = TARGET_KB * max(self.duration_s, 1.0) / TARGET_S
        return self.slope_kb_s < MAX_SLOPE_KB_S and self.growth_kb < max(allowed, 1024)

    def verdict(self) -> str:
        """One line: slope, growth, projection to 10 minutes and FLAT / GROWS."""
        projected = self.slope_kb_s * TARGET_S / 1024
        return (f'RSS slope {self.slope_kb_s:.2f} kB/s over {self.duration_s:.0f} s '
                f'({len(self.rss_kb)} samples after a {self.warmup_s:.0f} s warm-up), growth '
                f'{self.growth_kb / 1024:.2f} MB ({self.rss_kb[0] / 1024:.1f} -> '
                f'{self.rss_kb[-1] / 1024:.1f} MB), {projected:.1f} MB per 10 min: '
                + ('FLAT' if self.flat else 'GROWS')
                + f' (target: flat within {TARGET_KB / 1024:g} MB over '
                  f'{TARGET_S / 60:g} min, slope < {MAX_SLOPE_KB_S:.2f} kB/s)')


def least_squares_slope(times: List[float], values: List[float]) -> float:
    """Return the least-squares slope of ``values`` against ``times`` (0 for < 2 points)."""
    n = len(times)
    if n < 2:
        return 0.0
    mt = sum(times) / n
    mv = sum(values) / n
    sxx = sum((t - mt) ** 2 for t in times)
    sxy = sum((t - mt) * (v - mv) for t, v in zip(times, values))
    return sxy / sxx if sxx > 0.0 else 0.0


def rss_kb(pid: int) -> int:
    """Return ``VmRSS`` of process ``pid`` in kB (from ``/proc/<pid>/status``)."""
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1])
    raise RuntimeError(f'no VmRSS in /proc/{pid}/status')


def node_command(params_file: str) -> List[str]:
    """Return the node's command line: the installed executable, else ``python -m``."""
    exe = shutil.which('ring_gyro_node') or str(pathlib.Path(sys.executable).parent /
                                                'ring_gyro_node')
    head = [exe] if os.path.exists(exe) else [sys.executable, '-m', 'ring_gyro_sim.ros.node']
    return head + ['--ros-args', '--params-file', params_file]


def node_env(domain_id: int) -> dict:
    """Return the node's environment: own domain, localhost discovery, this repo first."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    env['PYTHONUNBUFFERED'] = '1'
    return env


class _Log:
    """Collect the node's stderr in a thread; tell when the start-up line was seen."""

    def __init__(self, stream):
        self.lines: List[str] = []
        self.started = threading.Event()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        for raw in stream:
            line = raw.decode(errors='replace')
            self.lines.append(line)
            if STARTED_MARKER in line:
                self.started.set()

    def tail(self, n: int = 20) -> str:
        return ''.join(self.lines[-n:])


def measure(minutes: float = 10.0, warmup_s: float = 60.0, interval_s: float = 5.0,
            output_rate: float = 200000.0, record: bool = True, verbose: bool = True,
            domain_id: Optional[int] = None, decimation: int = 1) -> MemoryResult:
    """
    Run a node and sample its RSS; see the module docstring.

    Parameters
    ----------
    minutes : float
        Sampling time after the warm-up, min.
    warmup_s : float
        Wait after the node's start-up line before the first sample, s.
    interval_s : float
        Time between samples, s.
    output_rate : float
        ``output.rate`` of the node, Hz (demo.yaml: 200 kHz). Blocks stay 10 ms, so the
        executor wakes as often at any rate.
    record : bool
        Record to a temporary file (deleted afterwards).
    verbose : bool
        Print each sample on stderr.
    domain_id : int, optional
        ROS domain of the node (default: random 215-232).
    decimation : int
        ``record.decimation`` of the recording (default 1: every sample).

    Returns
    -------
    MemoryResult
        The samples and their slope.

    """
    if domain_id is None:
        domain_id = random.SystemRandom().randrange(215, 233)
    with tempfile.TemporaryDirectory(prefix='bench_memory_') as tmp:
        params = pathlib.Path(tmp) / 'params.yaml'
        params.write_text(PARAMS.format(
            rate=float(output_rate), record=str(pathlib.Path(tmp) / 'run.mcap') if record
            else '', decimation=int(decimation)))
        proc = subprocess.Popen(node_command(str(params)), env=node_env(domain_id),
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        log = _Log(proc.stderr)
        try:
            times, values = _sample(proc, log, minutes, warmup_s, interval_s, verbose)
        finally:
            code = _stop(proc)
    slope = least_squares_slope(times, [float(v) for v in values])
    return MemoryResult(times_s=times, rss_kb=values, slope_kb_s=slope,
                        growth_kb=values[-1] - values[0], warmup_s=warmup_s, node_exit=code)


def _sample(proc, log, minutes, warmup_s, interval_s, verbose) -> Tuple[List[float], List[int]]:
    end = time.monotonic() + START_TIMEOUT_S
    while not log.started.wait(0.2):
        if proc.poll() is not None or time.monotonic() > end:
            raise RuntimeError(f'the node did not start (exit code {proc.poll()}):\n'
                               f'{log.tail()}')
    t0 = time.monotonic() + warmup_s
    count = max(2, int(round(minutes * 60.0 / interval_s)) + 1)
    times: List[float] = []
    values: List[int] = []
    for i in range(count):
        due = t0 + i * interval_s
        time.sleep(max(0.0, due - time.monotonic()))
        if proc.poll() is not None:
            raise RuntimeError(f'the node ended early (exit code {proc.returncode}):\n'
                               f'{log.tail()}')
        values.append(rss_kb(proc.pid))
        times.append(time.monotonic() - t0)
        if verbose:
            print(f'  t = {times[-1]:6.1f} s  RSS {values[-1] / 1024:8.2f} MB', file=sys.stderr,
                  flush=True)
    return times, values


def _stop(proc) -> Optional[int]:
    """SIGINT the node (it finalises its recording) and return its exit code."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point; exit code 0 when flat, 1 when the RSS grows."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    p.add_argument('--minutes', type=float, default=10.0,
                   help='sampling time after the warm-up, min (default 10)')
    p.add_argument('--warmup', type=float, default=60.0,
                   help='wait after start-up before sampling, s (default 60)')
    p.add_argument('--interval', type=float, default=5.0,
                   help='time between samples, s (default 5)')
    p.add_argument('--output-rate', type=float, default=200000.0,
                   help='output.rate of the node, Hz (default 200000, as demo.yaml)')
    p.add_argument('--no-record', action='store_true', help='do not record')
    p.add_argument('--decimation', type=int, default=1,
                   help='record.decimation of the recording (default 1: every sample)')
    p.add_argument('--json', action='store_true', help='also print the result as JSON')
    args = p.parse_args(argv)
    result = measure(args.minutes, args.warmup, args.interval, args.output_rate,
                     record=not args.no_record, decimation=args.decimation)
    print(result.verdict())
    if args.json:
        print(json.dumps({**asdict(result), 'duration_s': result.duration_s,
                          'flat': result.flat}))
    return 0 if result.flat else 1


if __name__ == '__main__':
    sys.exit(main())
