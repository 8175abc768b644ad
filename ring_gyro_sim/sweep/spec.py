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
The sweep spec (``ring_gyro sweep SPEC.yaml``): a base parameter file, fixed values, axes.

A spec is a YAML mapping (every key optional but ``axes``)::

    base: paper.yaml          # params file, relative to the spec (omitted: the paper's
                              # resonator, core.params.PAPER_RESONATOR)
    node_name: ring_gyro      # whose ros__parameters to read in it
    duration: 30.0            # simulated s per point (omitted: the base file's duration)
    output_rate: 100000.0     # Hz, envelope input (cases.DEFAULT_OUTPUT_RATE_HZ)
    envelope_window: 0.001    # s
    set:                      # fixed values over the base: ROS names or shock.*
      shock.peak_g: 10000.0
      drive.frequency: 15798.6
      gyro.calibration.temperature_points: [318.15]     # set takes a whole list
    axes:                     # in dimension order
      modes.quality_factors[0]: [5000, 20000, 40000]     # a list
      shock.peak_g: {linear: [1000, 12000, 8]}           # np.linspace, ends included
      modes.quality_factors[0]: {log: [5000, 180000, 8]} # np.geomspace, ends included
      device.seed: {range: [1, 100]}                     # integers, stop included (a step: 3rd)
    metrics: [final_branch, final_q2_m, min_gap_m]       # kept in results (default: all)
    envelopes: [q2]           # envelope channels kept over time per point (or all; default none)
    plot: {x: shock.peak_g, y: modes.quality_factors[0]} # axes of the maps (default: 1st, 2nd)

Kinds
    ``kind: case`` (the default) runs each point as a paper case (a shock on the drive, the
    branch it ends on: :mod:`.point`). ``kind: gyroscope`` measures each point's device as a
    datasheet lists it, from the factory's rate tables (``core.gyro.calibration``: bias,
    quadrature, scale factor and their temperature coefficients; ``gyro.enabled`` needed):
    a sweep over ``device.seed`` is a device population. A gyroscope point has no shock and
    no run of its own (``shock.*``, ``duration``, ``output_rate``, ``envelope_window`` and
    ``envelopes`` are refused); the device is simulated as configured, output rate
    included. Without ``base`` its base is the package's defaults (the gyroscope).
    ``kind: environment`` runs each point's gyroscope in its scenario's environment
    (``scenario.vibration_*``, ``scenario.acceleration``: axes like any parameter) for
    ``duration`` s, noise off, and reports its **rectified bias**: the mean of ``~/rate``
    over the last ``average`` s (default a fifth of ``duration``) less that of the same
    device without the environment (``analysis.environment``; the reference run is the
    setup task, one per device). ``output_rate``, ``envelope_window``, ``envelopes`` and
    ``shock.*`` are refused; ``gyro.enabled`` is needed, and without ``base`` the base is the
    package's defaults.

Names
    Any parameter of the table (:data:`ring_gyro_sim.core.params.SPECS`) by its ROS name;
    one element of a list parameter as ``name[i]`` (``modes.quality_factors[0]`` is Q_1):
    the rest of the list is the base's, and ``i`` must exist there. ``set`` also takes a
    list parameter as a whole (an axis does not: its values would be lists). The shock is not a ROS
    parameter but a scenario input, named ``shock.peak_g`` (half-sine peak, g = 9.80665
    m/s^2; default 0: no shock), ``shock.phase`` (start of the shock in drive periods, in
    [0, 1); default 0, t = 0, the paper's) and ``shock.angle_deg`` (from x towards y;
    default 0; another angle needs ``modes.companions: true``). A base with
    ``scenario.shock_times`` is refused: the sweep applies its own shock.

Points
    The Cartesian product of the axes, the last axis fastest. Each point has a key: the
    first 16 hex digits of the SHA-256 of its canonical JSON (the parameters that differ
    from the paper's resonator, after the table's coercion: the points are its cases,
    ``analysis.cases``, which a base file or ``set`` values change; the shock, the run
    length, output rate, envelope window, the package version and, when there are any, the
    envelope channels it keeps; a gyroscope point: its kind, parameters and the package
    version), so ``5000`` and ``5000.0`` are one point, and a point is
    recognised whatever spec, axis order or file it came from. A point that keeps envelopes
    is another record than the same point without (its record holds them), hence another key.

Envelopes
    ``envelopes`` names channels of the point's 1 ms envelopes to keep over time: ``q1``,
    ``q2``, ... (``q1s`` ... with companions), ``w0``, ``wmax``, or ``all`` (every channel,
    and with them what :func:`ring_gyro_sim.sweep.point.case_result` needs to give the
    point back as the :class:`~ring_gyro_sim.analysis.cases.CaseResult` of its run: what
    ``ring_gyro report`` does for Case 4). Default: none, and a point then keeps its
    metrics only (nothing more is done for it).

