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
Whether the kernels' machine code is in numba's disk cache: a first run compiles for a while.

The entry points :func:`~ring_gyro_sim.core.kernels.step.run_samples` and
:func:`~ring_gyro_sim.core.kernels.channels.output_channels` carry nearly all the compiled
code (the force, drift and forcing are inlined into the first); compiling them is what makes
a first run on a machine, or after an update of the package, slow (tens of seconds of CPU).
:func:`cold_kernels` reads their cache index the way numba does when it loads a function
(the index is invalidated when the source file changes) and looks for an entry made for this
CPU, without compiling anything, so that a command line can say what is about to happen.
It uses numba's cache objects (``Dispatcher._cache``), which are not a public API: whatever
it does not find where it expects is answered with None (unknown), never an error.
"""

from typing import List, Optional

__all__ = ['COMPILE_CPU_S', 'cold_kernels']

COMPILE_CPU_S = 25.0
"""CPU time of compiling the entry points with an empty cache, s (about; doc/performance.md)."""


def cold_kernels() -> Optional[List[str]]:
    """
    Return the entry-point kernels without cached machine code for this CPU.

    Returns
    -------
    list of str or None
        Their names (empty: every one will load from the cache); None when numba's cache
        cannot be inspected (caching off, another numba).

    """
    try:
        from numba.core.caching import NullCache
        from ring_gyro_sim.core.kernels.channels import output_channels
        from ring_gyro_sim.core.kernels.step import run_samples
        cold = []
        for kernel in (run_samples, output_channels):
            cache = kernel._cache
            if isinstance(cache, NullCache):
                return None
            magic = kernel.targetctx.codegen().magic_tuple()
            index = cache._cache_file._load_index()
            if not any(key[1] == magic for key in index):
                cold.append(kernel.py_func.__name__)
        return cold
    except Exception:  # noqa: B902 - numba internals moved: unknown, say nothing
        return None
