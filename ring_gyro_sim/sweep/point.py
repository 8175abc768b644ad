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
A sweep point: (parameter set) -> metrics, by one pure function.

:func:`evaluate` runs the point as a paper case (:func:`~ring_gyro_sim.analysis.cases.run_case`:
``Run(config)``, ``run.apply(Shock(...))``, ``run.advance(n)``)
and keeps the numbers of :data:`METRICS`, which are the case's numbers (branch logic and
all: cases.py's, not a copy). The result depends on the point only: not on the worker, the
order or what ran before in the process. What a point needs before it runs is the drive
setup (branches and start state, ~1.7 s of shooting, a quarter of a 25 s point): a pure
function of the configuration (the point without its shock), so computing it once per
configuration changes the cost only. The engine makes it a task of its own,
:func:`setup_task` (key :func:`setup_key`), once per configuration on the cluster, and
hands it to every point of that configuration, whichever worker computes it; a point
computed without one (:func:`evaluate`, :func:`compute` without ``setup``) takes it from
this process's cache.

:func:`compute` is the task a Dask worker runs: :func:`evaluate`, its wall and CPU time, an
exception turned into a failure record (with the point's parameters), and the record stored
at once in the sweep's point directory when the worker can see it (a worker of a cluster
without the client's file system cannot: the client stores it on receipt).

A gyroscope point (``kind: gyroscope``) runs no case: it measures its device as a datasheet
lists it, from the factory's rate tables (``core.gyro.calibration``, K1-K3), the figures of
:data:`GYRO_METRICS`: the bias ``b`` and the quadrature ``r_q(0) / S`` at the reference
temperature, the scale factor ``S`` and its error against the nominal device's (the same
configuration with ``device.seed`` 0), and the first-order temperature coefficients of the
three from the temperature series (``gyro.calibration.temperature_points``: the K3 fit's
``b_1`` and ``s_1``, the same fit of the quadrature), beside the drawn device itself
(``core.device``). Its setup is the nominal device's tables (:func:`setup_task`), one task for
all the devices of a population; the record also holds the nominal device's figures
(``nominal``).

An environment point (``kind: environment``) runs its gyroscope in its scenario's environment
and keeps the figures of :data:`ENVIRONMENT_METRICS`: the **rectified bias** (the mean of
``~/rate`` over the run's last ``average`` s less that of the same device without the
environment, noise off: ``analysis.environment``), the same of the quadrature, both means, and
the closed-form amplitude of the 1theta mode's answer. Its setup is the reference run (the
device without the environment), one task per device and run length, whatever the
environment of the points.

Kept envelopes (a point whose spec has ``envelopes``): the record also holds
``envelope`` (``names``, ``window_s``, ``t_s`` and ``values``: one list per channel kept, m,
the windows of :attr:`CaseResult.envelope`, exact) and ``outcome`` (the scalars of the
:class:`~ring_gyro_sim.analysis.cases.CaseResult` beside its envelope: gap, smallest gap,
contact, status, times, branches). With ``envelopes: all``, :func:`case_result` gives the
point back as the ``CaseResult`` of its run: the same envelopes, hence the same numbers
(``CaseResult`` computes them from these), which is how ``ring_gyro report`` runs Case 4
(Fig. 13 plots q2 over time). Points that keep no envelope do nothing of this.
"""

from collections import OrderedDict
from dataclasses import dataclass
import hashlib
import json
import math
import os
import socket
import time
import traceback
from typing import Any, Dict, Mapping, Optional

import numpy as np
from ring_gyro_sim import __version__
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.analysis import envelope as env
from ring_gyro_sim.analysis import environment as environment_runs
from ring_gyro_sim.core.bench import factory
from ring_gyro_sim.core.gyro import calibration
from ring_gyro_sim.core.params import SimConfig, to_flat
from ring_gyro_sim.sweep.metrics import (DEVICE_FIELDS, ENVIRONMENT_METRICS, GYRO_METRICS,
                                         metric_table, METRICS)
from ring_gyro_sim.sweep.spec import ALL_ENVELOPES, Point
from ring_gyro_sim.sweep.store import PointStore

__all__ = ['ENVIRONMENT_METRICS', 'GYRO_METRICS', 'METRICS', 'OUTCOME_FIELDS', 'SetupFailure',
           'case_result', 'compute', 'device_figures', 'evaluate', 'failure_record',
           'gyroscope_figures', 'kept_output', 'metric_table', 'setup_key', 'setup_task']

SETUP_CACHE_SIZE = 32
_SETUP_CACHE: 'OrderedDict[str, cases.DriveSetup]' = OrderedDict()


def _config(point: Point) -> SimConfig:
    """Return the configuration ``point`` runs (its shock is not part of it)."""
    return point.config()


def _setup(config: SimConfig) -> cases.DriveSetup:
    """Return :func:`cases.drive_setup` of ``config``, from this process's cache if there."""
    key = json.dumps(to_flat(config), sort_keys=True)
    found = _SETUP_CACHE.get(key)
    if found is None:
        found = cases.drive_setup(config)
        _SETUP_CACHE[key] = found
        while len(_SETUP_CACHE) > SETUP_CACHE_SIZE:
            _SETUP_CACHE.popitem(last=False)
    else:
        _SETUP_CACHE.move_to_end(key)
    return found