Errors
    :class:`SweepSpecError` (a ``ParameterError``) names the spec file, the key and the
    reason; every axis value is checked against the parameter table on the base when the
    spec is read (a combination of values may still fail: the point is then reported).
    A spec of more than :data:`MAX_POINTS` points is refused before any value is made,
    with its count and estimated cost; ``duration`` and ``output_rate`` must lie in the
    ranges of the ROS parameters ``duration`` and ``output.rate``.
"""

from dataclasses import dataclass, field
import hashlib
import itertools
import json
import math
import os
import re
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim import __version__
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.analysis import envelope as env
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import (coerce, defaults, LIST_KINDS, MAX_OUTPUT_RATE_HZ,
                                       MAX_TIME_S, paper_config, PAPER_RESONATOR, SimConfig,
                                       SPECS)
from ring_gyro_sim.paramfile import check_params_file, DEFAULT_NODE_NAME, RosYamlLoader
from ring_gyro_sim.sweep.metrics import metric_table
import yaml

__all__ = ['ALL_ENVELOPES', 'Axis', 'KINDS', 'Point', 'SCENARIO_NAMES', 'SweepSpec',
           'SweepSpecError', 'load_spec', 'parse_spec']

SCENARIO_NAMES = {
    'shock.peak_g': ('g', 'half-sine shock peak, g = 9.80665 m/s^2', 0.0),
    'shock.phase': ('1', 'shock start, fraction of the drive period', 0.0),
    'shock.angle_deg': ('deg', 'shock direction from x towards y', 0.0),
}
"""Scenario inputs that are not ROS parameters: name -> (unit, meaning, default)."""
SPEC_KEYS = ('base', 'node_name', 'kind', 'duration', 'average', 'output_rate',
             'envelope_window', 'set', 'axes', 'metrics', 'envelopes', 'plot')
KINDS = ('case', 'gyroscope', 'environment')
"""What a point is: a paper case (a shock on the drive), a gyroscope's datasheet figures or
a gyroscope's rectified bias in its environment."""
DEVICE_KINDS = ('gyroscope', 'environment')
"""Kinds whose points are a gyroscope as configured: no shock (``shock.*`` refused)."""
CASE_ONLY_KEYS = ('duration', 'output_rate', 'envelope_window', 'envelopes')
"""Spec keys of a run of its own, which a gyroscope point does not have."""
ENVIRONMENT_REFUSED_KEYS = ('output_rate', 'envelope_window', 'envelopes')
"""Spec keys of a case's envelopes, which an environment point does not have."""
ENVIRONMENT_DURATION_S = 10.0
"""Default run of an environment point, s: the open-loop rate path's 1.3 s settles 5 times
over before the default average (doc/environments.md)."""
GYRO_CPU_S_PER_SIMULATED_S = 0.45
"""CPU time per simulated s of the open-loop gyroscope of ``config/gyro.yaml`` (0.42 measured
on 8 s runs): the cost estimate of an environment spec."""
GYRO_CPU_S_PER_TABLE = 3.1
"""CPU time of one factory rate table of the default gyroscope (3.0-3.8 simulated s, each
rate averaged until it settles), s: the cost estimate of a gyroscope spec, as measured on 100
devices (doc/populations.md)."""
ALL_ENVELOPES = 'all'
"""``envelopes: all``: every envelope channel of the run."""
RUN_KEYS = {'duration': 'duration', 'output.rate': 'output_rate'}
"""ROS parameters that a spec sets with its own keys instead."""
_INDEXED = re.compile(r'^(?P<name>[A-Za-z_][A-Za-z0-9_.]*)\[(?P<index>[0-9]+)\]$')
KEY_DIGITS = 16
MAX_POINTS = 100_000
"""The most points a spec may have. Reading a spec builds a configuration per axis value
(~0.25 ms each) and a point object per point (~40 us); at this size that is seconds, and
the points cost ~170 CPU-hours at 25 s each: a larger map is several sweeps."""
CPU_S_PER_SIMULATED_S = 0.25
"""CPU time of a point per simulated second, s: the cost estimate of a spec (a 25 s point
of the jump map takes ~6 s, doc/sweeps.md)."""


class SweepSpecError(ParameterError):
    """A sweep spec is invalid; the message names the file, the key and the reason."""


