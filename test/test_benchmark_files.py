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
The benchmark's parameter files (``benchmarks/*.yaml``) load and run.

``make bench`` times these files; ``ring_gyro run benchmarks/<file>`` must reproduce each, so
each one is loaded as the CLI loads it and run offline past the start of its shock (10 ms)
from the start state the file asks for (the drive's upper branch).
"""

import math
import pathlib

import numpy as np
import pytest
from ring_gyro_sim import offline
from ring_gyro_sim.core.params import STANDARD_GRAVITY
from ring_gyro_sim.paramfile import load_yaml

BENCH = pathlib.Path(__file__).resolve().parents[1] / 'benchmarks'
FILES = ('paper.yaml', 'nr3_companions.yaml', 'nr5_companions.yaml')


def test_every_benchmark_file_is_tested():
    assert sorted(p.name for p in BENCH.glob('*.yaml')) == sorted(
        FILES + ('gyro.yaml', 'gyro_closed.yaml', 'gyro_imperfect.yaml'))


def test_the_gyroscope_benchmark_file_runs_with_its_rate_output():
    # benchmarks/gyro.yaml: config/gyro.yaml's operating point, 10 deg/s, a
    # 10 000 g shock at 0.5 s, nothing recorded; 20 ms here: the rate output is on and right.
    config = load_yaml(str(BENCH / 'gyro.yaml'))
    assert config.run.record_path == '' and config.run.real_time_factor == 0.0
    assert config.gyro.enabled and config.modes.companions
    (at_ns, peak_x, peak_y), = config.run.scheduled_shocks()
    assert at_ns == 500_000_000 and peak_y == 0.0
    assert peak_x == pytest.approx(10_000.0 * STANDARD_GRAVITY, rel=1e-12)
    summary = offline.run_offline(config, duration_s=0.02, progress=False)
    assert summary.extra['rate_mean_rad_s'] == pytest.approx(math.radians(10.0), rel=0.01)


def test_the_closed_loop_benchmark_file_is_the_gyroscope_file_with_the_loops():
    # benchmarks/gyro_closed.yaml: the same run with PLL, AGC and rebalance.
    open_loop = load_yaml(str(BENCH / 'gyro.yaml'))
    closed = load_yaml(str(BENCH / 'gyro_closed.yaml'))
    assert closed.control.mode == 'rebalance'
    assert closed.run == open_loop.run and closed.gyro == open_loop.gyro
    summary = offline.run_offline(closed, duration_s=0.02, progress=False)
    assert summary.extra['rate_mean_rad_s'] == pytest.approx(math.radians(10.0), rel=0.01)
    assert summary.extra['pll_lost_lock'] is False


def test_the_imperfect_benchmark_file_is_the_closed_loop_file_on_an_imperfect_ring():
    # benchmarks/gyro_imperfect.yaml: the same run, a coupled 2theta pair and the
    # pick-off's errors; factory-calibrated, it reads 10 deg/s as the perfect ring does
    closed = load_yaml(str(BENCH / 'gyro_closed.yaml'))
    imperfect = load_yaml(str(BENCH / 'gyro_imperfect.yaml'))
    assert imperfect.run == closed.run and imperfect.control == closed.control
    assert imperfect.modes.coupled_pairs() == [2]
    assert imperfect.gyro.calibration_source == 'factory'
    summary = offline.run_offline(imperfect, duration_s=0.02, progress=False)
    assert summary.extra['rate_mean_rad_s'] == pytest.approx(math.radians(10.0), rel=0.01)


@pytest.mark.parametrize('name', FILES)
@pytest.mark.filterwarnings('ignore:drive.start_on')  # the orbit's Floquet note (companions)
def test_benchmark_file_loads_and_runs_through_its_shock(name):
    config = load_yaml(str(BENCH / name))
    assert config.run.record_path == ''  # the benchmark times runs without a recording
    assert config.drive.amplitude != 0.0 and config.drive.start_on == 'upper_branch'
    (at_ns, peak_x, peak_y), = config.run.scheduled_shocks()
    assert at_ns == 10_000_000
    assert math.hypot(peak_x, peak_y) == pytest.approx(10_000.0 * STANDARD_GRAVITY, rel=1e-12)
    companions = name != 'paper.yaml'
    assert config.modes.companions == companions
    # 45 deg: x = y = peak / sqrt 2 (the companions are excited); the paper's shock is along x.
    assert peak_y == (pytest.approx(peak_x, rel=1e-12) if companions else 0.0)
    # 12 ms: through the 6.33 us shock at 10 ms and 2 ms of ringing.
    summary = offline.run_offline(config, duration_s=0.012, progress=False)
    assert summary.status == 'finished' and not summary.contact
    assert summary.samples == 2400
    # The shock moved the ring: q1 well beyond its drive-only amplitude (the upper branch
    # puts q1 at 0 by symmetry; the shock gives microns), and q1s too at 45 deg.
    assert summary.peak_abs_m['q1'] > 1e-7
    if companions:
        assert summary.peak_abs_m['q1s'] > 1e-7
        assert np.isfinite(summary.min_gap_m) and summary.min_gap_m < config.electrodes.gap
