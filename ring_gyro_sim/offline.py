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
Offline runs: a scenario file in, samples (and optionally a recording) out, no ROS graph.

:func:`run_offline` advances the same :class:`~ring_gyro_sim.core.simulator.Simulator` as the
node, in the node's blocks (``output.block_duration``), as fast as possible, and returns a
:class:`RunSummary`. With an output path it records exactly what the node would (same topic
names, scheduled shocks recorded on ``<ns>/shock`` at their times). :func:`resimulate` re-runs
a recording from its metadata and recorded inputs and reproduces its output blocks bit for bit.
"""

from dataclasses import asdict, dataclass, field
import json
import math
import sys
import time
from typing import Dict, List, Optional, Tuple

import numpy as np

from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.core.simulator import Samples, Simulator

FINAL_WINDOW_S = 0.01
"""The final amplitude is max |x| over the last 10 ms."""


@dataclass
class RunSummary:
    """Numbers of one run (SI units; ``*_m`` in metres)."""

    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    peak_abs_m: Dict[str, float]
    final_abs_m: Dict[str, float]
    min_gap_m: float
    contact: bool
    status: str
    message: str
    samples: int
    steps: int
    output: Optional[str] = None
    extra: Dict[str, float] = field(default_factory=dict)

    def to_json(self) -> str:
        """One JSON object."""
        return json.dumps(asdict(self), sort_keys=True)


class _Tracker:
    """Running peaks, smallest gap and the last 10 ms of every coordinate."""

    def __init__(self, names: List[str], period_s: float) -> None:
        self.names = names
        self.peak = np.zeros(len(names))
        self.min_gap = math.inf
        self.keep = max(1, int(round(FINAL_WINDOW_S / period_s)))
        self.tail = np.zeros((0, len(names)))

    def add(self, s: Samples) -> None:
        if len(s) == 0:
            return
        self.peak = np.maximum(self.peak, np.max(np.abs(s.q), axis=0))
        self.min_gap = min(self.min_gap, float(np.min(s.min_gap)))
        self.tail = np.concatenate([self.tail, s.q])[-self.keep:]

    def final(self) -> Dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, np.max(np.abs(self.tail), axis=0))}


class _Progress:
    """A one-line progress bar on stderr for runs longer than a few seconds of wall time."""

    def __init__(self, total_s: float, enabled: bool) -> None:
        self.total = total_s
        self.enabled = enabled
        self.start = time.monotonic()
        self.last = -math.inf  # the first line as soon as the run passes 2 s
        self.tty = sys.stderr.isatty()
        self.shown = False

    def update(self, sim_s: float, force: bool = False) -> None:
        now = time.monotonic()
        if not self.enabled or (now - self.start < 2.0 and not force):
            return
        if now - self.last < (0.5 if self.tty else 5.0) and not force:
            return
        self.last = now
        frac = min(1.0, sim_s / self.total) if self.total > 0 else 1.0
        elapsed = now - self.start
        eta = elapsed * (1.0 - frac) / frac if frac > 0 else math.inf
        bar = '#' * int(30 * frac)
        line = (f'[{bar:<30}] {100 * frac:5.1f}%  sim {sim_s:.3f}/{self.total:.3f} s  '
                f'x{sim_s / max(elapsed, 1e-9):.2f} real time  eta {eta:.0f} s')
        sys.stderr.write(('\r' + line) if self.tty else (line + '\n'))
        sys.stderr.flush()
        self.shown = True

    def close(self, sim_s: float) -> None:
        if self.shown:
            self.update(sim_s, force=True)
            if self.tty:
                sys.stderr.write('\n')


def initial_state(config: SimConfig) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """Return the start state for ``drive.start_on`` (None = rest)."""
    from ring_gyro_sim.analysis.nnm import drive_initial_state
    return drive_initial_state(config)


def run_offline(config: SimConfig, duration_s: Optional[float] = None,
                output: Optional[str] = None, progress: bool = True,
                namespace: str = '/ring_gyro', start_state=None,
                inputs: Optional[list] = None, block_sizes: Optional[List[int]] = None
                ) -> RunSummary:
    """
    Run a scenario as fast as possible.

    Parameters
    ----------
    config : SimConfig
        Scenario (``scenario.*`` shocks are scheduled).
    duration_s : float, optional
        Simulated time, s (default ``config.run.duration``, which must then be > 0).
    output : str, optional
        MCAP file to record to.
    progress : bool
        Show a progress bar on stderr when the run takes more than 2 s of wall time.
    start_state : (q, v), optional
        Initial state; default from ``drive.start_on``.
    inputs : list, optional
        Recorded inputs ``(t_ns, kind, payload)`` to apply (re-simulation).
    block_sizes : list of int, optional
        Samples per recorded block (re-simulation: the same cuts as the original).
    namespace : str
        Node namespace written into the recorded topic names and metadata.

    """
    duration = config.run.duration if duration_s is None else duration_s
    if not (math.isfinite(duration) and duration > 0.0):
        raise ParameterError('duration: must be > 0 for an offline run (or pass --duration)')
    sim = Simulator(config)
    state = initial_state(config) if start_state is None else start_state
    if state is not None:
        sim.set_state(*state)
    n_total = int(round(duration / sim.period_s))
    block = max(1, int(round(config.run.block_duration / sim.period_s)))
    recorder = None
    if output:
        from ring_gyro_sim.ros import conversions
        from ring_gyro_sim.ros.recorder import RunRecorder
        recorder = RunRecorder(output, config, sim.channel_names, namespace, state,
                               config.run.publish_clock)
    try:
        if recorder is not None:
            for t_s, peak in zip(config.run.shock_times, config.run.shock_peaks):
                recorder.shock(int(round(t_s * 1e9)), peak, 0.0)
        for item in inputs or []:
            _apply_input(sim, recorder, *item)
        tracker = _Tracker(sim.coordinates, sim.period_s)
        bar = _Progress(duration, progress)
        wall0 = time.perf_counter()
        done = 0
        sizes = list(block_sizes) if block_sizes is not None else None
        next_diag_ns = 1_000_000_000
        while done < n_total:
            size = sizes.pop(0) if sizes else min(block, n_total - done)
            samples = sim.advance_samples(size)
            done += size
            tracker.add(samples)
            if recorder is not None:
                t_ns = sim.time_ns
                recorder.outputs(conversions.output_blocks(samples, sim.channel_names), t_ns)
                recorder.clock(t_ns)
                if t_ns >= next_diag_ns or done >= n_total:
                    next_diag_ns += 1_000_000_000
                    recorder.diagnostics(_diagnostics(sim, tracker, wall0), t_ns)
            bar.update(sim.time_s)
        wall = time.perf_counter() - wall0
        bar.close(sim.time_s)
    finally:
        if recorder is not None:
            recorder.close()
    return RunSummary(
        sim_time_s=sim.time_s, wall_time_s=wall,
        real_time_factor=sim.time_s / wall if wall > 0 else math.inf,
        peak_abs_m={n: float(v) for n, v in zip(sim.coordinates, tracker.peak)},
        final_abs_m=tracker.final(), min_gap_m=tracker.min_gap,
        contact=sim.status != 'running', status=sim.status, message=sim.message,
        samples=done, steps=sim.steps_taken, output=output)


def _diagnostics(sim: Simulator, tracker: _Tracker, wall0: float):
    from ring_gyro_sim.ros import conversions
    wall = time.perf_counter() - wall0
    level = 'OK' if sim.status == 'running' else 'ERROR'
    return conversions.diagnostics_message(
        sim.time_ns, 'ring_gyro: simulator', 'ring_gyro_sim', level,
        sim.message or 'offline run',
        {'sim_time_s': sim.time_s, 'real_time_factor_target': 0.0,
         'real_time_factor_achieved': sim.time_s / wall if wall > 0 else 0.0,
         'lag_s': 0.0, 'steps': sim.steps_taken,
         'min_gap_ratio': tracker.min_gap / sim.model.gap, 'contact': sim.status != 'running',
         'rejected_inputs': 0})


def _apply_input(sim: Simulator, recorder, t_ns: int, kind: str, payload) -> None:
    """Apply (and record) one recorded input at its simulation time."""
    if kind == 'shock':
        sim.shock(payload[0], payload[1], at_ns=t_ns)
        if recorder is not None:
            recorder.shock(t_ns, payload[0], payload[1])
    elif kind == 'base_acceleration':
        sim.add_base_acceleration(t_ns, payload[0], payload[1])
        if recorder is not None:
            recorder.base_acceleration(t_ns, payload[0], payload[1])
    elif kind == 'drive/amplitude':
        sim.set_drive(amplitude=payload, at_ns=t_ns)
        if recorder is not None:
            recorder.drive(t_ns, amplitude=payload)
    elif kind == 'drive/frequency':
        sim.set_drive(frequency_hz=payload, at_ns=t_ns)
        if recorder is not None:
            recorder.drive(t_ns, frequency_hz=payload)
    elif kind == 'events/reset':
        sim.reset(at_ns=t_ns)
        if recorder is not None:
            recorder.reset(t_ns)
    elif kind == 'events/parameters':
        sim.update_parameters(payload, at_ns=t_ns)
        if recorder is not None:
            recorder.parameters(t_ns, payload)


def load_recording(path: str):
    """
    Parameters, initial state, inputs and block sizes of a recording (for re-simulation).

    Returns
    -------
    (SimConfig, (q, v), inputs, block_sizes, namespace)

    """
    from ring_gyro_sim.core.params import build_config
    from ring_gyro_sim.paramfile import load_text
    from ring_gyro_sim.recording.reader import decode, read_messages, read_metadata
    from ring_gyro_sim.ros import conversions
    from ring_gyro_sim.ros.recorder import INPUT_TOPICS, METADATA_NAME

    meta = read_metadata(path, METADATA_NAME)
    flat = load_text(meta['parameters'])
    config = build_config(flat)
    state = json.loads(meta['initial_state'])
    namespace = meta.get('namespace', '/ring_gyro')
    start = (np.array(state['q'], dtype=np.float64), np.array(state['v'], dtype=np.float64))
    inputs = []
    sizes = []
    block_topic = f'{namespace}/modal_displacement'
    wanted = {f'{namespace}/{name}': name for name in INPUT_TOPICS}
    scheduled = {(int(round(t * 1e9)), float(p)) for t, p in
                 zip(config.run.shock_times, config.run.shock_peaks)}
    for m in read_messages(path, topics=list(wanted) + [block_topic]):
        if m.topic == block_topic:
            sizes.append(decode(m).layout.dim[0].size)
            continue
        kind = wanted[m.topic]
        msg = decode(m)
        if kind == 'shock':
            s = conversions.shock_input(msg)
            t_ns = m.log_time_ns
            if (t_ns, s.x) in scheduled and s.y == 0.0:
                scheduled.discard((t_ns, s.x))  # the Simulator schedules these itself
                continue
            inputs.append((t_ns, kind, (s.x, s.y)))
        elif kind == 'base_acceleration':
            a = conversions.base_acceleration_input(msg)
            inputs.append((m.log_time_ns, kind, (a.x, a.y)))
        elif kind in ('drive/amplitude', 'drive/frequency'):
            inputs.append((m.log_time_ns, kind, float(msg.data)))
        elif kind == 'events/reset':
            inputs.append((m.log_time_ns, kind, None))
        elif kind == 'events/parameters':
            inputs.append((m.log_time_ns, kind, load_text(msg.data)))
    return config, start, inputs, sizes, namespace


def resimulate(path: str, output: Optional[str] = None, progress: bool = True) -> RunSummary:
    """Re-run a recording from its parameters and inputs (outputs identical bit for bit)."""
    config, start, inputs, sizes, namespace = load_recording(path)
    total = sum(sizes)
    duration = total * config.run.output_period_ns * 1e-9
    return run_offline(config, duration, output=output, progress=progress,
                       namespace=namespace, start_state=start, inputs=inputs,
                       block_sizes=sizes)
