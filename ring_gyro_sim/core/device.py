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

r"""
Device populations: a seeded draw of the manufacturing spread (D1-D5).

No two rings of a wafer are the ring of the drawing: etching leaves each 2theta pair with a
frequency split and a damping mismatch along axes of its own, the sense electrodes sit a
little off their angle and the electronics have their phase and gain errors. ``device.seed``
(0: none, the device as configured) draws one such device: the imperfections of
``doc/imperfections.md`` (P1-P4, E1b, E1c, E3b) get a random part, **added to** the
configured ones, of the spreads ``device.*_spread`` (one sigma each). The same configuration
and seed are the same device, bit for bit; :func:`ring_gyro_sim.core.params.build_config`
applies the draw where it resolves a configuration, so a run, the node, a recording's
parameters (which hold the configured values and the seed) and a re-simulation see one
device.

(D1) The numbers. One row of seven standard normals,
``z = noise.normals(seed, noise.STREAM_DEVICE, 0, 1, 7)[0]`` (``core.noise``: Philox-4x64-10
keyed by the seed and the stream, Box-Muller in a compiled loop, numbers that are the same
across CPUs with one libm; no global random state): ``z_0`` the split, ``z_1`` the Q mismatch,
``z_2`` the sense misalignment, ``z_3`` the phase error, ``z_4`` the gain mismatch, ``z_5``
and ``z_6`` the axes of the split and of the mismatch, each uniform over one period of the
pair's axes, ``theta = (90 / n) Phi(z)`` deg (``Phi`` the normal distribution function: a
uniform number in (0, 1)). Every seed draws all seven, whatever spreads are zero, so a spread
changes only its own parameters.

(D2) The split. ``delta = sigma_f z_0`` (Hz, signed; ``device.split_spread``) at the ring
angle ``theta_w = (90 / n) Phi(z_5)`` is the anisotropic part of the pair's stiffness (P2)
of a pair split by ``delta`` about its mean frequency ``f_m``, per unit modal mass
``(2 pi)^2 f_m delta [[cos 2n theta_w, sin 2n theta_w], [sin 2n theta_w, -cos 2n theta_w]]``.
It adds to the configured pair: with ``m = (w_x^2 + w_y^2) / 2`` and the anisotropy
``A = (w_x^2 - w_y^2) / 2 e^{i 2n theta}`` (P2 in complex form),
``A' = A + (2 pi)^2 f_m delta e^{i 2n theta_w}``, and the device's principal values and axis
are ``w_x'^2 = m + |A'|``, ``w_y'^2 = m - |A'|``, ``theta' = arg(A') / 2n``. A signed split
over one period 90/n of the axis covers every orientation once: turning the axis by 90/n with
the values swapped is the same pair (P4). On a configured pair without split the drawn split
is ``|delta|`` to ``O(delta^2 / f)``.

(D3) The Q mismatch. ``e = sigma_q z_1`` (``device.q_mismatch_spread``) at
``theta_t = (90 / n) Phi(z_6)`` adds, likewise, to the damping ``c = w / Q`` of each principal
axis (P3): mean ``c_m = (c_x + c_y) / 2``, anisotropy ``D = (c_x - c_y) / 2 e^{i 2n theta}``,
``D' = D + c_m e / (2 + e) e^{i 2n theta_t}``, ``c_x' = c_m + |D'|``, ``c_y' = c_m - |D'|``,
and the device's Q are ``Q_x' = w_x' / c_x'``, ``Q_y' = w_y' / c_y'`` (P3's ``c = w / Q``
with D2's frequencies). On a pair with equal Q and frequencies that is ``Q_y / Q_x = 1 + e``
exactly. A draw ``e <= -1`` (a Q at or below zero) is refused.

(D4) The electronics. ``gyro.sense_misalignment + sigma_d z_2`` (deg, E1b),
``gyro.phase_error + sigma_p z_3`` (rad, E3b), ``gyro.pickoff_gain_mismatch + sigma_g z_4``
(E1c).

(D5) What changes. Only the parameters of a spread above 0: a zero spread leaves its
parameters as configured, bit for bit. D2 and D3 act on the 2theta pair (n = 2, the gyroscope's
drive and sense modes) and need it: ``modes.companions`` and at least two modes (without the
companions there is no pair, and they change nothing); the other pairs stay as configured.
A drawn value goes through the parameter table's checks like a configured one; the table
refuses a value outside its range (``device.seed: seed N draws an invalid device: ...``),
it does not truncate it.

Not drawn: the pairs' mean frequencies and Q (a ring that is thicker than drawn is another
design point, and the drive's operating point with it), the gap, the voltages and the loops'
constants.
"""

from dataclasses import dataclass
import math
from typing import Any, Dict, Tuple

from ring_gyro_sim.core.errors import ParameterError

