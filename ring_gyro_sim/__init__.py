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
ring_gyro_sim: a ROS 2 emulator of a capacitive MEMS vibrating-ring gyroscope under shock.

Layers (import the modules directly; nothing is re-exported, so importing a layer loads only
what it needs): ``core`` (parameters, model and Simulator: stdlib, numpy, scipy, numba only),
``analysis`` (envelopes, nonlinear modes, harmonic balance, paper cases, report, plots),
``recording`` (MCAP bags), ``ros`` (the rclpy node); the command line in ``cli``, offline runs
in ``offline``, parameter files in ``paramfile``, bag replay in ``replay``.
"""

__all__ = ['__version__']

__version__ = '0.1.0'
