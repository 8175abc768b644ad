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
The results of a sweep as an ``xarray.Dataset``, netCDF4 and CSV.

Dimensions are the sweep axes (named as in the spec, e.g. ``modes.quality_factors[0]``,
``shock.peak_g``; coordinate attributes ``units`` and ``spacing``), one variable per metric
of the spec (:data:`ring_gyro_sim.sweep.metrics.METRICS`, ``GYRO_METRICS`` for a gyroscope
sweep; attributes ``units`` and ``long_name``), and always:

* ``branch_code`` (with ``final_branch``): int8, 0 lower, 1 upper, 2 contact, -1 no drive or
  the point failed (CF ``flag_values`` / ``flag_meanings``): what the jump map draws;
* ``error``: '' for a computed point, else the exception (type: message);
* ``wall_time_s``: wall time of the point on its worker (the one value that is not
  reproducible: it is left out of every comparison).

With ``envelopes`` in the spec, also ``envelope_<channel>_m`` for each channel kept (``q2``
...; every channel of the run with ``all``): float64 over the sweep axes and ``time`` (s, the
1 ms window centres of the longest run), nan after a contact (the run stopped) and for a
failed point.

Missing values (a failed point): nan for floats, -1 for the int8 flags (``contact``,
``settled``: 0 / 1), '' for strings. Global attributes: ``package_version``,
``base_parameters`` (JSON: the flat parameters of the base file), ``set`` and ``spec`` (JSON:
the resolved spec), ``base_path``. ``DIR/results.csv`` has one row per point: the axes, then
the variables (not the envelopes over time: they are in ``results.nc``).

