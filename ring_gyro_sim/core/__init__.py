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
Model core: parameters, structure, electrostatic forces, kernels and the Simulator.

This layer imports only the standard library, numpy, scipy and numba (a test enforces it).
Modules (import from them directly, nothing is re-exported here, so that reading parameters
does not load numba):

- ``params``: the parameter table, :class:`~ring_gyro_sim.core.params.SimConfig` and
  :func:`~ring_gyro_sim.core.params.build_config`;
- ``engine``: the engines that advance the gyroscope, the full model
  :class:`~ring_gyro_sim.core.engine.full.Simulator`, its
  :class:`~ring_gyro_sim.core.engine.full.Samples` and
  :class:`~ring_gyro_sim.core.engine.full.Status`;
- ``structure``: mass and stiffness matrices of the supported ring and its frequencies;
- ``forces``: the electrostatic force (:func:`~ring_gyro_sim.core.forces.build_force_model`,
  :func:`~ring_gyro_sim.core.forces.nonlinear_acceleration`, energies, Jacobian);
- ``kernels``: the compiled force and time stepper and their argument tuples;
- ``errors``: the exception hierarchy.

Every module of the core uses one coordinate order, the simulator's: ``q1 .. qN`` (the
cos(n theta) modes), then ``q1s .. qNs`` (their sine companions, when enabled).
"""

__all__ = ['engine', 'errors', 'forces', 'kernels', 'params', 'structure']