__all__ = ['DeviceDraw', 'DrawError', 'PAIR', 'add_damping', 'add_split', 'draw',
           'drawn_values']

PAIR = 2
"""n of the pair whose split and Q mismatch are drawn: the 2theta pair (drive and sense)."""
_WIDTH = 7


class DrawError(ParameterError):
    """A draw gives a pair the model cannot hold; the message starts with the spread's name."""


@dataclass(frozen=True)
class DeviceDraw:
    """
    The random part of one device (D1-D4): what is added to the configured device.

    Attributes
    ----------
    split_hz : float
        ``delta`` of D2, Hz (signed).
    split_axis_deg : float
        ``theta_w`` of D2, deg, in [0, 90 / n).
    q_mismatch : float
        ``e`` of D3 (Q_y / Q_x - 1 on a matched pair).
    damping_axis_deg : float
        ``theta_t`` of D3, deg, in [0, 90 / n).
    misalignment_deg, phase_error_rad, gain_mismatch : float
        Added to ``gyro.sense_misalignment`` (deg), ``gyro.phase_error`` (rad) and
        ``gyro.pickoff_gain_mismatch`` (D4).

    """

    split_hz: float
    split_axis_deg: float
    q_mismatch: float
    damping_axis_deg: float
    misalignment_deg: float
    phase_error_rad: float
    gain_mismatch: float


