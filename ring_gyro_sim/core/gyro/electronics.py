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
Sense electronics of the gyroscope: pick-off, charge amplifier, demodulator, low-pass, rate.

The chain runs at the internal sample rate ``f_s = output.rate`` on the capacitances of the
``E = electrodes.count`` outer electrodes (centres ``theta_e = 2 pi e / E``) that the simulator
publishes, and is chunk-invariant: its filter states are carried from one call to the next and
its noise is addressed by sample index (:mod:`ring_gyro_sim.core.noise`), so a run cut into
blocks of any length gives the same outputs bit for bit.

Pick-off and charge amplifier (E1)
    Two amplifiers. The sense one reads the electrodes at the nodes of the drive (cos 2theta)
    mode with the differential weights ``w_e = sin(2 theta_e)`` (the sin 2theta companion
    ``q2s``, the sense mode); the drive one reads the antinodes with ``cos(2 theta_e)``
    (weights below 1e-12 in magnitude are set to 0: they are round-off of a node)::

        V = -(V_b / C_f) sum_e w_e (C_e - C_e0)                                      (E1)

    ``C_e0`` the rest capacitances (``Simulator.outputs_for(0)``), ``V_b`` = ``gyro.bias_voltage``
    or ``electrodes.outer_voltage`` when 0, ``C_f`` = ``gyro.feedback_capacitance``. With
    the default 8 electrodes the sense amplifier sees e1, e3, e5, e7 with weights +1, -1, +1,
    -1 and the drive one e0, e2, e4, e6.

Pick-off imperfections (E1b, E1c)
    Sense electrodes whose axis is turned by ``delta`` (``gyro.sense_misalignment``) read
    ``w_e = sin(2 (theta_e - delta))``: for a pattern ``q2 cos 2theta + q2s sin 2theta`` the
    sum is ``cos(2 delta) q2s - sin(2 delta) q2`` per unit of the aligned gain. The drive's
    displacement leaks into the sense amplifier as ``-tan(2 delta)`` of the sense reading of
    an equal ``q2s`` (``PickOff.sense_cross_gain``). With the drive ``q2 = X sin(w t)`` and the
    reference on it, this is a signal in phase with the Coriolis response of a matched pair,
    whose sense coordinate answers a rate with ``q2s = -2 kappa Omega Q X / w sin(w t)``
    (E6 at match): a bias of magnitude ::

        Omega_b = tan(2 delta) w / (2 kappa Q_s)                                    (E1b)

    (0.1 deg at the default device: 3.4e-3 rad/s, 0.19 deg/s). A relative gain error ``g``
    of the sense amplifier against the drive one (``gyro.pickoff_gain_mismatch``) multiplies
    the sense column of (E1) by ``1 + g`` (E1c): the rate reads ``(1 + g)`` times the true
    one through a scale factor set without it (a calibration given from the design), while a
    calibration on a rate table absorbs it, unlike the bias of (E1b). The model's own
    readout includes it (``sense_gain`` is measured through the amplifier).

Electronic noise (E2)
    Input-referred white voltage density ``e_n`` (``gyro.input_noise_density``, V/sqrt(Hz),
    one-sided), output-referred through the noise gain of a charge amplifier::

        e_o = e_n (1 + C_in / C_f),  C_in = sum_{w_e != 0} C_e0 + gyro.parasitic_capacitance (E2)

    Sampled at ``f_s`` as white noise of standard deviation ``e_o sqrt(f_s / 2)`` (one-sided
    density over 0 .. f_s / 2), from ``noise.normals(gyro.noise_seed, STREAM_PICKOFF, k, ., 2)``
    (column 0 sense, 1 drive), added when ``e_n > 0``.

Demodulation and low-pass (E3)
    Reference: the drive displacement's phase ``phi_ref = phi_drive + drive_phase_rad``
    (``q2 ~ A cos(phi_ref)``)::

        I = LP[2 V cos(phi_ref)],  Q = LP[2 V sin(phi_ref)]                              (E3)

    so ``V = a cos(phi_ref) + b sin(phi_ref)`` gives ``I = a``, ``Q = b``. ``LP`` is
    ``scipy.signal.butter(gyro.filter_order, gyro.filter_bandwidth, fs=f_s, output='sos')``
    run by ``sosfilt`` with its state carried. The filter starts in the steady state of the
    operating point: ``sense_i = sense_q = drive_q = 0``, ``drive_i = G_d A`` (no start
    transient on the drive pick-off). The 2 omega products are attenuated by
    ``(f_bw / 2 f_drive)^order`` (1e-10 for 100 Hz, order 4, 15.8 kHz).

