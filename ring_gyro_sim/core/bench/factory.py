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
The factory calibration: the rate table run on the model (K2, K3 of ``core.gyro.calibration``).

``core.gyro.calibration`` states the laws (K1-K3) and holds what a run keeps (a
:class:`~ring_gyro_sim.core.gyro.calibration.Calibration`); this module measures one: it
runs the full model on a bench (:func:`for_config`, :func:`factory`, :func:`factory_tables`,
:func:`table_at`), memoised in the process and stored in ``$RING_GYRO_SIM_CACHE``.
"""

from collections import OrderedDict
from dataclasses import asdict, replace
import hashlib
import json
import math
import os
from pathlib import Path
import tempfile
import threading
from typing import Callable, Optional, Sequence, Tuple
import warnings

import numpy as np
from ring_gyro_sim.core import thermal
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.gyro import modes, operating_point
from ring_gyro_sim.core.gyro.calibration import (Calibration, fit_temperature_series, given,
                                                 readout_unit, TableReading)
from ring_gyro_sim.core.params import build_config, SimConfig, to_flat

__all__ = ['CACHE_ENV', 'FACTORY_AVERAGE_S', 'FACTORY_RATE', 'FACTORY_SETTLE_TIME_CONSTANTS',
           'factory', 'factory_tables', 'for_config', 'measure', 'table_at']


FACTORY_RATE = math.radians(10.0)
"""The rate table's rates, +-10 deg/s about 0: inside the linear range of every loop mode."""


FACTORY_SETTLE_TIME_CONSTANTS = 10.0
"""Time constants of the rate path each table rate settles for before it is averaged."""


FACTORY_MIN_SETTLE_S = 0.05
"""Shortest settling (s): the output filter and the loops' start."""


FACTORY_AVERAGE_S = 0.2
"""Length of each table rate's averaging window, s."""


FACTORY_TOLERANCE = 1e-7
"""
A table rate has settled when two successive windows' means differ by at most this fraction
of the reading (of the +-W readings for the zero rate): the loops' slowest transient decays
tenfold per window on the default gyroscope, so what is left is about a tenth of it.
"""


FACTORY_MAX_S = 20.0
"""Longest a table rate runs, s."""


FACTORY_MEMO_SIZE = 16


def for_config(config: SimConfig,
               log: Optional[Callable[[str], None]] = None) -> Optional[Calibration]:
    """
    Return the calibration ``gyro.calibration.source`` asks for (None: the model's readout).

    None also without the gyroscope, and for ``factory`` when the drive is off at the start
    (``drive.amplitude`` 0): there is no rate to measure on a table, the rate output is 0
    until a drive starts (``scale_factor_valid`` false), and then the model's readout.
    """
    if (not config.gyro.enabled or config.gyro.calibration_source == 'ideal'
            or (config.gyro.calibration_source == 'factory' and config.drive.amplitude == 0.0)):
        return None
    if config.gyro.calibration_source == 'given':
        return given(config)
    return factory(config, log)


def _bench(config: SimConfig) -> SimConfig:
    """Return the device on the factory's rate table: no noise, no scenario, raw readout."""
    # the table reads the readout inside the part, before its output word (E15): with the
    # raw calibration that is in readout units, which a range or LSB in rad/s cannot cut
    g = replace(config.gyro, temperature=0.0, input_noise_density=0.0, bias_instability=0.0,
                calibration_source='given', calibration_bias=0.0,
                calibration_scale_factor=1.0, range=0.0, resolution=0.0)
    # what only cuts, paces or records a run is the defaults' (the table reads the same)
    plain = build_config({}).run
    block = max(plain.block_duration, config.run.output_period_ns * 1e-9)
    run = replace(config.run, shock_times=(), shock_peaks=(), shock_angles=(),
                  rate_times=(0.0,), rate_values=(0.0,), temperature_times=(),
                  temperature_values=(), vibration_frequency=0.0, vibration_amplitude=0.0,
                  vibration_psd_frequencies=(), vibration_psd_values=(),
                  acceleration=(), record_path='', duration=0.0, block_duration=block,
                  real_time_factor=plain.real_time_factor, publish_clock=plain.publish_clock,
                  record_topics=plain.record_topics, record_decimation=plain.record_decimation,
                  record_compression=plain.record_compression,
                  record_overwrite=plain.record_overwrite, input_horizon=plain.input_horizon)
    drive = config.drive
    if drive.start_on == 'rest':  # the factory calibrates the running sensor
        drive = replace(drive, start_on='upper_branch')
    return replace(config, gyro=g, run=run, drive=drive)


_MEMO: 'OrderedDict[SimConfig, Tuple[TableReading, ...]]' = OrderedDict()


_MEMO_LOCK = threading.Lock()


def factory(config: SimConfig, log: Optional[Callable[[str], None]] = None) -> Calibration:
    """
    Return the factory calibration of the device of ``config`` (K2, K3), memoised and stored.

    ``log`` is told when one is measured (it takes the simulated time of three table runs per
    temperature).
    """
    bench = _bench(config)
    return _calibration(bench, factory_tables(config, log))


