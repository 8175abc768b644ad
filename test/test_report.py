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

"""Tests of report.py's summary.md (the runs themselves: test/sweep/test_case4.py, slow)."""

import pytest
from ring_gyro_sim import report


def summary_md(quick):
    return report._markdown({'quick': quick, 'wall_time_s': 60.0, 'workers': 2, 'cases': []})


@pytest.mark.parametrize('quick', [True, False])
def test_the_quick_summary_says_whose_numbers_its_notes_quote(quick):
    # `report --quick`'s summary.md must not quote the full run's return times and
    # frequencies (Case 1: 4.2 s, 10.75 kHz) as its own, against its own tables
    text = summary_md(quick)
    notes = text.split('## Where we differ from the paper, and why\n', 1)[1]
    first = notes.strip().splitlines()[0]
    if quick:
        assert first == report.QUICK_DIFFERENCES_NOTE
        assert 'not this run' in first and '`ring_gyro report` without `--quick`' in first
    else:
        assert first.startswith('- Outer voltage') and report.QUICK_DIFFERENCES_NOTE not in text
    assert 'Case 1: 4.2 s instead of about 7 s' in notes