class _Loader(RosYamlLoader):
    """rcl's float forms (``1e-5``), and a key given twice is refused."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if key in seen:
                raise SweepSpecError(f'{key!r}: given twice (lines {seen[key]} and '
                                     f'{key_node.start_mark.line + 1})')
            seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


@dataclass(frozen=True)
class Axis:
    """
    One sweep axis.

    Attributes
    ----------
    name : str
        ROS name, ``name[i]`` for a list element, or a :data:`SCENARIO_NAMES` entry.
    values : tuple
        Coordinate values, coerced to the parameter's kind.
    spacing : str
        'list', 'linear', 'log' or 'range' (how the values were given; 'log' plots on a log
        axis).
    unit : str
        Unit of the values.

    """

    name: str
    values: Tuple[Any, ...]
    spacing: str = 'list'
    unit: str = ''

    def __len__(self) -> int:
        return len(self.values)


@dataclass(frozen=True)
class Point:
    """
    One point of a sweep: what :func:`ring_gyro_sim.sweep.point.evaluate` needs, nothing else.

    Attributes
    ----------
    key : str
        Hash of the point (module docstring).
    coords : tuple of (str, value)
        The axis values of this point, in axis order.
    overrides : tuple of (str, value)
        Flat ROS parameters that differ from the defaults (base, ``set``, axes), sorted.
    shock_g, shock_phase, shock_angle_deg : float
        The shock (g, drive periods, deg).
    duration_s, output_rate_hz, window_s : float
        Run length, envelope input rate and envelope window.
    envelopes : tuple of str
        Envelope channels kept over time (``('all',)``: every one; empty: none).
    kind : str
        ``case`` or ``gyroscope`` (:data:`KINDS`; a gyroscope point has no shock nor run
        settings: 0).

    """

    key: str
    coords: Tuple[Tuple[str, Any], ...]
    overrides: Tuple[Tuple[str, Any], ...]
    shock_g: float
    shock_phase: float
    shock_angle_deg: float
    duration_s: float
    output_rate_hz: float
    window_s: float
    envelopes: Tuple[str, ...] = ()
    kind: str = 'case'

    def config(self) -> SimConfig:
        """Return the configuration the point runs (a case's: without its shock)."""
        if self.kind in DEVICE_KINDS:
            return paper_config(dict(self.overrides))
        return self.case_spec().config(None, self.output_rate_hz)

    def nominal_config(self) -> SimConfig:
        """Return the point's configuration without its device draw (``device.seed`` 0)."""
        return paper_config({k: v for k, v in self.overrides if k != 'device.seed'})

    def case_spec(self) -> cases.CaseSpec:
        """Return the :class:`~ring_gyro_sim.analysis.cases.CaseSpec` of this point."""
        flat = dict(self.overrides)
        return cases.CaseSpec(
            name=f'point_{self.key}', description=describe(self.coords),
            shock_g=self.shock_g, q1_quality=None, duration_s=self.duration_s,
            start_on=flat.get('drive.start_on', SPECS['drive.start_on'].default),
            overrides=self.overrides, shock_phase=self.shock_phase,
            shock_angle_deg=self.shock_angle_deg)

    def parameters(self) -> Dict[str, Any]:
        """Return coordinates, shock and run settings, JSON-ready (for reports)."""
        if self.kind == 'gyroscope':
            return {'coords': dict(self.coords), 'kind': self.kind}
        if self.kind == 'environment':
            return {'coords': dict(self.coords), 'kind': self.kind,
                    'duration_s': self.duration_s, 'average_s': self.window_s}
        return {'coords': dict(self.coords), 'shock.peak_g': self.shock_g,
                'shock.phase': self.shock_phase, 'shock.angle_deg': self.shock_angle_deg,
                'duration_s': self.duration_s}


def describe(coords: Sequence[Tuple[str, Any]]) -> str:
    """Return ``name = value, ...`` for a point's coordinates."""
    return ', '.join(f'{k} = {v:g}' if isinstance(v, float) else f'{k} = {v}'
                     for k, v in coords)


@dataclass(frozen=True)
class SweepSpec:
    """
    A parsed sweep spec (module docstring).

    Attributes
    ----------
    axes : tuple of Axis
        The sweep axes, in dimension order.
    base : dict
        Flat parameters of the base file (empty: defaults).
    base_path : str or None
        Where the base came from.
    fixed : dict
        The ``set`` values: ROS names (list elements already applied) and ``shock.*``.
    duration_s, output_rate_hz, window_s : float
        Run length (s), envelope input rate (Hz), envelope window (s).
    metrics : tuple of str
        Metrics kept in the results.
    envelopes : tuple of str
        Envelope channels kept over time per point (``('all',)``: every one; empty: none).
    plot_axes : tuple of str
        The two axes of the maps (one for a one-axis sweep).
    source : str
        The spec file (or '<text>').
    kind : str
        What a point is (:data:`KINDS`): ``case`` or ``gyroscope`` (then no run settings:
        ``duration_s`` 0).

    """

    axes: Tuple[Axis, ...]
    base: Dict[str, Any]
    base_path: Optional[str]
    fixed: Dict[str, Any]
    duration_s: float
    output_rate_hz: float = cases.DEFAULT_OUTPUT_RATE_HZ
    window_s: float = env.DEFAULT_WINDOW_S
    metrics: Tuple[str, ...] = ()
    envelopes: Tuple[str, ...] = ()
    plot_axes: Tuple[str, ...] = ()
    source: str = '<text>'
    raw: Dict[str, Any] = field(default_factory=dict, compare=False)
    kind: str = 'case'

    @property
    def shape(self) -> Tuple[int, ...]:
        """Return the number of values of each axis."""
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        """Return the number of points."""
        return int(np.prod(self.shape)) if self.axes else 1

    def point(self, values: Sequence[Any]) -> Point:
        """Return the :class:`Point` at axis ``values`` (one per axis, in order)."""
        coords = tuple((a.name, v) for a, v in zip(self.axes, values))
        assigned = dict(self.fixed)
        assigned.update(coords)
        flat = dict(self.base)
        scenario = {n: d for n, (_, _, d) in SCENARIO_NAMES.items()}
        for name, value in assigned.items():
            if name in SCENARIO_NAMES:
                scenario[name] = float(value)
            else:
                _assign(flat, name, value)
        if self.kind == 'gyroscope':  # the device as configured: no shock, no run of its own
            overrides = _differences(flat)
            text = json.dumps({'version': __version__, 'kind': self.kind,
                               'overrides': overrides}, sort_keys=True, allow_nan=False)
            key = hashlib.sha256(text.encode('utf-8')).hexdigest()[:KEY_DIGITS]
            return Point(key=key, coords=coords, overrides=tuple(sorted(overrides.items())),
                         shock_g=0.0, shock_phase=0.0, shock_angle_deg=0.0, duration_s=0.0,
                         output_rate_hz=0.0, window_s=0.0, kind=self.kind)
        if self.kind == 'environment':  # the device in its environment, its own run length
            overrides = _differences(flat)
            text = json.dumps({'version': __version__, 'kind': self.kind,
                               'overrides': overrides, 'duration_s': self.duration_s,
                               'average_s': self.window_s}, sort_keys=True, allow_nan=False)
            key = hashlib.sha256(text.encode('utf-8')).hexdigest()[:KEY_DIGITS]
            return Point(key=key, coords=coords, overrides=tuple(sorted(overrides.items())),
                         shock_g=0.0, shock_phase=0.0, shock_angle_deg=0.0,
                         duration_s=self.duration_s, output_rate_hz=0.0,
                         window_s=self.window_s, kind=self.kind)
        flat['output.rate'] = self.output_rate_hz  # what the run uses (CaseSpec.config)
        overrides = _differences(flat)
        payload = {'version': __version__, 'overrides': overrides, 'shock': scenario,
                   'duration_s': self.duration_s, 'output_rate_hz': self.output_rate_hz,
                   'window_s': self.window_s}
        if self.envelopes:  # only then: the keys of points without envelopes stay as they were
            payload['envelopes'] = list(self.envelopes)
        text = json.dumps(payload, sort_keys=True, allow_nan=False)
        key = hashlib.sha256(text.encode('utf-8')).hexdigest()[:KEY_DIGITS]
        return Point(key=key, coords=coords, overrides=tuple(sorted(overrides.items())),
                     shock_g=scenario['shock.peak_g'], shock_phase=scenario['shock.phase'],
                     shock_angle_deg=scenario['shock.angle_deg'], duration_s=self.duration_s,
                     output_rate_hz=self.output_rate_hz, window_s=self.window_s,
                     envelopes=self.envelopes)

    def points(self) -> List[Point]:
        """Return every point, the last axis fastest (C order of the result arrays)."""
        return [self.point(v) for v in itertools.product(*(a.values for a in self.axes))]

    def describe(self) -> Dict[str, Any]:
        """Return the spec as resolved (JSON-ready: the results' attributes)."""
        return {'source': self.source, 'base_path': self.base_path, 'kind': self.kind,
                'axes': {a.name: list(a.values) for a in self.axes},
                'spacing': {a.name: a.spacing for a in self.axes},
                'set': self.fixed, 'duration_s': self.duration_s,
                'output_rate_hz': self.output_rate_hz, 'window_s': self.window_s,
                'metrics': list(self.metrics), 'envelopes': list(self.envelopes),
                'plot_axes': list(self.plot_axes)}


def _differences(flat: Mapping[str, Any]) -> Dict[str, Any]:
    """Return the entries of ``flat`` (coerced) that differ from the paper's resonator."""
    base = {**defaults(), **PAPER_RESONATOR}
    out = {}
    for name, value in flat.items():
        value = coerce(name, value)
        if value != base[name]:
            out[name] = value
    return out


def _split(name: str) -> Tuple[str, Optional[int]]:
    m = _INDEXED.match(name)
    if m:
        return m.group('name'), int(m.group('index'))
    return name, None


def _assign(flat: Dict[str, Any], name: str, value: Any) -> None:
    """Set ``name`` (``param`` or ``param[i]``) in ``flat`` (ROS names, coerced)."""
    param, index = _split(name)
    if index is None:
        flat[param] = coerce(param, value)
        return
    current = list(coerce(param, flat.get(param, SPECS[param].default)))
    current[index] = coerce(param, [value])[0]
    flat[param] = current


def _where(source: str, key: str) -> str:
    return f'sweep spec {source}: {key}'


def _check_name(name: Any, base: Mapping[str, Any], source: str, key: str,
                whole_list: bool = False, kind: str = 'case') -> str:
    """Check an axis or ``set`` name (``whole_list``: a list parameter as a whole); return it."""
    where = _where(source, key)
    if not isinstance(name, str):
        raise SweepSpecError(f'{where}: a name must be a string, got {name!r}')
    if name in SCENARIO_NAMES:
        if kind in DEVICE_KINDS:
            raise SweepSpecError(f'{where}: {name!r}: a {kind} point has no shock (it runs '
                                 f'its device as configured)')
        return name
    param, index = _split(name)
    if param in RUN_KEYS:
        raise SweepSpecError(f'{where}: {name!r}: the run length and output rate of the points '
                             f'are the spec keys {RUN_KEYS[param]}')
    spec = SPECS.get(param)
    if spec is None:
        hint = ''
        if param.startswith('shock.'):
            hint = f' (scenario inputs: {", ".join(SCENARIO_NAMES)}; ROS: shock.duration)'
        raise SweepSpecError(f'{where}: {name!r}: unknown parameter{hint}')
    if index is None:
        if spec.kind in LIST_KINDS and not whole_list:
            raise SweepSpecError(f'{where}: {name!r} is a list parameter: sweep one element '
                                 f'of it, {param}[i] (set takes a whole list)')
        return name
    if spec.kind != 'float_list':
        raise SweepSpecError(f'{where}: {name!r}: [i] applies to list parameters only '
                             f'({param} is {spec.kind})')
    current = coerce(param, base.get(param, spec.default))
    if index >= len(current):
        raise SweepSpecError(f'{where}: {name!r}: index {index} is beyond the base list '
                             f'{param} = {list(current)} ({len(current)} elements)')
    return name


def _coerce_value(name: str, value: Any, where: str) -> Any:
    if name in SCENARIO_NAMES:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value):
            raise SweepSpecError(f'{where}: {name}: expected a finite number, got {value!r}')
        value = float(value)
        if name == 'shock.phase' and not 0.0 <= value < 1.0:
            raise SweepSpecError(f'{where}: shock.phase: must be in [0, 1) drive periods, '
                                 f'got {value!r}')
        if name == 'shock.peak_g' and value < 0.0:
            raise SweepSpecError(f'{where}: shock.peak_g: must be >= 0 g (use shock.angle_deg '
                                 f'for the direction), got {value!r}')
        return value
    param, index = _split(name)
    try:
        if index is None:
            return coerce(param, value)
        return coerce(param, [value])[0]
    except ParameterError as exc:
        raise SweepSpecError(f'{where}: {exc}') from None


