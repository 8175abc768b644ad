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
Analysis on top of the core: envelopes, spectra, harmonic balance (plots in one module).

Modules (import from them directly, nothing is re-exported here): ``envelope`` (envelopes and
spectrograms), ``nnm`` (nonlinear normal modes, forced orbits, the drive's start state),
``hbm`` (harmonic balance: backbones and frequency responses), ``cases`` (the paper's
simulation cases), ``report`` (the paper reproduction report) and ``plotting`` (the only
module that imports matplotlib, lazily).
"""

__all__ = ['cases', 'envelope', 'hbm', 'nnm', 'plotting', 'report']
