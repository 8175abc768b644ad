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
Write ``demo_reference.npz``: every output channel of a short ``config/demo.yaml`` run.

The scenario is ``config/demo.yaml`` (upper-branch drive start, a 10 000 g shock) with the
shock moved to 10 ms and 40 ms simulated. Stored: every ``DECIMATION``-th sample of every
channel (q, gap at each electrode centre, smallest gap, capacitances) as float64, and the
SHA-256 of each channel's complete array (all 8000 samples), so that the file stays small and
still pins every sample. It was made with the tree of commit 14aa740 (before the run-path
redesign of issue 9); ``test/test_reference_outputs.py`` checks that the current tree
reproduces it bit for bit. Run ``python test/data/make_demo_reference.py`` only when the
physics is meant to change, and say why in the commit. (The file was written through the
Simulator directly; it is now computed through :class:`ring_gyro_sim.run.Run`, the one run
path, which must give the same samples.)

The samples depend on the numerical libraries and on the CPU in their last bits (the start
state is a shooting solve through scipy, whose OpenBLAS picks its kernels by the CPU: on one
host, ``OPENBLAS_CORETYPE=Sandybridge`` moves the start state's q1 by 4e-12 of itself against
the default Zen/Haswell kernels; numba compiles the kernel through LLVM for the host CPU), so
the file records the versions (:func:`versions`) and the machine (:func:`machine`) it was made
with. CI machines differ: on 2026-12-02 the reference made on one host failed bit for bit on
the next one (4.9e-16 in q, 4e-11 of the peak after the shock).

It was regenerated on 2026-12-02 with the tree of commit fd02a0a when new wheels (numpy 2.4.6,
scipy 1.17.1, numba 0.68.1, llvmlite 0.50.0) moved the 14aa740 reference by up to 8.6e-11 of a
channel's peak (1e-12 in the first sample, the start state; the 10 000 g shock amplifies it);
fd02a0a and the tree of issue 14 give the same samples bit for bit under those versions. It was
regenerated again the same day, with the unchanged tree of commit 9f5620c, on a znver3 host, to
record its machine (the samples moved by up to 4.3e-11 of a peak, the start state by 1.1e-12:
the CPU, not the tree). It was regenerated on 2026-12-03 (commit a4378ba's kernels, an Intel
host LLVM calls rocketlake) because the physics' arithmetic changed on purpose (issue 11: the
series by Estrin's scheme instead of Horner's rule, kick and drift fused, the capacitances
summed four nodes per division): the tree moved the 9f5620c reference by up to 9.6e-11 of a
channel's peak (q; 8.1e-11 the smallest gap, 6.6e-11 the capacitances), round-off that the
10 000 g shock amplifies, as the CPU alone did before.
"""

import hashlib
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parents[1]
OVERRIDES = {'duration': 0.04, 'scenario.shock_times': [0.01], 'record.path': ''}
BLOCK_SAMPLES = (2000, 2000, 2000, 1500, 500)
DECIMATION = 10
CHANNELS = ('t', 'q', 'gap', 'min_gap', 'capacitance')


def compute():
    """Return the channels of the reference scenario as a dict of arrays."""
    sys.path.insert(0, str(REPO))
    from ring_gyro_sim.core.params import build_config, to_flat
    from ring_gyro_sim.paramfile import load_yaml
    from ring_gyro_sim.run import Run

    base = load_yaml(str(REPO / 'config' / 'demo.yaml'))
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