def _range_args(args: Any, where: str) -> Tuple[int, int, int]:
    """Check ``{range: [start, stop]}`` or ``[start, stop, step]``: integers, stop included."""
    if not (isinstance(args, list) and len(args) in (2, 3) and all(
            isinstance(a, int) and not isinstance(a, bool) for a in args)):
        raise SweepSpecError(f'{where}: range: expected integers [start, stop] or [start, '
                             f'stop, step], got {args!r}')
    start, stop, step = (args + [1])[:3]
    if step < 1 or stop < start:
        raise SweepSpecError(f'{where}: range: needs start <= stop and step >= 1, got '
                             f'{args!r}')
    return start, stop, step


def _axis_count(raw: Any, where: str) -> int:
    """Return the number of values of an axis as written, without making them."""
    if isinstance(raw, list):
        if not raw:
            raise SweepSpecError(f'{where}: no values')
        return len(raw)
    if isinstance(raw, dict) and len(raw) == 1 and next(iter(raw)) == 'range':
        start, stop, step = _range_args(raw['range'], where)
        return (stop - start) // step + 1
    if isinstance(raw, dict) and len(raw) == 1 and next(iter(raw)) in ('linear', 'log'):
        spacing, args = next(iter(raw.items()))
        if not (isinstance(args, list) and len(args) == 3 and all(
                isinstance(a, (int, float)) and not isinstance(a, bool) for a in args)):
            raise SweepSpecError(f'{where}: {spacing}: expected [start, stop, count], got '
                                 f'{args!r}')
        count = args[2]
        if not (math.isfinite(count) and float(count).is_integer() and count >= 1):
            raise SweepSpecError(f'{where}: {spacing}: count must be an integer >= 1, got '
                                 f'{count!r}')
        return int(count)
    raise SweepSpecError(f'{where}: expected a list of values, {{linear: [start, stop, '
                         f'count]}}, {{log: [start, stop, count]}} or {{range: [start, stop]}}, '
                         f'got {raw!r}')


