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
The gyroscope's modes of operation (``control.mode``), one module each, and the table.

- ``open_loop``: the paper's fixed drive, the sense mode read open loop (V);
- ``closed_loop``: PLL + AGC on the drive, the sense mode read open loop (V);
- ``rebalance``: PLL + AGC and force-to-rebalance, the rate read from the force (m/s^2).

:func:`of` returns the :class:`~ring_gyro_sim.core.gyro.modes.base.Mode` of a configuration.
"""

from typing import Dict

from ring_gyro_sim.core.gyro.modes.base import Axes, Mode
from ring_gyro_sim.core.gyro.modes.closed_loop import CLOSED_LOOP
from ring_gyro_sim.core.gyro.modes.open_loop import OPEN_LOOP
from ring_gyro_sim.core.gyro.modes.rebalance import REBALANCE

__all__ = ['Axes', 'MODES', 'Mode', 'of']

MODES: Dict[str, Mode] = {m.name: m for m in (OPEN_LOOP, CLOSED_LOOP, REBALANCE)}
"""Every mode by its ``control.mode`` name."""


def of(config) -> Mode:
    """Return the mode of ``config`` (a SimConfig, or its ControlParams)."""
    control = getattr(config, 'control', config)
    return MODES[control.mode]
