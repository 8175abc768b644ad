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
``ring_gyro rate``: the rate output of a recording against the applied rate (PNG, CSV, JSON).

Reads ``/ring_gyro/rate`` (``recording.reader.read_rate``), the parameters and the inputs as
they acted (``offline.load_recording``), rebuilds the applied rate at every rate sample with
the simulator's own rules (the ``scenario.rate_*`` knots, linear between them, and each
streamed ``~/angular_rate`` a step that replaces the knots after it:
``core.rate_profile.RateProfile``), and writes

* ``DIR/rate.png``: the rate output and the applied rate, their difference (log scale, the
  1 % band drawn) in deg/s, and the drive pick-off over its value at the start (from
  ``/ring_gyro/demodulator`` when recorded), the first shock marked and when the rate was
  back within its band for good (or that it was not by the end)
  (``analysis.plotting.plot_rate``);
* ``DIR/rate.csv``: ``t_s, rate_rad_s, applied_rad_s, error_rad_s``;
* the figures of ``ring_gyro run --json`` over the record (``core.gyro.stats.RateStats``),
  returned and printed as one JSON object.
"""

import csv
import json
from pathlib import Path
from typing import Any, Dict

import numpy as np

from ring_gyro_sim.core.gyro.electronics import RateSamples
from ring_gyro_sim.core.gyro.stats import RateStats
from ring_gyro_sim.core.rate_profile import RateProfile
from ring_gyro_sim.outdir import prepare_directory
from ring_gyro_sim.run import AngularRate, Shock

__all__ = ['applied_rate', 'rate_report']


def applied_rate(config, inputs, t_ns: np.ndarray) -> np.ndarray:
    """Return the applied rate (rad/s) at the times ``t_ns``: configuration and inputs."""
    profile = RateProfile.of(config)
    for event in sorted((e for e in inputs if isinstance(e, AngularRate)),
                        key=lambda e: e.at_ns):
        profile.step(int(event.at_ns), float(event.z))
    return profile.at(np.asarray(t_ns, dtype=np.int64))  # as Samples.applied_rate has them


def rate_report(path: str, out_dir: str) -> Dict[str, Any]:
    """
    Write ``rate.png`` and ``rate.csv`` of a gyroscope recording; return its figures.

    A recording without ``~/rate`` messages is refused (``RecordingError``): an empty CSV and
    a blank plot are not a report.
    """
    from ring_gyro_sim.analysis import plotting
    from ring_gyro_sim.offline import load_recording
    from ring_gyro_sim.recording.errors import RecordingError
    from ring_gyro_sim.recording.reader import read_block_topic, read_rate
    out = prepare_directory(out_dir, '--out')
    config, _, inputs, _, namespace = load_recording(path)
    series = read_rate(path)
    if not len(series.t_ns):
        why = ('it was recorded without the gyroscope (gyro.enabled: false)'
               if not config.gyro.enabled else
               'record.topics left it out, or the run ended before its first rate sample')
        raise RecordingError(f'{str(path)!r} holds no {namespace}/rate messages: {why}; '
                             f'there is no rate output to report')
    t_ns = np.asarray(series.t_ns, dtype=np.int64)
    rate = np.asarray(series.rate, dtype=np.float64)
    applied = applied_rate(config, inputs, t_ns)
    t = t_ns * 1e-9
    stats = RateStats(config.gyro.output_rate)
    shocks = ([e.at_ns for e in inputs if isinstance(e, Shock)]
              + [at_ns for at_ns, _, _ in config.run.scheduled_shocks()])
    shock_s = min(shocks) * 1e-9 if shocks else None
    if shock_s is not None:
        stats.shock_at(shock_s)
    stats.add(RateSamples(t=t, rate=rate, quadrature=np.zeros_like(rate)), applied)
    with open(out / 'rate.csv', 'w', newline='', encoding='utf-8') as f:
        writer = csv.writer(f)
        writer.writerow(['t_s', 'rate_rad_s', 'applied_rad_s', 'error_rad_s'])
        for row in zip(t, rate, applied, rate - applied):
            writer.writerow([repr(float(x)) for x in row])
    files = [str(out / 'rate.csv')]
    drive = None
    try:
        demod = read_block_topic(path, 'demodulator')
    except RecordingError:
        demod = None  # not recorded (record.topics)
    if demod is not None and len(demod.data):
        cols = {name: k for k, name in enumerate(demod.labels)}
        amp = np.hypot(demod.data[:, cols['drive_i']], demod.data[:, cols['drive_q']])
        drive = [('', demod.data[:, cols['t']], amp / amp[0])]
    figures = stats.figures()
    if plotting.plot_rate([('', t, rate, applied)], out / 'rate.png',
                          title=f'Rate output of {Path(path).name}', shock_s=shock_s,
                          drive=drive, recovery_s=figures.get('rate_recovery_s')):
        files.append(str(out / 'rate.png'))
    figures = dict(figures, samples=int(t.size), files=files)
    return json.loads(json.dumps(figures, allow_nan=False))