Demodulation phase error (E3b)
    The sense channel's reference off by ``eps`` (``gyro.phase_error``):
    ``I = LP[2 V cos(phi_ref + eps)]``. With ``V = a cos(phi_ref) + b sin(phi_ref)`` this reads
    ``I = a cos(eps) - b sin(eps)``, ``Q = a sin(eps) + b cos(eps)``: the rate channel reads
    ``Omega cos(eps) - Q_r sin(eps)`` in rate units, ``Q_r`` the quadrature (a frequency
    split's, P2). A quadrature of 1 deg/s with a 10 mrad error is a 0.01 deg/s bias, and its
    temperature drift is the quadrature's. The drive channel keeps the true reference.

Rate output (E4)
    ``D = output.rate / gyro.output_rate``; the rate samples are the internal samples of
    global index ``k`` with ``(k + 1) % D == 0`` (sample ``k`` is at ``(k + 1) P``), rate
    sample ``m = (k + 1) / D - 1``::

        rate = sense_i / (SF rho) + flicker_m,  quadrature = sense_q / (SF rho)          (E4)
        rho = max(|drive_i + i drive_q| / |G_d A|, RHO_FLOOR)

    a ratiometric readout: the sense channel is divided by the drive pick-off's amplitude
    relative to the operating point (what an AGC holds at 1; open loop, the drive amplitude
    falls like ``1 / (1 + (2 kappa Omega Q / omega)^2)`` with the rate itself, 3.2 % at
    10 deg/s, because the rate splits the matched pair, while the ratio q2s / q2 stays
    ``2 kappa Omega Q / omega``: measured in ``test/test_gyro.py``). When ``SF = 0`` (drive
    off, or no bias voltage) there is no rate: both are 0 and
    :meth:`SenseElectronics.diagnostics_values` says ``scale_factor_valid: False``.

Scale factor (E5-E8)
    The sense coordinate ``q2s`` (index ``N + 1``) obeys, in the rotating frame (the
    integrator's sign: ``q_ns'' = -2 kappa_n Omega q_n' + ...``)::

        q2s'' + (w_s / Q_s) q2s' + w_s^2 q2s = -2 kappa Omega q2',  kappa = 2n/(n^2+1) = 0.8 (E5)

    ``w_s^2 = (2 pi f_s2)^2 - J_ss`` with ``J = forces.jacobian(0)`` (the linear electrostatic
    stiffness at rest; 0 with ``fold_linear_stiffness``, the default, where the k <= 2 terms
    are folded into the frequencies). With ``q2 = A cos(w t + p)``,
    ``q2' = Re(i w A e^{i(w t + p)})`` and the steady response is
    ``q2s = Re(X Omega e^{i phi_ref})`` with ``X = -2 i kappa w A H_s(w)``,
    ``H_s(w) = 1 / (w_s^2 - w^2 + i w w_s / Q_s)``. Its part in phase with ``q2`` (what ``I``
    reads) per unit rate is the mechanical scale factor, m per rad/s::

        S_m = A Re(-2 i kappa w H_s(w))       (at match w = w_s: -2 kappa Q_s A / w)      (E6)

    The electronic gain ``G = dV_sense / dq2s`` (V/m) is the central difference of (E1)
    through ``Simulator.outputs_for`` at ``q2s = +-h``, ``h = 1e-5 d_g``: the published
    capacitances themselves, not a separate formula. Its error: the truncation term
    ``(h / d_g)^2 = 1e-10`` relative (the capacitance's cubic term; the quadratic one cancels
    in a central difference) plus round-off ``eps C_e0 / (2 h dC/dq) ~ eps d_g / (2 h) = 1e-11``
    (``test_electronics.py`` compares it with the closed form
    ``dC_e/dq2s = eps eps_0 l r_o / d_g^2 int_e sin 2theta dtheta``). ``G_d`` likewise for
    ``q2`` and the drive amplifier. Then::

        SF = G S_m  (V per rad/s),  rate = I / SF                                          (E7)

    and the drive pick-off's nominal amplitude is ``|G_d A|`` (E8); the ratio rho of the
    measured ``sqrt(drive_i^2 + drive_q^2)`` to it tells whether the drive still holds the
    operating point the scale factor was computed for: ``scale_factor_valid`` when rho is
    within 10 % of what the pair's linear response gives at the measured rate,
    ``|D / (D - g^2 / D_s)|`` with ``D = F / (A e^{ip})``, ``D_s = 1 / H_s``,
    ``g = 2 kappa Omega w`` (``analysis.nnm._add_sense_response``); when the drive falls to its
    lower branch, the paper's Case 3, rho drops to ~0.1 and the output says so.

Scale factor at the operating point (E6b)
    (E6) is the linear sense mode. At the drive's operating point the electrostatic force
    softens the sense mode through the drive's amplitude and pumps it at twice the drive
    frequency (the mechanism that makes the paper's standing wave whirl): the sense
    coordinate linearised about the drive orbit ``q2 = A cos psi`` obeys
    ``q2s'' + (w_s/Q_s) q2s' + (w_s^2 - J(psi)) q2s = -2 kappa Omega q2'`` with
    ``J(psi) = d a_2s / d q2s`` of the force at ``q2 = A cos psi`` (``forces.jacobian``, less
    its value at rest, which (E5) has). Its periodic solution per unit rate (the monodromy
    matrix of one drive period, DOP853 at rtol 1e-11, J on 128 phases through a periodic
    cubic spline) has the fundamental ``Re(c e^{i psi})``; ``S_m = Re(c)`` replaces (E6) and
    ``Im(c) / Re(c)`` is the quadrature a rate causes (``rate_quadrature_per_rate``). Default
    device: the 10 deg/s reading moves from -0.39 % (E6) to within 0.1 % (``test_gyro.py``).

Bandwidth (E9)
    Of the whole rate path: the envelope of the sense mode responds to a rate change as a
    first-order low-pass of pole ``w_s / (2 Q_s)`` (rad/s; the resonator's half-power
    half-width), followed by the Butterworth; ``bandwidth_hz`` solves
    ``|H_m(f)|^2 |B(f)|^2 = 1/2`` numerically (``brentq``; ``B`` from ``sosfreqz``). Default
    device: ``f_s2 / (2 Q_s) = 15800 / 129400 = 0.122 Hz`` (the open-loop, mode-matched
    ring is slow), the 100 Hz filter changes it by 1e-6.

Angle random walk (E10-E12)
    Allan variance of white rate noise of one-sided density ``S`` ((rad/s)^2/Hz):
    ``sigma^2(tau) = S / (2 tau)`` = ``N^2 / tau`` (IEEE 952: ``N^2`` is the two-sided
    density, ``S / 2``).

    * Thermomechanical: one-sided force density ``4 k_B T m w_s / Q_s`` on ``q2s``
      (fluctuation-dissipation for the damping ``m w_s / Q_s``), acceleration
      ``S_a = 4 k_B T w_s / (m Q_s)``. The Coriolis acceleration is
      ``2 kappa Omega A w sin(phi_ref)``; a narrow-band noise
      ``x cos(phi_ref) - y sin(phi_ref)`` has quadratures of one-sided density ``2 S_a``, so the
      equivalent rate has ``S = 2 S_a / (2 kappa A w)^2`` and (both pass the same mechanical
      response ``H_s``, so this holds at any detuning)::

          N_th = sqrt(S / 2) = sqrt(k_B T w_s / (m Q_s)) / (kappa A w)
               = sqrt(k_B T / (m w Q_s)) / (kappa A)   at match                          (E10)

      ``m`` = the modal mass of ``q2s`` (``config.modal_masses()``), ``T`` = ``gyro.temperature``.
    * Electronic: ``2 n(t) cos(phi_ref)`` of a white ``n`` of one-sided density ``e_o^2`` has
      the autocorrelation ``2 R_n(tau) cos(w tau)``, i.e. one-sided density ``2 e_o^2`` at
      low frequency (the demodulator's factor 2 squared, times the mean of cos^2)::

          N_el = sqrt(2 e_o^2 / SF^2 / 2) = e_o / |SF|                                      (E11)

    * Combined in quadrature: ``N = sqrt(N_th^2 + N_el^2)`` rad/sqrt(s);
      ``N [deg/sqrt(h)] = N (180 / pi) 60``.                                                 (E12)

Flicker (bias instability, E13)
    ``gyro.bias_instability`` ``B`` (deg/h) is the datasheet figure of IEEE 952: one-sided
    rate density ``S(f) = h_{-1} / f`` with ``h_{-1} = B^2 / pi`` (IEEE 952's two-sided
    ``B^2 / (2 pi f)``), whose Allan deviation has the floor
    ``sqrt(2 ln 2 h_{-1}) = sqrt(2 ln 2 / pi) B = 0.6643 B``. Generated at the rate samples
    (rate ``f_r = gyro.output_rate``) by :class:`FlickerNoise`: a bank of first-order
    (AR(1)) processes with corner frequencies ``f_j`` log-spaced by ``r = 10^(1/3)`` from
    :data:`FLICKER_LOWEST_HZ` to ``f_r / 2``; a Lorentzian of one-sided density
    ``a_j / (1 + (f/f_j)^2)`` per corner and ``1/ln r`` corners per unit ``ln f`` sum to
    ``(pi/2) a_j f_j / (f ln r)``, so ``a_j = (2 / pi) h_{-1} ln(r) / f_j`` and every process
    has the same variance ``sigma_j^2 = a_j f_j pi / 2 = h_{-1} ln r``. Process ``j`` is
    ``x_m = rho_j x_{m-1} + sqrt(1 - rho_j^2) sigma_j eps_{m+1, j}``,
    ``rho_j = exp(-2 pi f_j / f_r)``, started stationary from row 0 of
    ``noise.normals(seed, STREAM_FLICKER, ., ., J)``; rate sample ``m`` uses row ``m + 1``.
    The Allan deviation of the bank, computed exactly from its autocovariance
    (``test_electronics.py``), is within 1.5 % of ``0.6643 B`` from ``tau = 10 / f_r`` to
    ``tau = 0.01 / FLICKER_LOWEST_HZ``.

Force-to-rebalance readout (E14)
    With ``control.mode: rebalance`` the sense mode is held at 0 by a loop (``core.gyro.control``,
    C6-C8) and the rate is read from its force: the rebalance rate ``S_c / (2 kappa omega X)``
    and quadrature ``S_s / (2 kappa omega X)`` of each sample (``Samples.control``) pass the
    same Butterworth (own state, started at the rate at t = 0) and the same decimation;
    the sense pick-off still feeds ``~/demodulator``. The rate's bandwidth is then the
    loop's (``control.rebalance_bandwidth``), the ARW the same as open loop (E10-E12: the
    force noise is read the same way, and the pick-off noise referred to the rate through
    the loop's inverse plant equals ``e_o / SF`` below the sense pole); above the pole the
    loop turns the pick-off noise into force as ``|1 + i f / f_p|``, which
    :meth:`SenseElectronics.rate_variance` integrates through the loop's response.

Output word: resolution and range (E15)
    The rate a part outputs is a digital word: what (E4), (E14) or the held calibration (K1)
    read, plus the flicker (E13), is rounded to a whole number of LSB ``L``
    (``gyro.resolution``; ``numpy.round``, half to even) and then held within the full scale
    ``R`` (``gyro.range``)::

        rate = clip(L round(rate / L), -R, R)                                            (E15)

    A sample the clip changed (``|L round(rate / L)| > R``) is *saturated*
    (``RateSamples.saturated``): it reads ``+-R`` exactly, whatever the rate behind it, and
    is not a measurement (``core.gyro.validity``: reason ``saturated``, variance
    ``NOT_MEASURED_VARIANCE``); :attr:`SenseElectronics.saturated_samples` counts them. The
    rounding's error is uniform within ``+-L / 2`` (variance ``L^2 / 12``, in the stated
    variance of a measurement) and bounded by it. ``L = 0`` or ``R = 0``: that step is left
    out. The quadrature channel (a diagnostic, not on ``~/rate``) is left as read. Both steps
    are memoryless, so that the run stays chunk-invariant and, once the rate is back within
    the range, the next sample is a measurement again (no settling: the readout behind the
    word did not saturate).
"""

import cmath
from dataclasses import dataclass
import importlib
import math
import numbers
from typing import Dict, Optional, Tuple, Union

import numpy as np
from ring_gyro_sim.core import forces, kernels, noise, structure
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.gyro import control, modes
from ring_gyro_sim.core.params import BOLTZMANN, SimConfig


KAPPA_2 = structure.gyroscopic_coefficient(2)
"""Coriolis coefficient of the 2theta pair, 2 n / (n^2 + 1) = 0.8 (eqs. G5-G6)."""


class _LazyModule:
    """``scipy.<name>``, imported on first use: importing ``run`` (every verb) stays light."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attr: str):
        return getattr(importlib.import_module(f'scipy.{self._name}'), attr)


integrate = _LazyModule('integrate')
interpolate = _LazyModule('interpolate')
optimize = _LazyModule('optimize')
signal = _LazyModule('signal')


__all__ = ['DEMOD_CHANNELS', 'DemodSamples', 'RateSamples', 'KAPPA_2',
           'SCALE_FACTOR_TOLERANCE', 'GAIN_STEP_RATIO',
           'FLICKER_LOWEST_HZ', 'FLICKER_POLES_PER_DECADE', 'FLICKER_FLOOR_RATIO',
           'deg_per_h_to_rad_per_s', 'rad_per_sqrt_s_to_deg_per_sqrt_h', 'FlickerNoise',
           'SenseElectronics', 'orbit_sense_response']

DEMOD_CHANNELS = ('sense_i', 'sense_q', 'drive_i', 'drive_q')
"""Channels of ``~/demodulator`` after ``t`` (V, low-passed, at every internal sample)."""

SCALE_FACTOR_TOLERANCE = 0.1
ORBIT_PHASES = 128
"""Phases of the drive orbit at which the sense stiffness is evaluated (E6b)."""
RHO_FLOOR = 1e-3
"""Smallest drive pick-off ratio the ratiometric readout divides by (E4): a stopped drive
gives a bounded reading, flagged ``scale_factor_valid: False``, never inf or NaN."""
"""Largest relative deviation of the drive pick-off from its nominal for a valid scale factor."""
GAIN_STEP_RATIO = 1e-5
"""Step of the central difference of the electronic gain, in units of d_g (E7)."""
FLICKER_LOWEST_HZ = 1e-5
"""Lowest corner of the flicker bank, Hz: the Allan floor holds up to ~1e3 s (E13)."""
FLICKER_POLES_PER_DECADE = 3
"""Corners per decade of the flicker bank (ripple of the Allan floor below 1.5 %)."""
FLICKER_FLOOR_RATIO = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""Allan floor / bias instability B of IEEE 952, 0.6643 (E13)."""
_ZERO_WEIGHT = 1e-12


def deg_per_h_to_rad_per_s(value: float) -> float:
    """Convert deg/h to rad/s."""
    return value * math.pi / 180.0 / 3600.0


def rad_per_sqrt_s_to_deg_per_sqrt_h(value: float) -> float:
    """Convert an angle random walk from rad/sqrt(s) to deg/sqrt(h) (E12)."""
    return value * 180.0 / math.pi * 60.0


@dataclass(frozen=True)
class RateSamples:
    """
    The rate output of one block (``~/rate``).

    Attributes
    ----------
    t : ndarray, shape (M,)
        Sample times, s (every ``output.rate / gyro.output_rate``-th internal sample).
    rate : ndarray, shape (M,)
        Measured angular rate about z, rad/s (in-phase channel / scale factor).
    quadrature : ndarray, shape (M,)
        The quadrature channel in the same units, rad/s.
    variance : ndarray, shape (M,), optional
        The variance of each rate sample, (rad/s)^2 (``core.gyro.validity``: what the
        sample is worth, large when it is not a measurement); None: not judged.
    saturated : ndarray of bool, shape (M,), optional
        Whether each sample reads the full scale because the rate behind it is beyond it
        (``gyro.range``, E15); None: no range.

    """

    t: np.ndarray
    rate: np.ndarray
    quadrature: np.ndarray
    variance: Optional[np.ndarray] = None
    saturated: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass(frozen=True)
class DemodSamples:
    """
    The demodulator's low-passed outputs at every internal sample (``~/demodulator``).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s (those of the block).
    values : ndarray, shape (K, len(DEMOD_CHANNELS))
        ``sense_i, sense_q, drive_i, drive_q``, V.

    """

    t: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)


def _check_index(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise InputError(f'{name}: expected an integer >= 0, got {value!r}')
    return int(value)


def _check_array(name: str, value, shape) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f'{name}: expected numbers, got {type(value).__name__}') from None
    if arr.shape != shape:
        raise InputError(f'{name}: expected shape {shape}, got {arr.shape}')
    bad = ~np.isfinite(arr)
    if bad.any():
        first = np.argwhere(bad)[0]
        raise InputError(f'{name}: must be finite, got {arr[tuple(first)]!r} at index '
                         f'{tuple(int(i) for i in first)}')
    return arr


def output_word(rate: np.ndarray, resolution: float,
                full_scale: float) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """
    Return ``rate`` (rad/s) as the part outputs it, and which samples saturated (E15).

    Rounded to a whole number of ``resolution`` (half to even; 0: not), then held within
    ``+-full_scale`` (0: no range, and None for the second value).
    """
    if resolution > 0.0:
        rate = np.round(rate / resolution) * resolution
    if full_scale <= 0.0:
        return rate, None
    saturated = np.abs(rate) > full_scale
    if saturated.any():
        rate = np.clip(rate, -full_scale, full_scale)
    return rate, saturated


def _periodic_state(sos: np.ndarray, amplitude: complex, theta: float) -> np.ndarray:
    """
    Return the state of second-order sections under ``x[n] = a e^{i theta n}`` at n = 0.

    Complex, shape (sections, 2), in ``scipy.signal.sosfilt``'s transposed direct form II
    (``y = b0 x + z0``, ``z0' = b1 x - a1 y + z1``, ``z1' = b2 x - a2 y``): with ``h`` the
    section's response at ``theta``, ``z0 = (h - b0) x`` and
    ``z1 = (b2 - a2 h) e^{-i theta} x``; each section's input the previous one's output. At
    ``theta = 0`` it is ``sosfilt_zi`` times the input.
    """
    out = np.empty((sos.shape[0], 2), dtype=complex)
    back = cmath.exp(-1j * theta)
    x = complex(amplitude)
    for k, (b0, b1, b2, _, a1, a2) in enumerate(sos):
        h = (b0 + b1 * back + b2 * back * back) / (1.0 + a1 * back + a2 * back * back)
        out[k, 0] = (h - b0) * x
        out[k, 1] = (b2 - a2 * h) * back * x
        x = h * x
    return out


class FlickerNoise:
    """
    Flicker (1/f) rate noise of a given IEEE 952 bias instability, chunk-invariant (E13).

    Parameters
    ----------
    bias_instability_rad_s : float
        B, rad/s (>= 0; 0 gives zeros).
    sample_rate_hz : float
        Rate of the samples, Hz (``gyro.output_rate``).
    seed : int
        ``gyro.noise_seed``.

    """

    def __init__(self, bias_instability_rad_s: float, sample_rate_hz: float, seed: int) -> None:
        if not (math.isfinite(bias_instability_rad_s) and bias_instability_rad_s >= 0.0):
            raise InputError(f'bias_instability: must be finite and >= 0, got '
                             f'{bias_instability_rad_s!r}')
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0.0):
            raise InputError(f'sample_rate_hz: must be finite and > 0, got {sample_rate_hz!r}')
        self.seed = int(seed)
        self.bias_instability_rad_s = float(bias_instability_rad_s)
        self.sample_rate_hz = float(sample_rate_hz)
        self.h_minus1 = self.bias_instability_rad_s ** 2 / math.pi
        ratio = 10.0 ** (1.0 / FLICKER_POLES_PER_DECADE)
        top = 0.5 * sample_rate_hz
        decades = math.log(top / FLICKER_LOWEST_HZ) / math.log(ratio)
        count = max(1, int(math.floor(decades + 1e-9)) + 1)
        self.corners_hz = FLICKER_LOWEST_HZ * ratio ** np.arange(count)
        self.rho = np.exp(-2.0 * math.pi * self.corners_hz / sample_rate_hz)
        self.sigma = math.sqrt(self.h_minus1 * math.log(ratio))
        self._gain = self.sigma * np.sqrt(1.0 - self.rho ** 2)
        self._next = None
        if self.sigma > 0.0:
            self._state = self.sigma * noise.normals(self.seed, noise.STREAM_FLICKER, 0, 1,
                                                     count)[0]
        else:
            self._state = np.zeros(count)

    @property
    def next_index(self):
        """Index of the next sample :meth:`samples` expects (None before the first call)."""
        return self._next

    def samples(self, first_index: int, count: int) -> np.ndarray:
        """
        Return samples ``first_index .. first_index + count - 1``, rad/s.

        The first call may start at any index (the bank is stationary from its start); each
        further call continues where the previous one ended.

        Raises
        ------
        InputError
            ``first_index`` is negative or does not continue the previous call.

        """
        first_index = _check_index('first_index', first_index)
        count = _check_index('count', count)
        if self._next is not None and first_index != self._next:
            raise InputError(f'first_index: the flicker noise continues at sample {self._next}, '
                             f'got {first_index}')
        self._next = first_index + count
        if self.sigma == 0.0 or count == 0:
            return np.zeros(count)
        eps = noise.normals(self.seed, noise.STREAM_FLICKER, first_index + 1, count,
                            self.rho.size)
        out = np.zeros(count)
        for j, (rho, gain) in enumerate(zip(self.rho, self._gain)):
            # y[n] = gain e[n] + rho y[n-1]: direct form II transposed, zi = rho y[-1]
            x, _ = signal.lfilter([gain], [1.0, -rho], eps[:, j], zi=[rho * self._state[j]])
            self._state[j] = x[-1]
            out += x
        return out


def sense_mode(config: SimConfig, linear_stiffness: float) -> Tuple[float, float]:
    """
    Return the sense coordinate's ``(omega_s rad/s, Q_s)`` (E5), less ``linear_stiffness``.

    ``omega_s^2 = K_ss - J_ss``: the coordinate's own stiffness per unit modal mass less the
    linear electrostatic stiffness at rest (``linear_stiffness``, (rad/s)^2; 0 with the
    default fold). ``K_ss`` is ``(2 pi f_2^s)^2`` of ``modes.companion_frequencies``, and
    with an imperfect 2theta pair (principal axes off the electrodes) the pair's diagonal
    (``structure.pair_matrices``, P2); ``Q_s`` likewise ``omega_s / C_ss``.
    """
    m = config.modes.count
    if 2 in config.modes.coupled_pairs():
        stiffness, damping = config.modes.pair_matrices(2)
        ws = math.sqrt(stiffness[1, 1] - linear_stiffness)
        return ws, ws / damping[1, 1]
    ws = math.sqrt((2.0 * math.pi * config.modes.coordinate_frequencies()[m + 1]) ** 2
                   - linear_stiffness)
    return ws, float(config.modes.coordinate_quality_factors()[m + 1])


def orbit_sense_response(config: SimConfig, model, drive_amplitude_m: float) -> complex:
    """
    Return c of (E6b): the sense coordinate's steady response per unit rate, m per rad/s.

    ``q2s = Re(c Omega e^{i psi})`` about the drive orbit ``q2 = A cos psi``
    (``A = drive_amplitude_m``), the sense mode linearised there (module docstring).

    Parameters
    ----------
    config : SimConfig
        With the companions (the sense coordinate is ``q2s``).
    model : forces.ForceModel
        The configuration's force (``Simulator.model``).
    drive_amplitude_m : float
        A, m (> 0).

    """
    n = model.n_coordinates
    m = config.modes.count
    drive, sense = 1, m + 1
    zero = np.zeros(n)
    j_rest = forces.jacobian(zero, model)[sense, sense]
    ws, qs = sense_mode(config, j_rest)
    w = 2.0 * math.pi * float(config.drive.frequency)
    amp, kap = float(drive_amplitude_m), KAPPA_2
    psi = 2.0 * math.pi * np.arange(ORBIT_PHASES) / ORBIT_PHASES
    j = np.empty(ORBIT_PHASES + 1)
    q = zero.copy()
    for k, angle in enumerate(psi):
        q[drive] = amp * math.cos(angle)
        j[k] = forces.jacobian(q, model)[sense, sense] - j_rest
    j[-1] = j[0]
    spline = interpolate.CubicSpline(np.append(psi, 2.0 * math.pi), j, bc_type='periodic')
    period = 2.0 * math.pi / w

    def rhs(t, y):
        stiff = ws * ws - float(spline((w * t) % (2.0 * math.pi)))
        out = np.empty(6)
        # the particular solution (x, v), forced by -2 kappa q2' per unit rate
        out[0] = y[1]
        out[1] = -(ws / qs) * y[1] - stiff * y[0] + 2.0 * kap * amp * w * math.sin(w * t)
        for col in (2, 4):  # the homogeneous fundamental matrix, column by column
            out[col] = y[col + 1]
            out[col + 1] = -(ws / qs) * y[col + 1] - stiff * y[col]
        return out

    y0 = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    end = integrate.solve_ivp(rhs, (0.0, period), y0, method='DOP853', rtol=1e-11,
                              atol=1e-30).y[:, -1]
    monodromy = np.array([[end[2], end[4]], [end[3], end[5]]])
    start = np.linalg.solve(np.eye(2) - monodromy, end[:2])
    t = np.linspace(0.0, period, 257)
    x = integrate.solve_ivp(rhs, (0.0, period), np.concatenate([start, y0[2:]]),
                            method='DOP853', rtol=1e-11, atol=1e-30, t_eval=t).y[0]
    return complex(2.0 / 256.0 * np.sum(x[:-1] * np.exp(-1j * w * t[:-1])))


class PickOff:
    """
    The two charge amplifiers of the pick-off (E1) with their noise (E2).

    Shared by the sense chain (:class:`SenseElectronics`) and the closed-loop drive
    (``core.gyro.control``), which read the same amplifiers: the same voltages, the same noise
    samples (addressed by sample index), on when ``noisy`` and ``gyro.input_noise_density > 0``.

    Parameters
    ----------
    config : SimConfig
        The run's configuration (``electrodes.*``, ``gyro.*``).
    sim : Simulator
        Its simulator (rest capacitances, the gains through the published capacitances).
    noisy : bool
        Whether the amplifiers add their noise (the closed loop of a resonator without
        ``gyro.enabled`` reads ideal amplifiers).

    Attributes
    ----------
    sense_gain, drive_gain : float
        ``dV / dq2s`` and ``dV / dq2`` of the sense and drive amplifiers at rest, V/m (E7);
        ``sense_gain`` is 0 without the companions.

    """

    def __init__(self, config: SimConfig, sim, noisy: bool = True) -> None:
        g = config.gyro
        self.noise_seed = int(g.noise_seed)
        self.sample_rate_hz = float(config.run.output_rate)
        self.drive_index, self.sense_index = modes.of(config).axes(config)
        n_coord = sim.model.n_coordinates
        k = config.electrodes.count
        self.n_electrodes = k
        theta = 2.0 * math.pi * np.arange(k) / k
        # (E1b) the sense electrodes' axis turned by delta (gyro.sense_misalignment)
        delta = math.radians(g.sense_misalignment)
        weights = np.stack([np.sin(2.0 * (theta - delta)) if delta else np.sin(2.0 * theta),
                            np.cos(2.0 * theta)], axis=1)
        weights[np.abs(weights) < _ZERO_WEIGHT] = 0.0
        self.weights = weights
        self.bias_voltage = float(g.bias_voltage or config.electrodes.outer_voltage)
        self.feedback_capacitance = float(g.feedback_capacitance)
        self.volts_per_farad = -(self.bias_voltage / self.feedback_capacitance) * weights  # E1
        if g.pickoff_gain_mismatch:  # (E1c) the sense amplifier's gain against the drive's
            self.volts_per_farad[:, 0] *= 1.0 + g.pickoff_gain_mismatch
        self.rest_capacitance = sim.outputs_for(np.zeros(n_coord)).capacitance[0].copy()
        # (E2) noise gain of each amplifier
        c_in = np.array([self.rest_capacitance[weights[:, j] != 0.0].sum()
                         for j in range(2)]) + g.parasitic_capacitance
        self.input_capacitance = c_in
        self.output_noise_density = g.input_noise_density * (1.0 + c_in / g.feedback_capacitance)
        self._noise_std = self.output_noise_density * math.sqrt(0.5 * self.sample_rate_hz)
        self.noisy = bool(noisy and g.input_noise_density > 0.0)
        # (E7) gains by central differences through the published capacitances
        step = GAIN_STEP_RATIO * config.electrodes.gap
        self.sense_gain = (self._gain(sim, n_coord, self.sense_index, 0, step)
                           if self.sense_index >= 0 else 0.0)
        # what the sense amplifier reads of the drive coordinate: 0 unless misaligned (E1b)
        self.sense_cross_gain = (self._gain(sim, n_coord, self.drive_index, 0, step)
                                 if g.sense_misalignment else 0.0)
        self.drive_gain = self._gain(sim, n_coord, self.drive_index, 1, step)

    def _gain(self, sim, n_coord: int, index: int, amp: int, step: float) -> float:
        q = np.zeros((2, n_coord))
        q[0, index] = step
        q[1, index] = -step
        cap = sim.outputs_for(q).capacitance
        return float((cap[0] - cap[1]) @ self.volts_per_farad[:, amp] / (2.0 * step))

    def clean_volts(self, capacitance: np.ndarray, out: Optional[np.ndarray] = None
                    ) -> np.ndarray:
        """Return the amplifiers' outputs without noise (E1), V, shape (K, 2)."""
        capacitance = np.ascontiguousarray(capacitance, dtype=np.float64)
        if out is None:
            out = np.empty((capacitance.shape[0], self.volts_per_farad.shape[1]))
        kernels.pickoff_volts(capacitance, self.rest_capacitance, self.volts_per_farad, out)
        return out

    def noise(self, first_index: int, count: int) -> Optional[np.ndarray]:
        """Return the white noise of the amplifiers at the given samples, V (E2); None: off."""
        if not self.noisy or count == 0:
            return None
        return noise.block_normals(self.noise_seed, noise.STREAM_PICKOFF, first_index, count,
                                   2) * self._noise_std

    def volts(self, first_index: int, capacitance: np.ndarray) -> np.ndarray:
        """
        Return the amplifiers' outputs (V), shape (K, 2): columns sense, drive (E1, E2).

        ``capacitance`` (K, E) are the outer electrodes' at global samples
        ``first_index .. first_index + K - 1``; the noise is that of those sample indices.
        """
        volts = self.clean_volts(capacitance)
        extra = self.noise(first_index, volts.shape[0])
        if extra is not None:
            volts += extra
        return volts


class SenseElectronics:
    """
    Pick-off, demodulation, low-pass and rate output of the sense chain (module docstring).

    Parameters
    ----------
    config : SimConfig
        The run's configuration (``gyro.*``, ``electrodes.*``, ``drive.frequency``, modes).
    sim : Simulator
        Its simulator (rest capacitances, the electronic gains and the linear stiffness).
    drive_amplitude_m : float
        A, m: the drive mode's operating point ``q2 ~ A cos(phi_drive + drive_phase_rad)``.
    drive_phase_rad : float
        Phase of ``q2`` relative to the drive force's phase ``phi_drive``, rad.

    """

    def __init__(self, config: SimConfig, sim, drive_amplitude_m: float,
                 drive_phase_rad: float, start_rate: float = 0.0,
                 pickoff: Optional['PickOff'] = None) -> None:
        for name, val in (('drive_amplitude_m', drive_amplitude_m),
                          ('drive_phase_rad', drive_phase_rad)):
            if not (isinstance(val, numbers.Real) and math.isfinite(val)):
                raise InputError(f'{name}: must be a finite number, got {val!r}')
        n_modes = config.modes.count
        if not config.modes.companions or n_modes < 2:
            raise InputError('config: the sense electronics need the 2theta pair and its '
                             'companion (modes.companions, at least 2 modes)')
        g = config.gyro
        self.config = config
        self.drive_amplitude_m = float(drive_amplitude_m)
        self.drive_phase_rad = float(drive_phase_rad)
        self.sample_rate_hz = float(config.run.output_rate)
        self.decimation = int(round(config.run.output_rate / g.output_rate))
        self.noise_seed = int(g.noise_seed)
        self.pickoff = PickOff(config, sim) if pickoff is None else pickoff
        po = self.pickoff
        self.sense_index = po.sense_index
        self.drive_index = po.drive_index
        self.n_electrodes = po.n_electrodes
        self.weights = po.weights
        self.bias_voltage = po.bias_voltage
        self.feedback_capacitance = po.feedback_capacitance
        self._volts = po.volts_per_farad
        self.rest_capacitance = po.rest_capacitance
        self.input_capacitance = po.input_capacitance
        self.output_noise_density = po.output_noise_density
        self._noisy = po.noisy
        self.electronic_gain = po.sense_gain
        self.drive_gain = po.drive_gain
        n_coord = sim.model.n_coordinates
        zero = np.zeros(n_coord)
        # (E5, E6) the sense mode's response
        jac = forces.jacobian(zero, sim.model)
        self.sense_omega, self.sense_quality_factor = sense_mode(
            config, jac[self.sense_index, self.sense_index])
        self.drive_omega = 2.0 * math.pi * float(config.drive.frequency)
        self.sense_mass = float(config.modal_masses()[self.sense_index])
        w, ws, qs = self.drive_omega, self.sense_omega, self.sense_quality_factor
        self.sense_response = 1.0 / complex(ws * ws - w * w, w * ws / qs)
        self.mechanical_scale_factor = self.drive_amplitude_m * (
            -2j * KAPPA_2 * w * self.sense_response).real
        self.linear_mechanical_scale_factor = self.mechanical_scale_factor
        self.rate_quadrature_per_rate = 0.0
        if self.drive_amplitude_m > 0.0 and w > 0.0:
            c = orbit_sense_response(config, sim.model, self.drive_amplitude_m)
            self.mechanical_scale_factor = c.real  # (E6b)
            self.rate_quadrature_per_rate = -c.imag / c.real  # Q reads -Im(c) (E3)
        self.scale_factor = self.electronic_gain * self.mechanical_scale_factor
        self.drive_pickoff_nominal_v = abs(self.drive_gain * self.drive_amplitude_m)
        # (E3) filter, started at the operating point's steady state
        self._sos = signal.butter(g.filter_order, g.filter_bandwidth, fs=self.sample_rate_hz,
                                  output='sos')
        steady = np.array([0.0, 0.0, self.drive_gain * self.drive_amplitude_m, 0.0])
        self._zi = signal.sosfilt_zi(self._sos)[:, :, None] * steady[None, None, :]
        self._latest = steady.copy()
        self._latest_quadrature = 0.0
        self._latest_rate = 0.0
        self._next_index = None
        self.flicker = FlickerNoise(deg_per_h_to_rad_per_s(g.bias_instability),
                                    g.output_rate, self.noise_seed)
        self.rebalance = bool(modes.of(config).rebalance)
        self.start_rate = float(start_rate)
        self.phase_error = float(g.phase_error)
        # (E14) the rebalance loop's rate, quadrature and forces through the same low-pass
        self._zi_rb = signal.sosfilt_zi(self._sos)[:, :, None] * np.array(
            [float(start_rate), 0.0, 0.0, 0.0])[None, None, :]
        self.bandwidth_hz = self._bandwidth()
        # (K1) a held calibration (core.gyro.calibration; None: this model's readout), and
        # the drive pick-off's amplitude its ratiometric readout is relative to, held with it
        self.calibration = None
        self.readout_reference_v = self.drive_pickoff_nominal_v
        self.die_temperature: Optional[float] = None  # the die's sensor (K3; None: T_ref)
        self.saturated_samples = 0
        """Rate samples that read the full scale since the chain started (E15)."""

    def _bandwidth(self) -> float:
        """(E9): -3 dB frequency of the sense envelope's pole times the Butterworth, Hz."""
        f_m = self.sense_omega / (2.0 * self.sense_quality_factor) / (2.0 * math.pi)
        if modes.of(self.config).rebalance:  # (E14) the loop's bandwidth
            f_m = self.config.control.rebalance_bandwidth
        fs = self.sample_rate_hz

        def excess(f):
            _, b = signal.sosfreqz(self._sos, worN=[f], fs=fs)
            return math.log(abs(b[0]) ** 2 / (1.0 + (f / f_m) ** 2)) + math.log(2.0)
        top = min(f_m, self.config.gyro.filter_bandwidth)
        if excess(top) >= 0.0:
            return top
        return float(optimize.brentq(excess, 1e-9 * top, top, xtol=1e-12 * top))

    @property
    def has_scale_factor(self) -> bool:
        """Whether a rate can be measured at all (drive on and a bias voltage)."""
        return self.scale_factor != 0.0 and math.isfinite(self.scale_factor)

    @property
    def low_pass(self) -> np.ndarray:
        """Return the output low-pass (E5) as second-order sections at the sample rate."""
        return self._sos

    def rebalance_state(self) -> np.ndarray:
        """Return a copy of the rebalance output's low-pass state (E14)."""
        return self._zi_rb.copy()

    def latest_outputs(self) -> Tuple[float, float]:
        """Return the last ``~/rate`` sample's rate and quadrature before the flicker, rad/s."""
        return float(self._latest_rate), float(self._latest_quadrature)

    @property
    def next_index(self):
        """Global index of the sample :meth:`process` expects next (None before the first)."""
        return self._next_index

    def predicted_arw(self) -> Tuple[float, float, float]:
        """
        Return the predicted angle random walk, rad/sqrt(s) (E10-E12).

        ``(total, thermomechanical, electronic)``; ``inf`` where the scale factor is 0.
        """
        g = self.config.gyro
        if not self.has_scale_factor:
            return math.inf, math.inf, math.inf
        w, ws = self.drive_omega, self.sense_omega
        amp = abs(self.drive_amplitude_m)
        thermo = (math.sqrt(BOLTZMANN * g.temperature * ws
                            / (self.sense_mass * self.sense_quality_factor))
                  / (KAPPA_2 * amp * w))
        electronic = (self.output_noise_density[0] / abs(self.scale_factor)
                      if g.input_noise_density > 0.0 else 0.0)
        return math.hypot(thermo, electronic), thermo, electronic

    def start_outputs(self, values) -> None:
        """
        Start the low-pass in the steady state of given outputs (``DEMOD_CHANNELS``, V).

        Before the first :meth:`process`. The default is the operating point's drive pick-off
        and a sense channel at 0; a run that starts with the sense mode moving (a rate at
        t = 0) passes what its start state gives, so the output has no filter transient.
        """
        if self._next_index is not None:
            raise InputError('values: the filters are already running')
        steady = _check_array('values', values, (4,))
        self._zi = signal.sosfilt_zi(self._sos)[:, :, None] * steady[None, None, :]
        self._latest = steady.copy()

    def start_rebalance(self, values) -> None:
        """
        Start the rebalance output's low-pass in the steady state of the loop's start values.

        ``values``: its rate and quadrature (rad/s, C7) and its in-phase and quadrature
        forces (m/s^2, C6), as the loop holds the start state with them.
        """
        if self._next_index is not None:
            raise InputError('values: the filters are already running')
        steady = _check_array('values', values, (4,))
        self._zi_rb = signal.sosfilt_zi(self._sos)[:, :, None] * steady[None, None, :]

    def continue_from(self, previous: 'SenseElectronics') -> None:
        """
        Take over the running state of the chain this one replaces (a parameter change).

        The filters' states, the flicker bank, the next sample index and the latest outputs
        carry over: the physical electronics do not restart when a bias voltage or a Q
        changes, only their gains and the model's scale factor do.
        """
        self._zi = previous._zi.copy()
        self._zi_rb = previous._zi_rb.copy()
        self._latest = previous._latest.copy()
        self._latest_quadrature = previous._latest_quadrature
        self._latest_rate = previous._latest_rate
        self._next_index = previous._next_index
        self.flicker = previous.flicker
        self.readout_reference_v = previous.readout_reference_v
        self.die_temperature = previous.die_temperature
        self.saturated_samples = previous.saturated_samples

    def resume(self, next_index: int, harmonics: np.ndarray, next_phase: float,
               phase_step: float, rebalance_state: np.ndarray, latest_rate: float,
               latest_quadrature: float, flicker: Optional['FlickerNoise'] = None) -> None:
        """
        Go on at a later sample from a state taken outside the full model (a hand-back).

        ``harmonics``: the sense and drive amplifiers' first harmonics ``V`` (complex, V;
        ``volts = Re(V e^{i phi})``) at the NCO's phase ``phi``, which is ``next_phase`` at
        the next sample and moves by ``phase_step`` a sample. The mixers (E3) make of each
        a constant and a ``2 phi`` term: ``2 Re(V e^{i phi}) cos(phi + psi) = Re(V e^{-i psi})
        + Re(V e^{i psi} e^{2 i phi})`` and with ``sin``, ``-Im(V e^{-i psi})`` and
        ``Re(-i V e^{i psi} e^{2 i phi})``; the low-pass starts in its periodic steady state
        under both (:func:`_periodic_state`: starting it at the constant alone leaves a
        transient of 1.2e-3 of the drive channel 5 ms on). The rebalance output's low-pass
        takes ``rebalance_state`` (its own state, (sections, 2, 4)); the flicker bank, given,
        continues from its state.
        """
        harmonics = np.asarray(harmonics, dtype=complex)
        if harmonics.shape != (2,) or not np.all(np.isfinite(harmonics)):
            raise InputError('harmonics: two finite complex first harmonics expected')
        v_s, v_d = harmonics
        refs = ((v_s, self.drive_phase_rad + self.phase_error),
                (v_d, self.drive_phase_rad))
        zi = np.empty_like(self._zi)
        latest = np.empty(4)
        ripple_at = cmath.exp(2j * next_phase)
        for k, (v, psi) in enumerate(refs):
            mixed = (((v * cmath.exp(-1j * psi)).real, v * cmath.exp(1j * psi)),
                     (-(v * cmath.exp(-1j * psi)).imag, -1j * v * cmath.exp(1j * psi)))
            for j, (dc, ripple) in enumerate(mixed):
                ch = 2 * k + j
                zi[:, :, ch] = (_periodic_state(self._sos, dc, 0.0).real
                                + _periodic_state(self._sos, ripple * ripple_at,
                                                  2.0 * phase_step).real)
                latest[ch] = dc
        self._zi = zi
        self._latest = latest
        self._zi_rb = _check_array('rebalance_state', rebalance_state,
                                   self._zi_rb.shape).copy()
        self._latest_rate = float(latest_rate)
        self._latest_quadrature = float(latest_quadrature)
        if self._next_index is not None:
            self._next_index = int(next_index)
        if flicker is not None:
            self.flicker = flicker

    def rate_variance(self) -> float:
        """
        Return the predicted variance of the rate output, (rad/s)^2 (0 without a scale factor).

        White rate noise of one-sided density ``2 N^2`` (E10) through the path's noise
        bandwidth: the thermomechanical part through the sense mode's first-order pole
        (``pi / 2`` times its -3 dB frequency ``f_s / (2 Q_s)``), the electronic part through
        the Butterworth (its noise bandwidth, from ``sosfreqz``). The flicker term, whose
        variance grows with the record, is left out.

        With force-to-rebalance (E14) both parts pass the loop's closed-loop response ``T(f)``
        (``control.rebalance_response``) and the Butterworth, the electronic part also the
        inverse sense pole ``|1 + i f / f_p|^2``, integrated numerically.
        """
        if not self.has_scale_factor:
            return 0.0
        _, thermo, electronic = self.predicted_arw()
        pole_hz = self.sense_omega / (2.0 * self.sense_quality_factor) / (2.0 * math.pi)
        f, h = signal.sosfreqz(self._sos, worN=1 << 16, fs=self.sample_rate_hz)
        if self.rebalance:
            t2 = np.abs(control.rebalance_response(self.config, f, pole_hz)) ** 2
            density = 2.0 * t2 * (thermo ** 2 + electronic ** 2 * (1.0 + (f / pole_hz) ** 2))
            return float(np.sum(density * np.abs(h) ** 2) * (f[1] - f[0]))
        enbw = float(np.sum(np.abs(h) ** 2) * (f[1] - f[0]))
        return 2.0 * thermo ** 2 * 0.5 * math.pi * pole_hz + 2.0 * electronic ** 2 * enbw

    def predicted_arw_deg_per_sqrt_h(self) -> float:
        """Return the total predicted angle random walk, deg/sqrt(h) (E12)."""
        return rad_per_sqrt_s_to_deg_per_sqrt_h(self.predicted_arw()[0])

    def process(self, first_index: int, t: np.ndarray, capacitance: np.ndarray,
                drive_phase: np.ndarray, rebalance: Optional[np.ndarray] = None
                ) -> Tuple[DemodSamples, RateSamples]:
        """
        Run the chain over consecutive samples of one block.

        Parameters
        ----------
        first_index : int
            Global index of the first sample (sample ``k`` is at ``(k + 1) P``), >= 0; after
            the first call, the sample following the last one processed.
        t : ndarray, shape (K,)
            Sample times, s.
        capacitance : ndarray, shape (K, E)
            Outer electrode capacitances, F (``Samples.capacitance``).
        drive_phase : ndarray, shape (K,)
            Phase ``phi_drive`` of the drive force at each sample, rad.
        rebalance : ndarray, shape (K, 4), optional
            With ``control.mode: rebalance``: the rebalance rate and quadrature of each sample,
            rad/s, and its in-phase and quadrature forces, m/s^2 (E14, K1; required then).

        Returns
        -------
        (DemodSamples, RateSamples)

        Raises
        ------
        InputError
            A wrong shape, a non-finite value, or a sample index that does not continue the
            previous call (the message names the argument).

        """
        first_index = self._check_next(first_index)
        count = np.shape(t)[0] if np.ndim(t) == 1 else -1
        t = _check_array('t', t, (count,))
        capacitance = _check_array('capacitance', capacitance, (count, self.n_electrodes))
        drive_phase = _check_array('drive_phase', drive_phase, (count,))
        volts = self.pickoff.volts(first_index, capacitance)  # (E1, E2), (K, 2)
        return self.process_volts(first_index, t, volts, drive_phase, rebalance)

    def _check_next(self, first_index) -> int:
        first_index = _check_index('first_index', first_index)
        if self._next_index is not None and first_index != self._next_index:
            raise InputError(f'first_index: the electronics continue at sample '
                             f'{self._next_index}, got {first_index} (blocks must follow '
                             f'each other)')
        return first_index

    def process_volts(self, first_index: int, t: np.ndarray, volts: np.ndarray,
                      drive_phase: np.ndarray, rebalance: Optional[np.ndarray] = None
                      ) -> Tuple[DemodSamples, RateSamples]:
        """
        Run the chain from the amplifiers' outputs: :meth:`process` after (E1, E2).

        ``volts`` (K, 2): the sense and drive amplifiers' outputs (``PickOff.volts``) at the
        samples ``first_index ..``, V; the simulator computes them once for the loops and
        this chain. The other arguments and the result as :meth:`process`.
        """
        first_index = self._check_next(first_index)
        count = np.shape(t)[0] if np.ndim(t) == 1 else -1
        t = _check_array('t', t, (count,))
        volts = _check_array('volts', volts, (count, 2))
        drive_phase = _check_array('drive_phase', drive_phase, (count,))
        phi = drive_phase + self.drive_phase_rad
        two_cos = 2.0 * np.cos(phi)
        two_sin = 2.0 * np.sin(phi)
        mixed = np.empty((count, 4))
        if self.phase_error:  # (E3b) the sense channel's reference off by gyro.phase_error
            np.multiply(volts[:, 0], 2.0 * np.cos(phi + self.phase_error), out=mixed[:, 0])
            np.multiply(volts[:, 0], 2.0 * np.sin(phi + self.phase_error), out=mixed[:, 1])
        else:
            np.multiply(volts[:, 0], two_cos, out=mixed[:, 0])
            np.multiply(volts[:, 0], two_sin, out=mixed[:, 1])
        np.multiply(volts[:, 1], two_cos, out=mixed[:, 2])
        np.multiply(volts[:, 1], two_sin, out=mixed[:, 3])
        if count:
            values, self._zi = signal.sosfilt(self._sos, mixed, axis=0, zi=self._zi)  # (E3)
        else:
            values = mixed
        d = self.decimation
        start = (d - (first_index + 1) % d) % d
        picks = np.arange(start, count, d)
        held = self.calibration
        if self.rebalance:
            rebalance = _check_array('rebalance', rebalance, (count, 4))
            if count:
                rb, self._zi_rb = signal.sosfilt(self._sos, rebalance, axis=0,
                                                 zi=self._zi_rb)  # (E14)
            else:
                rb = rebalance
            if held is not None:  # (K1) the forces are the readout
                rate, quadrature = held.apply(rb[picks, 2], rb[picks, 3],
                                              self.die_temperature)
            else:
                rate = rb[picks, 0].copy()
                quadrature = rb[picks, 1].copy()
        elif held is not None:
            # (K1) the ratiometric readout against the drive pick-off's held amplitude
            rho = np.maximum(np.hypot(values[picks, 2], values[picks, 3])
                             / self.readout_reference_v, RHO_FLOOR)
            rate, quadrature = held.apply(values[picks, 0] / rho, values[picks, 1] / rho,
                                          self.die_temperature)
        elif self.has_scale_factor:
            rho = np.maximum(np.hypot(values[picks, 2], values[picks, 3])
                             / self.drive_pickoff_nominal_v, RHO_FLOOR)
            rate = values[picks, 0] / (self.scale_factor * rho)  # (E4)
            quadrature = values[picks, 1] / (self.scale_factor * rho)
        else:
            rate = np.zeros(picks.size)
            quadrature = np.zeros(picks.size)
        if picks.size and (self.rebalance or held is not None or self.has_scale_factor):
            self._latest_rate = float(rate[-1])
        if picks.size:
            rate += self.flicker.samples((first_index + start + 1) // d - 1, picks.size)
        rate, saturated = self.output_word(rate)
        self._next_index = first_index + count
        if count:
            self._latest = values[-1].copy()
            if held is not None:
                if picks.size:
                    self._latest_quadrature = float(quadrature[-1])
            elif self.rebalance:
                self._latest_quadrature = float(rb[-1, 1])
            elif self.has_scale_factor:
                rho = max(math.hypot(values[-1, 2], values[-1, 3])
                          / self.drive_pickoff_nominal_v, RHO_FLOOR)
                self._latest_quadrature = float(values[-1, 1] / (self.scale_factor * rho))
        return (DemodSamples(t=t, values=values),
                RateSamples(t=t[picks], rate=rate, quadrature=quadrature, saturated=saturated))

    def output_word(self, rate: np.ndarray) -> Tuple[np.ndarray, Optional[np.ndarray]]:
        """
        Return the rate as the part outputs it, and which samples saturated (E15).

        ``rate`` rounded to a whole number of ``gyro.resolution`` (half to even), then held
        within +-``gyro.range``; the second value is None without a range. Counts the
        saturated samples in :attr:`saturated_samples`.
        """
        g = self.config.gyro
        rate, saturated = output_word(rate, g.resolution, g.range)
        if saturated is not None:
            self.saturated_samples += int(np.count_nonzero(saturated))
        return rate, saturated

    def expected_drive_ratio(self, rate: float) -> float:
        """
        Return the drive amplitude over its operating point's at ``rate`` (rad/s), linear.

        The pair's linear response (E8) relative to the operating point, which already holds
        the response to the rate at t = 0 (``Omega_0``): with ``d = F / (A e^{ip})`` the
        operating point's ``D - g_0^2 / D_s``, the ratio is ``|d / (d + (g_0^2 - g^2) / D_s)|``
        (``g = 2 kappa Omega w``); 0 without a drive. With the closed-loop drive 1 (the AGC
        holds the amplitude).
        """
        if modes.of(self.config).closed:
            return 1.0
        amp = self.drive_amplitude_m
        force = self.config.drive.amplitude
        if amp <= 0.0 or force == 0.0:
            return 0.0
        w = 2.0 * math.pi * self.config.drive.frequency
        d = force / (amp * complex(math.cos(self.drive_phase_rad),
                                   math.sin(self.drive_phase_rad)))
        ws = self.sense_omega
        d_s = complex(ws * ws - w * w, w * ws / self.sense_quality_factor)
        g = 2.0 * KAPPA_2 * rate * w
        g_0 = 2.0 * KAPPA_2 * self.start_rate * w
        return abs(d / (d + (g_0 * g_0 - g * g) / d_s))

    def diagnostics_values(self) -> Dict[str, Union[float, bool, int]]:
        """Return the rate channel's state for ``/diagnostics`` (latest processed sample)."""
        g = self.config.gyro
        pickoff = math.hypot(self._latest[2], self._latest[3])
        nominal = self.drive_pickoff_nominal_v
        ratio = pickoff / nominal if nominal > 0.0 else 0.0
        expected = self.expected_drive_ratio(self._latest_rate)
        return {
            'rate_scale_factor_v_per_rad_s': float(self.scale_factor),
            'rate_quadrature_rad_s': float(self._latest_quadrature),
            'drive_pickoff_v': float(pickoff),
            'drive_pickoff_nominal_v': float(nominal),
            'drive_amplitude_ratio': float(ratio),
            'drive_amplitude_ratio_expected': float(expected),
            'scale_factor_valid': bool(self.has_scale_factor and expected > 0.0
                                       and abs(ratio / expected - 1.0)
                                       <= SCALE_FACTOR_TOLERANCE),
            'noise_seed': int(self.noise_seed),
            'input_noise_density_v_per_sqrt_hz': float(g.input_noise_density),
            'temperature_k': float(g.temperature),
            'bias_instability_deg_per_h': float(g.bias_instability),
            'predicted_arw_deg_per_sqrt_h': float(self.predicted_arw_deg_per_sqrt_h()),
            'bandwidth_hz': float(self.bandwidth_hz),
            'rate_range_rad_s': float(g.range),
            'rate_resolution_rad_s': float(g.resolution),
            'rate_saturated_samples': int(self.saturated_samples),
        }
