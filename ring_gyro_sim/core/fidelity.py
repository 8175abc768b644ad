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
The closed-loop gyroscope at two fidelity levels, handed between them (``auto``).

:class:`AutoGyro` runs the gyroscope offline and returns its ``~/rate``: on the averaged model
(``core.averaged.AveragedGyro``) while nothing fast acts, on the full model (``Simulator``)
around what the averaged model does not represent, with the hand-offs of S13 and S14.
:class:`AveragedStretch` is the averaged model inside a run (``run.Run``, whose docstring
has its rules): its stretches as the full model's samples, every output topic rebuilt.

The rules (``auto``)
--------------------
- **To the full model** at the last ``~/rate`` sample at or before the start of a shock pulse
  (scheduled in the configuration, ``scenario.shock_*``, or by :meth:`AutoGyro.shock`) or of
  a scheduled input of the full model (a parameter change, a rate or drive command, a reset:
  the simulator's events): the full model simulates the pulse or the input from its start.
- **Back to the averaged model** at a loop update once no pulse is acting, the loops are
  locked with force-to-rebalance on, the ring is free of the stops, and the modes the
  averaged model leaves out have rung down below ``HAND_BACK_THRESHOLD`` of the gap
  (``averaged.fast_mode_amplitude``: measured at 1e-3 of d_g to cost 1.4e-5 of the reading
  after a 10 000 g shock, doc/averaged.md), checked every :data:`CHECK_S`.
- **Never averaged**: a configuration the averaged model does not run (open loop, no
  rebalance, the untruncated force, a ``~/rate`` not a whole fraction of the loops' rate)
  or with an environment (steady acceleration, sine or random vibration: they act at every
  sample), which runs on the full model throughout (:attr:`AutoGyro.reason` says why).

``full`` runs the full model throughout; ``averaged`` the averaged model throughout and
refuses what it cannot run (a shock included).
"""

from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import numpy as np
from ring_gyro_sim.core import kernels, thermal
from ring_gyro_sim.core.averaged import AveragedGyro, fast_mode_amplitude, HAND_BACK_THRESHOLD
from ring_gyro_sim.core.engine.full import Samples, Simulator, Status
from ring_gyro_sim.core.errors import InputError, ParameterError
from ring_gyro_sim.core.params import FIDELITIES, SimConfig

__all__ = ['CHECK_S', 'AutoGyro', 'AutoSamples', 'AveragedStretch', 'unsupported']

CHECK_S = 0.01
"""How often the full model checks whether it may hand back to the averaged one, s."""


@dataclass(frozen=True)
class AutoSamples:
    """
    ``~/rate`` of :meth:`AutoGyro.advance`.

    Attributes
    ----------
    t, rate, quadrature : ndarray, shape (K,)
        Sample times (s), rate and quadrature (rad/s), as ``RateSamples``.
    averaged : ndarray of bool, shape (K,)
        Whether the averaged model produced each sample.

    """

    t: np.ndarray
    rate: np.ndarray
    quadrature: np.ndarray
    averaged: np.ndarray


def _unsupported(config: SimConfig, sim: Simulator) -> Optional[str]:
    """Return why the averaged model cannot run this gyroscope, None when it can."""
    c = config
    if not (c.control.closed and c.control.rebalance and c.gyro.enabled
            and c.modes.companions and c.modes.count >= 2):
        return 'the averaged model is the closed-loop gyroscope with force-to-rebalance'
    if c.electrodes.taylor_terms <= 0:
        return 'the averaged force is that of the truncated series (electrodes.taylor_terms)'
    decimation = int(round(c.run.output_rate / c.gyro.output_rate))
    if decimation % sim.loop.window:
        return 'gyro.output_rate is not a whole fraction of control.rate'
    if sim.has_environment:
        return 'an environment (steady acceleration or vibration) acts at every sample'
    return None


def unsupported(config: SimConfig, sim: Simulator, blocks: bool = False) -> Optional[str]:
    """
    Return why the averaged model cannot run this gyroscope, None when it can.

    ``blocks``: for a run that publishes blocks (``run.Run``), whose ``~/control`` rows and
    reconstructed samples need one ``~/rate`` sample per loop period.
    """
    if sim.loop is None:
        return 'the averaged model is the closed-loop gyroscope'
    reason = _unsupported(config, sim)
    if reason is None and blocks and (int(round(config.run.output_rate / config.gyro.output_rate))
                                      != sim.loop.window):
        reason = 'a run at fidelity auto needs gyro.output_rate equal to control.rate'
    return reason


class AutoGyro:
    """
    The closed-loop gyroscope offline at ``fidelity`` (module docstring), ``~/rate`` out.

    Parameters
    ----------
    config : SimConfig
        The gyroscope.
    start_state : (q, v), optional
        Default: the ``Run``'s (``operating_point.start_state`` at the die's start).
    calibration : Calibration, None or 'auto'
        As ``Simulator``'s; both models apply the same.
    fidelity : str, optional
        ``auto``, ``full`` or ``averaged``; default the configuration's
        ``integrator.fidelity``.

    Attributes
    ----------
    handoffs : list of (float, str)
        Each change of model: its time (s) and the model from then on (``averaged``,
        ``full``); the first entry is the start.
    reason : str or None
        Why the averaged model is not used at all (None: it is, where the rules allow).

    Raises
    ------
    ParameterError
        No gyroscope (``gyro.enabled`` off); an unknown fidelity; ``averaged`` for a
        gyroscope the averaged model cannot run.

    """

    def __init__(self, config: SimConfig, start_state=None, calibration='auto',
                 fidelity: Optional[str] = None) -> None:
        from ring_gyro_sim.core.gyro import operating_point
        if not config.gyro.enabled:
            raise ParameterError("gyro.enabled: AutoGyro returns the gyroscope's ~/rate, "
                                 'which needs gyro.enabled')
        if fidelity is None:
            fidelity = config.integrator.fidelity
        if fidelity not in FIDELITIES:
            raise ParameterError(f'integrator.fidelity: must be one of '
                                 f'{", ".join(FIDELITIES)}, got {fidelity!r}')
        if start_state is None:
            start_state = operating_point.start_state(thermal.start_state_device(config))
        self.config = config
        self.fidelity = fidelity
        self.sim = Simulator(config, start_state, calibration=calibration)
        self.reason = (_unsupported(config, self.sim) if self.sim.loop is not None
                       else 'the averaged model is the closed-loop gyroscope')
        if fidelity == 'averaged' and self.reason is not None:
            raise ParameterError(f'integrator.fidelity: averaged, but {self.reason}')
        if fidelity == 'full':
            self.reason = 'integrator.fidelity: full'
        self._loop_s = self.sim.loop.period_s if self.sim.loop is not None else 0.0
        decimation = int(round(config.run.output_rate / config.gyro.output_rate))
        self._rate_periods = (decimation // self.sim.loop.window
                              if self.sim.loop is not None else 0)
        self._check_samples = int(round(CHECK_S / self.sim.period_s))
        self.averaged: Optional[AveragedGyro] = None
        self.handoffs: List[Tuple[float, str]] = []
        if self.reason is None and self._fast_at() > 0.0:
            self._to_averaged()
        else:
            self.handoffs.append((0.0, 'full'))

    @property
    def time_s(self) -> float:
        """Return the simulated time, s."""
        return self.averaged.time_s if self.averaged is not None else self.sim.time_s

    def shock(self, peak_x: float, peak_y: float = 0.0, at_s: Optional[float] = None) -> None:
        """
        Schedule a half-sine shock as ``Simulator.shock`` does, at ``at_s`` (default now).

        Raises
        ------
        InputError
            A time in the past, or any shock at fidelity ``averaged``.

        """
        if self.fidelity == 'averaged':
            raise InputError('shock: integrator.fidelity averaged does not represent shocks')
        at_s = self.time_s if at_s is None else float(at_s)
        if not (math.isfinite(at_s) and at_s >= self.time_s):
            raise InputError(f'shock: time {at_s!r} s is before now ({self.time_s} s)')
        self.sim.shock(peak_x, peak_y, at_ns=int(round(at_s * 1e9)))

    def _fast_at(self) -> float:
        """
        Return when the next thing the averaged model does not represent starts, s.

        A pulse that has not ended (its duration is set when it starts: -1 before) or a
        pending event of the full model; inf when there is none.
        """
        return self.sim.next_scheduled_s()

    def _to_averaged(self) -> None:
        self.averaged = AveragedGyro(self.config, calibration=self.sim.calibration,
                                     simulator=self.sim)
        self.handoffs.append((self.averaged.time_s, 'averaged'))

    def _to_full(self) -> None:
        self.sim.resume(self.averaged.resume_state())
        self.averaged = None
        self.handoffs.append((self.sim.time_s, 'full'))

    def _may_hand_back(self) -> bool:
        """Whether the full model may hand back to the averaged one now (module docstring)."""
        sim, loop = self.sim, self.sim.loop
        now = sim.time_s
        if (self.fidelity != 'auto' or self.reason is not None
                or sim.status != Status.RUNNING or sim.in_stop_contact
                or not (loop.locked and loop.rebalance_on)):
            return False
        if self._fast_at() <= now + CHECK_S:
            return False
        return fast_mode_amplitude(sim) < HAND_BACK_THRESHOLD

    def advance(self, seconds: float) -> AutoSamples:
        """
        Advance by ``seconds`` (whole ``~/rate`` periods); return the ``~/rate`` samples.

        Raises
        ------
        ParameterError
            A negative or non-finite duration.

        """
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise ParameterError(f'seconds: must be finite and >= 0, got {seconds!r}')
        rate_s = self._rate_periods * self._loop_s if self._rate_periods else None
        if rate_s is None:   # no loops: the full model only
            step = self.config.run.output_period_ns * 1e-9
            s = self.sim.advance_samples(int(round(seconds / step)))
            r = s.rate_output
            return AutoSamples(r.t, r.rate, r.quadrature, np.zeros(r.t.size, dtype=bool))
        end = int(round((self.time_s + seconds) / rate_s))   # in ~/rate periods
        parts = []
        while True:
            now = int(round(self.time_s / rate_s))
            if now >= end:
                break
            if self.averaged is not None:
                fast = self._fast_at()
                stop = end
                if not math.isinf(fast):
                    stop = min(end, int(math.floor(fast / rate_s + 1e-9)))
                if stop > now:
                    out = self.averaged.advance((stop - now) * rate_s)
                    parts.append((out.t, out.rate, out.quadrature, True))
                if stop < end:
                    self._to_full()
                continue
            # the full model up to its next check (a whole number of ~/rate periods)
            samples_per_rate = self._rate_periods * self.sim.loop.window
            check = max(1, self._check_samples // samples_per_rate)
            count = min(end - now, check - now % check) * samples_per_rate
            r = self.sim.advance_samples(count).rate_output
            parts.append((r.t, r.rate, r.quadrature, False))
            if self.sim.status != Status.RUNNING:
                break
            if self._may_hand_back():
                self._to_averaged()
        if not parts:
            empty = np.empty(0)
            return AutoSamples(empty, empty, empty, np.empty(0, dtype=bool))
        return AutoSamples(np.concatenate([p[0] for p in parts]),
                           np.concatenate([p[1] for p in parts]),
                           np.concatenate([p[2] for p in parts]),
                           np.concatenate([np.full(p[0].size, p[3]) for p in parts]))


class AveragedStretch:
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

    def __init__(self, sim: Simulator) -> None:
        self.sim = sim
        self.gyro = AveragedGyro(sim.config, calibration=sim.calibration, simulator=sim)
        from scipy import signal
        el = sim.sense.electronics
        self._psi = (el.drive_phase_rad + el.phase_error, el.drive_phase_rad)
        _, omega = self.gyro.nco
        _, h2 = signal.sosfreqz(el._sos, worN=[2.0 * omega * sim.period_s])
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

    def advance(self, count: int, channels: bool = True) -> Samples:
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
        geometry = sim._output_geometry
        if geometry is not self._geometry_of:
            self._geometry_of = geometry
            self._geometry = geometry._replace(**{
                name: np.ascontiguousarray(getattr(geometry, name)[list(self._pair)])
                for name in ('centre_shapes', 'ring_shapes', 'electrode_shapes',
                             'fine_shapes', 'curvature')})
        if channels:
            out_channels = sim._channel_arrays(count)
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
        out = self.sim._channel_arrays(rows.size)
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

    def sync(self) -> None:
        """Hand the state now to the full model (S14): it may go on, or be read."""
        gyro, el = self.gyro, self.sim.sense.electronics
        self.sim.resume(gyro.resume_state())
        el.saturated_samples += gyro.saturated_samples - self._saturated
        self._saturated = gyro.saturated_samples