@dataclass(frozen=True)
class SetupFailure:
    """The drive setup of a configuration raised: what every point of it reports."""

    error: str
    traceback: str


def setup_key(point: Point) -> str:
    """
    Return the key of the drive setup of ``point``: equal for the points of one configuration.

    The first 16 hex digits of the SHA-256 of the configuration's flat parameters (canonical
    JSON) and the package version: the points of a sweep that differ in their shock only
    share it.

    Raises
    ------
    Exception
        The configuration cannot be built (the point will report it when computed).

    """
    if point.kind == 'gyroscope':  # the nominal device's tables: one for a population
        text = json.dumps([__version__, 'gyroscope', to_flat(point.nominal_config())],
                          sort_keys=True, default=str)
    elif point.kind == 'environment':  # the device without its environment: one per device
        text = json.dumps([__version__, 'environment', to_flat(_reference_config(point)),
                           point.duration_s, point.window_s], sort_keys=True, default=str)
    else:
        text = json.dumps([__version__, to_flat(_config(point))], sort_keys=True, default=str)
    return hashlib.sha256(text.encode('utf-8')).hexdigest()[:16]


def setup_task(point: Point):
    """
    Compute the drive setup of ``point``'s configuration: the task the engine runs once.

    A gyroscope point's setup is the factory tables of its nominal device (the scale factor
    its error is measured against), memoised by ``core.gyro.calibration``.

    Returns
    -------
    DriveSetup, tuple of TableReading, or SetupFailure
        The setup (also kept in this process's cache), or what it raised (never raises: the
        points of the configuration report it as their failure).

    """
    try:
        if point.kind == 'gyroscope':
            return factory.factory_tables(point.nominal_config())
        if point.kind == 'environment':
            return environment_runs.mean_output(_reference_config(point), point.duration_s,
                                                point.window_s)
        return _setup(_config(point))
    except Exception as exc:  # noqa: B902 - reported by each point of the configuration
        return SetupFailure(f'{type(exc).__name__}: {exc}', traceback.format_exc())


def run(point: Point, setup: Optional[cases.DriveSetup] = None) -> cases.CaseResult:
    """
    Run ``point`` as a case; its ``CaseResult``.

    ``setup``: the drive setup of its configuration (:func:`setup_task`); None: from this
    process's cache (computed there the first time).
    """
    spec = point.case_spec()
    config = spec.config(None, point.output_rate_hz)
    return cases.run_case(spec, output_rate_hz=point.output_rate_hz, window_s=point.window_s,
                          progress=False, setup=_setup(config) if setup is None else setup)


