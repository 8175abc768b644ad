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
The scenario's environment: the base acceleration in the ring's plane it imposes.

One reading of ``scenario.acceleration`` and ``scenario.vibration_*`` that the full model, the
operating point's shooting and the datasheet all take, so that each sees the same forcing.
"""

from dataclasses import dataclass
import math
from typing import Optional, Tuple

from ring_gyro_sim.core import vibration
from ring_gyro_sim.core.params import SimConfig, STANDARD_GRAVITY

__all__ = ['Environment', 'environment_of']


@dataclass(frozen=True)
class Environment:
    """
    The scenario's base acceleration in the ring's plane (:func:`environment_of`), m/s^2.

    ``steady + sine_peak sin(omega (t - t_ref) + phase) + direction a_r(n)``: the steady part,
    the sine's peak along x and y (its phase reference is the simulator's, which keeps it
    continuous across changes), the random vibration's multisine ``a_r`` at output sample
    ``n`` (``core.vibration``) and its direction.
    """

    steady: Tuple[float, float]
    sine_peak: Tuple[float, float]
    omega: float
    random: Optional[vibration.RandomVibration]
    direction: Tuple[float, float]


def environment_of(config: SimConfig) -> Optional[Environment]:
    """
    Return the scenario's environment, None without one.

    ``scenario.acceleration`` steady, the sine vibration of ``scenario.vibration_amplitude``
    (peak) at ``scenario.vibration_frequency`` and the random vibration of
    ``scenario.vibration_psd_*`` (seeded by ``gyro.noise_seed``), both along
    ``scenario.vibration_angle`` (from x towards y). It enters the equations as a streamed
    base acceleration does (eq. 32's forcing).
    """
    r = config.run
    steady = tuple(r.acceleration) if r.acceleration else (0.0, 0.0)
    peak = r.vibration_amplitude if r.vibration_frequency > 0.0 else 0.0
    random = None
    if r.vibration_psd_frequencies:
        random = vibration.random_vibration(
            tuple(r.vibration_psd_frequencies), tuple(r.vibration_psd_values), r.output_rate,
            config.gyro.noise_seed, STANDARD_GRAVITY)
    if peak == 0.0 and steady == (0.0, 0.0) and random is None:
        return None
    angle = math.radians(r.vibration_angle)
    return Environment(steady=(float(steady[0]), float(steady[1])),
                       sine_peak=(peak * math.cos(angle), peak * math.sin(angle)),
                       omega=2.0 * math.pi * r.vibration_frequency, random=random,
                       direction=(math.cos(angle), math.sin(angle)))
