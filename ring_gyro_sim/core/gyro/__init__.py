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
The gyroscope: everything that turns the ring into a rate sensor, in one place.

Modules (import from them directly; nothing is re-exported here):

- ``operating_point``: the drive's operating point: the start state of a run (the forced
  orbit by shooting, memoised per device), the response to the rate at t = 0, the PLL's
  lock frequency;
- ``electronics``: the pick-off amplifiers, the demodulator, the low-pass and the rate
  output, their noise and the closed forms of the scale factor and the angle random walk
  (E1-E14);
- ``control``: the closed loops: PLL, AGC and force-to-rebalance (C1-C9);
- ``channel``: :class:`~ring_gyro_sim.core.gyro.channel.SenseChain`, the electronics at the
  operating point, which the :class:`~ring_gyro_sim.core.engine.full.Simulator` owns and
  rebuilds on every parameter change;
- ``stats``: the figures of a run's rate output and drive (recovery after a shock, means).

The rotation itself (the Coriolis and centrifugal terms of the rotating frame) is part of the
equations of motion: ``core.structure.gyroscopic_coefficient`` and the compiled kernels.
"""

__all__ = ['channel', 'control', 'electronics', 'operating_point', 'stats']