A gyroscope sweep (``kind: gyroscope``, a device population) also has its datasheet
(:func:`population_datasheet`, :func:`write_datasheet`): for each figure of
:data:`DATASHEET_FIGURES` over the devices computed, the count, min, median, max, mean, the
sample standard deviation sigma (``ddof`` 1), mean -+ 3 sigma and the median magnitude, in
``DIR/datasheet.json`` (the figures' SI units) and ``DIR/datasheet.md`` (a table in the
units a datasheet gives: deg/s for rad/s).
"""

import json
import math
from typing import Any, Dict, List, Mapping, Optional, Sequence

import numpy as np
from ring_gyro_sim import __version__
from ring_gyro_sim.sweep.metrics import metric_table
from ring_gyro_sim.sweep.spec import Point, SweepSpec

__all__ = ['BRANCH_CODES', 'DATASHEET_FIGURES', 'ENVELOPE_PREFIX', 'REPRODUCIBLE_EXCLUDED',
           'TIME_DIM', 'build_dataset', 'comparable', 'datasheet_markdown', 'open_results',
           'population_datasheet', 'write_datasheet', 'write_results']

BRANCH_CODES = {'lower': 0, 'upper': 1, 'contact': 2}
"""``branch_code`` of each final branch (-1: none)."""
ENVELOPE_PREFIX = 'envelope_'
"""Kept envelopes: variable ``envelope_<channel>_m``."""
TIME_DIM = 'time'
"""The dimension (and coordinate, s) of the kept envelopes."""
REPRODUCIBLE_EXCLUDED = ('wall_time_s',)
"""Variables that differ between two runs of the same sweep."""
NO_VALUE = '-1: no value (the point failed)'
"""The int8 flags' missing value: not a CF ``missing_value`` attribute, which xarray would
decode into a float array with nan."""


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)


def build_dataset(spec: SweepSpec, points: Sequence[Point],
                  records: Mapping[str, Optional[Dict[str, Any]]],
                  failures: Mapping[str, Optional[Dict[str, Any]]]):
    """
    Assemble the Dataset of a sweep from its point records.

    Parameters
    ----------
    spec : SweepSpec
        The sweep.
    points : sequence of Point
        ``spec.points()`` (C order of the axes).
    records : mapping
        ``{key: computed record or None}``.
    failures : mapping
        ``{key: failure record or None}``, for the points without a computed record.

    Returns
    -------
    xarray.Dataset

    """
    import xarray as xr
    shape = spec.shape
    dims = [a.name for a in spec.axes]
    table = metric_table(spec.kind)
    data: Dict[str, np.ndarray] = {}
    for name in spec.metrics:
        kind = table[name][0]
        if kind == 'float':
            data[name] = np.full(shape, np.nan)
        elif kind == 'bool':
            data[name] = np.full(shape, -1, dtype=np.int8)
        else:
            data[name] = np.full(shape, '', dtype=object)
    if 'final_branch' in spec.metrics:
        data['branch_code'] = np.full(shape, -1, dtype=np.int8)
    data['error'] = np.full(shape, '', dtype=object)
    data['wall_time_s'] = np.full(shape, np.nan)
    for flat_index, point in enumerate(points):
        index = np.unravel_index(flat_index, shape)
        record = records.get(point.key)
        if record is None:
            failure = failures.get(point.key) or {}
            data['error'][index] = failure.get('error') or 'not computed'
            continue
        metrics = record['metrics']
        for name in spec.metrics:
            kind = table[name][0]
            value = metrics.get(name)
            if kind == 'float':
                data[name][index] = np.nan if value is None else float(value)
            elif kind == 'bool':
                data[name][index] = int(bool(value))
            else:
                data[name][index] = '' if value is None else str(value)
        if 'branch_code' in data:
            data['branch_code'][index] = BRANCH_CODES.get(metrics.get('final_branch'), -1)
        wall = record.get('wall_time_s')
        data['wall_time_s'][index] = np.nan if wall is None else float(wall)
    envelopes = _envelope_arrays(points, records, shape)
    coords = {}
    for axis in spec.axes:
        values = np.array(axis.values)
        if values.dtype.kind in 'US':
            values = values.astype(object)
        coords[axis.name] = xr.Variable(axis.name, values,
                                        attrs={'units': axis.unit, 'spacing': axis.spacing})
    variables = {}
    for name, values in data.items():
        if values.dtype == object:
            values = values.astype(str)
        attrs: Dict[str, Any] = {}
        if name in table:
            kind, unit, meaning = table[name]
            attrs = {'units': unit, 'long_name': meaning}
            if kind == 'bool':
                attrs.update(flag_values=np.array([0, 1], dtype=np.int8),
                             flag_meanings='false true', comment=NO_VALUE)
        elif name == 'branch_code':
            attrs = {'long_name': 'final branch code (the jump map)',
                     'flag_values': np.array([0, 1, 2], dtype=np.int8),
                     'flag_meanings': 'lower upper contact',
                     'comment': NO_VALUE + ' or no drive'}
        elif name == 'error':
            attrs = {'long_name': "'' or the exception of a failed point"}
        else:
            attrs = {'units': 's', 'long_name': 'wall time of the point (not reproducible)'}
        variables[name] = (dims, values, attrs)
    if envelopes is not None:
        t, arrays, window = envelopes
        coords[TIME_DIM] = xr.Variable(TIME_DIM, t, attrs={
            'units': 's', 'long_name': 'envelope window centre'})
        for name, values in arrays.items():
            variables[f'{ENVELOPE_PREFIX}{name}_m'] = (
                dims + [TIME_DIM], values,
                {'units': 'm', 'long_name': f'{name} positive envelope ({window:g} s windows; '
                                            f'nan after a contact or for a failed point)'})
    attrs = {'title': 'ring_gyro sweep', 'package_version': __version__,
             'base_parameters': _json(spec.base), 'base_path': str(spec.base_path or ''),
             'set': _json(spec.fixed), 'spec': _json(spec.describe()),
             'points': int(spec.size)}
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _envelope_arrays(points: Sequence[Point], records: Mapping[str, Optional[Dict[str, Any]]],
                     shape):
    """
    Return ``(time, {channel: array over the axes and time}, window s)`` of the kept envelopes.

    None when no record keeps any. Every run starts at t = 0 with the same windows, so the
    time of each is a prefix of the longest (shorter: stopped at a contact); checked.
    """
    kept = [(i, records[p.key]['envelope']) for i, p in enumerate(points)
            if records.get(p.key) and records[p.key].get('envelope')]
    if not kept:
        return None
    t = np.array(max((e['t_s'] for _, e in kept), key=len), dtype=float)
    names: List[str] = []
    for _, e in kept:
        names += [n for n in e['names'] if n not in names]
    arrays = {n: np.full(tuple(shape) + (t.size,), np.nan) for n in names}
    for i, e in kept:
        own = np.array(e['t_s'], dtype=float)
        if not np.array_equal(own, t[:own.size]):
            raise ValueError(f'envelopes: point {points[i].key} has other window times than '
                             f'the longest run')
        index = np.unravel_index(i, shape)
        for n in e['names']:
            arrays[n][index][:own.size] = [np.nan if v is None else v for v in e['values'][n]]
    return t, arrays, float(kept[0][1]['window_s'])


def write_results(ds, out_dir) -> Dict[str, str]:
    """Write ``results.nc`` (netCDF4) and ``results.csv`` into ``out_dir``; their paths."""
    from pathlib import Path
    out = Path(out_dir)
    nc = out / 'results.nc'
    csv = out / 'results.csv'
    tmp = out / '.results.nc.tmp'
    ds.to_netcdf(tmp, engine='netcdf4')
    tmp.replace(nc)
    per_point = ds.drop_dims(TIME_DIM) if TIME_DIM in ds.dims else ds
    frame = per_point.to_dataframe().reset_index()
    frame.to_csv(csv, index=False)
    return {'netcdf': str(nc), 'csv': str(csv)}


def open_results(path):
    """Open a ``results.nc`` fully into memory (file closed afterwards)."""
    import xarray as xr
    with xr.open_dataset(path, engine='netcdf4') as ds:
        return ds.load()


def comparable(ds) -> List[str]:
    """Names of the variables that two runs of one sweep must give identically."""
    return [n for n in ds.data_vars if n not in REPRODUCIBLE_EXCLUDED]


DATASHEET_FIGURES = {'bias_rad_s': 'bias', 'quadrature_rad_s': 'quadrature',
                     'scale_factor_error_ppm': 'scale-factor error',
                     'bias_tc_rad_s_k': 'bias temperature coefficient',
                     'quadrature_tc_rad_s_k': 'quadrature temperature coefficient',
                     'scale_factor_tc_ppm_k': 'scale-factor temperature coefficient'}
"""The figures of a population's datasheet (``sweep.point.FIGURES``), in its order: name ->
what a datasheet calls it."""
DISPLAY_UNITS = {'rad/s': ('deg/s', 180.0 / math.pi), 'rad/s/K': ('deg/s/K', 180.0 / math.pi)}
"""SI unit -> (the unit a datasheet gives, its factor)."""
STATISTICS = ('min', 'median', 'max', 'mean', 'sigma', 'mean_minus_3_sigma',
              'mean_plus_3_sigma', 'median_magnitude')
"""The numbers of each datasheet figure (besides its count ``n``)."""


def population_datasheet(ds) -> Dict[str, Any]:
    """
    Return the datasheet of a gyroscope sweep: each figure's spread over its devices.

    Parameters
    ----------
    ds : xarray.Dataset
        Results of a ``kind: gyroscope`` sweep (:func:`build_dataset`).

    Returns
    -------
    dict
        ``devices`` (points of the sweep), ``failed`` (points without a record), ``axes``
        (each axis' first and last value) and ``figures``: name -> ``units``,
        ``long_name``, ``display_units``, ``display_scale`` (the display value is the SI
        value times it), ``n`` and the :data:`STATISTICS` in SI units (figures the spec did
        not keep, or nan on every device, are left out).

    """
    errors = ds['error'].values.ravel() if 'error' in ds else np.array([])
    figures: Dict[str, Any] = {}
    for name in DATASHEET_FIGURES:
        if name not in ds:
            continue
        v = ds[name].values.ravel().astype(float)
        v = v[np.isfinite(v)]
        if not v.size:
            continue
        mean = float(np.mean(v))
        sigma = float(np.std(v, ddof=1)) if v.size > 1 else math.nan
        units = str(ds[name].attrs.get('units', ''))
        display, scale = DISPLAY_UNITS.get(units, (units, 1.0))
        figures[name] = {
            'label': DATASHEET_FIGURES[name], 'units': units,
            'long_name': str(ds[name].attrs.get('long_name', '')),
            'display_units': display, 'display_scale': scale, 'n': int(v.size),
            'min': float(np.min(v)), 'median': float(np.median(v)), 'max': float(np.max(v)),
            'mean': mean, 'sigma': sigma, 'mean_minus_3_sigma': mean - 3.0 * sigma,
            'mean_plus_3_sigma': mean + 3.0 * sigma,
            'median_magnitude': float(np.median(np.abs(v)))}
    axes = {d: [_plain(ds[d].values[0]), _plain(ds[d].values[-1])] for d in ds.dims
            if d != TIME_DIM}
    return {'devices': int(errors.size), 'failed': int(sum(1 for e in errors if e)),
            'axes': axes, 'figures': figures}


def _plain(value: Any) -> Any:
    """Return a numpy scalar as the Python number it is (JSON-ready)."""
    return value.item() if hasattr(value, 'item') else value


def datasheet_markdown(sheet: Mapping[str, Any]) -> str:
    """Return a datasheet (:func:`population_datasheet`) as a Markdown table, display units."""
    axes = ', '.join(f'{k} {v[0]} to {v[1]}' for k, v in sheet['axes'].items())
    lines = [f'{sheet["devices"]} devices ({axes}; {sheet["failed"]} failed). sigma: sample '
             f'standard deviation (ddof 1).', '',
             '| figure | unit | n | min | median | max | mean | sigma | mean - 3 sigma '
             '| mean + 3 sigma | median abs |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for name, f in sheet['figures'].items():
        scale = f['display_scale']
        numbers = ' | '.join(f'{f[k] * scale:.3g}' for k in STATISTICS)
        lines.append(f'| {f["label"]} (`{name}`) | {f["display_units"]} | {f["n"]} | '
                     f'{numbers} |')
    return '\n'.join(lines) + '\n'


def write_datasheet(sheet: Mapping[str, Any], out_dir) -> Dict[str, str]:
    """Write a datasheet (:func:`population_datasheet`) as ``datasheet.json`` and ``.md``."""
    from pathlib import Path
    out = Path(out_dir)
    paths = {'datasheet_json': out / 'datasheet.json', 'datasheet_md': out / 'datasheet.md'}
    paths['datasheet_json'].write_text(json.dumps(sheet, indent=1) + '\n', encoding='utf-8')
    paths['datasheet_md'].write_text(datasheet_markdown(sheet), encoding='utf-8')
    return {k: str(v) for k, v in paths.items()}
