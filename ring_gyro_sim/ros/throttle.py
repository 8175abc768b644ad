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
A warning logged at most once per period for each kind, saying how many were held back.

rcutils' ``throttle_duration_sec`` throttles per call site and drops the rest silently; a
refused input or parameter instead needs one line per kind (topic and reason shape, or
parameter) that counts the ones suppressed since the last line.
"""

import math
import time
from typing import Callable, Dict, Hashable, Tuple

__all__ = ['ThrottledWarnings']


class ThrottledWarnings:
    """
    Emit ``warn(text)`` at most every ``period_s`` per key; count the ones held back.

    Parameters
    ----------
    warn : callable
        Writes one warning line (e.g. a node logger's ``warn``).
    period_s : float
        Shortest wall time between two lines of one key, s.

    """

    def __init__(self, warn: Callable[[str], None], period_s: float) -> None:
        self._warn = warn
        self.period_s = period_s
        self._last: Dict[Hashable, Tuple[float, int]] = {}

    def __call__(self, key: Hashable, text: str) -> None:
        """Log ``text`` for ``key`` unless one was logged less than ``period_s`` ago."""
        now = time.monotonic()
        last, suppressed = self._last.get(key, (-math.inf, 0))
        if now - last < self.period_s:
            self._last[key] = (last, suppressed + 1)
            return
        more = f' ({suppressed} more like it since the last message)' if suppressed else ''
        self._warn(f'{text}{more}')
        self._last[key] = (now, 0)
