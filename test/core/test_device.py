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
The seeded draw of a device from its manufacturing spread (core.device, D1-D5).

Through :func:`build_config`, the path every run takes: the same seed is the same
configuration bit for bit (in this process and in a fresh one), seeds differ, the
configuration rebuilds from its flat parameters (which hold the configured values and the
seed), the draw adds to the configured pair as P2 / P3 add matrices, and 2000 seeds have the
statistics the spreads say (with a control: the same check refuses spreads 10 % off). A
draw outside the table's ranges is refused naming the seed and the check.
"""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import build_config, device_values, SPECS, to_flat
from scipy import stats

DRAWN = ('gyro.phase_error', 'gyro.pickoff_gain_mismatch', 'gyro.sense_misalignment',
         'modes.companion_frequencies', 'modes.companion_quality_factors',
         'modes.damping_axes', 'modes.frequencies', 'modes.frequency_axes',
         'modes.quality_factors')
# a configured imperfect pair (doc/imperfections.md): 20 mHz at 10 deg, Q_y = 0.95 Q_x at 22.5
IMPERFECT = {'modes.companion_frequencies': [11200.0, 15800.02, 22000.0],
             'modes.companion_quality_factors': [120000.0, 0.95 * 64700.0, 170000.0],
             'modes.frequency_axes': [0.0, 10.0, 0.0], 'modes.damping_axes': [0.0, 22.5, 0.0],
             'gyro.phase_error': 0.002}
SPREADS = {name: SPECS[name].default for name in (
    'device.split_spread', 'device.q_mismatch_spread', 'device.misalignment_spread',
    'device.phase_error_spread', 'device.gain_mismatch_spread')}
N_DRAWS = 2000


def test_seed_zero_is_the_device_as_configured():
    plain = build_config(IMPERFECT)
    assert build_config({**IMPERFECT, 'device.seed': 0}) == plain
    assert plain.configured == () and device_values(plain) == {}
    assert all(v > 0.0 for v in SPREADS.values())  # the spreads alone draw nothing


def test_the_same_seed_is_the_same_device_bit_for_bit():
    a = build_config({'device.seed': 12345})
    b = build_config({'device.seed': 12345})
    assert a == b
    assert json.dumps(device_values(a)) == json.dumps(device_values(b))  # repr: every bit
    assert sorted(device_values(a)) == sorted(DRAWN)
    assert a != build_config({})
    # rebuilt from its flat parameters, which hold the configured values and the seed (what a
    # recording holds and a re-simulation reads)
    flat = to_flat(a)
    assert flat['device.seed'] == 12345 and flat['gyro.phase_error'] == 0.0
    assert flat['modes.companion_frequencies'] == []
    assert build_config(flat) == a
    assert to_flat(build_config(flat)) == flat


def test_a_fresh_process_draws_the_same_device():
    code = ('import json; from ring_gyro_sim.core.params import build_config, device_values; '
            'print(json.dumps(device_values(build_config({"device.seed": 12345}))))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True).stdout.strip().splitlines()[-1]
    assert out == json.dumps(device_values(build_config({'device.seed': 12345})))


def test_different_seeds_draw_different_devices():
    values = [device_values(build_config({'device.seed': s})) for s in range(1, 51)]
    for name in ('gyro.phase_error', 'gyro.sense_misalignment', 'gyro.pickoff_gain_mismatch'):
        assert len({v[name] for v in values}) == 50, name
    nominal = to_flat(build_config({}))
    for name in ('modes.frequencies', 'modes.frequency_axes', 'modes.quality_factors',
                 'modes.damping_axes'):
        assert len({v[name][1] for v in values}) == 50, name
        for v in values:  # the 1theta and 3theta pairs stay as configured
            assert [v[name][0], v[name][2]] == [(nominal[name] or [0.0] * 3)[i]
                                                for i in (0, 2)], name


def test_a_zero_spread_leaves_its_parameters_as_configured():
    config = build_config({**IMPERFECT, 'device.seed': 3, 'device.split_spread': 0.0,
                           'device.phase_error_spread': 0.0})
    plain = build_config(IMPERFECT)
    assert config.modes.frequencies == plain.modes.frequencies
    assert config.modes.companion_frequencies == plain.modes.companion_frequencies
    assert config.modes.frequency_axes == plain.modes.frequency_axes
    assert config.gyro.phase_error == plain.gyro.phase_error
    assert 'modes.frequencies' not in device_values(config)
    assert config.modes.quality_factors != plain.modes.quality_factors


def pair(config):
    """Return the 2theta pair's (K, C) per unit modal mass (P2, P3)."""
    return config.modes.pair_matrices(2)


def test_the_draw_adds_to_the_configured_pair_as_matrices():
    # (D2, D3) the drawn anisotropy adds to the configured pair's stiffness and damping: the
    # drawn device's K and C are the configured ones plus those of the draw alone on a
    # matched pair with the configured means. Checked through P2 / P3's own matrices.
    from ring_gyro_sim.core import device
    seed = 11
    drawn = build_config({**IMPERFECT, 'device.seed': seed})
    configured = build_config(IMPERFECT)
    d = device.draw(seed, **{k.split('.')[1]: v for k, v in SPREADS.items()})
    k0, c0 = pair(configured)
    k1, c1 = pair(drawn)
    f_m = 0.5 * (15800.0 + 15800.02)
    phi = 4.0 * math.radians(d.split_axis_deg)
    dk = (2.0 * math.pi) ** 2 * f_m * d.split_hz * np.array(
        [[math.cos(phi), math.sin(phi)], [math.sin(phi), -math.cos(phi)]])
    np.testing.assert_allclose(k1, k0 + dk, rtol=0, atol=1e-12 * k0[0, 0])
    assert abs(dk[0, 1]) > 1e-3 * abs(k0[0, 1])  # the draw moves the coupling measurably
    c_mean = 0.5 * (c0[0, 0] + c0[1, 1])
    psi = 4.0 * math.radians(d.damping_axis_deg)
    e = d.q_mismatch
    dc = c_mean * e / (2.0 + e) * np.array(
        [[math.cos(psi), math.sin(psi)], [math.sin(psi), -math.cos(psi)]])
    # the damping is rebuilt as c = w / Q with the drawn w: equal to 1e-12 relative
    np.testing.assert_allclose(c1, c0 + dc, rtol=0, atol=1e-10 * c_mean)
    assert drawn.gyro.phase_error == 0.002 + d.phase_error_rad


