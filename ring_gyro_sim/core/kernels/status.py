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
Status codes of the kernels: why a run stopped, and their text.

A kernel that meets a state outside the model's range stops with one of these codes in its
``info`` array (never with NaN); :func:`describe_status` turns a code and the angle where it
happened into the message the simulator reports.
"""

import math

__all__ = ['STATUS_OK', 'STATUS_OUTER_CONTACT', 'STATUS_INNER_CONTACT', 'STATUS_SERIES_RANGE',
           'STATUS_NONFINITE', 'describe_status']


STATUS_OK = 0
STATUS_OUTER_CONTACT = 1
STATUS_INNER_CONTACT = 2
STATUS_SERIES_RANGE = 3
STATUS_NONFINITE = 4

_STATUS_TEXT = {
    STATUS_OUTER_CONTACT: 'outer electrode contact (outer gap closed)',
    STATUS_INNER_CONTACT: 'inner electrode contact (inner gap closed)',
    STATUS_SERIES_RANGE: 'displacement beyond the range of the Taylor series (|w| >= d_g)',
    STATUS_NONFINITE: 'non-finite state (numerical failure)',
}


def describe_status(status: int, theta_rad: float) -> str:
    """Human text for a kernel status and the angle where it happened."""
    text = _STATUS_TEXT.get(status, f'unknown status {status}')
    return f'{text} at theta = {math.degrees(theta_rad):.1f} deg'
