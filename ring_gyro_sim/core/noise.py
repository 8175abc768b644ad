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
Counter-based random streams: normals addressed by (seed, stream, sample index).

Every random number of a run comes from :func:`normals`; there is no global generator. Row
``r`` of ``normals(seed, stream, first_index, count, width)`` is a pure function of
``(seed, stream, first_index + r, width)``, so a run cut into blocks of any length draws the
same numbers as one long call, bit for bit, and a re-simulation from a recording (which holds
the seed) reproduces its noise.

Construction
------------
The generator is numpy's Philox-4x64-10 (:class:`numpy.random.Philox`, Salmon et al., SC'11):
a keyed bijection of a 256-bit counter, each counter value giving four 64-bit words.

* key (128 bits) = ``seed + 2**64 * stream``: the seed and the stream are the two words of the
  key, so two streams or two seeds are two unrelated permutations;
* row ``i`` owns the counter values ``i B + 1 .. i B + B``, ``B = ceil(width / 4)`` (Philox
  increments its counter before each block: the ``+ 1``); a call sets the counter once to
  ``first_index * B`` and draws ``4 B count`` words in one go, which is what makes it fast;
* words -> uniforms ``u = (floor(x / 2**11) + 1/2) 2**-53`` in (0, 1] (53 bits; never 0,
  so the logarithm is finite);
* uniforms -> normals by Box-Muller: the first ``P = ceil(width / 2)`` uniforms of a row are
  the radii ``u1``, the next ``P`` the angles ``u2``; normal ``j < P`` is
  ``sqrt(-2 ln u1_j) cos(2 pi u2_j - pi)`` and normal ``P + j`` the same with ``sin``, exactly
  standard normal and independent
  (numpy's own ``Generator.standard_normal`` uses a ziggurat, which consumes a variable
  number of words per normal and so cannot be addressed by index).

A row of another ``width`` is a different row (the layout depends on ``width``): a stream is
meant to be read at one width for the whole run.

Cost
----
The uniforms and Box-Muller are one compiled loop (:func:`_box_muller`, numba, the GIL
released), with the same operations per value as the formulas above, in the platform's libm
(``log``, ``cos``, ``sin``; numpy's own vectorised versions, used on some CPUs, may differ
in the last bit, so a compiled loop also makes the numbers the same across CPUs with one
libm). The loop is also faster than numpy's ufuncs over the same block, and the Philox words
are a small part of it (doc/performance.md, "The normals").

:func:`block_normals` is what the simulator and the electronics call: the same numbers,
memoised (the loop's pick-off and the sense electronics' draw the same block of
:data:`STREAM_PICKOFF`) and drawn one block ahead on a worker thread (the next block of a
stream usually follows this one), so that a paced run's normals are off its critical path.
"""

from collections import OrderedDict
from concurrent.futures import Future, ThreadPoolExecutor
import math
import numbers
import os
import threading
from typing import Optional, Tuple

from numba import njit
import numpy as np

from ring_gyro_sim.core.errors import InputError

__all__ = ['STREAM_BROWNIAN', 'STREAM_PICKOFF', 'STREAM_FLICKER', 'STREAM_DEVICE',
           'STREAM_VIBRATION', 'STREAM_ENVELOPE_FORCE', 'STREAM_ENVELOPE_PICKOFF',
           'MAX_KEY_WORD', 'normals', 'block_normals']

STREAM_BROWNIAN = 1
"""Thermomechanical force noise of the modes (simulator kernel): width = coordinates x steps."""
STREAM_PICKOFF = 2
"""Electronic noise of the pick-off amplifiers (core/gyro/electronics.py): width 2."""
STREAM_FLICKER = 3
"""Flicker (bias-instability) rate noise (core/gyro/electronics.py), at the rate samples."""
STREAM_DEVICE = 4
"""The draw of a device from its manufacturing spread (core/device.py, D1): one row of 7."""
STREAM_VIBRATION = 5
"""The phases of the random vibration's lines (core/vibration.py): row k, width 2."""
STREAM_ENVELOPE_FORCE = 6
"""The averaged model's thermomechanical force (core/engine/averaged.py, S9): row = loop period,
width 4 (the real parts of the pair's first harmonics, then their imaginary parts)."""
STREAM_ENVELOPE_PICKOFF = 7
"""The averaged model's pick-off noise after the fit (core/engine/averaged.py, S10): row = loop
period, width 4 (drive cos, drive sin, sense cos, sense sin)."""

MAX_KEY_WORD = 2 ** 64 - 1
"""Largest seed and stream: each is one 64-bit word of the Philox key."""

_WORDS_PER_BLOCK = 4
_TO_UNIT = 2.0 ** -53


def _check_int(name: str, value, low: int, high=None) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(f'{name}: expected an integer, got {value!r}')
    value = int(value)
    if value < low or (high is not None and value > high):
        bound = f'in [{low}, {high}]' if high is not None else f'>= {low}'
        raise InputError(f'{name}: must be {bound}, got {value}')
    return value