def _cost(cpu_s: float) -> str:
    """Return a CPU time, s, in the unit that reads best."""
    for unit, size in (('CPU-years', 365.25 * 86400.0), ('CPU-days', 86400.0),
                       ('CPU-hours', 3600.0), ('CPU-minutes', 60.0)):
        if cpu_s >= size:
            return f'{cpu_s / size:.3g} {unit}'
    return f'{cpu_s:.3g} CPU-seconds'


def _check_size(counts: Sequence[Tuple[str, int]], cpu_per_point_s: float,
                per_point: Tuple[str, str], source: str) -> None:
    """
    Refuse more than :data:`MAX_POINTS` points, with the count and the estimated cost.

    ``per_point``: what a point is (``'25 s per point'``) and how its cost is estimated.
    """
    size = math.prod(n for _, n in counts)
    if size <= MAX_POINTS:
        return
    shape = ' x '.join(f'{n} ({name})' for name, n in counts)
    cpu_s = size * cpu_per_point_s
    raise SweepSpecError(f'{_where(source, "axes")}: {size} points ({shape}): more than the '
                         f'{MAX_POINTS} a sweep takes; at {per_point[0]} that is about '
                         f'{_cost(cpu_s)} ({per_point[1]}): split it into smaller sweeps (one '
                         f'--out with --resume shares their points)')


