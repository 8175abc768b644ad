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
When a run hands the gyroscope from one engine to the other: the one hand-off policy.

``run.Run`` asks this module; nothing else decides a hand-off.

- **To the full model** at the last loop update at or before the start of a shock pulse
  (scheduled, ``scenario.shock_*``, or streamed on ``~/shock``) or of a scheduled input of
  the full model (a parameter change, a drive command, a reset: the full model's events),
  :meth:`Engine.next_scheduled_s` of the full model: the full model simulates it from its
  start.
- **Back to the averaged model** at a check (every :data:`CHECK_S` of simulated time) that
  :func:`may_hand_back` allows: the averaged model runs the gyroscope (:func:`refusal`),
  the ring free, the loops locked with force-to-rebalance on and the drive at its set-point
  (within ``validity.DRIVE_TOLERANCE``), the last ``~/rate`` sample a measurement (V1),
  nothing scheduled acting now, the last input other than a rate ``CHECK_S`` ago or more,
  and the modes the averaged model leaves out rung down below :data:`HAND_BACK_THRESHOLD`
  of the gap (:func:`fast_mode_amplitude`).
- **Never averaged**: a gyroscope the averaged model does not run (:func:`refusal`: open
  loop, no rebalance, the untruncated force, a ``~/rate`` not at the loops' rate, an
  environment, which acts at every sample).

Each condition depends on the state and on the acting times of the inputs that have acted,
never on when an input arrived: a re-simulation makes the same hand-offs.
"""

import math
from typing import Callable, Optional

import numpy as np
from ring_gyro_sim.core.gyro import modes, validity
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.core.ring.environment import environment_of

__all__ = ['CHECK_S', 'HAND_BACK_THRESHOLD', 'fast_mode_amplitude', 'may_hand_back',
           'refusal']

CHECK_S = 0.01
"""How often the full model checks whether it may hand back to the averaged one, s."""


HAND_BACK_THRESHOLD = 1e-3
"""
Largest amplitude of the modes other than the driven pair, over d_g, at a hand-off to the
averaged model (S13). After a 10 000 g shock on the default gyroscope (they reach 0.53 d_g and
ring down over ~20 s), the readout after the hand-off against the full model's: at 3e-2 of
d_g 11 % of the reading, 1e-2 2.7 %, 3e-3 6.1e-4, 1e-3 1.4e-5, 3e-4 1.2e-5 (doc/averaged.md).
"""


def fast_mode_amplitude(sim) -> float:
    """
    Return the largest amplitude of the modes the averaged model leaves out, over d_g (S13).

    ``sqrt(q^2 + (q' / omega_n)^2)`` of every coordinate of a full model (``Simulator``)
    but the driven pair's (q2, q2s): what a shock or vibration left ringing, which the
    averaged model takes at rest.
    """
    config = sim.config
    m = config.modes.count
    pair = (1, m + 1) if config.modes.companions else (1,)
    omega = 2.0 * math.pi * np.asarray(config.modes.coordinate_frequencies(), dtype=float)
    others = np.ones(omega.size, dtype=bool)
    others[list(pair)] = False
    if not np.any(others):
        return 0.0
    amplitude = np.hypot(sim.q[others], sim.v[others] / omega[others])
    return float(np.max(amplitude) / config.electrodes.gap)


def refusal(config: SimConfig, blocks: bool = True) -> Optional[str]:
    """
    Return why the averaged model cannot run the gyroscope of ``config``; None when it can.

    ``blocks``: for a run that publishes blocks (``run.Run``), whose ``~/control`` rows and
    rebuilt samples need one ``~/rate`` sample per loop period.
    """
    c = config
    refused = modes.of(c).averaged_refusal(c)
    if refused is not None:
        return refused
    if c.electrodes.taylor_terms <= 0:
        return 'the averaged force is that of the truncated series (electrodes.taylor_terms)'
    window = int(round(c.run.output_rate / c.control.rate))
    decimation = int(round(c.run.output_rate / c.gyro.output_rate))
    if decimation % window:
        return 'gyro.output_rate is not a whole fraction of control.rate'
    if environment_of(c) is not None:
        return 'an environment (steady acceleration or vibration) acts at every sample'
    if blocks and decimation != window:
        return 'a run at fidelity auto needs gyro.output_rate equal to control.rate'
    return None


def may_hand_back(full, refused: Optional[str], last_input_ns: Callable[[], int],
                  check_samples: int) -> bool:
    """
    Whether the full model ``full`` may hand over to the averaged one now (module docstring).

    Parameters
    ----------
    full : core.engine.full.Simulator
        The full model, now at a check.
    refused : str or None
        :func:`refusal` of the configuration in force (None: the averaged model runs it).
    last_input_ns : callable
        Returns the acting time of the latest input other than a rate that has acted, ns;
        called only once the state allows a hand-back (a run hands its inputs that have
        acted to its sink there).
    check_samples : int
        The samples between two checks (:data:`CHECK_S`).

    """
    if refused is not None or full.status != 'running' or full.in_stop_contact:
        return False
    loop = full.loop
    if loop is None or full.sample_index == 0 or full.sample_index % loop.window:
        return False   # the first check after the full model's first samples
    if not (loop.locked and loop.rebalance_on):
        return False
    # the loops at their operating point, ~/rate a measurement (V1)
    if (not loop.setpoint_m > 0.0
            or not abs(loop.amplitude / loop.setpoint_m - 1.0) <= validity.DRIVE_TOLERANCE
            or full.sense.validity.state.reason):
        return False
    last_ns = last_input_ns()
    if (full.next_scheduled_s() <= full.time_s
            or full.time_ns - last_ns < check_samples * full.period_ns):
        return False
    return fast_mode_amplitude(full) < HAND_BACK_THRESHOLD