def _uniform(z: float) -> float:
    """Return ``Phi(z)``, the standard normal distribution function: uniform in (0, 1)."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def draw(seed: int, split_spread: float, q_mismatch_spread: float,
         misalignment_spread: float, phase_error_spread: float, gain_mismatch_spread: float,
         n: int = PAIR) -> DeviceDraw:
    """
    Return the random part of device ``seed`` (D1-D4).

    Parameters
    ----------
    seed : int
        ``device.seed``, 1 .. 2**63 - 1.
    split_spread : float
        One sigma of the split, Hz.
    q_mismatch_spread : float
        One sigma of ``Q_y / Q_x - 1``.
    misalignment_spread : float
        One sigma of the sense misalignment, deg.
    phase_error_spread : float
        One sigma of the phase error, rad.
    gain_mismatch_spread : float
        One sigma of the pick-off gain mismatch.
    n : int
        n of the pair (the period of its axes is 90 / n deg).

    """
    from ring_gyro_sim.core import noise
    z = [float(v) for v in noise.normals(int(seed), noise.STREAM_DEVICE, 0, 1, _WIDTH)[0]]
    period = 90.0 / n
    return DeviceDraw(split_hz=split_spread * z[0], split_axis_deg=period * _uniform(z[5]),
                      q_mismatch=q_mismatch_spread * z[1],
                      damping_axis_deg=period * _uniform(z[6]),
                      misalignment_deg=misalignment_spread * z[2],
                      phase_error_rad=phase_error_spread * z[3],
                      gain_mismatch=gain_mismatch_spread * z[4])


def _turn(angle_deg: float, n: int) -> complex:
    """Return ``e^{i 2n theta}`` of a ring angle, deg (the anisotropy's phase, P2)."""
    phi = 2.0 * n * math.radians(angle_deg)
    return complex(math.cos(phi), math.sin(phi))


def _axis(anisotropy: complex, n: int) -> float:
    """Return the ring angle ``arg(A) / 2n``, deg, of an anisotropy (0 when there is none)."""
    if anisotropy == 0:
        return 0.0
    return math.degrees(math.atan2(anisotropy.imag, anisotropy.real) / (2.0 * n))


def add_split(omega_x: float, omega_y: float, axis_deg: float, split_hz: float,
              split_axis_deg: float, n: int = PAIR) -> Tuple[float, float, float]:
    """
    Add a split to a pair (D2): its principal angular frequencies and axis.

    Parameters
    ----------
    omega_x, omega_y : float
        The configured principal angular frequencies, rad/s.
    axis_deg : float
        The configured axis of ``omega_x``, deg.
    split_hz, split_axis_deg : float
        ``delta`` (Hz) and ``theta_w`` (deg) of the draw.
    n : int
        n of the pair.

    Returns
    -------
    (float, float, float)
        ``w_x'`` >= ``w_y'`` (rad/s) and the axis of ``w_x'``, deg.

    Raises
    ------
    DrawError
        The pair would have a frequency at or below 0.

    """
    mean_sq = 0.5 * (omega_x * omega_x + omega_y * omega_y)
    mean_hz = 0.5 * (omega_x + omega_y) / (2.0 * math.pi)
    a = 0.5 * (omega_x * omega_x - omega_y * omega_y) * _turn(axis_deg, n)
    a += (2.0 * math.pi) ** 2 * mean_hz * split_hz * _turn(split_axis_deg, n)
    size = abs(a)
    if size >= mean_sq:
        raise DrawError(f'device.split_spread: draws a split of {split_hz!r} Hz, which takes '
                        f'a frequency of the {n}theta pair to 0')
    return math.sqrt(mean_sq + size), math.sqrt(mean_sq - size), _axis(a, n)


def add_damping(c_x: float, c_y: float, axis_deg: float, q_mismatch: float,
                damping_axis_deg: float, n: int = PAIR) -> Tuple[float, float, float]:
    """
    Add a Q mismatch to a pair's damping (D3): its principal dampings and axis.

    Parameters
    ----------
    c_x, c_y : float
        The configured principal dampings ``w / Q``, 1/s.
    axis_deg : float
        The configured axis of ``c_x``, deg.
    q_mismatch, damping_axis_deg : float
        ``e`` and ``theta_t`` (deg) of the draw.
    n : int
        n of the pair.

    Returns
    -------
    (float, float, float)
        ``c_x'`` >= ``c_y'`` (1/s) and the axis of ``c_x'``, deg.

    Raises
    ------
    DrawError
        ``e <= -1`` or a damping at or below 0.

    """
    if q_mismatch <= -1.0:
        raise DrawError(f'device.q_mismatch_spread: draws Q_y / Q_x - 1 = {q_mismatch!r}, '
                        f'a quality factor at or below 0')
    mean = 0.5 * (c_x + c_y)
    d = 0.5 * (c_x - c_y) * _turn(axis_deg, n)
    d += mean * q_mismatch / (2.0 + q_mismatch) * _turn(damping_axis_deg, n)
    size = abs(d)
    if size >= mean:
        raise DrawError(f'device.q_mismatch_spread: draws Q_y / Q_x - 1 = {q_mismatch!r}, '
                        f'which takes a damping of the {n}theta pair to 0')
    return mean + size, mean - size, _axis(d, n)


def _element(values: Tuple[float, ...], fallback: Tuple[float, ...], count: int) -> list:
    """Return a per-mode list as set, its fallback when empty, or zeros."""
    if values:
        return [float(v) for v in values]
    if fallback:
        return [float(v) for v in fallback]
    return [0.0] * count


def drawn_values(config) -> Dict[str, Any]:
    """
    Return the parameters that the draw of ``config.device`` changes, with their values (D5).

    Parameters
    ----------
    config : SimConfig
        The device as configured (``device.seed`` > 0).

    Returns
    -------
    dict
        ``{dotted name: value}`` (lists as lists) of the parameters of every spread above 0.

    Raises
    ------
    DrawError
        A draw the pair cannot take (D2, D3): the message names the spread.

    """
    dev = config.device
    d = draw(dev.seed, dev.split_spread, dev.q_mismatch_spread, dev.misalignment_spread,
             dev.phase_error_spread, dev.gain_mismatch_spread)
    out: Dict[str, Any] = {}
    g = config.gyro
    if dev.misalignment_spread > 0.0:
        out['gyro.sense_misalignment'] = g.sense_misalignment + d.misalignment_deg
    if dev.phase_error_spread > 0.0:
        out['gyro.phase_error'] = g.phase_error + d.phase_error_rad
    if dev.gain_mismatch_spread > 0.0:
        out['gyro.pickoff_gain_mismatch'] = g.pickoff_gain_mismatch + d.gain_mismatch
    m = config.modes
    count = m.count
    if not m.companions or count < PAIR:
        return out
    i = PAIR - 1
    freqs = _element(m.frequencies, (), count)
    comp_freqs = _element(m.companion_frequencies, m.frequencies, count)
    f_axes = _element(m.frequency_axes, (), count)
    qs = _element(m.quality_factors, (), count)
    comp_qs = _element(m.companion_quality_factors, m.quality_factors, count)
    t_axes = _element(m.damping_axes, (), count)
    w_x0, w_y0 = 2.0 * math.pi * freqs[i], 2.0 * math.pi * comp_freqs[i]
    w_x, w_y = w_x0, w_y0
    if dev.split_spread > 0.0:
        w_x, w_y, f_axes[i] = add_split(w_x0, w_y0, f_axes[i], d.split_hz, d.split_axis_deg)
        freqs[i], comp_freqs[i] = w_x / (2.0 * math.pi), w_y / (2.0 * math.pi)
        out.update({'modes.frequencies': freqs, 'modes.companion_frequencies': comp_freqs,
                    'modes.frequency_axes': f_axes})
    if dev.q_mismatch_spread > 0.0:
        c_x, c_y, t_axes[i] = add_damping(w_x0 / qs[i], w_y0 / comp_qs[i], t_axes[i],
                                          d.q_mismatch, d.damping_axis_deg)
        qs[i], comp_qs[i] = w_x / c_x, w_y / c_y
        out.update({'modes.quality_factors': qs, 'modes.companion_quality_factors': comp_qs,
                    'modes.damping_axes': t_axes})
    return out
