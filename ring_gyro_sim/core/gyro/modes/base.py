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
What a mode of operation of the gyroscope is: its loops, its readout, its axes, its refusals.

A mode (``control.mode``) is one way to run the ring as a gyroscope. It says

- which loops run: the drive's PLL and AGC (``closed``, C1-C6 of ``core.gyro.control``)
  and force-to-rebalance on the sense axis (``rebalance``, C7-C9);
- what the readout ``r`` of the rate is (K1): the demodulated sense pick-off in V, or the
  rebalance force in m/s^2;
- which ring coordinates are the drive and the sense axes: the cos and sin members of the
  ``drive_order`` theta pair (the 2theta pair, q2 and q2s, for every mode here);
- what a configuration must have for it, and why an engine cannot run it.

The modes are the modules of this package (``open_loop``, ``closed_loop``, ``rebalance``)
and :data:`ring_gyro_sim.core.gyro.modes.MODES` is the table that picks. A new mode is one
module with one :class:`Mode` and one row there (doc/architecture.md).
"""

from dataclasses import dataclass
from typing import List, NamedTuple, Optional, Tuple

__all__ = ['Axes', 'Mode']


class Axes(NamedTuple):
    """The coordinate indices of the drive and the sense axes (-1: not in the model)."""

    drive: int
    sense: int


@dataclass(frozen=True)
class Mode:
    """
    One mode of operation (``control.mode``); subclasses add their checks.

    Attributes
    ----------
    name : str
        The value of ``control.mode``.
    title : str
        How reports name it.
    closed : bool
        Whether the drive is the closed loop (PLL + AGC) rather than the paper's fixed
        ``drive.amplitude`` at ``drive.frequency``.
    rebalance : bool
        Whether a loop nulls the sense axis and the rate is read from its force.
    drive_order : int
        n of the n-theta pair that is driven and sensed: the drive is its cos member q_n,
        the sense its sin companion q_ns.

    """

    name: str
    title: str
    closed: bool
    rebalance: bool
    drive_order: int = 2

    @property
    def readout_unit(self) -> str:
        """Return the unit of the readout ``r`` of (K1) and of ``S`` per rad/s."""
        return 'm/s^2' if self.rebalance else 'V'

    def axes(self, config) -> Axes:
        """
        Return the indices of the drive and the sense axes in the ring's coordinates.

        The coordinates are the cos modes 1theta .. N_R theta, then (``modes.companions``)
        their sin companions in the same order (``core.structure.coordinate_names``).
        """
        n = config.modes.count
        order = self.drive_order
        drive = order - 1 if n >= order else -1
        sense = n + order - 1 if config.modes.companions and n >= order else -1
        return Axes(drive, sense)

    def settle_bandwidths(self, config) -> List[float]:
        """
        Return the bandwidths (Hz) a table rate settles with: the output filter's and the loops'.

        Not the open-loop sense mode's (E9: 0.12 Hz at the default Q): a table rate starts in
        the sense mode's steady response to it (``operating_point.with_rate_response``).
        """
        c = config.control
        out = [config.gyro.filter_bandwidth]
        if self.rebalance:
            out.append(c.rebalance_bandwidth)
        if self.closed:
            out += [c.agc_bandwidth, c.pll_bandwidth]
        return out

    def refusal(self, config) -> Optional[Tuple[str, str]]:
        """Return ``(parameter, reason)`` when ``config`` cannot run this mode, else None."""
        return None

    def averaged_refusal(self, config) -> Optional[str]:
        """Return why the averaged model cannot run this mode; None when it can."""
        if not self.closed:
            return 'the averaged model is the closed-loop gyroscope'
        return 'the averaged model is the closed-loop gyroscope with force-to-rebalance'
