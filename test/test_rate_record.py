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

"""Tests of rate_record.py (``ring_gyro rate``) beyond the gyroscope's own (test_gyro.py)."""

from pathlib import Path

import pytest
from ring_gyro_sim import cli
from ring_gyro_sim.rate_record import rate_report
from ring_gyro_sim.recording.errors import RecordingError

REPO = Path(__file__).resolve().parents[1]

RESONATOR = """\
/**:
  ros__parameters:
    duration: 0.01
    modes: {companions: false}
    gyro: {enabled: false}
    control: {mode: open_loop}
    drive: {start_on: rest}
"""


def test_a_recording_without_the_rate_is_refused(tmp_path, capsys):
    # Refused, not an exit 0 with an empty rate.csv and a blank rate.png
    params = tmp_path / 'resonator.yaml'
    params.write_text(RESONATOR, encoding='utf-8')
    recording = tmp_path / 'r.mcap'
    assert cli.main(['run', str(params), '-o', str(recording), '--no-progress']) == 0
    capsys.readouterr()
    with pytest.raises(RecordingError, match=r'holds no /ring_gyro/rate messages: it was '
                                             r'recorded without the gyroscope'):
        rate_report(str(recording), str(tmp_path / 'a'))
    assert cli.main(['rate', str(recording), '--out', str(tmp_path / 'b')]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ring_gyro rate: error: ') and err.count('\n') == 1, err
    assert capsys.readouterr().out == ''
    assert not list(tmp_path.glob('*/rate.*'))


def test_the_plot_is_given_the_recovery(tmp_path, monkeypatch):
    # rate.png marks the recovery: the figures' rate_recovery_s
    # (None: not back by the end of this 0.1 s after the shock) is what the plot gets
    from ring_gyro_sim.analysis import plotting
    seen = {}

    def plot_rate(traces, path, **kwargs):
        seen.update(kwargs)
        return False
    monkeypatch.setattr(plotting, 'plot_rate', plot_rate)
    recording = tmp_path / 'demo.mcap'
    assert cli.main(['run', str(REPO / 'config' / 'demo.yaml'), '--duration', '0.6', '-o',
                     str(recording), '--no-progress', '--json']) == 0
    figures = rate_report(str(recording), str(tmp_path / 'rate'))
    assert seen['shock_s'] == pytest.approx(0.5)
    assert 'recovery_s' in seen and seen['recovery_s'] == figures['rate_recovery_s']
