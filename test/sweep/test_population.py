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
A device population through the real sweep engine (``kind: gyroscope``, doc/populations.md).

Three devices of the default gyroscope (``device.seed`` 1 to 3; no ``base``: the package's
defaults), each with the factory's table at the reference and at 318.15 K, on a local cluster
of two workers: every record holds the datasheet figures and its device, the device is the
one ``build_config`` draws from the seed, the quadrature is the drawn split's in closed form,
and one point re-run in this process gives the same numbers bit for bit.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from ring_gyro_sim.core.bench import factory
from ring_gyro_sim.core.gyro.control import KAPPA_2
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.sweep import load_spec, point, results, run_sweep
from ring_gyro_sim.sweep.store import PointStore
from sweep_harness import write_spec

REPO = Path(__file__).resolve().parents[2]
SPEC = """\
kind: gyroscope
set:
  gyro.calibration.temperature_points: [318.15]
axes:
  device.seed: {range: [1, 3]}
"""


@pytest.fixture(scope='module')
def population(tmp_path_factory):
    """Run the three-device population on two local workers: (spec, output dir, outcome)."""
    d = tmp_path_factory.mktemp('population')
    spec = load_spec(str(write_spec(d, SPEC)))
    with pytest.MonkeyPatch.context() as mp:  # the workers' tables: measured, stored apart
        mp.setenv(factory.CACHE_ENV, str(d / 'cache'))
        outcome = run_sweep(spec, d / 'out', workers=2, progress=False,
                            dashboard_address=None, plots=True)
    return spec, d / 'out', outcome


def records(spec, out):
    """Return the stored records of the spec's points, in axis order."""
    store = PointStore(out, create=False)
    return [store.read(p.key) for p in spec.points()]


def test_each_device_gets_its_datasheet_figures(population):
    spec, out, outcome = population
    assert (outcome.computed, outcome.failures) == (3, [])
    ds = outcome.dataset
    assert list(ds['device.seed'].values) == [1, 2, 3]
    assert set(point.GYRO_METRICS) <= set(ds.data_vars)
    for name in point.GYRO_METRICS:
        assert np.all(np.isfinite(ds[name].values)), name
        assert ds[name].attrs['units'] == point.GYRO_METRICS[name][1]
    nominal = [r['nominal'] for r in records(spec, out)]
    assert all(n == nominal[0] for n in nominal)  # one nominal device, the setup task's
    assert nominal[0]['scale_factor_error_ppm'] == 0.0
    # every device differs from the nominal and from the others
    assert len(set(ds['bias_rad_s'].values)) == 3
    assert not np.any(ds['scale_factor'].values == nominal[0]['scale_factor'])


def test_the_device_is_the_one_its_seed_draws(population):
    spec, out, _ = population
    for p, record in zip(spec.points(), records(spec, out)):
        seed = dict(p.coords)['device.seed']
        config = build_config({'device.seed': seed,
                               'gyro.calibration.temperature_points': [318.15]})
        assert p.config() == config
        drawn = point.device_figures(config)
        assert {k: record['metrics'][k] for k in drawn} == drawn
        # the quadrature is the drawn split's, K_sc / (2 kappa omega) (P2, K1)
        k, _ = config.modes.pair_matrices(2)
        closed_form = k[0, 1] / (2.0 * KAPPA_2 * 2.0 * math.pi * 15800.0)
        print(f'seed {seed}: quadrature {record["metrics"]["quadrature_rad_s"]:.6e} rad/s, '
              f'closed form {closed_form:.6e}')
        assert record['metrics']['quadrature_rad_s'] == pytest.approx(closed_form, rel=1e-2)


def test_one_point_run_again_gives_the_same_numbers_bit_for_bit(population, monkeypatch):
    spec, out, _ = population
    p = spec.points()[1]
    stored = PointStore(out, create=False).read(p.key)
    # this process runs the tables again: no stored tables, none memoised
    monkeypatch.setenv(factory.CACHE_ENV, '')
    monkeypatch.setattr(factory, '_MEMO', type(factory._MEMO)())
    again = point.compute(p)  # its own nominal device and tables
    for key in ('metrics', 'nominal'):  # the JSON text: repr, every bit of every float
        assert json.dumps(again[key], sort_keys=True) == json.dumps(stored[key], sort_keys=True)
    assert again['metrics'] != PointStore(out, create=False).read(spec.points()[0].key)[
        'metrics']  # control: another device's numbers are not these


def test_the_datasheet_is_the_populations_spread(population):
    # datasheet.json: per figure over the devices, min / median / max, the mean, the sample
    # sigma (ddof 1) and mean -+ 3 sigma; datasheet.md the same in deg/s; population.png drawn
    _, out, outcome = population
    sheet = json.loads((out / 'datasheet.json').read_text(encoding='utf-8'))
    assert (sheet['devices'], sheet['failed']) == (3, 0)
    assert sheet['axes'] == {'device.seed': [1, 3]}
    assert list(sheet['figures']) == list(results.DATASHEET_FIGURES)
    for name, f in sheet['figures'].items():
        v = outcome.dataset[name].values
        mean, sigma = sum(v) / 3.0, math.sqrt(sum((x - sum(v) / 3.0) ** 2 for x in v) / 2.0)
        assert f['n'] == 3
        assert (f['min'], f['median'], f['max']) == (min(v), sorted(v)[1], max(v))
        assert f['mean'] == pytest.approx(mean, rel=1e-12)
        assert f['sigma'] == pytest.approx(sigma, rel=1e-12)
        assert f['mean_plus_3_sigma'] == pytest.approx(mean + 3.0 * sigma, rel=1e-12)
        assert f['mean_minus_3_sigma'] == pytest.approx(mean - 3.0 * sigma, rel=1e-12)
    bias = sheet['figures']['bias_rad_s']
    assert (bias['display_units'], bias['display_scale']) == ('deg/s', 180.0 / math.pi)
    table = (out / 'datasheet.md').read_text(encoding='utf-8')
    assert f'| bias (`bias_rad_s`) | deg/s | 3 | {math.degrees(bias["min"]):.3g} |' in table
    assert str(out / 'population.png') in outcome.files['plots']
    assert (out / 'population.png').stat().st_size > 10000


def test_the_population_spec_of_the_docs_is_this_one_over_100_seeds(tmp_path):
    # config/sweep_population.yaml (doc/populations.md) is SPEC over seeds 1 to 100
    spec = load_spec(str(REPO / 'config' / 'sweep_population.yaml'))
    short = load_spec(str(write_spec(tmp_path, SPEC)))
    assert spec.kind == short.kind == 'gyroscope'
    assert spec.fixed == short.fixed == {'gyro.calibration.temperature_points': [318.15]}
    assert [p.key for p in spec.points()[:3]] == [p.key for p in short.points()]
    assert [dict(p.coords)['device.seed'] for p in spec.points()] == list(range(1, 101))
