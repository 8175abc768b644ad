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
The output channels of every sample: the electrodes' gaps, the smallest gap, the capacitances.

:func:`output_channels` is the entry point (its docstring gives the accuracy); the mode shapes
and quadrature it takes are built once per configuration by
``core/engine/full.py`` (``Simulator._build_outputs``).
"""

from typing import NamedTuple

from numba import njit
import numpy as np

from ring_gyro_sim.core.kernels.force import _angle_values

__all__ = ['OutputGeometry', 'Channels', 'output_channels', 'RING_MAX_MARGIN']


class OutputGeometry(NamedTuple):
    """
    A configuration's gap, mode shapes and quadrature, as :func:`output_channels` takes them.

    Built once per configuration by ``Simulator._build_outputs`` (``core/engine/full.py``). The
    shapes are stored coordinate-major, so that every loop runs over the angles innermost and
    vectorises.

    Attributes
    ----------
    gap : float
        d_g, m.
    centre_shapes : ndarray, shape (n, K)
        Mode shapes at the electrode centres.
    ring_shapes : ndarray, shape (n, G)
        Mode shapes on G equally spaced angles; the maximum of w is refined by a parabola
        through the best grid angle and its neighbours.
    electrode_shapes : ndarray, shape (n, K * P)
        Mode shapes at the P Gauss-Legendre angles (all panels) of each electrode.
    electrode_weights : ndarray, shape (K * P,)
        Their weights (Gauss-Legendre weights times the half panel length), rad, the same P
        for every electrode (repeated, so that one loop runs over all K * P angles); P a
        multiple of 4 (the sum takes four nodes per division).
    fine_shapes : ndarray, shape (n, K * F)
        Mode shapes at the F = (2 + 4 + ... + R) P angles of each electrode's finer levels:
        each panel cut into 2, then 4, ... R panels, one level after the other.
    fine_weights : ndarray, shape (F,)
        Their weights, rad.
    curvature : ndarray, shape (n,)
        n^2 of each coordinate: ``sum n^2 |q_n|`` bounds ``|w''|``.
    refine_coeff : float
        An electrode is refined when its smallest node gap < ``refine_coeff * sum n^2 |q_n|``.
    cap_scale : float
        eps eps_0 l r_o, F m / rad.
    gap_floor : float
        Smallest gap used in 1 / gap (contact keeps the capacitance finite), m.

    """

    gap: float
    centre_shapes: np.ndarray
    ring_shapes: np.ndarray
    electrode_shapes: np.ndarray
    electrode_weights: np.ndarray
    fine_shapes: np.ndarray
    fine_weights: np.ndarray
    curvature: np.ndarray
    refine_coeff: float
    cap_scale: float
    gap_floor: float


class Channels(NamedTuple):
    """
    The output channels of S samples, filled by :func:`output_channels`.

    Attributes
    ----------
    gap : ndarray, shape (S, K)
        Gaps at the electrode centres, m.
    min_gap : ndarray, shape (S,)
        Smallest gap around the ring, m.
    capacitance : ndarray, shape (S, K)
        Electrode capacitances, F.

    """

    gap: np.ndarray
    min_gap: np.ndarray
    capacitance: np.ndarray


_LANES = 8


RING_MAX_MARGIN = 1e-3
"""
Bound on the error of the ring's smallest gap (grid and parabola, :func:`output_channels`) in
units of ``sum n^2 |q_n|``: the third derivative of w is at most ``n_max sum n^2 |q_n|``, so
the error ``|w_3| delta^3 / (9 sqrt 3)`` is at most ``n_max delta^3 / (9 sqrt 3)`` of it, with
``n_max delta <= 2 pi / 32`` (``simulator.GAP_GRID_POINTS_PER_MODE``): below 5e-4. Twice
that: the estimate ``w_max`` is within this times ``sum n^2 |q_n|`` of the largest w, round-off
included (the kernel's refinement test and ``core.engine.averaged.AveragedEngine`` rely on it).
"""


@njit(cache=True, inline='always')
def _first_argmax(w, m, lanes):
    """
    Index of the first largest of ``w[:m]`` (finite values), as a scan with ``>`` finds it.

    The maximum is exact whatever the order of comparisons, so it is found in
    :data:`_LANES` independent lanes (a loop that vectorises; a scan is one chain of
    dependent compares), then its first index, looked for a block of :data:`_LANES` at a
    time (a count of equal values per block vectorises; a scan of single values is again
    one chain of dependent compares).
    """
    if m < _LANES:
        best = 0
        for g in range(1, m):
            if w[g] > w[best]:
                best = g
        return best
    for c in range(_LANES):
        lanes[c] = w[c]
    full = m - m % _LANES
    for g0 in range(_LANES, full, _LANES):
        for c in range(_LANES):
            lanes[c] = max(lanes[c], w[g0 + c])
    top = lanes[0]
    for c in range(1, _LANES):
        top = max(top, lanes[c])
    for g in range(full, m):
        top = max(top, w[g])
    for g0 in range(0, full, _LANES):
        hits = 0
        for c in range(_LANES):
            hits += 1 if w[g0 + c] == top else 0
        if hits > 0:
            for c in range(_LANES):
                if w[g0 + c] == top:
                    return g0 + c
    for g in range(full, m):
        if w[g] == top:
            return g
    return 0


@njit(cache=True, nogil=True)
def output_channels(q, geometry, out):
    """
    Outer gaps, smallest gap and electrode capacitances of every sample.

    Accuracy (``test/core/test_outputs.py``, against dense sampling and ``quad``): the
    centre gaps are exact to round-off and stop at 0 in contact; the smallest gap is within
    ``|w'''| delta^3 / (9 sqrt 3)`` of ``d_g - max w`` (``delta`` the grid spacing,
    ``|w'''| <= sum n^3 |q_n|``). Each capacitance is a composite Gauss-Legendre sum whose
    panels keep the relative error below 1e-7 down to gaps of 0.01 d_g: every panel
    covers at most half a period of the highest harmonic, and an electrode whose smallest
    node gap g is below ``refine_coeff * sum n^2 |q_n|`` is summed again on the first finer
    level whose panels number at least ``sqrt(refine_coeff * sum n^2 |q_n| / g)`` per panel
    (``core/engine/full.py`` derives the coefficient). In contact the integrand is
    ``1 / max(gap, gap_floor)``: finite.

    Parameters
    ----------
    q : ndarray, shape (S, n)
        Coordinates of the samples, m.
    geometry : OutputGeometry
        The configuration's gap, mode shapes and quadrature.
    out : Channels
        The channels of the S samples, written.

    """
    gap = geometry.gap
    centre_shapes = geometry.centre_shapes
    ring_shapes = geometry.ring_shapes
    electrode_shapes = geometry.electrode_shapes
    electrode_weights = geometry.electrode_weights
    fine_shapes = geometry.fine_shapes
    fine_weights = geometry.fine_weights
    curvature = geometry.curvature
    refine_coeff = geometry.refine_coeff
    cap_scale = geometry.cap_scale
    gap_floor = geometry.gap_floor
    out_gap = out.gap
    out_min = out.min_gap
    out_cap = out.capacitance
    n_s, n = q.shape
    n_k = centre_shapes.shape[1]
    n_g = ring_shapes.shape[1]
    n_e = electrode_shapes.shape[1]
    n_p = n_e // n_k
    n_f = fine_weights.size
    max_level = 2
    while (2 * max_level - 2) * n_p < n_f:
        max_level *= 2
    wg = np.empty(n_g)
    we = np.empty(n_e)
    wq = np.empty(n_e // 4)
    w_top = np.empty(n_k)
    lanes = np.empty(_LANES)
    qs = np.empty(n)
    for s in range(n_s):
        for k in range(n_k):
            w = 0.0
            for i in range(n):
                w += centre_shapes[i, k] * q[s, i]
            out_gap[s, k] = max(gap - w, 0.0)
        for i in range(n):  # a copy, not a view: a view per sample is reference counted
            qs[i] = q[s, i]
        _angle_values(qs, ring_shapes, n_g, wg)
        best = _first_argmax(wg, n_g, lanes)
        y0 = wg[best - 1 if best > 0 else n_g - 1]
        y1 = wg[best]
        y2 = wg[best + 1 if best < n_g - 1 else 0]
        den = y0 - 2.0 * y1 + y2
        w_max = y1
        if den < 0.0:
            w_max = y1 - 0.125 * (y2 - y0) * (y2 - y0) / den
        out_min[s] = max(gap - w_max, 0.0)
        _angle_values(qs, electrode_shapes, n_e, we)
        c2 = 0.0
        for i in range(n):
            c2 += curvature[i] * abs(qs[i])
        # No electrode node can be nearer than the ring's smallest gap (less the parabola's
        # error, RING_MAX_MARGIN): far from contact the nodes' own maxima are not needed to
        # know that no electrode is refined.
        near = gap - w_max < (refine_coeff + RING_MAX_MARGIN) * c2
        for k in range(n_k):
            top = -np.inf
            if near:
                top = we[k * n_p]
                for j in range(1, n_p):
                    top = max(top, we[k * n_p + j])
            w_top[k] = top
        # sum_j weight_j / gap_j four nodes at a time, as one fraction:
        # (a/x + b/y) + (c/z + d/t) = ((a y + b x) z t + (c t + d z) x y) / (x y z t), one
        # division for four (divisions are the slowest operation of the sum); the gaps
        # are >= gap_floor, so the products neither underflow nor lose accuracy (a few ulps
        # of the sum of positive terms). One loop over every group: it vectorises.
        for g in range(n_e // 4):
            e = 4 * g
            x = max(gap - we[e], gap_floor)
            y = max(gap - we[e + 1], gap_floor)
            z = max(gap - we[e + 2], gap_floor)
            t = max(gap - we[e + 3], gap_floor)
            xy = x * y
            zt = z * t
            num = ((electrode_weights[e] * y + electrode_weights[e + 1] * x) * zt
                   + (electrode_weights[e + 2] * t + electrode_weights[e + 3] * z) * xy)
            wq[g] = num / (xy * zt)
        for k in range(n_k):
            c = 0.0
            g_top = gap - w_top[k]
            if g_top < refine_coeff * c2:
                # Halve the panels until their half-length is within reach of the pole:
                # (panels)^2 >= refine_coeff * c2 / g_top, at most the finest level.
                need = refine_coeff * c2 / max(g_top, gap_floor)
                level = 2
                start = 0
                while level < max_level and level * level < need:
                    start += level * n_p
                    level *= 2
                base = k * n_f + start
                for j in range(level * n_p):
                    w = 0.0
                    for i in range(n):
                        w += fine_shapes[i, base + j] * qs[i]
                    c += fine_weights[start + j] / max(gap - w, gap_floor)
            else:
                for j in range(n_p // 4):
                    c += wq[k * (n_p // 4) + j]
            out_cap[s, k] = cap_scale * c