def _axis_values(name: str, raw: Any, where: str) -> Tuple[Tuple[Any, ...], str]:
    """Make and check the values of an axis that :func:`_axis_count` has accepted."""
    if isinstance(raw, list):
        values = [_coerce_value(name, v, where) for v in raw]
        spacing = 'list'
    elif 'range' in raw:
        start, stop, step = _range_args(raw['range'], where)
        values = [_coerce_value(name, v, where) for v in range(start, stop + 1, step)]
        spacing = 'range'
    else:
        spacing, (start, stop, count) = next(iter(raw.items()))
        if spacing == 'log' and not (start > 0 and stop > 0):
            raise SweepSpecError(f'{where}: log: start and stop must be > 0, got '
                                 f'{[start, stop, count]!r}')
        fn = np.linspace if spacing == 'linear' else np.geomspace
        values = [_coerce_value(name, float(v), where) for v in fn(start, stop, int(count))]
    if len(set(map(repr, values))) != len(values):
        raise SweepSpecError(f'{where}: a value is given twice: {values!r}')
    return tuple(values), spacing


def _unit(name: str) -> str:
    if name in SCENARIO_NAMES:
        return SCENARIO_NAMES[name][0]
    return SPECS[_split(name)[0]].unit


def _positive(data: Mapping[str, Any], key: str, default: Optional[float], source: str,
              maximum: float = math.inf, why: str = ''):
    value = data.get(key, default)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not (math.isfinite(value) and value > 0):
        raise SweepSpecError(f'{_where(source, key)}: must be a number > 0, got {value!r}')
    if value > maximum:
        raise SweepSpecError(f'{_where(source, key)}: must be at most {maximum:g} ({why}), '
                             f'got {value!r}')
    return float(value)


