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
``control.mode: closed_loop``: PLL and AGC on the drive, the sense mode read open loop.

A PLL locks an NCO to the drive pick-off and an AGC holds the drive amplitude
(C1-C6 of ``core.gyro.control``, doc/control.md); the rate is read from the demodulated
sense pick-off (E5-E8), in V, as in the open loop.
"""

from typing import Optional, Tuple

from ring_gyro_sim.core.gyro.modes.base import Mode

__all__ = ['CLOSED_LOOP', 'ClosedLoop', 'loop_refusal']

CONTROL_MIN_SAMPLES = 8
"""Fewest output samples per loop period (the demodulation's least-squares fit)."""


def loop_refusal(config) -> Optional[Tuple[str, str]]:
    """Return ``(parameter, reason)`` when ``config`` cannot run the drive's loops."""
    c = config.control
    if config.modes.count < 2:
        return 'control.mode', f'{c.mode} drives the 2theta mode: needs at least 2 modes'
    if config.drive.frequency <= 0.0:
        return 'drive.frequency', (f'is the centre of the NCO of the closed loop: must be > 0 '
                                   f'with control.mode: {c.mode}')
    if c.pll_range >= config.drive.frequency:
        return 'control.pll_range', (f'must be below drive.frequency '
                                     f'({config.drive.frequency:g} Hz), got {c.pll_range:g} Hz')
    ratio = config.run.output_rate / c.rate
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        return 'control.rate', (f'output.rate ({config.run.output_rate:g} Hz) must be a whole '
                                f'multiple of it, got {c.rate:g} Hz')
    if round(ratio) < CONTROL_MIN_SAMPLES:
        return 'control.rate', (f'needs at least {CONTROL_MIN_SAMPLES} output samples per loop '
                                f'period (output.rate / control.rate = {round(ratio)})')
    if c.rate > config.drive.frequency / 2.0:
        return 'control.rate', (f'the demodulation integrates over one loop period: at most '
                                f'half of drive.frequency ({config.drive.frequency / 2.0:g} '
                                f'Hz), got {c.rate:g} Hz')
    return None


class ClosedLoop(Mode):
    """The drive's loops: refuses what they cannot run."""

    def refusal(self, config) -> Optional[Tuple[str, str]]:
        """Return ``(parameter, reason)`` when ``config`` cannot run the loops, else None."""
        return loop_refusal(config)


CLOSED_LOOP = ClosedLoop(name='closed_loop', title='closed loop (PLL + AGC)', closed=True,
                         rebalance=False)
