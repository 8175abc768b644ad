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
Counter-based random streams (core/noise.py): addressing, independence, statistics, errors.

Statistical tolerances are 5 standard errors of the estimator for independent standard
normals (so a correct generator fails one with probability ~6e-7); the seeds are fixed, so
each test is deterministic, and a mutation of the generator (a shared counter between rows,
a lost factor in Box-Muller) moves the statistic by far more.
"""

import math
import multiprocessing
import signal
import threading

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from ring_gyro_sim.core import noise
from ring_gyro_sim.core.errors import InputError
from scipy import stats


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 64 - 1), stream=st.integers(0, 5),
       start=st.integers(0, 2 ** 40), width=st.integers(1, 13),
       cuts=st.lists(st.integers(0, 40), min_size=1, max_size=6))
def test_rows_do_not_depend_on_the_chunking(seed, stream, start, width, cuts):
    total = sum(cuts)
    whole = noise.normals(seed, stream, start, total, width)
    parts, at = [], start
    for c in cuts:
        parts.append(noise.normals(seed, stream, at, c, width))
        at += c
    assert np.array_equal(np.concatenate(parts), whole)
    assert whole.shape == (total, width) and whole.dtype == np.float64


def test_the_brief_example_bit_for_bit():
    assert np.array_equal(noise.normals(7, noise.STREAM_BROWNIAN, 0, 10, 12)[3:],
                          noise.normals(7, noise.STREAM_BROWNIAN, 3, 7, 12))


def test_a_row_is_the_documented_function_of_philox():
    # Rebuilt from the module docstring with numpy's Philox alone, one row at a time, and
    # the platform's libm through Python's math (numpy's own vectorised log / cos / sin,
    # used on some CPUs, may differ in the last bit: the module documents libm).
    seed, stream, width = 123456789, noise.STREAM_PICKOFF, 5
    blocks, pairs = 2, 3
    got = noise.normals(seed, stream, 1000, 4, width)
    for r in range(4):
        gen = np.random.Philox(key=seed + stream * 2 ** 64, counter=(1000 + r) * blocks)
        words = gen.random_raw(4 * blocks)
        u = [(float(w >> np.uint64(11)) + 0.5) * 2.0 ** -53 for w in words]
        rad = [math.sqrt(-2.0 * math.log(x)) for x in u[:pairs]]
        ang = [2.0 * math.pi * x - math.pi for x in u[pairs:2 * pairs]]
        expect = ([a * math.cos(b) for a, b in zip(rad, ang)]
                  + [a * math.sin(b) for a, b in zip(rad, ang)])[:width]
        assert got[r].tolist() == expect


def test_seeds_and_streams_give_unrelated_numbers():
    base = noise.normals(1, noise.STREAM_BROWNIAN, 0, 2000, 4).ravel()
    others = [noise.normals(2, noise.STREAM_BROWNIAN, 0, 2000, 4).ravel(),
              noise.normals(1, noise.STREAM_PICKOFF, 0, 2000, 4).ravel(),
              noise.normals(1, noise.STREAM_FLICKER, 0, 2000, 4).ravel(),
              noise.normals(1 + 2 ** 63, noise.STREAM_BROWNIAN, 0, 2000, 4).ravel()]
    n = base.size
    for other in others:
        assert not np.any(other == base)
        # correlation of independent normals: standard error 1/sqrt(n)
        assert abs(np.corrcoef(base, other)[0, 1]) < 5.0 / math.sqrt(n)


def test_moments_and_independence():
    rows, width = 100_000, 6
    x = noise.normals(42, noise.STREAM_BROWNIAN, 5_000_000, rows, width)
    n = x.size
    assert abs(x.mean()) < 5.0 / math.sqrt(n)  # standard error of the mean: 1/sqrt(n)
    assert abs(x.var() - 1.0) < 5.0 * math.sqrt(2.0 / n)  # of the variance: sqrt(2/n)
    # kurtosis 3 (standard error sqrt(96/n) of the sample kurtosis of a normal)
    assert abs(np.mean(x ** 4) / x.var() ** 2 - 3.0) < 5.0 * math.sqrt(96.0 / n)
    # every pair of columns (cos and sin halves of Box-Muller included) and lag-1 rows:
    # correlation standard error 1/sqrt(rows)
    corr = np.corrcoef(x.T)
    off = corr[~np.eye(width, dtype=bool)]
    assert np.max(np.abs(off)) < 5.0 / math.sqrt(rows)
    for j in range(width):
        assert abs(np.corrcoef(x[1:, j], x[:-1, j])[0, 1]) < 5.0 / math.sqrt(rows)
    # the whole distribution: Kolmogorov-Smirnov against N(0, 1)
    assert stats.kstest(x[:, 0], 'norm').pvalue > 1e-6
    assert stats.kstest(x[:, width - 1], 'norm').pvalue > 1e-6


@pytest.mark.parametrize('kwargs, name', [
    ({'seed': -1}, 'seed'), ({'seed': 2 ** 64}, 'seed'), ({'seed': 1.5}, 'seed'),
    ({'seed': True}, 'seed'), ({'stream': -2}, 'stream'), ({'first_index': -1}, 'first_index'),
    ({'count': -3}, 'count'), ({'width': 0}, 'width'), ({'width': 2.0}, 'width'),
])
def test_bad_arguments_name_themselves(kwargs, name):
    args = {'seed': 0, 'stream': 1, 'first_index': 0, 'count': 3, 'width': 2, **kwargs}
    with pytest.raises(InputError, match=f'^{name}: '):
        noise.normals(**args)


def test_empty_and_numpy_integers():
    assert noise.normals(0, 1, 0, 0, 3).shape == (0, 3)
    assert np.array_equal(noise.normals(np.int64(3), np.uint8(1), np.int64(4), 2, 3),
                          noise.normals(3, 1, 4, 2, 3))


def test_block_normals_are_the_normals_memoised_and_drawn_ahead():
    seed, stream, width, block = 99, noise.STREAM_BROWNIAN, 6, 500
    first = 10_000
    got = [noise.block_normals(seed, stream, first + k * block, block, width) for k in range(4)]
    expect = noise.normals(seed, stream, first, 4 * block, width)
    assert np.array_equal(np.concatenate(got), expect)
    # the block after the last one was drawn ahead; a repeated block comes from the memo
    memo = noise._AHEAD.memo
    following = (seed, stream, first + 4 * block, block, width)
    assert following in memo
    assert np.array_equal(memo[following].result(),
                          noise.normals(seed, stream, first + 4 * block, block, width))
    again = noise.block_normals(seed, stream, first + 3 * block, block, width)
    assert again is got[3]
    assert not again.flags.writeable
    with pytest.raises(ValueError):
        again[0, 0] = 1.0
    # a jump back (a reset) and another block length: not in the memo, drawn, same values
    assert np.array_equal(noise.block_normals(seed, stream, 0, 7, width),
                          noise.normals(seed, stream, 0, 7, width))
    assert len(memo) <= noise._MEMO_ENTRIES


def test_block_normals_without_ahead_and_too_large_for_the_memo():
    noise.block_normals(5, noise.STREAM_PICKOFF, 0, 100, 2, ahead=False)
    assert (5, noise.STREAM_PICKOFF, 100, 100, 2) not in noise._AHEAD.memo
    rows = noise.AHEAD_MAX_NORMALS // 2 + 1
    big = noise.block_normals(5, noise.STREAM_PICKOFF, 0, rows, 2)
    assert (5, noise.STREAM_PICKOFF, 0, rows, 2) not in noise._AHEAD.memo
    assert np.array_equal(big, noise.normals(5, noise.STREAM_PICKOFF, 0, rows, 2))


@pytest.mark.parametrize('kwargs, name', [
    ({'seed': -1}, 'seed'), ({'stream': 2 ** 64}, 'stream'), ({'first_index': -1}, 'first_index'),
    ({'count': 1.5}, 'count'), ({'width': 0}, 'width'),
])
def test_block_normals_bad_arguments_name_themselves(kwargs, name):
    args = {'seed': 0, 'stream': 1, 'first_index': 0, 'count': 3, 'width': 2, **kwargs}
    with pytest.raises(InputError, match=f'^{name}: '):
        noise.block_normals(**args)


def test_a_forked_child_draws_ahead_with_its_own_worker():
    # A child forked while a block is pending must not wait for the parent's worker thread
    # (it has none): it starts its own.
    noise.block_normals(4, noise.STREAM_BROWNIAN, 0, 10, 2)  # the worker exists
    gate = threading.Event()
    noise._AHEAD.worker.submit(gate.wait, 30.0)  # ... and is busy until the fork is done
    noise.block_normals(3, noise.STREAM_BROWNIAN, 0, 2000, 12)  # the next one is pending
    assert not noise._AHEAD.memo[(3, noise.STREAM_BROWNIAN, 2000, 2000, 12)].done()
    pool = multiprocessing.get_context('fork').Pool(1, initializer=_default_sigterm)
    try:
        child = pool.apply_async(_draw_two_blocks, ()).get(timeout=20)
        pool.close()  # the worker ends its loop by itself: no signal needed
    except BaseException:
        pool.terminate()
        raise
    finally:
        gate.set()
    pool.join()
    assert np.array_equal(child, noise.normals(3, noise.STREAM_BROWNIAN, 0, 4000, 12))


def _default_sigterm():
    # Pool.terminate ends its worker with SIGTERM. Forked from a test process whose earlier
    # tests installed a handler, ignored or blocked the signal (a pytest-xdist worker runs
    # many modules), the worker would live on and the join wait for it for ever.
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})


def _draw_two_blocks():
    return np.concatenate([noise.block_normals(3, noise.STREAM_BROWNIAN, k * 2000, 2000, 12)
                           for k in range(2)])