def parse_spec(data: Any, source: str = '<text>', directory: str = '.',
               base_params: Optional[Mapping[str, Any]] = None) -> SweepSpec:
    """
    Check and resolve a spec mapping (as read from YAML); see the module docstring.

    Parameters
    ----------
    data : mapping
        The spec.
    source : str
        Name of the spec in error messages.
    directory : str
        Directory a relative ``base`` path is taken from (the spec file's).
    base_params : mapping, optional
        Flat parameters (ROS names) under a spec that names no ``base`` file: a caller's
        own base, e.g. ``ring_gyro report``'s (refused together with ``base``).

    Raises
    ------
    SweepSpecError
        The message names the spec, the key and the reason.

    """
    if not isinstance(data, dict):
        raise SweepSpecError(f'sweep spec {source}: the top level must be a mapping '
                             f'({", ".join(SPEC_KEYS)})')
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise SweepSpecError(f'sweep spec {source}: unknown key(s) {unknown} (known: '
                             f'{", ".join(SPEC_KEYS)})')
    node = data.get('node_name', DEFAULT_NODE_NAME)
    kind = data.get('kind', 'case')
    if kind not in KINDS:
        raise SweepSpecError(f'{_where(source, "kind")}: must be one of {", ".join(KINDS)}, '
                             f'got {kind!r}')
    if kind == 'gyroscope':
        given = [k for k in CASE_ONLY_KEYS if k in data]
        if given:
            raise SweepSpecError(f'{_where(source, given[0])}: applies to kind: case only (a '
                                 f'gyroscope point runs the factory rate tables of its device '
                                 f'as configured)')
    if kind == 'environment':
        given = [k for k in ENVIRONMENT_REFUSED_KEYS if k in data]
        if given:
            raise SweepSpecError(f'{_where(source, given[0])}: applies to kind: case only (an '
                                 f'environment point reads the mean of ~/rate, not envelopes)')
    if kind != 'environment' and 'average' in data:
        raise SweepSpecError(f'{_where(source, "average")}: applies to kind: environment '
                             f'only')
    base_path = data.get('base')
    base: Dict[str, Any] = {}
    if base_path is not None:
        if not isinstance(base_path, str) or not base_path:
            raise SweepSpecError(f'{_where(source, "base")}: expected a file path, got '
                                 f'{base_path!r}')
        if base_params is not None:
            raise SweepSpecError(f'{_where(source, "base")}: a base file and base parameters '
                                 f'given together')
        base_path = os.path.normpath(os.path.join(directory, os.path.expanduser(base_path)))
        base = dict(check_params_file(base_path, node))
    elif base_params is not None:
        base = {str(k): v for k, v in base_params.items()}
    elif kind in DEVICE_KINDS:  # the package's defaults: the gyroscope
        base = {name: SPECS[name].default for name in PAPER_RESONATOR}
    try:
        base_config = paper_config(base)
    except ParameterError as exc:
        raise SweepSpecError(f'{_where(source, "base")}: {exc}') from None
    if kind in DEVICE_KINDS and not base_config.gyro.enabled:
        raise SweepSpecError(f'{_where(source, "base")}: kind {kind} needs a gyroscope '
                             f'(gyro.enabled: true; e.g. base: default.yaml)')
    if base_config.run.shock_times:
        raise SweepSpecError(f'{_where(source, "base")}: {base_path} schedules shocks '
                             f'(scenario.shock_times): the sweep applies its own shock '
                             f'(shock.peak_g, shock.phase, shock.angle_deg); clear them')
    fixed_raw = data.get('set') or {}
    if not isinstance(fixed_raw, dict):
        raise SweepSpecError(f'{_where(source, "set")}: expected a mapping of names to '
                             f'values, got {fixed_raw!r}')
    fixed: Dict[str, Any] = {}
    for name, value in fixed_raw.items():
        name = _check_name(name, base, source, 'set', whole_list=True, kind=kind)
        fixed[name] = _coerce_value(name, value, _where(source, f'set: {name}'))
    axes_raw = data.get('axes')
    if not isinstance(axes_raw, dict) or not axes_raw:
        raise SweepSpecError(f'{_where(source, "axes")}: expected a mapping of names to '
                             f'values (at least one axis), got {axes_raw!r}')
    if kind == 'gyroscope':
        duration, rate, window = 0.0, 0.0, 0.0
        points = [t for t in fixed.get('gyro.calibration.temperature_points', base_config.gyro
                                       .calibration_temperature_points)
                  if t != base_config.thermal.reference_temperature]
        tables = 1 + len(points)
        cpu_per_point = tables * GYRO_CPU_S_PER_TABLE
        per_point = (f'{tables} rate tables per point',
                     f'{GYRO_CPU_S_PER_TABLE:g} CPU s per table of the default gyroscope')
    elif kind == 'environment':
        duration = _positive(data, 'duration', ENVIRONMENT_DURATION_S, source, MAX_TIME_S,
                             SPECS['duration'].range_note)
        window = _positive(data, 'average', duration / 5.0, source, duration,
                           'the simulated time per point')
        rate = 0.0
        cpu_per_point = duration * GYRO_CPU_S_PER_SIMULATED_S
        per_point = (f'{duration:g} s per point',
                     f'{GYRO_CPU_S_PER_SIMULATED_S:g} CPU s per simulated s')
    else:
        duration = _positive(data, 'duration', base_config.run.duration or None, source,
                             MAX_TIME_S, SPECS['duration'].range_note)
        if duration is None:
            raise SweepSpecError(f'{_where(source, "duration")}: give the simulated time per '
                                 f'point, s (the base has duration 0: run forever)')
        rate = _positive(data, 'output_rate', cases.DEFAULT_OUTPUT_RATE_HZ, source,
                         MAX_OUTPUT_RATE_HZ, SPECS['output.rate'].range_note)
        window = _positive(data, 'envelope_window', env.DEFAULT_WINDOW_S, source, duration,
                           'the simulated time per point')
        cpu_per_point = duration * CPU_S_PER_SIMULATED_S
        per_point = (f'{duration:g} s per point',
                     f'{CPU_S_PER_SIMULATED_S:g} CPU s per simulated s')
    context = dict(base)  # the lists an axis indexes: the base's, or a list under set
    context.update({k: v for k, v in fixed.items() if k in SPECS})
    counts = []
    for name, raw in axes_raw.items():
        name = _check_name(name, context, source, 'axes', kind=kind)
        if name in fixed:
            raise SweepSpecError(f'{_where(source, "axes")}: {name!r} is also under set')
        counts.append((name, _axis_count(raw, _where(source, f'axes: {name}'))))
    _check_size(counts, cpu_per_point, per_point, source)  # before any value is made
    axes = []
    for (name, _), raw in zip(counts, axes_raw.values()):
        values, spacing = _axis_values(name, raw, _where(source, f'axes: {name}'))
        axes.append(Axis(name=name, values=values, spacing=spacing, unit=_unit(name)))
    known = metric_table(kind)
    metrics = data.get('metrics', list(known))
    if not isinstance(metrics, list) or not metrics or not all(
            isinstance(m, str) for m in metrics):
        raise SweepSpecError(f'{_where(source, "metrics")}: expected a list of names '
                             f'({", ".join(known)}), got {metrics!r}')
    bad = [m for m in metrics if m not in known]
    if bad:
        raise SweepSpecError(f'{_where(source, "metrics")}: unknown {bad} (known for kind '
                             f'{kind}: {", ".join(known)})')
    envelopes = _envelope_names(data.get('envelopes'), source)
    names = [a.name for a in axes]
    plot = data.get('plot') or {}
    if not isinstance(plot, dict) or set(plot) - {'x', 'y'}:
        raise SweepSpecError(f'{_where(source, "plot")}: expected {{x: axis, y: axis}}, got '
                             f'{plot!r}')
    plot_axes = [plot.get('x', names[0])]
    if len(names) > 1:
        plot_axes.append(plot.get('y', next(n for n in names if n != plot_axes[0])))
    for p in plot_axes:
        if p not in names:
            raise SweepSpecError(f'{_where(source, "plot")}: {p!r} is not an axis ({names})')
    if len(set(plot_axes)) != len(plot_axes):
        raise SweepSpecError(f'{_where(source, "plot")}: x and y are the same axis')
    spec = SweepSpec(axes=tuple(axes), base=base, base_path=base_path, fixed=fixed,
                     duration_s=duration, output_rate_hz=rate, window_s=window,
                     metrics=tuple(metrics), envelopes=envelopes,
                     plot_axes=tuple(plot_axes), source=source, raw=dict(data), kind=kind)
    _check_axis_values(spec)
    return spec