def normals(seed: int, stream: int, first_index: int, count: int, width: int) -> np.ndarray:
    """
    Return standard normals: rows ``first_index .. first_index + count - 1`` of a stream.

    Parameters
    ----------
    seed : int
        Run seed (``gyro.noise_seed``), 0 .. 2**64 - 1.
    stream : int
        Stream number (:data:`STREAM_BROWNIAN`, ...), 0 .. 2**64 - 1.
    first_index : int
        Index of the first row (a sample index), >= 0.
    count : int
        Number of rows, >= 0.
    width : int
        Normals per row, >= 1.

    Returns
    -------
    ndarray, shape (count, width), float64
        Row ``r`` depends only on ``(seed, stream, first_index + r, width)``.

    Raises
    ------
    InputError
        An argument is not an integer or is out of its range (the message names it).

    """
    seed = _check_int('seed', seed, 0, MAX_KEY_WORD)
    stream = _check_int('stream', stream, 0, MAX_KEY_WORD)
    first_index = _check_int('first_index', first_index, 0)
    count = _check_int('count', count, 0)
    width = _check_int('width', width, 1)
    blocks = -(-width // _WORDS_PER_BLOCK)
    words = _WORDS_PER_BLOCK * blocks
    if count == 0:
        return np.empty((0, width))
    gen = np.random.Philox(key=seed + (stream << 64), counter=first_index * blocks)
    raw = gen.random_raw(count * words).reshape(count, words)
    out = np.empty((count, width))
    _box_muller(raw, width, out)
    return out


@njit(cache=True, nogil=True)
def _box_muller(raw, width, out):
    """
    ``out[r] =`` Box-Muller of the words ``raw[r]`` (see the module doc), row by row.

    Per value the operations of the documented formulas, in their order: ``u = (floor(x /
    2**11) + 1/2) 2**-53``, radius ``sqrt(-2 ln u1)``, angle ``2 pi u2 - pi``, then ``cos``
    and ``sin`` of the angle times the radius.
    """
    pairs = (width + 1) // 2
    for r in range(raw.shape[0]):
        for j in range(pairs):
            u1 = (float(raw[r, j] >> np.uint64(11)) + 0.5) * _TO_UNIT
            u2 = (float(raw[r, pairs + j] >> np.uint64(11)) + 0.5) * _TO_UNIT
            radius = math.sqrt(math.log(u1) * -2.0)
            angle = u2 * (2.0 * math.pi) - math.pi
            out[r, j] = math.cos(angle) * radius
            if pairs + j < width:
                out[r, pairs + j] = math.sin(angle) * radius


AHEAD_MAX_NORMALS = 1 << 19
"""Largest block :func:`block_normals` keeps or draws ahead (4 MB); larger ones are drawn."""
_MEMO_ENTRIES = 6

_Key = Tuple[int, int, int, int, int]


class _Ahead:
    """The memo and the worker of :func:`block_normals` (one per process)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.memo: 'OrderedDict[_Key, Future]' = OrderedDict()
        self.worker: Optional[ThreadPoolExecutor] = None

    def submit(self, key: _Key) -> Future:
        if self.worker is None:
            self.worker = ThreadPoolExecutor(max_workers=1,
                                             thread_name_prefix='ring_gyro_noise')
        return self.worker.submit(_frozen_normals, key)


def _frozen_normals(key: _Key) -> np.ndarray:
    out = normals(*key)
    out.flags.writeable = False  # shared by the memo's readers
    return out


_AHEAD = _Ahead()


def _after_fork_in_child() -> None:
    # A forked child has no worker thread: pending futures of the parent would never end.
    global _AHEAD
    _AHEAD = _Ahead()


if hasattr(os, 'register_at_fork'):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def block_normals(seed: int, stream: int, first_index: int, count: int, width: int,
                  ahead: bool = True) -> np.ndarray:
    """
    Return :func:`normals` of these arguments, memoised and drawn a block ahead.

    The values are those of :func:`normals`, bit for bit (a pure function of the arguments,
    whichever thread draws them). A block asked for again (another consumer of the same
    stream) comes from the memo; unless ``ahead`` is false, the block that follows,
    ``(first_index + count, count)``, is then drawn on a worker thread (numba and numpy's
    Philox release the GIL), so that the caller finds it ready next time. Blocks of more
    than :data:`AHEAD_MAX_NORMALS` are drawn directly. The array is read-only.

    Raises
    ------
    InputError
        As :func:`normals` (at this call, not on the worker).

    """
    key = (_check_int('seed', seed, 0, MAX_KEY_WORD),
           _check_int('stream', stream, 0, MAX_KEY_WORD),
           _check_int('first_index', first_index, 0), _check_int('count', count, 0),
           _check_int('width', width, 1))
    if key[3] * key[4] > AHEAD_MAX_NORMALS or key[3] == 0:
        return normals(*key)
    state = _AHEAD
    with state.lock:
        future = state.memo.pop(key, None)
    result = None
    if future is not None:
        try:
            result = future.result()
        except Exception:  # noqa: B902 (drawn again below: the error, if any, is raised here)
            result = None
    if result is None:
        result = _frozen_normals(key)
    with state.lock:
        done: Future = Future()
        done.set_result(result)
        state.memo[key] = done
        following = (key[0], key[1], key[2] + key[3], key[3], key[4])
        if ahead and following not in state.memo:
            state.memo[following] = state.submit(following)
        while len(state.memo) > _MEMO_ENTRIES:
            state.memo.popitem(last=False)
    return result