def metrics_of(result: cases.CaseResult) -> Dict[str, Any]:
    """Return the :data:`METRICS` of a case's numbers (nan / 'none' where they do not apply)."""
    numbers = result.numbers
    out: Dict[str, Any] = {}
    for name, (kind, _, _) in METRICS.items():
        value = numbers.get(name)
        if kind == 'float':
            out[name] = math.nan if value is None else float(value)
        elif kind == 'bool':
            out[name] = bool(value)
        else:
            out[name] = 'none' if value is None else str(value)
    return out


def device_figures(config: SimConfig) -> Dict[str, float]:
    """Return the :data:`DEVICE_FIELDS` of a configuration's device (as simulated)."""
    m, g = config.modes, config.gyro
    out = {name: math.nan for name in DEVICE_FIELDS}
    if m.companions and m.count >= 2:
        f = m.principal_frequencies()
        q = m.principal_quality_factors()
        out.update(split_hz=f[1] - f[m.count + 1],
                   frequency_axis_deg=m.frequency_axes[1] if m.frequency_axes else 0.0,
                   q_mismatch=q[m.count + 1] / q[1] - 1.0,
                   damping_axis_deg=m.damping_axes[1] if m.damping_axes else 0.0)
    out.update(sense_misalignment_deg=g.sense_misalignment, phase_error_rad=g.phase_error,
               pickoff_gain_mismatch=g.pickoff_gain_mismatch)
    return {k: float(v) for k, v in out.items()}


def gyroscope_figures(tables, nominal_scale_factor: float) -> Dict[str, float]:
    """
    Return the :data:`FIGURES` of a device's factory tables (``factory.factory_tables``).

    Parameters
    ----------
    tables : sequence of TableReading
        The reference's table first, then the temperature points'.
    nominal_scale_factor : float
        ``S`` of the nominal device, readout per rad/s (the scale-factor error's reference).

    """
    ref, series = tables[0], tables[1:]
    out = {'bias_rad_s': ref.bias, 'quadrature_rad_s': ref.quadrature,
           'scale_factor': ref.scale_factor,
           'scale_factor_error_ppm': (ref.scale_factor / nominal_scale_factor - 1.0) * 1e6,
           'bias_tc_rad_s_k': math.nan, 'scale_factor_tc_ppm_k': math.nan,
           'quadrature_tc_rad_s_k': math.nan}
    if series:
        reference = ref.temperature_k
        kelvins = [r.temperature_k for r in series]
        out['bias_tc_rad_s_k'] = calibration.fit_temperature_series(
            reference, kelvins, [r.bias - ref.bias for r in series])[0]
        out['scale_factor_tc_ppm_k'] = 1e6 * calibration.fit_temperature_series(
            reference, kelvins, [r.scale_factor / ref.scale_factor - 1.0 for r in series])[0]
        out['quadrature_tc_rad_s_k'] = calibration.fit_temperature_series(
            reference, kelvins, [r.quadrature - ref.quadrature for r in series])[0]
    return {k: float(v) for k, v in out.items()}


def _gyroscope(point: Point, nominal=None) -> Dict[str, Any]:
    """Return the metrics of a gyroscope point and its nominal device's figures."""
    if nominal is None:
        nominal = factory.factory_tables(point.nominal_config())
    config = point.config()
    tables = factory.factory_tables(config)
    reference = nominal[0].scale_factor
    metrics = {**gyroscope_figures(tables, reference), **device_figures(config)}
    return {'metrics': metrics, 'nominal': gyroscope_figures(nominal, reference)}


def _reference_config(point: Point) -> SimConfig:
    """Return the quiet device of an environment point without its environment."""
    return environment_runs.quiet(environment_runs.without_environment(point.config()))


