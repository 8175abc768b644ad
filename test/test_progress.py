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

"""Tests of progress.py: whole lines, never carriage-return frames, into what is not a tty."""

import io

import pytest
from ring_gyro_sim import progress


@pytest.fixture
def at_once(monkeypatch):
    """No delay and no interval: every update is drawn (the defaults are 2 s and 5 s)."""
    monkeypatch.setattr(progress, 'DELAY_S', 0.0)
    monkeypatch.setattr(progress, 'PIPE_INTERVAL_S', 0.0)


def test_the_counter_writes_whole_lines_into_a_log(at_once):
    log = io.StringIO()
    bar = progress.Counter(4, initial=1, enabled=True, name='sweep', stream=log)
    bar.update(1)
    bar.write('[sweep] point failed: shock.peak_g = 1000 (abc): boom')
    bar.update(2)
    bar.close()
    text = log.getvalue()
    assert '\r' not in text and '\x1b[' not in text, repr(text)
    lines = text.splitlines()
    assert '[sweep] point failed: shock.peak_g = 1000 (abc): boom' in lines
    assert lines[-1].startswith('sweep: 100%') and '4/4' in lines[-1], lines


def test_a_disabled_counter_still_writes_its_notes():
    log = io.StringIO()
    bar = progress.Counter(2, enabled=False, stream=log)
    bar.update(2)
    bar.write('a note')
    bar.close()
    assert log.getvalue() == 'a note\n'


def test_the_progress_note_goes_above_the_bar_or_alone(at_once, capsys):
    bar = progress.Progress(1.0, enabled=True, name='run')
    bar.note('computing the start state')
    bar.update(1.0)
    bar.close()
    silent = progress.Progress(1.0, enabled=False)
    silent.note('said without a bar')
    err = capsys.readouterr().err
    assert '\r' not in err
    assert 'computing the start state' in err.splitlines()
    assert err.splitlines()[-1] == 'said without a bar'
