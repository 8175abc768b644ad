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
The splitting of the equations of motion: its coefficients and a configuration's Method.

A BAB splitting step of length h alternates ``s + 1`` kicks (B: the force and the forcing,
:mod:`ring_gyro_sim.core.kernels.step`) of ``b_i h`` with ``s`` drifts (A: the exact linear
flow, :mod:`ring_gyro_sim.core.kernels.drift`) of ``a_i h``; :func:`splitting_coefficients`
gives ``a`` and ``b`` of each method, :class:`Method` holds them with the time grid and the
drifts' propagators of a configuration.
"""

from typing import NamedTuple

import numpy as np

__all__ = ['Method', 'splitting_coefficients']


class Method(NamedTuple):
    """
    The integration method of a configuration: time grid, splitting, linear propagators.

    Attributes
    ----------
    period_s : float
        Output sample period, s.
    n_sub : int
        Steps per sample period.
    h : float
        Step, s (``period_s / n_sub``).
    a, b : ndarray, shapes (s,), (s + 1,)
        Drift and kick coefficients (:func:`splitting_coefficients`).
    prop : ndarray, shape (s, n, 4)
        Exact linear flows of the drifts ``a h`` (:func:`drift.linear_propagators`).
    omega, zeta : ndarray, shape (n,)
        Natural angular frequencies (rad/s) and damping ratios, for the sub-steps' flows.
    coupled : ndarray of bool, shape (n,)
        The coordinates of coupled pairs (their flow is the pair's).
    pairs : ndarray of int64, shape (p, 2)
        The coupled pairs' coordinates ``(c, s)`` (``drift`` module docstring); (0, 2): none.
    pair_prop : ndarray, shape (s, p, 16)
        Their exact 4x4 flows over the drifts ``a h`` (:func:`drift.pair_propagators`).
    pair_system : ndarray, shape (p, 16)
        Their ``A`` (:func:`drift.pair_system`), for the sub-steps' flows.

    """

    period_s: float
    n_sub: int
    h: float
    a: np.ndarray
    b: np.ndarray
    prop: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray
    coupled: np.ndarray
    pairs: np.ndarray
    pair_prop: np.ndarray
    pair_system: np.ndarray


def splitting_coefficients(method: str):
    """
    Drift (``a``) and kick (``b``) coefficients of a BAB splitting, ``len(b) = len(a) + 1``.

    The last coefficient of each half is derived from the consistency conditions
    (``sum a = sum b = 1``) rather than copied.
    """
    if method == 'strang':
        return np.array([1.0]), np.array([0.5, 0.5])
    if method == 'bm4':  # Blanes & Moan 2002, SRKN_6^b
        b = [0.0829844064174052, 0.396309801498368, -0.0390563049223486]
        a = [0.245298957184271, 0.604872665711080]
        a.append(0.5 - sum(a))
        b.append(1.0 - 2.0 * sum(b))
        return np.array(a + a[::-1]), np.array(b + b[-2::-1])
    if method == 'bm6':  # Blanes & Moan 2002, SRKN_11^b
        b = [0.0414649985182624, 0.198128671918067, -0.0400061921041533,
             0.0752539843015807, -0.0115113874206879]
        b.append(0.5 - sum(b))
        a = [0.123229775946271, 0.290553797799558, -0.127049212625417,
             -0.246331761062075, 0.357208872795928]
        middle = 1.0 - 2.0 * sum(a)
        return np.array(a + [middle] + a[::-1]), np.array(b + b[::-1])
    raise ValueError(f'integrator.method: unknown method {method!r}')