def _envelope_names(raw: Any, source: str) -> Tuple[str, ...]:
    """Check the ``envelopes`` key: ``all``, or a list of distinct channel names."""
    where = _where(source, 'envelopes')
    if raw is None:
        return ()
    if raw == ALL_ENVELOPES:
        return (ALL_ENVELOPES,)
    if not isinstance(raw, list) or not all(isinstance(n, str) and n for n in raw):
        raise SweepSpecError(f'{where}: expected {ALL_ENVELOPES!r} or a list of envelope '
                             f'channels (q1, q2, ..., w0, wmax), got {raw!r}')
    if ALL_ENVELOPES in raw:
        raise SweepSpecError(f'{where}: {ALL_ENVELOPES!r} is not a channel: give it alone, '
                             f'not in a list')
    if len(set(raw)) != len(raw):
        raise SweepSpecError(f'{where}: a channel is given twice: {raw!r}')
    return tuple(raw)


def _check_axis_values(spec: SweepSpec) -> None:
    """Build the configuration of each axis value alone on the base: range errors now."""
    first = [a.values[0] for a in spec.axes]
    for i, axis in enumerate(spec.axes):
        for value in axis.values:
            values = list(first)
            values[i] = value
            point = spec.point(values)
            try:
                config = point.config()
            except ParameterError as exc:
                raise SweepSpecError(f'{_where(spec.source, "axes")}: {axis.name} = '
                                     f'{value!r}: {exc}') from None
            if spec.kind in DEVICE_KINDS:
                if not config.gyro.enabled:
                    raise SweepSpecError(f'{_where(spec.source, "axes")}: {axis.name} = '
                                         f'{value!r}: kind {spec.kind} needs gyro.enabled')
                continue
            if point.shock_angle_deg and not config.modes.companions:
                raise SweepSpecError(f'{_where(spec.source, "axes")}: shock.angle_deg = '
                                     f'{point.shock_angle_deg:g}: a shock off the x axis '
                                     f'drives q1s: needs modes.companions: true')
            if point.shock_phase and config.drive.frequency <= 0.0:
                raise SweepSpecError(f'{_where(spec.source, "axes")}: shock.phase needs a '
                                     f'drive frequency (drive.frequency > 0)')
            channels = cases.envelope_channels(config)
            unknown = [n for n in spec.envelopes if n != ALL_ENVELOPES and n not in channels]
            if unknown:
                raise SweepSpecError(f'{_where(spec.source, "envelopes")}: {unknown}: not an '
                                     f'envelope channel of the points (with {axis.name} = '
                                     f'{value!r}: {", ".join(channels)})')


def load_spec(path: str) -> SweepSpec:
    """Read and check a spec file (:func:`parse_spec`; ``base`` relative to it)."""
    try:
        with open(path, 'r', encoding='utf-8') as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise SweepSpecError(f'sweep spec {path!r}: {exc}') from None
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except SweepSpecError as exc:
        raise SweepSpecError(f'sweep spec {path!r}: {exc}') from None
    except yaml.YAMLError as exc:
        raise SweepSpecError(f'sweep spec {path!r}: not valid YAML ({exc})') from None
    return parse_spec(data, source=repr(path), directory=os.path.dirname(os.path.abspath(path)))
