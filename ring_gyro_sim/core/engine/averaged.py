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
The averaged (slow-flow) model of the driven 2theta pair, open loop and closed loop.

What it is
----------
The 2theta pair ``q_c = q2``, ``q_s = q2s`` driven open loop at the fixed frequency and force
of ``drive.*``, in the sensor frame turning at the scheduled rate ``scenario.rate_*``
(``gyro.enabled``), written as two slowly varying complex envelopes in the frame that turns
at the drive frequency ``omega = 2 pi drive.frequency``::

    q_c(t) = Re(A_c(t) e^{i phi(t)}),   q_c'(t) = Re(i omega A_c(t) e^{i phi(t)})       (S1)

and likewise q_s with A_s; ``phi(t) = omega t`` is the drive's phase (0 at t = 0, as in the
full model). A = (A_c, A_s). One step of the averaged model is a step of an ODE in these 4
real numbers whose rates are those of the envelopes (at most ``omega / Q`` and the
detunings), not of the 15.8 kHz carrier: ``solve_ivp`` takes steps of milliseconds.

The closed-loop gyroscope
-------------------------
:class:`AveragedGyro` closes the PLL, the AGC and force-to-rebalance on these envelopes, in
the frame of the NCO's phase, with the pick-off's first harmonic and the output filter of
``~/rate`` (its docstring: S5-S8), and the noises of the full model as their baseband
equivalents (S9-S11); the averaged force of both is the closed form (S3) of
``kernels.envelope``.

What it is not
--------------
In ``analysis.slow_flow.AveragedModel``: the loops and the sense electronics
(:class:`AveragedGyro` has them), the noises (:class:`AveragedGyro` has them, S9-S11).
``analysis.slow_flow.AveragedModel`` takes the device at the die temperature of t = 0;
:class:`AveragedGyro` follows the die (S12). In both: the open-loop sense readout of
``~/rate``, ``~/demodulator``, the other modes (q1, q3, ...: see "Validity"), shocks, base
acceleration, vibration and contact are not represented: a run hands the stretches they act in
to the full model, and builds ``~/demodulator`` of an averaged stretch from the envelopes
(``core.engine.averaged.AveragedEngine``; doc/averaged.md, "The hand-offs in a run").

Derivation
----------
(M) The modal equations of the pair, per unit modal mass (doc/physics.md eq. 28; the
imperfect pair's matrices P2, P3 of ``structure.pair_matrices``; the rotating frame's
terms G5, G6 of ``structure.gyroscopic_coefficient``; the drive of section 3.4)::

    q'' + (C + 2 kappa Omega J) q' + (K + kappa Omega' J - Omega^2 I) q
        = a_nl(q) + F e_c cos(phi(t)),        J = [[0, -1], [1, 0]],  kappa = 0.8

K and C the 2x2 stiffness and damping of the pair (``modes.pair_matrices(2)``: diagonal
``omega_2^2`` and ``omega_2 / Q_2`` for the perfect ring, coupled by a frequency split or
damping mismatch off the electrodes' axes), F = ``drive.amplitude`` (m/s^2) on the cos
coordinate only, ``a_nl`` the electrostatic force per modal mass without its folded linear
part (eq. 21 differentiated, ``forces.nonlinear_acceleration``) restricted to the pair.

(V) Variation of constants. (S1) is a change of variables from (q, q') to A with the
constraint ``Re(A' e^{i phi}) = 0``; then ``q'' = Re((i omega A' - omega^2 A) e^{i phi})``
and (M) becomes exactly ``Re(i omega A' e^{i phi}) = f(q, q', t)`` with f everything in (M)
but ``q''`` plus ``omega^2 q``. The two real equations solve to ``A' = f e^{-i phi} /
(i omega)``: exact, but with terms at 0, 2 phi, 3 phi, ...

(A) First-order averaging over the fast phase keeps the mean of ``f e^{-i phi}``, that is
half the complex first-harmonic coefficient ``f_1`` of f (``f = Re(f_1 e^{i phi}) + ...``)::

    A' = -(i / (2 omega)) [ (omega^2 + Omega^2) A - K A - i omega (C + 2 kappa Omega J) A
                            - kappa Omega' J A + N(A) + F e_c ]                       (S2)

with N(A) the first-harmonic coefficient of ``a_nl(Re(A e^{i phi}))`` over one period of
phi: the describing function of the electrostatic force, computed by
``harmonic_balance``'s alternating-frequency-time machinery (``Balance.nonlinear`` with
one harmonic: the orbit sampled at N equally spaced phases, the exact quadrature force at
each, projected on cos and sin; exact for the Taylor force since ``N > N_T``). Term by term:

- ``(omega^2 - K) A - i omega C A``: detuning and damping. Kept as ``omega^2 - K`` (not
  linearised to ``2 omega (omega - omega_2)``): the steady state of the linear part is then
  the exact phasor ``F / (omega_2^2 - omega^2 + i omega omega_2 / Q)``. With F = 0 and
  ``omega = omega_2`` it gives ``|A| ~ exp(-omega_2 t / (2 Q))``, the modal decay.
- ``-2 i omega kappa Omega J A``: the Coriolis coupling; ``-(i/2omega)`` of it is the real
  rotation ``-kappa Omega J A`` of (A_c, A_s): it conserves ``|A_c|^2 + |A_s|^2``.
  Matched modes at resonance give the steady sense response
  ``A_s / A_c = -2 kappa Omega Q / omega`` (doc/gyroscope.md; ``operating_point``'s
  ``_add_sense_response`` has the same phasors).
- ``-kappa Omega' J A``: the angular acceleration (G5, G6), the slope of the rate profile
  between its knots. A step of the rate (a repeated knot) is taken as the full model takes
  it (``kernels.forcing._rate_at``: the value after the step, derivative 0), with no
  impulse. (Integrated across a step, G5-G6 would make ``q'`` jump by
  ``-kappa dOmega J q``, ``A -> A + (i kappa dOmega / omega) J A``: ``kappa dOmega / omega``
  of the drive envelope, 1.4e-6 for a 10 deg/s step, below the averaging error 1 / (2 Q) =
  7.7e-6. Both models leave it out, and agree on what a step is.)
