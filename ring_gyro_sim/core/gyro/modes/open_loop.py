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
``control.mode: open_loop``: the paper's drive, the sense mode read open loop.

The 2theta mode is driven by the fixed ``A_e cos(omega t)`` of ``drive.amplitude`` and
``drive.frequency`` (section 3.4 of the paper); no loop runs. With ``gyro.enabled`` the
rate is read from the sense pick-off, demodulated against the drive's phase (E5-E8), in V.
It is the only mode a shock can knock to the lower branch for good (Case 3): nothing holds the
amplitude.
"""

from ring_gyro_sim.core.gyro.modes.base import Mode

__all__ = ['OPEN_LOOP']

OPEN_LOOP = Mode(name='open_loop', title='open loop', closed=False, rebalance=False)
