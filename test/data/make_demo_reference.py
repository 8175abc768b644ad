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
Write ``demo_reference.npz``: every output channel of a short run of the paper's resonator.

The scenario is the paper's demo (``config/paper.yaml``: the upper-branch drive start; a
10 000 g shock at 10 ms) for 40 ms. Stored: every ``DECIMATION``-th sample of every
channel (q, gap at each electrode centre, smallest gap, capacitances) as float64, and the
SHA-256 of each channel's complete array (all 8000 samples), so that the file stays small and
still pins every sample. ``test/test_reference_outputs.py`` checks that the current tree
reproduces it bit for bit, computed through :class:`ring_gyro_sim.run.Run`, the one run path.
Run ``python test/data/make_demo_reference.py`` only when the physics is meant to change, or
when the numerical libraries or the CI machine moved the last bits; say why in the commit and
add the regeneration to CHANGELOG.md ("Reference outputs"), which lists every one so far.

The samples depend on the numerical libraries and on the CPU in their last bits (the start
state is a shooting solve through scipy, whose OpenBLAS picks its kernels by the CPU: on one
host, ``OPENBLAS_CORETYPE=Sandybridge`` moves the start state's q1 by 4e-12 of itself against
the default Zen/Haswell kernels; numba compiles the kernel through LLVM for the host CPU), so
the file records the versions (:func:`versions`) and the machine (:func:`machine`) it was made
with. A reference made on one CI host can fail bit for bit on the next (4.9e-16 in q, 4e-11 of
the peak once the 10 000 g shock has amplified it).
"""

import hashlib
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parents[1]
OVERRIDES = {'duration': 0.04, 'scenario.shock_times': [0.01],
             'scenario.shock_peaks': [98066.5]}
BLOCK_SAMPLES = (2000, 2000, 2000, 1500, 500)
DECIMATION = 10
CHANNELS = ('t', 'q', 'gap', 'min_gap', 'capacitance')


def compute():
    """Return the channels of the reference scenario as a dict of arrays."""
    sys.path.insert(0, str(REPO))
    from ring_gyro_sim.core.params import build_config, to_flat
    from ring_gyro_sim.paramfile import load_yaml
    from ring_gyro_sim.run import Run

    base = load_yaml(str(REPO / 'config' / 'paper.yaml'))
    config = build_config({**to_flat(base), **OVERRIDES})
    run = Run(config)  # the one run path
    parts = [run.advance(n).samples for n in BLOCK_SAMPLES]
    return {name: np.ascontiguousarray(np.concatenate([getattr(p, name) for p in parts]))
            for name in CHANNELS}


def versions():
    """Return the versions the samples depend on, one string (``name=version`` joined by ``;``)."""
    import llvmlite
    import numba
    import scipy
    return ';'.join(f'{m.__name__}={m.__version__}' for m in (np, scipy, numba, llvmlite))


def machine():
    """
    Return the CPU the samples were computed on: LLVM's name for it and a hash of its features.

    The name (``znver3``, ``skylake-avx512``...) is what numba compiles for and, with the
    features (AVX-512 or not), what OpenBLAS chooses its kernels by.
    """
    import hashlib
    import llvmlite.binding as llvm
    features = str(llvm.get_host_cpu_features().flatten())
    tag = hashlib.sha256(features.encode()).hexdigest()[:12]
    return f'cpu={llvm.get_host_cpu_name()};features={tag}'


def digest(array):
    """Return the SHA-256 (hex) of a float64 array's bytes."""
    return hashlib.sha256(np.ascontiguousarray(array, dtype=np.float64).tobytes()).hexdigest()


if __name__ == '__main__':
    channels = compute()
    stored = {name: a[::DECIMATION] for name, a in channels.items()}
    stored.update({f'sha256_{name}': np.array(digest(a)) for name, a in channels.items()})
    stored['versions'] = np.array(versions())
    stored['machine'] = np.array(machine())
    np.savez_compressed(HERE / 'demo_reference.npz', **stored)