def factory_tables(config: SimConfig,
                   log: Optional[Callable[[str], None]] = None) -> Tuple[TableReading, ...]:
    """
    Return the factory's rate tables of the device of ``config``, memoised and stored.

    The reference temperature's first, then those of ``gyro.calibration.temperature_points``
    (the reference itself left out) in their order: what :func:`factory` calibrates with.
    They are kept in this process and in a file (``$RING_GYRO_SIM_CACHE``), the calibration
    being derived from them.
    """
    bench = _bench(config)
    with _MEMO_LOCK:
        if bench in _MEMO:
            _MEMO.move_to_end(bench)
            return _MEMO[bench]
    path = _stored_path(bench)
    tables = _load(path)
    if tables is None:
        tables = measure(bench, log)
        _store(path, tables)
    with _MEMO_LOCK:
        _MEMO[bench] = tables
        while len(_MEMO) > FACTORY_MEMO_SIZE:
            _MEMO.popitem(last=False)
    return tables


CACHE_ENV = 'RING_GYRO_SIM_CACHE'
"""Environment variable naming the directory of stored factory tables (empty: none)."""


_CODE_DIGEST: Optional[str] = None


def _code_digest() -> str:
    """Return the SHA-256 of the source of ``ring_gyro_sim.core`` (what a calibration ran)."""
    global _CODE_DIGEST
    if _CODE_DIGEST is None:
        root = Path(__file__).resolve().parents[1]
        h = hashlib.sha256()
        for source in sorted(root.rglob('*.py')):
            h.update(str(source.relative_to(root)).encode())
            h.update(source.read_bytes())
        _CODE_DIGEST = h.hexdigest()
    return _CODE_DIGEST


def _stored_path(bench: SimConfig) -> Optional[Path]:
    """Return the file of a bench's stored factory tables (None: storing is off)."""
    directory = os.environ.get(CACHE_ENV)
    if directory is None:
        directory = str(Path.home() / '.cache' / 'ring_gyro_sim')
    if not directory:
        return None
    text = json.dumps(to_flat(bench), sort_keys=True, default=list) + _code_digest()
    key = hashlib.sha256(text.encode()).hexdigest()[:32]
    return Path(directory) / f'calibration-{key}.json'


def _load(path: Optional[Path]) -> Optional[Tuple[TableReading, ...]]:
    """Return stored factory tables, None when there are none (or they cannot be read)."""
    if path is None:
        return None
    try:
        tables = json.loads(path.read_text(encoding='utf-8'))['tables']
        return tuple(TableReading(**{k: float(v) for k, v in t.items()}) for t in tables)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def _store(path: Optional[Path], tables: Sequence[TableReading]) -> None:
    """Store factory tables (atomically: a reader sees the whole file or none); best effort."""
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix='.calibration-', suffix='.json')
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            json.dump({'tables': [asdict(t) for t in tables]}, f)
        os.replace(tmp, path)
    except OSError:
        pass


def _bandwidths_hz(config: SimConfig) -> list:
    """
    Return the bandwidths (Hz) a table rate settles with: the output filter's and the loops'.

    Not the open-loop sense mode's (E9: 0.12 Hz at the default Q): a table rate starts in
    the sense mode's steady response to it (``operating_point.with_rate_response``).
    """
    return modes.of(config).settle_bandwidths(config)


def measure(bench: SimConfig,
            log: Optional[Callable[[str], None]] = None) -> Tuple[TableReading, ...]:
    """
    Run the tables of a bench configuration (``_bench``): the reference's (K2), then the series'.

    The series' tables (K3) read with the reference table's ``V_ref``, the part's trim.
    """
    reference = bench.thermal.reference_temperature
    scale, zero, zero_q, reference_v = _table(bench, log)
    if not (math.isfinite(scale) and scale != 0.0 and math.isfinite(zero)):
        raise SimulationError(
            f'gyro.calibration.source: the factory rate table reads no rate on this device '
            f'(scale factor {scale:.3g} {readout_unit(bench)} per rad/s: is the drive on?); '
            f'use given or ideal')
    out = [TableReading(float(reference), scale, zero, zero_q, reference_v)]
    for kelvin in bench.gyro.calibration_temperature_points:
        if kelvin == reference:
            continue
        at = replace(bench, run=replace(bench.run, temperature_times=(0.0,),
                                        temperature_values=(kelvin,)))
        out.append(TableReading(float(kelvin), *_table(at, log, reference_v)))
    return tuple(out)


def _calibration(bench: SimConfig, tables: Sequence[TableReading]) -> Calibration:
    """Return the calibration of a bench's tables: ``S``, ``b`` (K2) and the fit (K3)."""
    ref, series = tables[0], tables[1:]
    coefficients: Tuple[float, ...] = ()
    if series:
        kelvins = [r.temperature_k for r in series]
        coefficients = (fit_temperature_series(ref.temperature_k, kelvins,
                                               [r.bias - ref.bias for r in series])
                        + fit_temperature_series(
                            ref.temperature_k, kelvins,
                            [r.scale_factor / ref.scale_factor - 1.0 for r in series]))
    return Calibration('factory', ref.bias, ref.scale_factor, readout_unit(bench),
                       ref.temperature_k, coefficients, ref.readout_reference_v)