def _environment(point: Point, reference=None) -> Dict[str, Any]:
    """Return the :data:`ENVIRONMENT_METRICS` of an environment point."""
    if reference is None:
        reference = environment_runs.mean_output(_reference_config(point), point.duration_s,
                                                 point.window_s)
    config = environment_runs.quiet(point.config())
    out = environment_runs.mean_output(config, point.duration_s, point.window_s)
    r = config.run
    amplitude = 0.0
    if r.vibration_frequency > 0.0:
        w1 = 2.0 * math.pi * config.modes.coordinate_frequencies()[0]
        w = 2.0 * math.pi * r.vibration_frequency
        amplitude = r.vibration_amplitude / (w1 * w1 - w * w)
    bias = out['rate_rad_s'] - reference['rate_rad_s']
    return {'rectified_bias_rad_s': bias,
            'rectified_bias_deg_per_h': math.degrees(bias) * 3600.0,
            'rectified_quadrature_rad_s': out['quadrature_rad_s']
            - reference['quadrature_rad_s'],
            'rate_rad_s': out['rate_rad_s'], 'reference_rate_rad_s': reference['rate_rad_s'],
            'q1_amplitude_m': amplitude,
            'contact': bool(out['contact'] or reference['contact'])}


def evaluate(point: Point) -> Dict[str, Any]:
    """
    Run ``point`` and return its :data:`METRICS` (SI; nan where a metric does not apply).

    A gyroscope point: its :data:`GYRO_METRICS` (the factory's tables of its device and of
    the nominal one).

    Parameters
    ----------
    point : Point
        The point (:meth:`ring_gyro_sim.sweep.spec.SweepSpec.points`).

    Returns
    -------
    dict
        ``{metric: value}`` for every name of :data:`METRICS`.

    Raises
    ------
    Exception
        Whatever the run raises (an invalid combination of parameters, a failed shooting):
        contact is not an exception but a result.

    """
    if point.kind == 'gyroscope':
        return _gyroscope(point)['metrics']
    if point.kind == 'environment':
        return _environment(point)
    return metrics_of(run(point))


OUTCOME_FIELDS = ('gap_m', 'min_gap_m', 'contact', 'status', 'message', 'contact_time_s',
                  'contact_theta_rad', 'sim_time_s', 'wall_time_s', 'sample_rate_hz')
"""Scalars of a ``CaseResult`` kept in ``outcome`` beside the envelopes (and ``branches``)."""


def kept_output(point: Point, result: cases.CaseResult) -> Dict[str, Any]:
    """
    Return the ``envelope`` and ``outcome`` entries of the record of ``point`` (module doc).

    Raises
    ------
    ValueError
        A channel of ``point.envelopes`` is not one of the run (the spec checks it first).

    """
    e = result.envelope
    names = list(e.names) if ALL_ENVELOPES in point.envelopes else list(point.envelopes)
    missing = [n for n in names if n not in e.names]
    if missing:
        raise ValueError(f'envelopes: {missing}: not a channel of this run ({e.names})')
    envelope = {'names': names, 'complete': names == list(e.names), 'window_s': e.window_s,
                't_s': e.t.tolist(),
                'values': {n: e.channel(n).tolist() for n in names}}
    outcome: Dict[str, Any] = {f: getattr(result, f) for f in OUTCOME_FIELDS}
    b = result.branches
    outcome['branches'] = None if b is None else {
        'upper_m': b.upper_m, 'lower_m': b.lower_m, 'threshold_m': b.threshold_m}
    return {'envelope': envelope, 'outcome': outcome}


def _floats(values) -> np.ndarray:
    """Return a stored list of floats as float64 (null, a stored nan, back to nan)."""
    return np.array([math.nan if v is None else v for v in values], dtype=float)


def _number(value) -> float:
    return math.nan if value is None else float(value)


