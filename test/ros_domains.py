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
ROS domain ids for the tests: one per purpose and test process, held while the process lives.

A test process (a pytest session, or one of its ``pytest-xdist`` workers) claims an id per
purpose (the node tests, the replay tests, the colcon build, the README's commands) so that
neither two purposes nor two processes on this machine share a ROS graph: a node left over by
one cannot answer another's probe. An id is held by an exclusive ``flock`` on a file in the
temporary directory, released by the kernel when the process ends, however it ends.

The ids are those whose Fast DDS ports stay out of Linux's ephemeral range (32768-60999),
where a port taken by any other program would make discovery fail at random: 1-101 and
215-232 (port 7400 + 250 id + offsets; ROS 2's "The ROS_DOMAIN_ID" concept page).
"""

import fcntl
import os
import pathlib
import random
import tempfile
from typing import Dict, IO, Tuple

SAFE_IDS = tuple(range(1, 102)) + tuple(range(215, 233))
"""Domain ids whose DDS ports are outside Linux's ephemeral port range."""
LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'ring_gyro_sim_ros_domains'
_held: Dict[str, Tuple[int, IO]] = {}


def claim(purpose: str) -> int:
    """Return this process's domain id for ``purpose``, claiming a free one the first time."""
    if purpose in _held:
        return _held[purpose][0]
    LOCK_DIR.mkdir(exist_ok=True)
    mine = {domain for domain, _ in _held.values()}
    ids = [i for i in SAFE_IDS if i not in mine]
    random.SystemRandom().shuffle(ids)
    for domain in ids:
        handle = open(LOCK_DIR / f'{domain}.lock', 'a', encoding='utf-8')
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        handle.write(f'{os.getpid()} {purpose}\n')
        handle.flush()
        _held[purpose] = (domain, handle)
        return domain
    raise RuntimeError(f'no free ROS domain id for {purpose!r}: all of {len(SAFE_IDS)} are '
                       f'held by other test processes ({LOCK_DIR})')