def _table(bench: SimConfig, log: Optional[Callable[[str], None]],
           reference_v: float = 0.0) -> Tuple[float, float, float, float]:
    """
    Return ``(S, r(0), r_q(0), V_ref)`` of the three table rates (K2) on a bench, at its die T.

    ``V_ref`` is the open-loop readout's drive pick-off amplitude (K1): ``reference_v`` when
    given (the part's trim, held over the temperature series), else the one at rate 0, which
    the runs at +-W keep (their operating points are lower: the pair's response to the rate).
    The runs at +-W go first: the zero-rate run settles to a fraction of their reading.
    """
    sims = {}
    for rate in (0.0, FACTORY_RATE, -FACTORY_RATE):
        cfg = replace(bench, run=replace(bench.run, rate_values=(rate,)))
        state = operating_point.start_state(thermal.start_state_device(cfg))
        raw = Calibration('given', 0.0, 1.0, readout_unit(bench),
                          readout_reference_v=reference_v)
        sims[rate] = Simulator(cfg, state, calibration=raw)
        if rate == 0.0 and not reference_v and not modes.of(bench).rebalance:
            reference_v = sims[rate].sense.electronics.readout_reference_v
    if log is not None:
        log(f'calibrating the device on a simulated rate table at '
            f'{sims[0.0].device_temperature:.2f} K (0, +-10 deg/s, each until it settles)')
    plus, _ = _settled_reading(sims[FACTORY_RATE], None)
    minus, _ = _settled_reading(sims[-FACTORY_RATE], None)
    zero, zero_quadrature = _settled_reading(sims[0.0], 0.5 * (abs(plus) + abs(minus)))
    return (plus - minus) / (2.0 * FACTORY_RATE), zero, zero_quadrature, float(reference_v)


def _settled_reading(sim, scale: Optional[float]) -> Tuple[float, float]:
    """
    Return a table run's settled reading and quadrature reading (window means, K1).

    After the settling of :func:`_bandwidths_hz` (:data:`FACTORY_SETTLE_TIME_CONSTANTS` time
    constants, at least :data:`FACTORY_MIN_SETTLE_S`), means over successive windows of
    :data:`FACTORY_AVERAGE_S` until two in a row differ by at most
    :data:`FACTORY_TOLERANCE` of ``scale`` (None: of the reading), the later one returned
    with the quadrature's mean over the same window; at most :data:`FACTORY_MAX_S` (then a
    RuntimeWarning says how far it was).
    """
    cfg = sim.config
    per_block = cfg.run.block_samples
    rate_hz = cfg.run.output_rate
    tau = 1.0 / (2.0 * math.pi * min(_bandwidths_hz(cfg)))
    settle = max(FACTORY_SETTLE_TIME_CONSTANTS * tau, FACTORY_MIN_SETTLE_S)

    def mean_over(seconds: float) -> Tuple[float, float]:
        outputs = [sim.advance_samples(per_block).rate_output
                   for _ in range(int(math.ceil(seconds * rate_hz / per_block)))]
        return (float(np.mean(np.concatenate([o.rate for o in outputs]))),
                float(np.mean(np.concatenate([o.quadrature for o in outputs]))))
    mean_over(settle)
    previous, _ = mean_over(FACTORY_AVERAGE_S)
    elapsed = settle + FACTORY_AVERAGE_S
    while True:
        current, quadrature = mean_over(FACTORY_AVERAGE_S)
        elapsed += FACTORY_AVERAGE_S
        change = abs(current - previous)
        if change <= FACTORY_TOLERANCE * abs(current if scale is None else scale):
            return current, quadrature
        if elapsed >= FACTORY_MAX_S:
            warnings.warn(f'gyro.calibration: the factory table did not settle within '
                          f'{FACTORY_MAX_S:g} s (its last windows differ by {change:.3g}); '
                          f'the calibration takes the last', RuntimeWarning, stacklevel=3)
            return current, quadrature
        previous = current


def table_at(config: SimConfig, kelvin: float, held: Calibration) -> Tuple[float, float]:
    """
    Return ``(S, r(0))`` of the factory's table (K2) on this device with its die at ``kelvin``.

    The die steady at ``kelvin`` (core.thermal T3-T6), noise off, read relative to the
    readout reference ``held`` was trimmed with (K1): a temperature test of IEEE Std 1431
    on the device as owned. ``r(0) / S_held - b_held`` is then its zero-rate output with
    that calibration held, ``S / S_held - 1`` its scale-factor error.
    """
    bench = _bench(config)
    if kelvin != bench.thermal.reference_temperature:
        bench = replace(bench, run=replace(bench.run, temperature_times=(0.0,),
                                           temperature_values=(float(kelvin),)))
    scale, zero, _, _ = _table(bench, None, held.readout_reference_v)
    return scale, zero