def case_result(record: Mapping[str, Any], spec: cases.CaseSpec) -> cases.CaseResult:
    """
    Return a point's run as the :class:`~ring_gyro_sim.analysis.cases.CaseResult` it was.

    The envelopes and outcome of the record (a point of ``envelopes: all``), under ``spec``
    (the case the point is, for its name, description and paper text): its numbers are
    computed from them by ``CaseResult`` itself, so they are the run's.

    Parameters
    ----------
    record : mapping
        A computed point record (:func:`compute`, or read back from the store).
    spec : CaseSpec
        The case the point runs.

    Raises
    ------
    ValueError
        The record keeps no envelopes, or not every channel (``envelopes: all`` needed).

    """
    e = record.get('envelope')
    out = record.get('outcome')
    if not e or not out or not e.get('complete'):
        raise ValueError(f'point {record.get("key")}: its record does not keep every '
                         f'envelope (a spec with envelopes: {ALL_ENVELOPES} does)')
    names = tuple(e['names'])
    t = _floats(e['t_s'])
    values = np.column_stack([_floats(e['values'][n]) for n in names]) if t.size else \
        np.zeros((0, len(names)))
    b = out.get('branches')
    branches = None if b is None else cases.Branches(
        upper_m=_number(b['upper_m']), lower_m=_number(b['lower_m']),
        threshold_m=_number(b['threshold_m']))
    return cases.CaseResult(
        spec=spec, envelope=env.Envelope(t=t, values=values, names=names,
                                         window_s=float(e['window_s'])),
        branches=branches, gap_m=_number(out['gap_m']), min_gap_m=_number(out['min_gap_m']),
        contact=bool(out['contact']), status=str(out['status']), message=str(out['message']),
        contact_time_s=_number(out['contact_time_s']),
        contact_theta_rad=_number(out['contact_theta_rad']),
        sim_time_s=_number(out['sim_time_s']), wall_time_s=_number(out['wall_time_s']),
        sample_rate_hz=_number(out['sample_rate_hz']))


def failure_record(point: Point, error: str, detail: str = '') -> Dict[str, Any]:
    """Return the record of a point that raised (or whose worker died): no metrics."""
    return {'key': point.key, 'coords': [[k, v] for k, v in point.coords],
            'parameters': point.parameters(), 'metrics': None, 'error': error,
            'traceback': detail, 'wall_time_s': math.nan, 'cpu_time_s': math.nan,
            'worker': '', 'version': __version__}


def compute(point: Point, store_dir: Optional[str] = None,
            setup: Optional[Any] = None) -> Dict[str, Any]:
    """
    Evaluate ``point`` on a worker: its record, stored under ``store_dir`` if it exists.

    ``setup`` is the result of :func:`setup_task` for the point's configuration (None: the
    point takes it from this process's cache); a :class:`SetupFailure` is the point's
    failure. Besides the metrics the record holds ``wall_time_s`` and ``cpu_time_s`` (the CPU
    time of the thread that computed it, s; neither is reproducible) and the worker.
    Never raises for a failing point: the record's ``error`` says what happened.
    """
    wall0 = time.perf_counter()
    cpu0 = time.thread_time()
    if isinstance(setup, SetupFailure):
        record = failure_record(point, setup.error, setup.traceback)
    else:
        record = _evaluated(point, setup)
    record['wall_time_s'] = time.perf_counter() - wall0
    record['cpu_time_s'] = time.thread_time() - cpu0
    record['worker'] = f'{socket.gethostname()}:{os.getpid()}'
    if store_dir is not None and PointStore.reachable(store_dir):
        PointStore(store_dir, create=False).write(record)
    return record


def _evaluated(point: Point, setup: Optional[Any]) -> Dict[str, Any]:
    """Return the record of ``point`` run with ``setup``, or its failure record."""
    try:
        if point.kind == 'gyroscope':
            kept = _gyroscope(point, setup)
            metrics = kept.pop('metrics')
        elif point.kind == 'environment':
            metrics, kept = _environment(point, setup), {}
        else:
            result = run(point, setup)
            metrics = metrics_of(result)
            kept = kept_output(point, result) if point.envelopes else {}
    except Exception as exc:  # noqa: B902 - any failure of one point is reported, not fatal
        return failure_record(point, f'{type(exc).__name__}: {exc}', traceback.format_exc())
    record = {'key': point.key, 'coords': [[k, v] for k, v in point.coords],
              'parameters': point.parameters(), 'metrics': metrics, 'error': None,
              'traceback': '', 'version': __version__}
    record.update(kept)
    return record