- ``Omega^2 A``: the centrifugal term (3e-11 of ``omega^2`` at 300 deg/s).
- ``N(A)``: the electrostatic softening and the coupling of the pair through the force
  (the drive's amplitude softens and pumps the sense mode: the terms of N in conj(A_s)).
  N conserves ``|A|^2`` too: ``Im(A^H N(A)) = (2 / omega) <q' . a_nl(q)>`` = the mean
  rate of change of the electrostatic energy over a period, 0 (``test_averaged``).
- ``F e_c``: the drive's first harmonic.

(R) The outputs: A at the requested sample times and ``q = Re(A e^{i phi})``,
``q' = Re(i omega A e^{i phi})`` (S1). :func:`envelope_of` is the inverse map from a state
``(q, q')`` of the full model (exact: S1 is a change of variables).

Validity
--------
The error of first-order averaging is ``O(epsilon)`` of the envelope over times
``O(1 / epsilon)`` (Bogoliubov-Mitropolsky; Sanders-Verhulst, ch. 2), epsilon the largest of
the pair's slow rates over omega: ``1 / (2 Q)``, the detuning ``|omega_2 - omega| / omega``,
``kappa |Omega| / omega``, the electrostatic frequency shift over omega and the split over
omega. On the default device each is below 1e-4 (7.7e-6, 0 to 9e-5, 1.4e-6 at 10 deg/s,
9e-5 at the paper's drive amplitude, 0). It needs:

- slowly varying inputs: the rate's and the drive's changes slow against omega (a step of
  the rate as in the full model, above);
- no other mode near a multiple or a combination of the drive frequency: the higher modes
  are assumed at rest. With N_R = 3 (the default) this is exact for the modes' coupling:
  a pure 2theta displacement has no force on the 1theta and 3theta pairs (its powers hold
  only even harmonics of theta), so q1 = q3 = 0 is invariant. From N_R = 4 the 4theta pair
  is forced at 0 and 2 omega by ``q2^2``; its response (off resonance) is left out;
- the higher harmonics of the pair (3 omega, ...) neglected: their feedback on the first
  harmonic is of the second order in the nonlinearity (``test_averaged`` measures it
  against the shooting orbit);
- none of what is listed above as not represented: shocks, base acceleration, vibration,
  contact, noise (in ``analysis.slow_flow.AveragedModel``), loops, temperature changes.
"""

import copy
from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np
from ring_gyro_sim.core import kernels, noise, structure, thermal
from ring_gyro_sim.core.engine.base import Engine, GyroState, Samples
from ring_gyro_sim.core.errors import ParameterError, SimulationError
from ring_gyro_sim.core.gyro import electronics, modes
from ring_gyro_sim.core.params import BOLTZMANN, SimConfig

__all__ = ['AveragedEngine', 'AveragedGyro', 'GyroSamples',
           'envelope_of', 'pair_force_arrays', 'state_of']


def pair_force_arrays(model, index_c: int, index_s: int) -> Tuple[np.ndarray, ...]:
    """
    Return ``(fb_c, fb_s, fw_c, fw_s, dcoef)`` of (S3) from a truncated force model.

    The kernel's angles at their four orbit members (``kernels.member_basis``): the pair's
    shapes over d_g, the projections with each coordinate's parities, and ``D(s)``.
    """
    k = model.kernel
    kb = k.kbasis
    s1, s2 = k.signs[0], k.signs[1]

    def weights(i):
        p = k.projection[i]
        return np.ascontiguousarray(np.concatenate([p, s1[i] * p, s2[i] * p,
                                                    s1[i] * s2[i] * p]))
    poly = np.asarray(k.poly, dtype=float)
    dcoef = np.zeros(max(1, (poly.size + 1) // 2))
    for order in range(1, poly.size, 2):   # (S3): odd powers only
        dcoef[(order - 1) // 2] = (poly[order] * 2.0 ** (1 - order)
                                   * math.comb(order, (order - 1) // 2))
    return (np.ascontiguousarray(kb[index_c]), np.ascontiguousarray(kb[index_s]),
            weights(index_c), weights(index_s), dcoef)


def envelope_of(q: np.ndarray, v: np.ndarray, omega: float, phase: np.ndarray) -> np.ndarray:
    """
    Return the complex envelopes ``A = (q - i v / omega) e^{-i phase}`` of states (S1).

    Parameters
    ----------
    q, v : ndarray, shape (..., 2)
        Displacements (m) and velocities (m/s) of the pair (q_c, q_s).
    omega : float
        The drive's angular frequency, rad/s.
    phase : ndarray, shape (...)
        The drive's phase at each state, rad.

    Returns
    -------
    ndarray of complex, shape (..., 2)
        A, m.

    """
    rot = np.exp(-1j * np.asarray(phase, dtype=float))[..., None]
    return (np.asarray(q, dtype=float) - 1j * np.asarray(v, dtype=float) / omega) * rot


def state_of(envelope: np.ndarray, omega: float,
             phase: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Return ``(q, v)`` (m, m/s) of envelopes ``A`` (m) at the drive phases (rad) (S1)."""
    z = np.asarray(envelope) * np.exp(1j * np.asarray(phase, dtype=float))[..., None]
    return z.real, (1j * omega * z).real


@dataclass(frozen=True)
class GyroSamples:
    """
    Output of :meth:`AveragedGyro.advance`: one row per ``~/rate`` sample (S8).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s (every ``1 / gyro.output_rate``).
    rate, quadrature : ndarray, shape (K,)
        ``~/rate``'s rate and quadrature, rad/s: the held calibration applied to the
        filtered rebalance forces (K1), or without one the filtered rebalance rate and
        quadrature (C7, E14); the rate plus the flicker (S11), then the output word (E15:
        ``gyro.resolution``, ``gyro.range``).
    readout : ndarray, shape (K, 2)
        The filtered rebalance forces ``(S_c, S_s)``, m/s^2: the readout before calibration.
    envelope : ndarray of complex, shape (K, 2)
        ``(B_c, B_s)``, m: the pair's envelopes in the NCO's frame (S5).
    control : ndarray, shape (K, len(control.CONTROL_CHANNELS))
        The loops' state after the update at each sample time (``~/control``'s columns).
    nco_phase : ndarray, shape (K,)
        The NCO's phase at each sample time, rad: ``q = Re(B e^{i phase})`` (S5).
    saturated : ndarray of bool, shape (K,), or None
        Which samples read the full scale (E15); None without ``gyro.range``.

    """

    t: np.ndarray
    rate: np.ndarray
    quadrature: np.ndarray
    readout: np.ndarray
    envelope: np.ndarray
    control: np.ndarray
    nco_phase: np.ndarray
    saturated: Optional[np.ndarray] = None


_NO_NOISE = np.zeros((0, 8))


def _control_rows(rows: np.ndarray) -> np.ndarray:
    """Return the loops' states ``(K, LOOP_STATE_SIZE)`` as ``~/control`` rows (C9)."""
    e = kernels.envelope
    return np.stack([rows[:, e.OMEGA] / (2.0 * math.pi), rows[:, e.PHASE_ERR],
                     rows[:, e.AMP], rows[:, e.FORCE], rows[:, e.SC],
                     rows[:, e.SS], rows[:, e.RB_RATE], rows[:, e.RB_QUAD],
                     rows[:, e.LOCKED], rows[:, e.RB_ON]], axis=1)


NOISE_CHUNK = 1024
"""Loop periods of normals drawn at once per noise stream (``AveragedGyro._normals``)."""

MAX_ROTATION = 0.05
"""Largest ``|lambda| h`` of an RK4 substep (S6): local error ``(lambda h)^5 / 120`` = 3e-9."""


class AveragedGyro:
    """
    The closed-loop gyroscope at envelope level: the pair's slow flow and the loops (S5-S11).

    What it is
    ----------
    The pair's envelopes of (S2) in the frame of the NCO's phase ``phi`` (the drive's),
    ``q = Re(B e^{i phi})``, ``q' = Re(i omega_c B e^{i phi})`` (``omega_c = 2 pi
    drive.frequency``): with ``A = B e^{i theta}``, ``theta = phi - omega_c t``, (S2) gives::

        B' = -(i / (2 omega_c)) [ ... of (S2) at B ... + F_c ] - i (omega - omega_c) B  (S5)

    ``omega`` the NCO's frequency of the loop period, ``F_c = (F, (S_c - i S_s)
    e^{i eps})`` the commands in force over it: the drive ``F cos(phi)`` on q2 and the
    rebalance ``S_c cos(phi) + S_s sin(phi)`` on q2s (``kernels.forcing``; ``eps`` =
    ``gyro.phase_error``). N(B) is (S3), exact for the truncated force.

    (S6) The step: RK4, each loop period (``1 / control.rate``) cut at the rate profile's
    knots (each stage takes the profile's value at its time, the last stage its left limit:
    a step of the rate acts from its time on, as in the full model) and each piece into the
    fewest equal substeps with ``|lambda| h <= MAX_ROTATION``, ``|lambda|`` a bound of the
    flow's rates (the NCO's offset, the pair's detunings from omega_c and 1e-4 omega_c for the
    electrostatic shift, 9e-5 omega at the default drive): one substep per 1 ms period on
    the default gyroscope, whose rates are ~10 rad/s (local error ~(0.01)^5 / 120 = 1e-12
    of the envelope). The commands are constant over a period (C1): the step never crosses
    a change of them. At a constant rate with the loops settled the readout is the
    equilibrium of (S5) and the loops, which a Runge-Kutta step keeps exactly: the step
    moves transients only.

    (S7) The loops read what the full model's least-squares fit (C2) reads of a sinusoid of
    slowly varying envelope: the first harmonic of the pick-off's voltages (S4) at the
    period's mean envelope (the mean by the RK4 quadrature of the same step; the fit of
    a linearly varying envelope is its value at the window's centre, to ``1 / (2 omega)``
    of its slope). The loops' update is ``DriveLoop.update``'s (C3-C8b) compiled, from the
    state :meth:`DriveLoop.start` gives at the start state.

    (S8) The rate: the held rows (C7, C6) through the output low-pass (E14), stepped exactly
    over each period's ``N`` samples of a held input (a linear map of its state), read at
    the period's last sample (E4's decimation), then the held calibration (K1) when given.

    The noises: the full model's three (``gyro.temperature``, ``gyro.input_noise_density``,
    ``gyro.bias_instability``), each as the baseband noise with the same statistics, drawn
    per loop period from counter-based streams of ``gyro.noise_seed`` (``core.noise``: a
    run cut into calls of any length draws the same numbers). All three off, the
    arithmetic is that of the noiseless model, bit for bit.

    (S9) The thermomechanical force. The full model's is white, of two-sided acceleration
    density (a 2x2 matrix on the pair) ``S = 2 k_B T_n C / m`` (``T_n`` =
    ``gyro.temperature``, C the pair's damping per unit modal mass, m the modal mass of q2:
    fluctuation-dissipation, ``Simulator._build_rotation``). In (V) it is part of f: a force
    ``xi`` adds ``xi e^{-i phi} / (i omega)`` to A', whose increment over a period T,
    ``dA = -(i / omega) int xi e^{-i phi} dt``, has real and imaginary parts of covariance
    ``S T / (2 omega^2)`` each and uncorrelated (``int cos^2 = int sin^2 = T / 2``,
    ``int cos sin = 0``, to ``1 / (2 omega T)`` = 0.5 % in a given period, which averages
    out as the period's start phase moves): a circular complex Gaussian, the same in any
    frame that turns with phi (B's). The model holds over each period a first
    harmonic ``f_n`` with real and imaginary parts each ``N(0, 2 S / T)``
    (``= 4 k_B T_n C / (m T)``, by its Cholesky factor), added to the commands ``F_c`` of
    (S5): the increment ``-(i / (2 omega_c)) f_n T`` has the covariance above. Within a
    period the noise's time structure is not kept (the loops read once a period); the
    stationary state of the undriven pair is equipartition, ``E(|B_c|^2 + |B_s|^2) = 4 k_B
    T_n / (m omega_c^2)``, i.e. ``<q^2> = k_B T_n / (m omega^2)`` per coordinate (the
    Lyapunov equation of (S5): the detunings and the Coriolis term rotate B, C dissipates
    what the noise brings; the increment's first-order error in ``gamma T``, gamma =
    ``omega / (2 Q)``, cancels in the stationary variance to ``(gamma T)^2`` = 6e-7).

    (S10) The pick-off noise after the fit. The full model adds white noise of standard
    deviation ``sigma = e_o sqrt(f_s / 2)`` to each amplifier's samples (E2, ``e_o`` the
    output-referred density); the fit of C2 on ``cos, sin, 1`` over the period's
    ``N = f_s T`` samples has coefficient errors of covariance ``sigma^2 (X^T X)^{-1}``,
    ``(2 sigma^2 / N) I`` on cos and sin to ``O(1 / (N sin(omega / f_s)))`` (within 1.1 %
    at a given window phase, 3e-4 on average; correlation within 1 %). So each component of
    each amplifier's first harmonic, as the loops read it, gets ``N(0, e_o^2 / T)`` per
    period, independent across components, amplifiers and periods. It reaches ``~/rate`` as
    in the full model: through the loops (the rebalance force and the measured amplitude
    that scales it, C7); not into the sense chain's own reading (``~/demodulator``, which
    ``AveragedEngine`` builds from the envelopes without it).

    (S11) The flicker: the full model's bank (E13, ``electronics.FlickerNoise``, the same
    seed and rate-sample indices), added to ``~/rate`` after the calibration as E13 adds it:
    the same samples.

    (S12) Temperature: the die (T2, ``thermal.DieTemperature``) is followed as the full model
    follows it: every ``THERMAL_UPDATE_S`` the die's sensor (the calibration's
    compensation, K3) reads it, and once it has moved ``THERMAL_STEP_K`` from the device's
    temperature the pair's K and C (T3-T5) and the amplifiers' volts per farad (T6) are
    rebuilt; the loops keep their designed gains. The frame of (S5) turns at
    ``omega_frame = omega_c (1 + alpha dT)`` (T3), the drive mode's frequency on that die:
    held at ``omega_c``, the averaging's error ``(omega - omega_frame) / omega`` would be
    the NCO's offset, 6e-4 at 20 K, against 1 / (2 Q) = 7.7e-6. On a change of frame, B
    is rescaled to the slow part of the same oscillation at the NCO's omega:
    ``(q - i q' / w) e^{-i phi}`` of an oscillation of amplitude X at omega has the slow
    part ``X (1 + omega / w) / 2``.

    (S13) The hand-off from the full model (``simulator``): at a loop update the state maps
    exactly. The pair's envelopes are ``(q - i q' / omega_frame) e^{-i phi}`` of the full
    model's state at the NCO's phase ``phi`` now (S1, an exact change of variables); the
    loops' state is the one their last update left (C3-C8b, the lock and qualification
    counters included); the output filter's state and the die's are copied. The averaged
    model then drops what averaging drops: the envelope's ripple at ``2 omega`` (of
    relative size ``(omega - omega_frame) / omega`` and ``kappa Omega / omega``) and the
    other modes, which the caller hands off only once they have rung down
    (:func:`fast_mode_amplitude`).

    (S14) The hand-back to the full model (:meth:`AveragedGyro.export_state`,
    ``Simulator.import_state``): at a loop update the pair's coordinates and velocities are
    those of the envelopes at the NCO's phase (S1, exact for the averaged state) and the other
    modes at rest; the loops, the output filter, the die and the flicker bank carry over; the
    demodulator's low-pass (E3, not in the averaged model) restarts in its periodic steady
    state under the mixers' products of the amplifiers' first harmonics (S4), the constant and
    the ``2 omega`` terms. The full model's clock jumps; its noises are addressed by sample
    index and go on.

    What it is not: the block topics and the open-loop sense readout; shocks, base
    acceleration, vibration and contact (doc/averaged.md).

    Parameters
    ----------
    config : SimConfig
        ``control.mode: rebalance``, ``gyro.enabled``, the
        companions, ``electrodes.taylor_terms > 0``, ``gyro.output_rate`` a whole fraction
        of ``control.rate``.
    start_state : (q, v), optional
        The full model's start state; default that of ``run.Run``
        (``operating_point.start_state`` of the device at the die's start temperature).
    calibration : gyro_calibration.Calibration or None
        The held calibration (K1) of ``~/rate``; None: the model's own rebalance readout.
    simulator : Simulator, optional
        A running full model of ``config`` to continue from (S13, the hand-off to the
        averaged model): its state at its current time, which must be a loop update (a
        whole number of loop periods); ``start_state`` is then not used.

    """

    def __init__(self, config: SimConfig, start_state=None, calibration=None,
                 simulator=None) -> None:
        from ring_gyro_sim.core.gyro import control, operating_point
        from ring_gyro_sim.core.engine.full import Simulator, THERMAL_UPDATE_S
        from scipy import signal
        if not modes.of(config).rebalance:
            raise ParameterError('control.mode: the closed-loop averaged model needs '
                                 f'control.mode: rebalance, got {config.control.mode}')
        if not config.gyro.enabled or not config.modes.companions or config.modes.count < 2:
            raise ParameterError('gyro.enabled: the closed-loop averaged model is the '
                                 'gyroscope (gyro.enabled, modes.companions, N_R >= 2)')
        if config.electrodes.taylor_terms <= 0:
            raise ParameterError('electrodes.taylor_terms: the averaged force (S3) is that '
                                 'of the truncated series, got 0')
        if simulator is not None:
            sim = simulator
            if sim.loop is None or sim.sample_index % sim.loop.window:
                raise ParameterError(f'simulator: the hand-off is at a loop update; sample '
                                     f'{sim.sample_index} is not a whole number of loop '
                                     f'periods')
        else:
            if start_state is None:
                start_state = operating_point.start_state(thermal.start_state_device(config))
            sim = Simulator(config, start_state, calibration=None)
        # what the averaged model is derived from: the full model's design and its state
        # now (the engine contract, core.engine.base)
        design, state = sim.design(), sim.export_state()
        if simulator is not None:
            start_state = (state.q, state.v)
        loop = design.loop
        window = loop.window
        decimation = int(round(config.run.output_rate / config.gyro.output_rate))
        if decimation % window:
            raise ParameterError(f'gyro.output_rate: the averaged model outputs at loop '
                                 f'updates; {config.gyro.output_rate} Hz is not a whole '
                                 f'fraction of control.rate = {config.control.rate} Hz')
        self.config = config
        self.calibration = calibration
        self.decimate = decimation // window
        self._period_ns = int(design.period_ns)
        device = thermal.device_at(config, design.device_temperature)
        m = device.modes.count
        ic, is_ = 1, m + 1
        fb_c, fb_s, fw_c, fw_s, dcoef = pair_force_arrays(design.model, ic, is_)
        geometry = design.output_geometry
        n_k = design.pickoff.n_electrodes
        n_e = geometry.electrode_weights.size
        node_electrode = np.arange(n_e) // (n_e // n_k)
        vpf = design.pickoff.volts_per_farad
        node = geometry.cap_scale * geometry.electrode_weights
        # the output low-pass over one period of a held input, as a linear map (S8)
        sos = signal.butter(config.gyro.filter_order, config.gyro.filter_bandwidth,
                            fs=config.run.output_rate, output='sos')
        size = 2 * sos.shape[0]
        f_state = np.empty((size, size))
        out_state = np.empty(size)
        for j in range(size):
            zi = np.zeros(size)
            zi[j] = 1.0
            y, zf = signal.sosfilt(sos, np.zeros(window), zi=zi.reshape(-1, 2))
            f_state[:, j] = zf.ravel()
            out_state[j] = y[-1]
        y, zf = signal.sosfilt(sos, np.ones(window), zi=np.zeros((sos.shape[0], 2)))
        stiffness, damping = device.modes.pair_matrices(2)
        # (S12) the frame turns at the drive mode's frequency on this die: the NCO's centre
        # moved with the frequencies (T3), as the full model starts the NCO
        frame = float(loop.omega_c * thermal.frequency_scale(config, design.device_temperature))
        if simulator is not None:   # the profile in force: streamed rates included
            times, values = state.rate_knots
        else:
            times = np.asarray(config.run.rate_times, dtype=float)
            values = np.asarray(config.run.rate_values, dtype=float)
        pb_c = np.ascontiguousarray(geometry.electrode_shapes[ic])
        pb_s = np.ascontiguousarray(geometry.electrode_shapes[is_])
        pg_drive = np.ascontiguousarray(node * vpf[node_electrode, 1])
        pg_sense = np.ascontiguousarray(node * vpf[node_electrode, 0])
        gap = float(geometry.gap)
        # (S3) and (S4)'s sums over angles with the symmetric angles merged
        groups = kernels.envelope.harmonic_groups
        fgroups = groups(fb_c, fb_s, fw_c, fw_s)
        pgroups = groups(pb_c / gap, pb_s / gap, pg_drive / gap, pg_sense / gap)
        self.model = kernels.EnvelopeModel(
            fb_c=fb_c, fb_s=fb_s, fw_c=fw_c, fw_s=fw_s, dcoef=dcoef, fgroups=fgroups,
            pb_c=pb_c, pb_s=pb_s, pg_drive=pg_drive, pg_sense=pg_sense, pgroups=pgroups,
            gap=gap, omega_c=float(loop.omega_c), omega_frame=frame,
            stiffness=np.ascontiguousarray(stiffness, dtype=float),
            damping=np.ascontiguousarray(damping, dtype=float),
            kappa=float(structure.gyroscopic_coefficient(2)),
            rate_times=times, rate_values=values, window=window,
            period=float(loop.period_s), pll_kp=float(loop.pll_gains[0]),
            pll_ki=float(loop.pll_gains[1]), agc_kp=float(loop.agc_gains[0]),
            agc_ki=float(loop.agc_gains[1]), rb_kp=float(loop.rebalance_gains[0]),
            rb_ki=float(loop.rebalance_gains[1]), omega_range=float(loop.omega_range),
            lock_threshold=float(loop.lock_threshold), drive_limit=float(loop.drive_limit),
            setpoint=float(loop.setpoint_m), rebalance=bool(loop.rebalance),
            sense_phase_error=float(loop.sense_phase_error),
            drive_gain=float(loop.pickoff.drive_gain), sense_gain=float(loop.pickoff.sense_gain),
            f_state=f_state, f_input=np.ascontiguousarray(zf.ravel()), out_state=out_state,
            out_input=float(y[-1]), qualify=control.REBALANCE_QUALIFY,
            disqualify=control.REBALANCE_DISQUALIFY,
            qualify_periods=control.REBALANCE_QUALIFY_PERIODS,
            lock_periods=control.LOCK_PERIODS, max_rotation=MAX_ROTATION)
        # the loops' state (DriveLoop.start at the start state, or the running loops'
        # after their last update, S13) and B of the state now at the NCO's phase now
        phase = state.nco_phase
        ls = state.loop
        st = np.zeros(kernels.envelope.LOOP_STATE_SIZE)
        st[:17] = (ls['pll_integral'], ls['agc_integral'], ls['rb_integral'][0],
                   ls['rb_integral'][1], ls['omega'], ls['force'], ls['rebalance_force'][0],
                   ls['rebalance_force'][1], ls['phase_error'], ls['amplitude'],
                   ls['rebalance_rate'], ls['rebalance_quadrature'], float(ls['locked']),
                   float(ls['rebalance_on']), float(ls['locking']), float(ls['qualifying']),
                   phase)
        self._loop = st
        q, v = (np.asarray(x, dtype=float) for x in start_state)
        self._envelope = envelope_of(q[[ic, is_]], v[[ic, is_]], frame, phase).astype(complex)
        # the filter's state now, (sections, 2, 4); a copy: the kernel writes its own (a
        # view would be the running full model's, which sosfilt may leave in this layout)
        zi = state.rebalance_state
        self._filter = np.array(np.moveaxis(zi, 2, 0).reshape(4, size), order='C', copy=True)
        self._die_temperature = state.die_reading
        # (S12) the die temperature, followed as the full model follows it (T2): every
        # THERMAL_UPDATE_S, the device rebuilt once the die has moved THERMAL_STEP_K
        self.die = copy.deepcopy(state.die)
        self.device_temperature = state.device_temperature
        self._thermal_live = bool(config.run.temperature_times) or state.thermal_live
        thermal_window = max(1, int(round(THERMAL_UPDATE_S / (design.period_ns * 1e-9))))
        self._thermal_periods = max(1, int(round(thermal_window / window)))
        # the amplifiers' volts per farad scale as 1 / feedback capacitance (T6)
        self._feedback = float(device.gyro.feedback_capacitance)
        self.period_index = state.sample_index // window
        # (S9, S10) the noises' scales, of the device at the die's temperature (T5, T6)
        self.noise_seed = int(config.gyro.noise_seed)
        self._chunks = {}   # stream -> (first period, its NOISE_CHUNK rows of normals)
        self._modal_mass = float(device.modal_masses()[ic])
        self._input_capacitance = np.asarray(design.pickoff.input_capacitance, dtype=float)
        self._pickoff_noisy = bool(design.pickoff.noisy)
        self._set_noise(device)
        # (S11) the flicker of ~/rate: the full model's bank (E13), so the same samples
        # (from a running full model, its bank's state now)
        self.flicker = copy.deepcopy(state.flicker)
        self.saturated_samples = 0
        """``~/rate`` samples that read the full scale (E15), as the sense chain counts them."""
        # for the hand-back (S14): the coordinates' layout, the demodulator's references
        self._pair = (ic, is_)
        self._n_coordinates = int(design.model.n_coordinates)
        self._latest = (float(state.latest_rate), float(state.latest_quadrature))

    def _set_noise(self, device: SimConfig) -> None:
        """
        Set the noises' scales of the device (its die temperature's, T5, T6; S9, S10).

        (S9) re and im of the force's first harmonic per period each ``N(0, 2 S / T)``,
        ``S = 2 k_B T_n C / m`` the pair's two-sided acceleration density (the full model's,
        ``T_n`` the device's ``gyro.temperature``). (S10) the fit's error per component,
        ``e_o sqrt(f_s / N)``, of the amplifiers' output-referred density at the device's
        feedback capacitance (E2; drive, sense).
        """
        g = device.gyro
        _, damping = device.modes.pair_matrices(2)
        self.force_noise_factor = None
        if g.temperature > 0.0:
            self.force_noise_factor = np.linalg.cholesky(
                4.0 * BOLTZMANN * g.temperature * damping / (self._modal_mass * self.model.period))
        self.pickoff_noise_std = None
        if self._pickoff_noisy:
            density = g.input_noise_density * (1.0 + self._input_capacitance
                                               / g.feedback_capacitance)
            self.pickoff_noise_std = density[[1, 0]] * math.sqrt(
                self.config.run.output_rate / self.model.window)

    def _follow_die(self) -> None:
        """
        Advance the die to now; rebuild the pair and the amplifiers if it moved enough (S12).

        As ``Simulator._follow_die``: the die's sensor (the calibration's compensation)
        follows every update; the pair's K and C (T3-T5) and the amplifiers' volts per
        farad (T6) are rebuilt once the die has moved ``THERMAL_STEP_K`` from the
        temperature they were built at. The loops keep the gains they were designed with.
        """
        from ring_gyro_sim.core.engine.full import THERMAL_STEP_K
        kelvin = self.die.advance_to(self.time_s)
        self._die_temperature = kelvin
        if abs(kelvin - self.device_temperature) < THERMAL_STEP_K:
            return
        self.device_temperature = kelvin
        device = thermal.device_at(self.config, kelvin)
        stiffness, damping = device.modes.pair_matrices(2)
        gain = self._feedback / float(device.gyro.feedback_capacitance)
        self._feedback = float(device.gyro.feedback_capacitance)
        m = self.model
        # the frame follows the frequencies (T3); B of the same oscillation at the NCO's
        # omega in the new frame: the slow part of (q - i q' / w) e^{-i phi} is
        # X (1 + omega / w) / 2 for an amplitude X, so B scales by the ratio of those
        frame = float(m.omega_c * thermal.frequency_scale(self.config, kelvin))
        omega = self._loop[kernels.envelope.OMEGA]
        self._envelope *= (m.omega_frame * (frame + omega)) / (frame * (m.omega_frame + omega))
        pgroups = m.pgroups.copy()
        pgroups[:, 3:] *= gain    # (S4)'s merged weights: the amplifiers' volts per farad
        self.model = m._replace(stiffness=np.ascontiguousarray(stiffness, dtype=float),
                                damping=np.ascontiguousarray(damping, dtype=float),
                                pg_drive=m.pg_drive * gain, pg_sense=m.pg_sense * gain,
                                pgroups=pgroups, omega_frame=frame)
        self._set_noise(device)

    def _noise(self, count: int) -> np.ndarray:
        """
        Return the noise of the next ``count`` periods as ``run_periods`` takes it (S9, S10).

        Rows of :data:`noise.STREAM_ENVELOPE_FORCE` and :data:`noise.STREAM_ENVELOPE_PICKOFF`
        addressed by period index, so that a run cut into calls of any length draws the same
        numbers; ``(0, 8)`` with both noises off.
        """
        if self.force_noise_factor is None and self.pickoff_noise_std is None:
            return _NO_NOISE
        out = np.zeros((count, 8))
        if count == 0:
            return out
        if self.force_noise_factor is not None:
            z = self._normals(noise.STREAM_ENVELOPE_FORCE, count)
            factor = self.force_noise_factor
            out[:, 0:4:2] = z[:, 0:2] @ factor.T   # re of (f_c, f_s)
            out[:, 1:4:2] = z[:, 2:4] @ factor.T   # im of (f_c, f_s)
        if self.pickoff_noise_std is not None:
            z = self._normals(noise.STREAM_ENVELOPE_PICKOFF, count)
            out[:, 4:6] = z[:, 0:2] * self.pickoff_noise_std[0]
            out[:, 6:8] = z[:, 2:4] * self.pickoff_noise_std[1]
        return out

    def _normals(self, stream: int, count: int) -> np.ndarray:
        """
        Return the normals of the next ``count`` periods of ``stream``, ``(count, 4)``.

        Rows of :func:`noise.normals` by period index (a row depends on its index only),
        drawn :data:`NOISE_CHUNK` periods at a time on chunk boundaries (the next chunk
        ahead on the noise module's thread) and sliced: a run's short calls (a block of 10
        ms in a run) do not pay a draw each.
        """
        out = np.empty((count, 4))
        done = 0
        while done < count:
            index = self.period_index + done
            start = index - index % NOISE_CHUNK
            cached = self._chunks.get(stream)
            if cached is None or cached[0] != start:
                cached = (start, noise.block_normals(self.noise_seed, stream, start,
                                                     NOISE_CHUNK, 4))
                self._chunks[stream] = cached
            take = min(count - done, start + NOISE_CHUNK - index)
            out[done:done + take] = cached[1][index - start:index - start + take]
            done += take
        return out

    @property
    def time_s(self) -> float:
        """Return the simulated time, s (as the full model's clock reads it)."""
        return self.period_index * self.model.window * self._period_ns * 1e-9

    def export_state(self) -> GyroState:
        """
        Return the state now for a full model to go on from (S14, the hand-back).

        The pair's coordinates and velocities of the envelopes at the NCO's phase (S1: the
        other modes at rest), the loops' state, the output filter's, the demodulator's
        channels (the pick-off's first harmonics, S4, mixed with the sense chain's
        references, E3), the die and the flicker bank: ``Simulator.resume`` takes it.
        """
        e = kernels.envelope
        st = self._loop
        m = self.model
        phase = float(st[e.NCO_PHASE])
        pair_q, pair_v = state_of(self._envelope, m.omega_frame, np.float64(phase))
        q = np.zeros(self._n_coordinates)
        v = np.zeros(self._n_coordinates)
        q[list(self._pair)] = pair_q
        v[list(self._pair)] = pair_v
        loop = {'pll_integral': st[e.PLL_I], 'agc_integral': st[e.AGC_I],
                'rb_integral': st[[e.RB_IC, e.RB_IS]], 'omega': st[e.OMEGA],
                'force': st[e.FORCE], 'rebalance_force': st[[e.SC, e.SS]],
                'phase_error': st[e.PHASE_ERR], 'amplitude': st[e.AMP],
                'rebalance_rate': st[e.RB_RATE], 'rebalance_quadrature': st[e.RB_QUAD],
                'locked': st[e.LOCKED] > 0.5, 'rebalance_on': st[e.RB_ON] > 0.5,
                'locking': int(st[e.LOCKING]), 'qualifying': int(st[e.QUALIFYING])}
        # the amplifiers' first harmonics (S4), from which the demodulator restarts (E3)
        v_d, v_s = kernels.pickoff_harmonic(self._envelope[0], self._envelope[1], m.pb_c,
                                            m.pb_s, m.pg_drive, m.pg_sense, m.gap)
        size = self._filter.shape[1]
        rebalance = np.moveaxis(self._filter.reshape(4, size // 2, 2), 0, 2).copy()
        die = copy.deepcopy(self.die)
        die.advance_to(self.time_s)
        return GyroState(sample_index=self.period_index * m.window, q=q, v=v, loop=loop,
                         nco_phase=phase, harmonics=np.array([v_s, v_d]),
                         rebalance_state=rebalance,
                         latest_rate=self._latest[0], latest_quadrature=self._latest[1],
                         die=die, flicker=copy.deepcopy(self.flicker),
                         device_temperature=self.device_temperature)

    def set_rate_profile(self, times: np.ndarray, values: np.ndarray) -> None:
        """Take the angular rate's profile in force from now on: knots (s, rad/s) (S6)."""
        self.model = self.model._replace(
            rate_times=np.ascontiguousarray(times, dtype=float),
            rate_values=np.ascontiguousarray(values, dtype=float))

    @property
    def envelope(self) -> np.ndarray:
        """Return the pair's envelopes ``(B_c, B_s)`` now, m (S5)."""
        return self._envelope.copy()

    @property
    def nco(self) -> Tuple[float, float]:
        """Return the NCO's phase (rad) now and its angular frequency (rad/s) in force."""
        e = kernels.envelope
        return float(self._loop[e.NCO_PHASE]), float(self._loop[e.OMEGA])

    def control_row(self) -> np.ndarray:
        """Return the loops' state in force now as a ``~/control`` row (C9)."""
        return _control_rows(self._loop[None, :])[0]

    def harmonics(self, envelope: np.ndarray) -> np.ndarray:
        """
        Return the amplifiers' first harmonics of envelopes ``(K, 2)`` (S4), ``(K, 2)``, V.

        Columns sense and drive, ``volts = Re(V e^{i phi})`` at the NCO's phase.
        """
        m = self.model
        out = np.empty((len(envelope), 2), dtype=complex)
        for k, (b_c, b_s) in enumerate(envelope):
            v_d, v_s = kernels.pickoff_harmonic(b_c, b_s, m.pb_c, m.pb_s, m.pg_drive,
                                                m.pg_sense, m.gap)
            out[k] = v_s, v_d
        return out

    def advance(self, seconds: float) -> GyroSamples:
        """
        Advance by ``seconds`` (whole ``~/rate`` periods) and return the ``~/rate`` samples.

        Raises
        ------
        ParameterError
            A negative or non-finite duration.
        SimulationError
            The orbit left the force's or the pick-off's range.

        """
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise ParameterError(f'seconds: must be finite and >= 0, got {seconds!r}')
        per_output = self.decimate * self.model.period
        outputs = int(round(seconds / per_output))
        count = outputs * self.decimate
        t = np.empty(outputs)
        env = np.empty((outputs, 2), dtype=complex)
        rows = np.empty((outputs, kernels.envelope.LOOP_STATE_SIZE))
        filtered = np.empty((outputs, 4))
        die = np.empty(outputs)
        first_output = self.period_index // self.decimate
        written = done = 0
        while done < count:
            stop = count - done
            if self._thermal_live:   # (S12) at the die's update times, as the full model (T2)
                since = self.period_index % self._thermal_periods
                if since == 0:
                    self._follow_die()
                stop = min(stop, self._thermal_periods - since)
            n = kernels.run_periods(self.model, self._envelope, self._loop, self._filter,
                                    self.period_index, stop, self.decimate, self._noise(stop),
                                    t[written:], env[written:], rows[written:],
                                    filtered[written:])
            if n < 0:
                self.period_index = -1 - n
                raise SimulationError(f"averaged model: the orbit left the force's or the "
                                      f"pick-off's range at {self.time_s:.6f} s")
            die[written:written + n] = (math.nan if self._die_temperature is None
                                        else self._die_temperature)
            written += n
            done += stop
            self.period_index += stop
        e = kernels.envelope
        control_rows = _control_rows(rows)
        if self.calibration is not None:
            # the die's sensor not read yet: the calibration at its reference (K3)
            known = None if np.isnan(die).any() else die
            rate, quadrature = self.calibration.apply(filtered[:, 2], filtered[:, 3], known)
        else:
            rate, quadrature = filtered[:, 0].copy(), filtered[:, 1].copy()
        if outputs:   # what the sense chain holds as its latest sample (before the flicker)
            self._latest = (float(rate[-1]), float(quadrature[-1]))
        flicker = self.flicker.samples(first_output, outputs)   # the bank's index moves on
        if self.flicker.sigma > 0.0:  # (S11) after the calibration, as E13
            rate += flicker
        # (E15) the output word, last, as the full model's sense chain
        g = self.config.gyro
        rate, saturated = electronics.output_word(rate, g.resolution, g.range)
        if saturated is not None:
            self.saturated_samples += int(np.count_nonzero(saturated))
        return GyroSamples(t=t, rate=rate, quadrature=quadrature, readout=filtered[:, 2:],
                           envelope=env, control=control_rows,
                           nco_phase=rows[:, e.NCO_PHASE].copy(), saturated=saturated)


class AveragedEngine(Engine):
    """
    The averaged model inside a run (``run.Run``): its stretches as the full model's samples.

    Taken over from the run's full model ``sim`` at a loop update (S13); :meth:`advance`
    returns what ``Simulator.advance_samples`` returns for the same samples, built from the
    envelopes (R1-R4 below); :meth:`sync` hands the state back to ``sim`` (S14), which the
    run does before anything reads or changes the full model.

    (R1) The coordinates. Over each loop period the NCO turns at the frequency its update
    at the period's start set, so its phase at sample ``j`` (1..N) of the period is the
    phase at the start plus ``omega j P``; the envelopes, known at the loop updates, are
    taken linear between them (the slow flow moves them by ``|B'| T``, ~1e-5 of ``|B|`` a
    period in a quiet stretch). The pair is ``q = Re(B e^{i phi})``,
    ``q' = Re(i omega_frame B e^{i phi})`` (S1); the other modes are at rest (what the
    hand-off demands of them, ``HAND_BACK_THRESHOLD``). So the block topics (q_n, gaps,
    capacitances: ``Simulator`` computes them from q exactly as for its own samples) show
    the driven pair's oscillation without the 2 omega ripple of the envelope and without
    the fast modes' residue below the threshold.

    (R2) ``~/control``: the loops' rows of the averaged model (S7), held over each period
    as the full model holds them.

    (R3) ``~/demodulator``: the mixers' constant outputs of the amplifiers' first
    harmonics (S4), at the loop updates and linear between them. Left out: the ``2 omega``
    terms the low-pass passes (:attr:`ripple_gain` of them: 7e-11 at the defaults), its lag
    behind the slowly moving constants, the pick-off's higher harmonics, and the pick-off
    noise (S10 drives the loops only).

    (R4) ``~/rate``: the averaged model's (S8-S11), with the variance the full model's
    validity monitor gives the same rows (``SenseChain.judge``).

    (R5) The run's statistics (the smallest gap of the run and of each diagnostics interval)
    need only the smallest of the samples' smallest gaps: when the run's sink keeps no
    channel (a node nobody subscribes to that records none) the block's gaps and
    capacitances are not computed, and that one value comes from the samples that can hold
    it (:meth:`_smallest_gap`), the same value bit for bit.
    """

    name = 'averaged'

    @classmethod
    def refusal(cls, config: SimConfig) -> Optional[str]:
        """Return why the averaged model cannot run this gyroscope (``handoff.refusal``)."""
        from ring_gyro_sim.core.engine import handoff
        return handoff.refusal(config)

    def __init__(self, sim) -> None:
        self.sim = sim
        self.gyro = AveragedGyro(sim.config, calibration=sim.calibration, simulator=sim)
        from scipy import signal
        design = sim.design()
        el = sim.sense.electronics
        self._psi = (el.drive_phase_rad + el.phase_error, el.drive_phase_rad)
        self.period_ns = int(design.period_ns)
        _, omega = self.gyro.nco
        _, h2 = signal.sosfreqz(design.low_pass, worN=[2.0 * omega * sim.period_s])
        self.ripple_gain = float(abs(h2[0]))
        """The low-pass's gain at twice the NCO's frequency: the ``2 phi`` terms left out
        of ``~/demodulator`` (R3), relative to the constants (7e-11 at the defaults)."""
        self._pair = (1, sim.config.modes.count + 1)
        self._saturated = 0
        self.rate_version = sim.rate_profile.version
        self._geometry_of = self._geometry = None

    @property
    def sample_index(self) -> int:
        """Return the global sample index now (a loop update)."""
        return self.gyro.period_index * self.gyro.model.window

    def follow_rate(self) -> None:
        """Take the full model's angular-rate profile if it changed (a streamed rate)."""
        profile = self.sim.rate_profile
        if profile.version != self.rate_version:
            self.gyro.set_rate_profile(*profile.knots_from(self.gyro.time_s))
            self.rate_version = profile.version

    def next_scheduled_s(self) -> float:
        """Return when the full model's next scheduled input acts, s (the run hands over)."""
        return self.sim.next_scheduled_s()

    def advance_samples(self, count: int, between=None, channels: bool = True) -> Samples:
        """
        Advance by ``count`` samples (whole loop periods); return them (R1-R5).

        ``channels`` False (the run's sink keeps none: ``run.Sink.needs_channels``): the
        samples carry no gaps or capacitances, only their smallest gap (R5).
        """
        from ring_gyro_sim.core.gyro.electronics import DemodSamples, RateSamples
        sim, gyro = self.sim, self.gyro
        window = gyro.model.window
        if count % window:
            raise ParameterError(f'count: {count} samples is not a whole number of loop '
                                 f'periods ({window} samples)')
        self.follow_rate()
        periods = count // window
        first = self.sample_index
        env0, (phase0, omega0), row0 = gyro.envelope, gyro.nco, gyro.control_row()
        out = gyro.advance(periods * gyro.model.period)
        index = np.arange(count)
        k = index // window
        t = (first + index + 1) * sim.period_s
        dc = self._demodulator(np.vstack([env0[None, :], out.envelope]))
        # (R1) the pair at every sample
        n = sim.model.n_coordinates
        pair_q = np.empty((count, 2))
        pair_v = np.empty((count, 2))
        phase = np.empty(count)
        demod = np.empty((count, 4))
        kernels.envelope.stretch_samples(
            np.vstack([env0[None, :], out.envelope]),
            np.concatenate([[phase0], out.nco_phase[:-1]]),
            np.concatenate([[omega0], out.control[:-1, 0] * (2.0 * math.pi)]),
            window, sim.period_s, gyro.model.omega_frame, dc, pair_q, pair_v, phase, demod)
        q = np.zeros((count, n))
        v = np.zeros((count, n))
        q[:, self._pair] = pair_q
        v[:, self._pair] = pair_v
        # the channels of the pair's coordinates: the full model's kernel on the pair's
        # rows of its geometry (the other coordinates are 0: the same sums)
        geometry = sim.output_geometry
        if geometry is not self._geometry_of:
            self._geometry_of = geometry
            self._geometry = geometry._replace(**{
                name: np.ascontiguousarray(getattr(geometry, name)[list(self._pair)])
                for name in ('centre_shapes', 'ring_shapes', 'electrode_shapes',
                             'fine_shapes', 'curvature')})
        if channels:
            out_channels = sim.channel_arrays(count)
            kernels.output_channels(pair_q, self._geometry, out_channels)
            gap, min_gap, capacitance = out_channels
            smallest = None
        else:
            gap = min_gap = capacitance = None
            smallest = self._smallest_gap(pair_q)
        t_ns = (first + index + 1).astype(np.int64) * sim.period_ns
        # (R2) the loops' rows, held over each period
        control = np.vstack([row0[None, :], out.control])[k]
        rate = RateSamples(t=out.t, rate=out.rate, quadrature=out.quadrature,
                           saturated=out.saturated)
        rate = sim.sense.judge(rate, control[index[window - 1::window]])
        return Samples(t=t, q=q, v=v, gap=gap, min_gap=min_gap, capacitance=capacitance,
                       drive_phase=phase, applied_rate=sim.rates_at(t_ns), control=control,
                       demod=DemodSamples(t=t, values=demod), rate_output=rate,
                       die_temperature=gyro.die.advance_to(gyro.time_s), smallest_gap=smallest)

    def _smallest_gap(self, pair_q: np.ndarray) -> float:
        """
        Return the smallest of the samples' smallest gaps, m, from the samples that can hold it.

        (R5) With the other modes at rest, w = q_c cos(2 theta) + q_s sin(2 theta), whose
        largest value is r = hypot(q_c, q_s); the kernel's estimate ``w_max`` (grid and
        parabola) is within ``m = RING_MAX_MARGIN * 4 (|q_c| + |q_s|)`` of r
        (``kernels.channels``), so a sample with ``r + m`` below the largest ``r - m`` of the
        block has a smaller estimate than that sample's and cannot hold the smallest gap. The
        kernel runs on the others (those within about 0.8 % of the amplitude: 8 % of a driven
        pair's samples): the same value as on every sample, bit for bit.
        """
        geometry = self._geometry
        r = np.hypot(pair_q[:, 0], pair_q[:, 1])
        margin = kernels.RING_MAX_MARGIN * (np.abs(pair_q) @ geometry.curvature)
        rows = np.flatnonzero(r + margin >= np.max(r - margin))
        out = self.sim.channel_arrays(rows.size)
        kernels.output_channels(np.ascontiguousarray(pair_q[rows]), geometry, out)
        return float(np.min(out.min_gap))

    def _demodulator(self, envelope: np.ndarray) -> np.ndarray:
        """
        Return the demodulator's outputs of envelopes ``(K, 2)``: ``(K, 4)``, V (R3).

        The mixers make of an amplifier's first harmonic V, with the reference's phase psi,
        ``Re(V e^{-i psi})`` (I) and ``-Im(V e^{-i psi})`` (Q) and terms at ``2 phi``
        (``SenseElectronics.resume``), which the low-pass passes by its response there
        (:attr:`ripple_gain`), left out.
        """
        volts = self.gyro.harmonics(envelope)
        dc = np.empty((len(envelope), 4))
        for ch, psi in enumerate(self._psi):
            down = volts[:, ch] * complex(math.cos(psi), -math.sin(psi))
            dc[:, 2 * ch] = down.real
            dc[:, 2 * ch + 1] = -down.imag
        return dc

    def import_state(self, state: GyroState) -> None:
        """Refuse: the averaged model takes over from the full model only (S13)."""
        raise SimulationError('import_state: the averaged model takes over from a running '
                              'full model (AveragedEngine(full)), not from a state')

    def export_state(self) -> GyroState:
        """Return the state now (S14), for the full model to go on from."""
        return self.gyro.export_state()

    def sync(self) -> None:
        """Hand the state now to the full model (S14): it may go on, or be read."""
        gyro, el = self.gyro, self.sim.sense.electronics
        self.sim.import_state(gyro.export_state())
        el.saturated_samples += gyro.saturated_samples - self._saturated
        self._saturated = gyro.saturated_samples
