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

:func:`run_offline` drives the one run path (:class:`~ring_gyro_sim.run.Run`) with a plain
loop, in the node's blocks (``output.block_duration``), as fast as possible, and returns a
:class:`~ring_gyro_sim.run.RunSummary`. With an output path it records exactly what the node
would (the same topic names, scheduled shocks on ``<ns>/shock`` at their times, the same
diagnostics keys about once per simulated second; with ``gyro.enabled`` also ``<ns>/rate``,
``<ns>/demodulator`` and the rates that acted on ``<ns>/angular_rate``; with
a closed ``control.mode`` the loops' updates on ``<ns>/control``). :func:`resimulate`
re-runs a recording from its metadata and recorded inputs (angular rates included) and
reproduces its outputs bit for bit, whatever the recording kept of them: with
``decimation=1`` a recording of every N-th sample (``record.decimation``) gives every sample
again.
"""

from dataclasses import replace
import json
import math
from typing import Any, Callable, List, Optional, Sequence

import numpy as np

from ring_gyro_sim.core.engine.full import channel_names
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro.calibration import Calibration
from ring_gyro_sim.core.params import build_config, SimConfig, to_flat, upgraded
from ring_gyro_sim.paramfile import load_text
from ring_gyro_sim.progress import Progress
from ring_gyro_sim.recording.reader import (block_sample_counts, decode, read_messages,
                                            read_metadata)
from ring_gyro_sim.ros import conversions
from ring_gyro_sim.ros.recorder import INPUT_TOPICS, METADATA_NAME, RunRecorder
from ring_gyro_sim.ros.sinks import RosSink
from ring_gyro_sim.run import (AmbientTemperature, AngularRate, BaseAcceleration,
                               DriveAmplitude, DriveFrequency, Input, NullSink, Pacing,
                               ParameterChange, Reset, Run, RunSummary, Shock, Sink)

__all__ = ['DIAGNOSTICS_PERIOD_NS', 'RunSummary', 'load_recording', 'recorded_calibration',
           'resimulate', 'run_offline', 'with_record_decimation']

DIAGNOSTICS_PERIOD_NS = 1_000_000_000
"""An offline recording gets a diagnostics snapshot every simulated second (and at the end)."""


def with_record_decimation(config: SimConfig, decimation: Optional[int]) -> SimConfig:
    """
    Return ``config`` with ``record.decimation`` set to ``decimation`` (None: unchanged).

    Raises
    ------
    ParameterError
        If ``decimation`` is not a valid ``record.decimation`` (the message names it).

    """
    if decimation is None:
        return config
    return build_config({**to_flat(config), 'record.decimation': decimation})


def run_offline(config: SimConfig, duration_s: Optional[float] = None,
                output: Optional[str] = None, progress: bool = True,
                namespace: str = '/ring_gyro', start_state=None,
                inputs: Sequence[Input] = (), block_sizes: Optional[List[int]] = None,
                overwrite: Optional[bool] = None,
                log: Optional[Callable[[str], None]] = None,
                calibration: Any = 'auto') -> RunSummary:
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
    namespace : str
        Node namespace written into the recorded topic names and metadata.
    start_state : (q, v), optional
        Initial state (a recording's); default: the run starts itself (``drive.start_on``).
    inputs : sequence of Input
        Inputs with their acting times (``at_ns``), e.g. a recording's (re-simulation). Each
        is applied before the block that holds its time, as the node applied it.
    block_sizes : list of int, optional
        Samples per block (re-simulation: the same cuts as the original).
    overwrite : bool, optional
        Replace an existing ``output`` (default: ``record.overwrite`` of the configuration).
    log : callable, optional
        Told, one line each, what takes a while before the first block (computing the start
        state of ``drive.start_on``: seconds, silent otherwise), as the node logs it.
    calibration : Calibration, None or 'auto'
        The rate output's held calibration (a recording's); ``'auto'``: as ``Run``.

    """
    duration = config.run.duration if duration_s is None else duration_s
    if not (math.isfinite(duration) and duration > 0.0):
        raise ParameterError('duration: must be > 0 for an offline run (or pass --duration)')
    if overwrite is not None:
        config = replace(config, run=replace(config.run, record_overwrite=bool(overwrite)))
    period_s = config.run.output_period_ns * 1e-9
    n_total = int(round(duration / period_s))
    if block_sizes is None:
        block = max(1, int(round(config.run.block_duration / period_s)))
        block_sizes = [block] * (n_total // block) + ([n_total % block] if n_total % block else [])
    sink: Sink = NullSink()
    if output:
        names = channel_names(config)
        sink = RosSink(names, namespace, recorder=RunRecorder(
            output, config, names, namespace, publish_clock=config.run.publish_clock),
            frame_id=config.gyro.frame_id)
    try:
        run = Run(config, start_state=start_state, sink=sink, log=log,
                  calibration=calibration)
    except BaseException:
        sink.discard()
        raise
    try:
        pending = sorted(inputs, key=lambda e: e.at_ns)[::-1]  # a stack, earliest last
        bar = Progress(duration, progress)
        next_diag_ns = DIAGNOSTICS_PERIOD_NS
        for i, size in enumerate(block_sizes):
            end_ns = run.time_ns + size * config.run.output_period_ns
            while pending and pending[-1].at_ns < end_ns:
                run.apply(pending.pop())
            run.advance(size)
            last = i == len(block_sizes) - 1
            if run.time_ns >= next_diag_ns or last:
                next_diag_ns += DIAGNOSTICS_PERIOD_NS
                run.diagnostics(_pacing(run), finished=last)
            bar.update(run.time_s)
        bar.close()
        return run.summary(output)
    finally:
        run.close()


def _pacing(run: Run) -> Pacing:
    wall = run.wall_time_s()
    rtf = run.time_s / wall if wall > 0 else 0.0
    return Pacing(target=0.0, achieved=rtf, average=rtf)


def load_recording(path: str):
    """
    Parameters, initial state, inputs and block sizes of a recording (for re-simulation).

    Returns
    -------
    (SimConfig, (q, v), inputs, block_sizes, namespace)

    """
    meta = read_metadata(path, METADATA_NAME)
    config = build_config(upgraded(load_text(meta['parameters'])))
    state = json.loads(meta['initial_state'])
    namespace = meta.get('namespace', '/ring_gyro')
    start = (np.array(state['q'], dtype=np.float64), np.array(state['v'], dtype=np.float64))
    inputs: List[Input] = []
    sizes = block_sample_counts(path)
    wanted = {f'{namespace}/{name}': name for name in INPUT_TOPICS}
    scheduled = set(config.run.scheduled_shocks())
    # Knots of scenario.rate_*, should the run record them on angular_rate as it records the
    # scheduled shocks: the configuration schedules them again.
    knots = [(int(round(t_s * 1e9)), float(z))
             for t_s, z in zip(config.run.rate_times, config.run.rate_values)]
    for m in read_messages(path, topics=list(wanted)):
        kind = wanted[m.topic]
        msg = decode(m)
        t_ns = m.log_time_ns
        if kind == 'shock':
            s = conversions.shock_input(msg)
            if (t_ns, s.x, s.y) in scheduled:
                scheduled.discard((t_ns, s.x, s.y))  # the Simulator schedules these itself
                continue
            inputs.append(Shock(x=s.x, y=s.y, at_ns=t_ns))
        elif kind == 'base_acceleration':
            a = conversions.base_acceleration_input(msg)
            inputs.append(BaseAcceleration(x=a.x, y=a.y, at_ns=t_ns))
        elif kind == 'drive/amplitude':
            inputs.append(DriveAmplitude(float(msg.data), at_ns=t_ns))
        elif kind == 'drive/frequency':
            inputs.append(DriveFrequency(float(msg.data), at_ns=t_ns))
        elif kind == 'events/reset':
            inputs.append(Reset(at_ns=t_ns))
        elif kind == 'events/parameters':
            inputs.append(ParameterChange(load_text(msg.data), at_ns=t_ns))
        elif kind == conversions.ANGULAR_RATE_TOPIC:
            r = conversions.angular_rate_input(msg)
            if (t_ns, r.z) in knots:
                knots.remove((t_ns, r.z))
                continue
            inputs.append(AngularRate(z=r.z, x=r.x, y=r.y, at_ns=t_ns))
        elif kind == conversions.TEMPERATURE_TOPIC:
            inputs.append(AmbientTemperature(conversions.temperature_input(msg).kelvin,
                                             at_ns=t_ns))
    return config, start, inputs, sizes, namespace


def resimulate(path: str, output: Optional[str] = None, progress: bool = True,
               overwrite: Optional[bool] = None,
               decimation: Optional[int] = None) -> RunSummary:
    """
    Re-run a recording from its parameters and inputs (outputs identical bit for bit).

    ``decimation``: ``record.decimation`` of ``output`` (default: the recording's own); 1
    records every sample of the block topics, also from a recording that kept fewer.
    """
    config, start, inputs, sizes, namespace = load_recording(path)
    config = with_record_decimation(config, decimation)
    duration = sum(sizes) * config.run.output_period_ns * 1e-9
    return run_offline(config, duration, output=output, progress=progress,
                       namespace=namespace, start_state=start, inputs=inputs,
                       block_sizes=sizes, overwrite=overwrite,
                       calibration=recorded_calibration(path))


def recorded_calibration(path: str) -> Any:
    """
    Return the held calibration a recording holds (None: ideal), 'auto' when it has none.

    A recording made before the calibration was recorded leaves it to ``Run`` (``'auto'``).
    """
    text = read_metadata(path, METADATA_NAME).get('calibration')
    if text is None:
        return 'auto'
    values = json.loads(text)
    if values is None:
        return None
    return Calibration.from_dict(values)
