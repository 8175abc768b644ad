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
``control.mode: rebalance``: the closed-loop drive with force-to-rebalance (the default).

The drive's PLL and AGC as in ``closed_loop``, and a loop that nulls the sense axis q2s
(C7-C9 of ``core.gyro.control``): the rate is read from the force it applies, in m/s^2
(K1). It is the mode the averaged model runs (``core.engine.averaged``, S5-S8).
"""

from typing import Optional, Tuple

from ring_gyro_sim.core.gyro.modes.closed_loop import ClosedLoop, loop_refusal

__all__ = ['REBALANCE', 'Rebalance']


class Rebalance(ClosedLoop):
    """Force-to-rebalance: the loops' refusals and those of the rebalance force."""

    def refusal(self, config) -> Optional[Tuple[str, str]]:
        """Return ``(parameter, reason)`` when ``config`` cannot run the mode, else None."""
        refused = loop_refusal(config)
        if refused is None and not config.gyro.enabled:
            refused = ('control.mode', 'rebalance needs gyro.enabled: true (the rebalance '
                       'force acts on the sense mode q2s)')
        return refused

    def averaged_refusal(self, config) -> Optional[str]:
        """Return why the averaged model cannot run this gyroscope; None when it can."""
        c = config
        if not (c.gyro.enabled and c.modes.companions and c.modes.count >= 2):
            return 'the averaged model is the closed-loop gyroscope with force-to-rebalance'
        return None


REBALANCE = Rebalance(name='rebalance', title='closed loop + force-to-rebalance', closed=True,
                      rebalance=True)
