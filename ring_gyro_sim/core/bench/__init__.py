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
The bench above the instrument: what is measured on a running model before a run starts.

``factory``: the factory calibration on a simulated rate table (K2, K3). It runs the full
model (``core.engine.full``), which is why it sits above it: the model never calls it. The
operating point's shooting (the start state on the drive's branch) belongs here too and is
still ``core.gyro.operating_point``: the averaged model shoots its own start state when it
is given none, so moving it here waits for that to become the caller's job.
"""
