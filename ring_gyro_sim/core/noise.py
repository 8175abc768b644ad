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
Measured on this machine (2 cores shared with other jobs, numpy 2.4): 1.2 ms for a block of
2000 x 12 (the Brownian force noise of 6 coordinates x 2 steps per sample for 10 ms at
200 kHz), i.e. ~50 ns per normal, and 0.17 ms for 2000 x 2 (~43 ns). About a quarter is the
Philox words (5.5 ns each), most of the rest numpy's scalar cos / sin (~9 ns each per pair,
not vectorised on this CPU) and the temporaries of the block.
"""

import math
import numbers

import numpy as np

from ring_gyro_sim.core.errors import InputError

__all__ = ['STREAM_BROWNIAN', 'STREAM_PICKOFF', 'STREAM_FLICKER', 'MAX_KEY_WORD', 'normals']

STREAM_BROWNIAN = 1
"""Thermomechanical force noise of the modes (simulator kernel): width = coordinates x steps."""
STREAM_PICKOFF = 2
"""Electronic noise of the pick-off amplifiers (core/electronics.py): width 2 (sense, drive)."""
STREAM_FLICKER = 3
"""Flicker (bias-instability) rate noise (core/electronics.py), at the rate samples."""

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
    pairs = (width + 1) // 2
    u = (raw[:, :2 * pairs] >> np.uint64(11)).astype(np.float64)
    u += 0.5
    u *= _TO_UNIT
    radius = np.log(u[:, :pairs])
    radius *= -2.0
    np.sqrt(radius, out=radius)
    angle = u[:, pairs:]
    angle *= 2.0 * math.pi
    angle -= math.pi  # uniform on [-pi, pi): numpy's cos / sin reduce it faster than [0, 2 pi)
    out = np.empty((count, 2 * pairs))
    out[:, :pairs] = np.cos(angle)
    out[:, pairs:] = np.sin(angle)
    out[:, :pairs] *= radius
    out[:, pairs:] *= radius
    return out[:, :width] if 2 * pairs != width else out