def population(count=N_DRAWS, **values):
    """Return the drawn 2theta pairs and electronics of seeds 1..count, as arrays."""
    out = {k: [] for k in ('split', 'f_axis', 'ratio', 't_axis', 'mis', 'phase', 'gain')}
    for seed in range(1, count + 1):
        c = build_config({**values, 'device.seed': seed})
        m, g = c.modes, c.gyro
        w_x, w_y = m.frequencies[1], m.companion_frequencies[1]
        out['split'].append(w_x - w_y)
        out['f_axis'].append(m.frequency_axes[1])
        out['ratio'].append(math.log((w_x / m.quality_factors[1]) / (
            w_y / m.companion_quality_factors[1])))  # ln(c_x / c_y) = |ln(1 + e)|
        out['t_axis'].append(m.damping_axes[1])
        out['mis'].append(g.sense_misalignment)
        out['phase'].append(g.phase_error)
        out['gain'].append(g.pickoff_gain_mismatch)
    return {k: np.array(v) for k, v in out.items()}


def spread_errors(draws, spreads):
    """
    Return the relative errors of the drawn spreads against ``spreads``, and the problems.

    The split and the mismatch as 2-D vectors ``size e^{i 4 theta}`` (their axes uniform over
    45 deg): each component zero-mean with sigma / sqrt(2); the electronics' draws
    zero-mean with sigma. Means within 4 standard errors, components uncorrelated.
    """
    errors, problems = {}, []
    n = len(draws['split'])
    columns = []
    for name, size, axis in (('split_spread', draws['split'], draws['f_axis']),
                             ('q_mismatch_spread', draws['ratio'], draws['t_axis'])):
        phi = np.radians(4.0 * axis)
        sigma = spreads[f'device.{name}'] / math.sqrt(2.0)
        for part in (size * np.cos(phi), size * np.sin(phi)):
            columns.append(part)
            errors[name] = max(errors.get(name, 0.0), abs(np.std(part, ddof=1) / sigma - 1.0))
            if abs(np.mean(part)) > 4.0 * sigma / math.sqrt(n):
                problems.append(f'{name}: mean {np.mean(part):.3g}')
        if np.any(size < 0.0):
            problems.append(f'{name}: a principal value pair out of order')
        p = stats.kstest((axis % 45.0) / 45.0, 'uniform').pvalue
        if p < 1e-3:
            problems.append(f'{name}: axes not uniform over 45 deg (KS p = {p:.2g})')
    for name, key in (('misalignment_spread', 'mis'), ('phase_error_spread', 'phase'),
                      ('gain_mismatch_spread', 'gain')):
        sigma = spreads[f'device.{name}']
        columns.append(draws[key])
        errors[name] = abs(np.std(draws[key], ddof=1) / sigma - 1.0)
        if abs(np.mean(draws[key])) > 4.0 * sigma / math.sqrt(n):
            problems.append(f'{name}: mean {np.mean(draws[key]):.3g}')
    corr = np.corrcoef(np.array(columns))
    worst = np.max(np.abs(corr - np.eye(len(columns))))
    if worst > 4.5 / math.sqrt(n):
        problems.append(f'correlated draws ({worst:.3f})')
    return errors, problems


def test_2000_draws_have_the_spreads_statistics():
    draws = population()
    errors, problems = spread_errors(draws, SPREADS)
    print({k: f'{v:.3%}' for k, v in errors.items()})
    assert problems == []
    # the standard error of a sample sigma over 2000 draws is 1.6 %: 5 % is 3 of them
    assert max(errors.values()) < 0.05, errors
    # control: the same check refuses spreads 10 % off
    off = {k: 1.1 * v for k, v in SPREADS.items()}
    refused, _ = spread_errors(draws, off)
    assert min(refused.values()) > 0.05, refused


def test_a_draw_outside_the_table_is_refused_naming_the_seed():
    values = {'device.misalignment_spread': 15.0}  # |z| > 1.5 leaves +-22.5 deg
    verdicts = {}
    for seed in range(1, 30):
        try:
            build_config({**values, 'device.seed': seed})
            verdicts[seed] = ''
        except ParameterError as exc:
            verdicts[seed] = str(exc)
    refused = {s: m for s, m in verdicts.items() if m}
    assert refused and len(refused) < len(verdicts)  # some draws pass, some do not
    seed, message = next(iter(refused.items()))
    assert message.startswith(f'device.seed: seed {seed} draws an invalid device: '
                              f'gyro.sense_misalignment: must be '), message
    # a Q mismatch at or below -1 is refused by the draw itself (D3)
    q_values = {'device.q_mismatch_spread': 0.5}
    for seed in range(1, 400):
        try:
            build_config({**q_values, 'device.seed': seed})
        except ParameterError as exc:
            assert str(exc).startswith(f'device.seed: seed {seed} draws an invalid device: '
                                       f'device.q_mismatch_spread: draws Q_y / Q_x - 1 = ')
            break
    else:
        pytest.fail('no seed of 400 drew e <= -1 at sigma 0.5 (expected ~9)')
