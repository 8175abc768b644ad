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
The engines that advance the gyroscope: the full model and the averaged model.

``base`` states the contract (``Engine``) and what engines exchange (``GyroState``,
``Design``, ``Samples``); ``full`` is the full model (``Simulator``), ``averaged`` the
averaged model (``AveragedEngine``, over the slow flow of ``AveragedGyro``); ``handoff`` is
the one policy that says when a run hands the gyroscope from one to the other. ``ENGINES``
is the table ``run.Run`` picks from by name (``integrator.fidelity``, the hand-offs).
"""

from ring_gyro_sim.core.engine.averaged import AveragedEngine
from ring_gyro_sim.core.engine.full import Simulator

__all__ = ['ENGINES']

ENGINES = {Simulator.name: Simulator, AveragedEngine.name: AveragedEngine}
"""The engines by name: ``full`` and ``averaged``."""
