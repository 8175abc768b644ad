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
``ring_gyro characterize``: the emulated gyroscope's datasheet, measured as IEEE Std 1431 does.

IEEE Std 1431-2004 (Coriolis vibratory gyros), part II, measures a gyroscope by test series
on a rate table; its Allan-variance analysis is that of IEEE Std 952-1997, annex C. Each test
here is one or more runs of the one run path (:class:`~ring_gyro_sim.run.Run`, the start state
of ``drive.start_on`` as ``ring_gyro run`` makes it) of the device of one params file, read
only through ``~/rate`` (1 kHz), its drive pick-off (``~/demodulator``) and the run summary,
as a test engineer reads a real sensor. The file's ``scenario.*`` and ``duration`` are
replaced by each test's own; everything else (drive, modes, electronics, noise, seed) is the
device. Durations below are :data:`FULL` / :data:`QUICK` (``--quick``).

1. Drift (12.11, with IEEE 952 annex C) and bandwidth (12.15), one run: the device at zero
   rate for 310 s / 8 s, then a rate step of 10 deg/s held for 12 s / 2.5 s.

   * **Bias**: the mean of the zero-rate output after the first 10 s / 2 s (the noise
     starts from a ring at rest: the thermomechanical response needs a few sense time
     constants, 1.3 s, to become stationary), deg/h, with its standard error
     ``N / sqrt(T)``.
   * **Allan deviation**: ``allantools.oadev`` (overlapping) of that record at log-spaced
     tau from one sample to ``T / 8``. The open-loop, mode-matched ring filters its white
     rate noise through the sense mode's pole (time constant ``Tc = 2 Q / omega``, 1.3 s):
     the curve follows ``N / sqrt(tau)`` only for ``tau >> Tc`` (still 5 % low in variance
     at 30 Tc), so a plain -1/2 line fitted at the tau a record of minutes reaches reads the
     ARW low. The fit is therefore that of the noise model, IEEE 952's way for correlated
     noise: ``sigma^2(tau) = a h(tau) + b / tau + c`` by non-negative least squares over
     ``tau`` from ``max(0.01 s, 1 / gyro.filter_bandwidth)`` to ``T / 8``, weighted by the
     number of independent clusters ``T / tau``, where
     ``h(tau) = [1 - (Tc / 2 tau)(3 - 4 e^{-tau/Tc} + e^{-2 tau/Tc})] / tau`` is the Allan
     variance of unit white rate noise through a first-order low-pass of time constant
     ``Tc`` (the measured one, from the step below), ``b`` white rate noise that bypasses
     the pole (the pick-off's) and ``c`` the flicker floor; each term only when the device
     has that source (``gyro.temperature``, ``gyro.input_noise_density``,
     ``gyro.bias_instability`` > 0; with ``control.mode: rebalance`` the fit starts at 10 Tc, the
     loop's response not being first-order). **ARW** = the -1/2 asymptote
     ``sqrt(a + b) / sqrt(tau)`` read at ``tau = 1 s``, in deg/sqrt(h). Beside it, where
     the record reaches ``tau >= 10 Tc`` over a factor 2 of tau (the full form: 15.6 to
     37.5 s), the plain -1/2 line fitted there (``arw_slope_only``; the pole still lowers
     the curve there by 3-6 % in deviation, and 8 clusters of 37 s make it noisy). The
     **standard error** of the ARW is that of the same estimator on 200 / 50 records of the
     fitted noise model with the same length and start (a parametric bootstrap, Gaussian
     first-order noise:
     ``arw_relative_standard_error``; ``arw_bootstrap`` holds the bias and spread of both
     estimators).
   * **Bias instability**: the minimum of the Allan deviation / 0.664 (the flicker floor of
     IEEE 952), deg/h, and the tau where it lies, sought over the fitted tau from the
     curve's maximum on (below ~Tc the curve rises with tau, the pole's doing: its low end
     is not a floor). When the minimum is at the longest tau the curve has not turned: the
     figure is an upper bound set by the record length (``bias_instability_floor_reached``
     false; ``--quick``'s record ends before the maximum, so its figure is only that).
   * **Bandwidth**: the step response (10 deg/s, small enough that the rate's splitting of
     the pair, ``2 kappa Omega`` = 0.28 rad/s against the 0.77 rad/s half-width, bends it by
     ~2 %) fitted by a first-order response ``y0 + G Omega (1 - e^{-t / tau})`` (least
     squares for ``G`` and ``tau``, ``y0`` the mean of the last second before the step);
     ``bandwidth_hz = 1 / (2 pi tau)``, the -3 dB frequency of that first-order fit. The
     time to 63.2 % of the step is given beside it.

1b. The long zero-rate record (:func:`_long_record`, :func:`_long_allan`): 3 h /
   200 s at zero rate on the averaged model
   (``core.engine.averaged.AveragedGyro``, hours in seconds:
   doc/averaged.md, "Speed"), run first, when
   ``integrator.fidelity`` is ``auto`` or ``averaged`` and the averaged model runs the device
   (the closed loop with force-to-rebalance, the truncated force). Its Allan deviation goes to
   ``T / 8`` (1 349 s / 24.75 s) with 68.3 % intervals (allantools: Greenhall's degrees of
   freedom of the overlapping estimator, white rate noise); the same fit as the short record
   (its ARW beside the full model's), the bias instability (the minimum / 0.664, an upper bound
   when the curve has not turned), the log-log slope over the last decade, and the rate random
   walk (the +1/2 line ``K sqrt(tau / 3)``) where the curve rises beyond its minimum. With
   ``full``, or on a device the averaged model cannot run under ``auto``, the section says it
   was not run and why; ``averaged`` refuses such a device before any run. The short record
   above stays (its step gives the time constant the fits start from) on the full model, unless
   the averaged model runs the device: then the drift-and-step run is on it too
   (``drift_model``), which reproduces the full model's step response (time constant and gain
   within 1e-3 noise off; measured 1.1e-4) and its ARW within the statistics (doc/averaged.md).
   The other tests stay on the full model: the shocks and the environment are not quiet, and
   the rate table's nonlinearity is read to ~0.002 ppm of full scale, finer than the two
   models' agreement has been measured (3e-6 of the reading at 10 deg/s).

2. Scale factor (12.9): one run per rate of the table, -300 .. 300 deg/s in 13 points of
   12 s each, the mean over the last 4 s (``--quick``: -300, -100, 0, 100, 300 deg/s, 0.5 s
   each, the mean after 0.1 s). The start state holds the pair's steady linear response to
   the rate (``drive.start_on``), so the output starts at the rate; the nonlinear pair
   settles from there within ~8 s at 30-50 deg/s (up to 0.2 % off before), hence the
   window. **One calibration for the whole table**: the electronics of a run compute their
   scale factor at the start state's drive amplitude, and a rate at t = 0 lowers that
   amplitude (open loop: to 0.034 of rest at 300 deg/s), so each point's ``~/rate`` is put
   back on the calibration of the device at rest,
   ``rate x (SF_p / A_p) / (SF_0 / A_0)`` (``SF`` the electronics' scale factor, ``A`` the
   drive amplitude it was computed at; only the orbit correction E6b makes the ratio differ
   from 1; the flicker term, 0 by default, is scaled along). The output in volts is that
   rate times ``SF_0``. **Scale factor** = the least-squares slope of output against input,
   V/(rad/s) (and mV/(deg/s)); **nonlinearity** = the largest residual from that line over
   the full-scale output ``slope x 300 deg/s``, ppm. Each point's standard error is that of
   the mean of the fitted noise model over the window, times ``A_0 / A_p`` (the signal falls
   with the drive, the thermomechanical noise does not). The model's own table (the
   electronics' ``SF_p / A_p`` ratios, the settled per-run readings taken as exact) is given
   as ``predicted``.

3. Shock (12.17, the environment series): per shock amplitude (1 000, 3 000, 10 000 g, a
   half-sine along x, ``shock.duration``) and per loop mode, one run at 10 deg/s with the
   shock at 1 s, 40 s after it (``--quick``: 1 000 and 10 000 g at 0.2 s, 0.6 s after).
   **Peak rate error** and **recovery** are the run's own figures (``core.gyro.stats``:
   back within ``max(1 % of the rate, 4 sigma of the pre-shock error)`` for good, ``None`` if not
   by the end). **Jumped**: the drive pick-off over the last 0.5 s is below half its mean
   over the 0.5 s before the shock (the drive has not come back; in the paper's Case 3 it
   sits at ~0.1 on its lower branch); with a record as short as ``--quick``'s a drive still
   recovering counts too. ``drive_recovery_s``: from the shock to the last sample of the
   pick-off more than 1 % off its pre-shock mean (``None`` if not back for the last 0.1 s).
   **Lost lock**: the PLL's ``pll_lost_lock`` of the closed loop (``None`` open loop: there
   is no loop to lose). **Contact**: the run summary's (the run stops there).

4. The device as owned (section of its own): the factory calibration, the quadrature at
   zero rate (one ``rate_point_s`` run, noise off) and the temperature series (the factory's
   tables at each temperature: ``core.gyro.calibration``, run until settled and kept).

5. Environment (12.17's environment series): g-sensitivity (a steady 1 g, + and -
   along x and y: its odd part per g and per m/s^2, and its even part), vibration
   rectification (10 g sine along x at 100 Hz, 1 kHz and 3 kHz; at 1 kHz along 0, 22.5 and
   45 deg; a random profile, 20-2 000 Hz at 0.01 g^2/Hz, 4.45 g rms, along x) and the
   rectified bias against amplitude over a decade (1 to 10 g at 1 kHz along x) with its
   log-log slope. Each is one run of 10 s / 0.3 s, noise off, from the drive
   orbit with the 1theta pair on its answer to the environment, the mean of ``~/rate`` over
   the last 2 s / 0.1 s less the same without the environment (``analysis.environment``,
   :func:`_environment`; the open-loop rate path settles with 1.3 s, so ``--quick`` reads
   low). 14 runs. **Shock survival with stops** (:func:`_stop_shock`): the file's stops (or
   0.6 d_g if it has none, said so), half-sines along x; the largest shock without impact,
   predicted for the 1theta mode in closed form and bracketed by runs (2 + 7 / 2 + 4 runs of
   20 ms / 5 ms after the shock), then per level (1 000, 10 000, 30 000 g / 1 000, 5 000 g,
   below the impacts) one run at 100 deg/s and the same run unshocked, 30 s / 0.1 s after the
   shock: impacts, survival, how long ``~/rate`` is not a measurement and the recovery to
   within 1 and 0.1 deg/s of the unshocked run (``--quick`` is far too short to see it).

Loop modes: the shock table has one entry per amplitude and per mode of ``loops``:
``open`` (``control.mode: open_loop``, the paper's fixed drive), ``closed``
(``control.mode: closed_loop``: PLL and AGC, the sense mode read open loop) and ``rebalance``
(``control.mode: rebalance``: the rate read from the force-to-rebalance loop); a build has
the modes its ``control.mode`` offers (:func:`available_loops`). The other tests run the
file's own setting (a file with ``control.mode: rebalance`` gets the datasheet of that
readout).

Processes (``workers``, :class:`_Farm`): the long record, the zero-rate and step record,
each shock run, the device as owned, the environment series and the rate table's runs
are independent pieces, run on a process pool of the standard library, the longest
submitted first (the table is read with the step record's calibration afterwards); each
seeds from the file, so the datasheet does not depend on the number of processes. A failing
piece or Ctrl-C ends the workers at once. Not the sweep engine: a sweep point
(``sweep.point.evaluate``) is a paper case that keeps scalar metrics of the 100 kHz modal
envelopes (and, on request, the envelopes); these tests need the 1 kHz rate records
themselves (the Allan deviation, the step, the error curves of the shock plot) and the
electronics' calibration of each run, and a dozen pieces need no scheduler.
"""

from dataclasses import dataclass, replace
import json
import math
import os
from pathlib import Path
import signal
import time
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple
import warnings

import numpy as np

from ring_gyro_sim import extras
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import build_config, SimConfig, SPECS, STANDARD_GRAVITY
from ring_gyro_sim.outdir import prepare_directory
from ring_gyro_sim.run import Run, Sink

__all__ = ['FULL', 'LOOP_PARAMETER', 'Plan', 'QUICK', 'allan_fit', 'available_loops',
           'characterize', 'load_device', 'lp1_allan_variance', 'parse_loops',
           'scale_factor_fit', 'step_fit']

LOOP_PARAMETER = 'control.mode'
"""The parameter that selects the gyroscope's mode (core.gyro.modes)."""
LOOP_MODES = {'open': {LOOP_PARAMETER: 'open_loop'},
              'closed': {LOOP_PARAMETER: 'closed_loop'},
              'rebalance': {LOOP_PARAMETER: 'rebalance'}}
"""Loop modes of the shock table: the parameters each sets (those the build has)."""
LOOP_TITLES = {'open': 'open loop', 'closed': 'closed loop (PLL + AGC)',
               'rebalance': 'closed loop + force-to-rebalance'}
DEG = math.pi / 180.0
RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0
RAD_SQRT_S_TO_DEG_SQRT_H = 180.0 / math.pi * 60.0
FLICKER_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""Allan floor of flicker rate noise over the bias instability B, 0.6643 (IEEE 952)."""
JUMP_RATIO = 0.5
"""Jumped: the drive pick-off ends below this fraction of its pre-shock value."""
DRIVE_BAND = 0.01
"""Drive recovery: back within 1 % of the pre-shock pick-off."""
DRIVE_WINDOW_S = 0.5
"""Windows of the pre-shock and final drive pick-off, s."""
HOLD_S = 0.1
"""A recovery counts when it held for at least this long at the end (``core.gyro.stats``)."""
SLOPE_ONLY_TC = 10.0
"""The plain -1/2 fit starts at this many time constants."""
TAU_FRACTION = 8.0
"""The Allan deviation is computed up to ``record / TAU_FRACTION``."""
STOP_THRESHOLD_AT_S = 0.001
"""The shock time of the no-impact threshold's runs, s (they start on the drive's orbit)."""
STOP_BRACKET = (0.5, 1.1)
"""The threshold's first two runs, times the 1theta mode's closed form: they bracket it."""
LONG_CHUNK_S = 100.0
"""The long record is advanced in pieces this long: the bar moves, and only the rate is kept."""
AVERAGED_COST = 1.0 / 800.0
"""The progress bar's weight of a second of the averaged model, in seconds of the full model:
the closed-loop gyroscope with its noises runs ~800 times faster on it (``make
bench-averaged``, doc/performance.md)."""
RRW_MIN_SLOPE = 0.25
"""A rise beyond the Allan minimum counts as rate random walk (+1/2) above this log-log slope."""
RRW_START = 3.0
"""The rate random walk's line is fitted from this many times the minimum's tau on: where
white rate noise meeting it at the minimum (``N^2 / tau = K^2 tau / 3`` there) adds at most
``(1 / 3)^2`` to the variance, 5.4 % to the deviation."""
NEEDS = ('allantools',)
"""Libraries beyond the node's (:mod:`ring_gyro_sim.extras`), checked before anything runs."""


@dataclass(frozen=True)
class Plan:
    """
    Record lengths and tables of a characterization (module docstring).

    Attributes
    ----------
    zero_rate_s, zero_rate_skip_s : float
        The zero-rate record and its first part left out (s).
    step_rate_dps, step_s : float
        The rate step (deg/s) and how long it is recorded (s).
    rate_points_dps : tuple of float
        The rate table, deg/s.
    rate_point_s, rate_average_s : float
        Length of each table run and the final part averaged, s.
    shock_peaks_g : tuple of float
        Shock amplitudes, g (9.80665 m/s^2).
    shock_rate_dps, shock_at_s, shock_after_s : float
        The rate during the shock runs (deg/s), the shock's start and the record after it (s).
    bootstrap : int
        Records of the ARW's parametric bootstrap.
    temperature_points_k : tuple of float
        Die temperatures of the temperature series (K): a factory table at each.
    compensation_points_k : tuple of float
        Where the compensation (K3) is fitted, with the reference, unless the file gives
        ``gyro.calibration.temperature_points``.
    environment_s, environment_average_s : float
        Length of each run of the environment tests and its final part averaged, s.
    g_level_g : float
        The steady acceleration of the g-sensitivity test, g (+ and - along x and y).
    vibration_amplitude_g, vibration_frequencies_hz, vibration_angles_deg : float, tuples
        The sine vibration tests: at ``vibration_amplitude_g`` (peak), along x at each
        frequency, and at the middle frequency at each angle (from x towards y).
    rectification_amplitudes_g : tuple of float
        The amplitude series (peak g) at the middle frequency along x: the log-log slope.
    random_psd_frequencies_hz, random_psd_values_g2_per_hz : tuple of float
        The random profile along x (``scenario.vibration_psd_*``; empty: no such test).
    stop_test : bool
        Whether to run the shock survival test with stops (:func:`_stop_shock`).
    stop_gap_fraction : float
        The stops' clearance when the file has none (``stops.gap`` 0), a fraction of d_g.
    stop_shock_peaks_g : tuple of float
        The shock levels of the survival test (half-sines along x), g.
    stop_rate_dps, stop_shock_at_s, stop_shock_after_s : float
        The rate during each level's run (deg/s), its shock time and the record after it, s.
    stop_threshold_after_s, stop_bisections : float, int
        The no-impact threshold's runs: the record after the shock (at 1 ms) of each, and
        how many bisections follow the two that bracket it.
    stop_tolerances_dps : tuple of float
        The recovery tolerances: back within each of the unshocked reading, deg/s.
    long_record_s : float
        The long zero-rate record on the averaged model (``integrator.fidelity`` auto or
        averaged; :func:`_long_record`), s, the first ``zero_rate_skip_s`` left out: its
        Allan deviation reaches ``(long_record_s - zero_rate_skip_s) / TAU_FRACTION``.

    """

    zero_rate_s: float
    zero_rate_skip_s: float
    step_rate_dps: float
    step_s: float
    rate_points_dps: Tuple[float, ...]
    rate_point_s: float
    rate_average_s: float
    shock_peaks_g: Tuple[float, ...]
    shock_rate_dps: float
    shock_at_s: float
    shock_after_s: float
    bootstrap: int
    temperature_points_k: Tuple[float, ...] = (263.15, 283.15, 298.15, 313.15, 333.15)
    compensation_points_k: Tuple[float, ...] = (273.15, 323.15)
    environment_s: float = 10.0
    environment_average_s: float = 2.0
    g_level_g: float = 1.0
    vibration_amplitude_g: float = 10.0
    vibration_frequencies_hz: Tuple[float, ...] = (100.0, 1000.0, 3000.0)
    vibration_angles_deg: Tuple[float, ...] = (0.0, 22.5, 45.0)
    rectification_amplitudes_g: Tuple[float, ...] = (1.0, 2.154434690031884,
                                                     4.641588833612778, 10.0)
    random_psd_frequencies_hz: Tuple[float, ...] = (20.0, 2000.0)
    random_psd_values_g2_per_hz: Tuple[float, ...] = (0.01, 0.01)
    stop_test: bool = True
    stop_gap_fraction: float = 0.6
    stop_shock_peaks_g: Tuple[float, ...] = (1000.0, 10000.0, 30000.0)
    stop_rate_dps: float = 100.0
    stop_shock_at_s: float = 0.5
    stop_shock_after_s: float = 30.0
    stop_threshold_after_s: float = 0.02
    stop_bisections: int = 7
    stop_tolerances_dps: Tuple[float, ...] = (1.0, 0.1)
    long_record_s: float = 10800.0

    def environment_runs(self, output_rate_hz: float = 200000.0) -> List[Dict[str, Any]]:
        """
        Return the runs of the environment tests: one dict of scenario values each.

        The reference (no environment) first, then the g-sensitivity's four, then every
        distinct sine vibration of the three tests, frequencies above ``output.rate / 40``
        (the scenario's limit) left out, then the random profile, then the shock survival
        test with stops (``stop_test``): the runs of its no-impact threshold (their levels
        are found as they run, :func:`_stop_shock`), the unshocked run (``peak_g`` 0) and
        one per shock level. Each dict has its length, ``duration_s``.
        """
        g = STANDARD_GRAVITY
        runs: List[Dict[str, Any]] = [{'test': 'reference'}]
        for axis, (ux, uy) in (('x', (1.0, 0.0)), ('y', (0.0, 1.0))):
            for sign in (1.0, -1.0):
                runs.append({'test': 'g_sensitivity', 'axis': axis, 'sign': sign,
                             'scenario.acceleration': [sign * ux * self.g_level_g * g,
                                                       sign * uy * self.g_level_g * g]})
        middle = self.vibration_frequencies_hz[len(self.vibration_frequencies_hz) // 2]
        sines = [(self.vibration_amplitude_g, f, 0.0) for f in self.vibration_frequencies_hz]
        sines += [(self.vibration_amplitude_g, middle, a) for a in self.vibration_angles_deg]
        sines += [(a, middle, 0.0) for a in self.rectification_amplitudes_g]
        for amplitude, frequency, angle in dict.fromkeys(sines):
            if frequency > output_rate_hz / 40.0:
                continue
            runs.append({'test': 'vibration', 'amplitude_g': amplitude,
                         'frequency_hz': frequency, 'angle_deg': angle,
                         'scenario.vibration_amplitude': amplitude * g,
                         'scenario.vibration_frequency': frequency,
                         'scenario.vibration_angle': angle})
        if self.random_psd_frequencies_hz and \
                self.random_psd_frequencies_hz[-1] <= output_rate_hz / 40.0:
            runs.append({'test': 'random',
                         'scenario.vibration_psd_frequencies': list(
                             self.random_psd_frequencies_hz),
                         'scenario.vibration_psd_values': list(
                             self.random_psd_values_g2_per_hz)})
        for run in runs:
            run['duration_s'] = self.environment_s
        if self.stop_test:
            runs += [{'test': 'stop_threshold', 'index': k,
                      'duration_s': STOP_THRESHOLD_AT_S + self.stop_threshold_after_s}
                     for k in range(2 + self.stop_bisections)]
            runs += [{'test': 'stop_shock', 'peak_g': g,
                      'duration_s': self.stop_shock_at_s + self.stop_shock_after_s}
                     for g in (0.0,) + tuple(self.stop_shock_peaks_g)]
        return runs

    def runs(self, loops: int = 1, output_rate_hz: float = 200000.0) -> List[Tuple[str, float]]:
        """
        Return every run of the characterization: ``(section, simulated s)``, in order.

        ``loops`` loop modes of the shock table. The one place the totals come from (the
        progress bar's, :attr:`simulated_s`, the sheet's ``simulated_s``). The factory's rate
        tables of the device as owned are not among them: ``core.gyro.calibration`` runs
        each table rate until it has settled (3 simulated s per table on the default
        gyroscope, 29 s on the open loops of ``config/gyro.yaml``) and keeps them (in this
        process and in its cache file), so their length is not the plan's. Nor is the long
        record's (``long_record_s``): it runs on the averaged model, and the sheet counts it
        apart (``averaged_simulated_s``), as it counts the drift and step run when that runs
        on the averaged model too (:func:`averaged_refusal` None).
        """
        out = [('drift and step', self.zero_rate_s + self.step_s)]
        out += [('rate table', self.rate_point_s)] * len(self.rate_points_dps)
        out += [('shock', self.shock_at_s + self.shock_after_s)] * (
            loops * len(self.shock_peaks_g))
        out += [('device as owned', self.rate_point_s)]
        out += [('environment', r['duration_s']) for r in self.environment_runs(
            output_rate_hz)]
        return out

    def simulated_s(self, loops: int = 1, output_rate_hz: float = 200000.0) -> float:
        """Return the simulated seconds of :meth:`runs`."""
        return float(sum(s for _, s in self.runs(loops, output_rate_hz)))


FULL = Plan(zero_rate_s=310.0, zero_rate_skip_s=10.0, step_rate_dps=10.0, step_s=12.0,
            rate_points_dps=tuple(float(r) for r in range(-300, 301, 50)), rate_point_s=12.0,
            rate_average_s=4.0, shock_peaks_g=(1000.0, 3000.0, 10000.0), shock_rate_dps=10.0,
            shock_at_s=1.0, shock_after_s=40.0, bootstrap=50)
"""The full characterization: 1 121 simulated s with the three loop modes' shocks."""
QUICK = Plan(zero_rate_s=8.0, zero_rate_skip_s=2.0, step_rate_dps=10.0, step_s=2.5,
             rate_points_dps=(-300.0, -100.0, 0.0, 100.0, 300.0), rate_point_s=0.5,
             rate_average_s=0.4, shock_peaks_g=(1000.0, 10000.0), shock_rate_dps=10.0,
             shock_at_s=0.2, shock_after_s=0.6, bootstrap=200,
             temperature_points_k=(283.15, 313.15), environment_s=0.3,
             environment_average_s=0.1, stop_shock_peaks_g=(1000.0, 5000.0),
             stop_shock_at_s=0.02, stop_shock_after_s=0.1, stop_threshold_after_s=0.005,
             stop_bisections=4, long_record_s=200.0)
"""``--quick``: 22.9 simulated s with the three loop modes (short records; the tests)."""


# ----------------------------------------------------------------------------- the device
def available_loops() -> Tuple[str, ...]:
    """Return the loop modes this build has: ``open``, and ``closed``, ``rebalance`` if so."""
    if LOOP_PARAMETER not in SPECS:
        return ('open',)
    choices = SPECS[LOOP_PARAMETER].choices or ()
    return tuple(m for m, p in LOOP_MODES.items() if p[LOOP_PARAMETER] in choices)


def _loop_parameters(loop: str) -> Dict[str, Any]:
    """Return the parameters that select ``loop`` (none the build does not have)."""
    return {k: v for k, v in LOOP_MODES[loop].items() if k in SPECS}


def parse_loops(text: Optional[str]) -> Tuple[str, ...]:
    """
    Return the loop modes of ``--loops`` (comma-separated; None: all this build has).

    Raises
    ------
    ParameterError
        An unknown mode, none, or ``closed`` / ``rebalance`` without the ``control.*``
        parameters that select them.

    """
    have = available_loops()
    if text is None:
        return have
    chosen = tuple(m.strip() for m in text.split(',') if m.strip())
    if not chosen:
        raise ParameterError('--loops: give one or more of open, closed, rebalance')
    for m in chosen:
        if m not in LOOP_MODES:
            raise ParameterError(f'--loops: unknown loop mode {m!r} (open, closed, '
                                 f'rebalance)')
        if m not in have:
            raise ParameterError(f'--loops: {m!r} needs {LOOP_PARAMETER}: '
                                 f'{LOOP_MODES[m][LOOP_PARAMETER]}, which this build does '
                                 f'not have')
    return tuple(dict.fromkeys(chosen))


def load_device(path: str, node_name: str = 'ring_gyro') -> Dict[str, Any]:
    """
    Read a params file as ``ring_gyro run`` does and return its flat parameters.

    Raises
    ------
    ParameterError
        The file cannot be read or is invalid (``paramfile.check_params_file``'s message),
        or it is not a gyroscope: ``gyro.enabled`` must be true.

    """
    from ring_gyro_sim.paramfile import check_params_file
    flat = check_params_file(path, node_name)
    config = build_config(flat)
    if not config.gyro.enabled:
        raise ParameterError(f'params file {path!r}: gyro.enabled: must be true (characterize '
                             f'measures the gyroscope; the file describes the resonator '
                             f'alone)')
    return flat


def _test_parameters(flat: Mapping[str, Any], duration_s: float,
                     **values: Any) -> Dict[str, Any]:
    """
    Return the device's parameters with a test's scenario: no shock, no rate but ``values``.

    The tests read the model's own readout (``gyro.calibration.source: ideal``): the sheet
    compares the device with the model (E4-E14), whose scale factor the readout divides by.
    """
    out = {k: v for k, v in flat.items() if not k.startswith('scenario.')}
    out['gyro.calibration.source'] = 'ideal'
    out['duration'] = float(duration_s)
    out.update(values)
    return out


# ----------------------------------------------------------------------------- runs
class _Trace(Sink):
    """Keeps the rate output, the applied rate, the drive pick-off and the quadrature."""

    def __init__(self) -> None:
        self.parts: List[Tuple[np.ndarray, ...]] = []

    def block(self, block) -> None:
        rate = block.rate
        if rate is None or len(rate) == 0:
            return
        s = block.samples
        at = np.clip(np.searchsorted(s.t, rate.t), 0, len(s) - 1)
        drive = np.hypot(block.demod.values[at, 2], block.demod.values[at, 3])
        self.parts.append((rate.t, rate.rate, s.applied_rate[at], drive, rate.quadrature))

    def arrays(self) -> Tuple[np.ndarray, ...]:
        if not self.parts:
            return tuple(np.zeros(0) for _ in range(5))
        return tuple(np.concatenate([p[k] for p in self.parts]) for k in range(5))


@dataclass
class _Record:
    """One run: its rate samples, the electronics' calibration and the summary."""

    t: np.ndarray
    rate: np.ndarray
    applied: np.ndarray
    drive: np.ndarray
    quadrature: np.ndarray
    scale_factor: float
    drive_amplitude_m: float
    electronics: Any
    summary: Any
    config: SimConfig
    model: str = 'full'


class _Bar:
    """
    One progress bar over every run of the characterization (simulated s).

    Runs may be under way at once (on :class:`_Farm`'s workers): each reports as its
    ``task``, and the bar shows the runs finished plus each running one's part.
    """

    def __init__(self, total_s: float, enabled: bool, averaged_s: float = 0.0) -> None:
        from ring_gyro_sim.progress import Progress
        # the averaged model's seconds weigh AVERAGED_COST of the full model's
        self.progress = Progress(total_s + averaged_s * AVERAGED_COST, enabled,
                                 name='characterize')
        self.work = 0.0
        self.running: Dict[Any, float] = {}
        self.finished: List[float] = []
        self.finished_averaged: List[float] = []

    @property
    def runs(self) -> int:
        """Return how many runs have finished."""
        return len(self.finished)

    @property
    def done_s(self) -> float:
        """Return their planned simulated seconds (a correctly rounded sum: any order's)."""
        return math.fsum(self.finished)

    @property
    def averaged_s(self) -> float:
        """Return the averaged model's finished runs' simulated seconds (as :attr:`done_s`)."""
        return math.fsum(self.finished_averaged)

    def _show(self, note: str = '') -> None:
        self.progress.update(self.work + sum(self.running.values()), note)

    def update(self, run_s: float, note: str, weight: float = 1.0, task: Any = None) -> None:
        self.running[task] = run_s * weight
        self._show(note)

    def note(self, text: str) -> None:
        self.progress.note(f'characterize: {text}')

    def finish_run(self, planned_s: float, task: Any = None) -> None:
        self.running.pop(task, None)
        self.finished.append(planned_s)
        self.work += planned_s
        self._show()

    def finish_averaged(self, planned_s: float, task: Any = None) -> None:
        self.running.pop(task, None)
        self.finished_averaged.append(planned_s)
        self.work += planned_s * AVERAGED_COST
        self._show()

    def close(self) -> None:
        self.progress.close()


class _BarClient:
    """:class:`_Bar`'s calls made in a worker process: sent to the parent's bar as ``task``."""

    def __init__(self, queue, task: int) -> None:
        self.queue, self.task = queue, task

    def update(self, run_s: float, note: str, weight: float = 1.0) -> None:
        self.queue.put(('update', (run_s, note, weight), self.task))

    def note(self, text: str) -> None:
        self.queue.put(('note', (text,), None))

    def finish_run(self, planned_s: float) -> None:
        self.queue.put(('finish_run', (planned_s,), self.task))

    def finish_averaged(self, planned_s: float) -> None:
        self.queue.put(('finish_averaged', (planned_s,), self.task))


_WORKER_QUEUE = None
"""The progress queue of a worker process of :class:`_Farm` (set by its initializer)."""


def _worker_start(queue) -> None:
    global _WORKER_QUEUE
    _WORKER_QUEUE = queue
    # Ctrl-C is the parent's to handle: it ends the workers (_Farm.close)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_task(task: int, function, args, kwargs):
    return function(*args, bar=_BarClient(_WORKER_QUEUE, task), **kwargs)


class _Done:
    """A piece run in this process: its answer, as a worker's pending result gives it."""

    def __init__(self, value) -> None:
        self.value = value

    def ready(self) -> bool:
        return True

    def get(self):
        return self.value


class _Farm:
    """
    Runs the characterization's independent pieces: here, or on ``workers`` processes.

    :meth:`submit` takes a function with a ``bar`` keyword (it gets the bar, or a
    :class:`_BarClient` in a worker) and returns its pending result; :meth:`result` waits
    for one, passing the workers' progress to the bar meanwhile, and raises a worker's
    error. With one worker each piece runs at submission, in this process, and its error
    is raised there. Each piece is a run or a series of runs that depends on no other (its
    seeds are the file's), so the datasheet is the same for any number of workers
    (``test_characterize``). The workers are a spawned ``multiprocessing`` pool (a fresh
    interpreter each: numba's threads and the parent's state are not forked), which
    :meth:`close` ends at once after an error or Ctrl-C; their CPU time is counted once
    they have ended.
    """

    def __init__(self, bar: _Bar, workers: int) -> None:
        self.bar = bar
        self.workers = max(1, int(workers))
        self.pool = self.queue = None
        self.tasks = 0
        if self.workers > 1:
            import multiprocessing
            context = multiprocessing.get_context('spawn')
            self.queue = context.Queue()
            self.pool = context.Pool(self.workers, initializer=_worker_start,
                                     initargs=(self.queue,))

    def submit(self, function, *args, **kwargs):
        if self.pool is not None:
            self.tasks += 1
            return self.pool.apply_async(_worker_task, (self.tasks, function, args, kwargs))
        # here an error (Ctrl-C too) stops the characterization at once, as it did in order
        return _Done(function(*args, bar=self.bar, **kwargs))

    def _drain(self, timeout: float) -> None:
        import queue as queue_mod
        try:
            kind, args, task = self.queue.get(timeout=timeout)
            while True:
                if kind == 'note':
                    self.bar.note(*args)
                else:
                    getattr(self.bar, kind)(*args, task=task)
                kind, args, task = self.queue.get_nowait()
        except queue_mod.Empty:
            pass

    def result(self, pending):
        while self.queue is not None and not pending.ready():
            self._drain(0.2)
        if self.queue is not None:
            self._drain(0.0)
        return pending.get()

    def close(self, abort: bool = False) -> None:
        """End the workers: once their pieces are done, or at once (``abort``)."""
        pool, self.pool = self.pool, None
        if pool is None:
            return
        if abort:
            pool.terminate()  # a worker stopped mid-message leaves the queue unread
            pool.join()
            return
        pool.close()
        pool.join()
        self._drain(0.0)


def _simulate(values: Mapping[str, Any], duration_s: float, bar: _Bar, note: str) -> _Record:
    """Run the device on ``values`` for ``duration_s`` (stops at contact)."""
    config = build_config(dict(values))
    trace = _Trace()
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)  # unstable to the companions
        run = Run(config, sink=trace, log=bar.note)  # one shooting per device and drive
    try:
        run.advance_for(duration_s, lambda t: bar.update(t, note))
        summary = run.summary()
    finally:
        run.close()
    bar.finish_run(duration_s)
    t, rate, applied, drive, quadrature = trace.arrays()
    el = run.full_model().sense.electronics
    return _Record(t=t, rate=rate, applied=applied, drive=drive, quadrature=quadrature,
                   scale_factor=float(el.scale_factor),
                   drive_amplitude_m=float(el.drive_amplitude_m), electronics=el,
                   summary=summary, config=config)


def averaged_refusal(flat: Mapping[str, Any]) -> Optional[str]:
    """
    Return why the quiet tests will not run on the averaged model, or None if they will.

    ``integrator.fidelity: full``, or under ``auto`` a device ``core.engine.averaged.AveragedGyro``
    cannot run (its own message, naming the parameter: the open loop, the untruncated
    force...). Quiet: the tests' scenarios have no shock, base acceleration, vibration or
    contact (:func:`_test_parameters` drops the file's).

    Raises
    ------
    ParameterError
        ``integrator.fidelity: averaged`` and a device the averaged model cannot run.

    """
    config = build_config(_test_parameters(flat, 0.0))
    fidelity = config.integrator.fidelity
    if fidelity == 'full':
        return 'integrator.fidelity: full'
    try:
        _averaged_gyro(config)
    except ParameterError as exc:
        if fidelity == 'averaged':
            raise ParameterError(f'integrator.fidelity: averaged, but the averaged model '
                                 f'cannot run this device: {exc}') from exc
        return f'the averaged model cannot run this device ({exc})'
    return None


def _averaged_gyro(config: SimConfig, start_state=None):
    from ring_gyro_sim.core.engine.averaged import AveragedGyro
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)  # as _simulate's Run
        return AveragedGyro(config, start_state)


def _advance_averaged(gyro, duration_s: float, bar: _Bar, note: str):
    """Advance ``gyro`` by ``duration_s`` in pieces; return ``(t, rate, quadrature)``."""
    rate_hz = float(gyro.config.gyro.output_rate)
    total = int(round(duration_s * rate_hz))
    chunk = max(1, int(round(LONG_CHUNK_S * rate_hz)))
    parts, done = [], 0
    while done < total:
        count = min(chunk, total - done)
        out = gyro.advance(count / rate_hz)
        parts.append((out.t, out.rate, out.quadrature))
        done += count
        bar.update(done / rate_hz, note, AVERAGED_COST)
    bar.finish_averaged(duration_s)
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(3))


def _simulate_averaged(values: Mapping[str, Any], duration_s: float, bar: _Bar,
                       note: str) -> _Record:
    """
    Run a quiet test on the averaged model (:func:`averaged_refusal` said it may).

    As :func:`_simulate` reads a run: ``~/rate`` (the model's own readout, C7), the applied
    rate (the scenario's profile, a repeated knot a step), the electronics of the device at
    its start state (``Run``'s, built, not run: the scale factor, the predictions). No drive
    pick-off (``drive`` NaN) and no run summary.
    """
    from ring_gyro_sim.core.rate_profile import RateProfile
    config = build_config(dict(values))
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        run = Run(config, log=bar.note)
    try:
        el, start = run.full_model().sense.electronics, run.start_state
    finally:
        run.close()
    gyro = _averaged_gyro(config, start)   # the Run's start state: one orbit shooting
    t, rate, quadrature = _advance_averaged(gyro, duration_s, bar, f'{note} (averaged model)')
    # the profile as both models apply it (0 before its first knot, the value after a step)
    applied = RateProfile.of(config).at(np.round(t * 1e9).astype(np.int64))
    return _Record(t=t, rate=rate, applied=applied, drive=np.full(t.size, math.nan),
                   quadrature=quadrature, scale_factor=float(el.scale_factor),
                   drive_amplitude_m=float(el.drive_amplitude_m), electronics=el,
                   summary=None, config=config, model='averaged')


# ----------------------------------------------------------------------------- analyses
def lp1_allan_variance(tau_s: np.ndarray, time_constant_s: float) -> np.ndarray:
    """
    Allan variance of unit white rate noise through a first-order low-pass, (rad/s)^2.

    ``h(tau) = [1 - (Tc / 2 tau)(3 - 4 e^{-tau/Tc} + e^{-2 tau/Tc})] / tau`` for white noise
    of two-sided density 1 (so ``N^2 h`` for an ARW ``N``): ``1 / tau`` for ``tau >> Tc``,
    ``tau / (3 Tc^2)`` for ``tau << Tc``.

    Parameters
    ----------
    tau_s : ndarray
        Averaging times, s.
    time_constant_s : float
        Time constant ``Tc`` of the low-pass, s.

    """
    tau = np.asarray(tau_s, dtype=np.float64)
    r = tau / time_constant_s
    return (1.0 - (3.0 - 4.0 * np.exp(-r) + np.exp(-2.0 * r)) / (2.0 * r)) / tau


def _oadev(x: np.ndarray, rate_hz: float, taus: np.ndarray):
    import allantools
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        tau, dev, err, n = allantools.oadev(x, rate=rate_hz, data_type='freq', taus=taus)
    return np.asarray(tau), np.asarray(dev), np.asarray(err), np.asarray(n)


def _allan_taus(n_samples: int, rate_hz: float) -> np.ndarray:
    top = n_samples / rate_hz / TAU_FRACTION
    m = np.unique(np.round(np.geomspace(1.0, top * rate_hz, 1 + int(8 * math.log10(
        max(top * rate_hz, 10.0))))).astype(np.int64))
    return m / rate_hz


def allan_fit(rate: np.ndarray, rate_hz: float, time_constant_s: float,
              terms: Sequence[str] = ('correlated',), tau_min_s: float = 0.01
              ) -> Dict[str, Any]:
    """
    Allan deviation of a zero-rate record and its noise-model fit (module docstring, 1).

    Parameters
    ----------
    rate : ndarray
        Rate samples, rad/s (the stationary part of the record).
    rate_hz : float
        Their sample rate, Hz.
    time_constant_s : float
        Time constant of the rate path (the sense pole), s.
    terms : sequence of str
        Terms of the model: ``correlated`` (white rate noise through the pole),
        ``white`` (white rate noise, not through it), ``flicker`` (a constant floor).
    tau_min_s : float
        Shortest tau of the fit, s.

    Returns
    -------
    dict
        ``tau_s``, ``adev_rad_s``, ``adev_err_rad_s`` (the curve), ``arw_rad_sqrt_s`` (the
        -1/2 asymptote's level: ``sigma(1 s)`` of the line), ``coefficients`` (a, b, c of
        ``sigma^2 = a h + b / tau + c``, those not in ``terms`` 0), ``fit_tau_s`` (range),
        ``slope_only`` (the plain -1/2 fit over ``tau >= 10 Tc``, or None),
        ``minimum_rad_s`` and ``minimum_tau_s`` (the smallest deviation from the curve's
        maximum on, within the fit range), ``floor_reached`` (that minimum is not the last
        tau: the curve has turned).

    """
    from scipy import optimize
    x = np.asarray(rate, dtype=np.float64)
    record_s = x.size / rate_hz
    tau, dev, err, _ = _oadev(x, rate_hz, _allan_taus(x.size, rate_hz))
    fit = tau >= tau_min_s * (1.0 - 1e-9)
    if np.count_nonzero(fit) < 2:
        raise ParameterError(f'zero-rate record of {record_s:.3g} s: too short for an Allan '
                             f'fit from {tau_min_s:g} s')
    basis = {'correlated': lp1_allan_variance(tau, time_constant_s),
             'white': 1.0 / tau, 'flicker': np.ones_like(tau)}
    names = [n for n in ('correlated', 'white', 'flicker') if n in terms]
    weight = np.sqrt(record_s / tau[fit])
    design = np.stack([basis[n][fit] for n in names], axis=1) / (dev[fit] ** 2)[:, None]
    solution, _ = optimize.nnls(design * weight[:, None], weight)
    coefficients = {n: 0.0 for n in ('correlated', 'white', 'flicker')}
    coefficients.update({n: float(v) for n, v in zip(names, solution)})
    arw = math.sqrt(coefficients['correlated'] + coefficients['white'])
    model = sum(coefficients[n] * basis[n] for n in coefficients)
    slope_only = None
    lo = SLOPE_ONLY_TC * time_constant_s
    region = fit & (tau >= lo)
    if np.any(region) and tau[region][-1] >= 2.0 * lo:
        w = record_s / tau[region]
        level = float(np.exp(np.sum(w * np.log(dev[region] * np.sqrt(tau[region])))
                             / np.sum(w)))
        slope_only = {'arw_rad_sqrt_s': level,
                      'tau_s': [float(tau[region][0]), float(tau[region][-1])]}
    # The bias instability is read on the flat part after the white-noise descent: below
    # Tc the curve rises (the pole), so the minimum is sought from the curve's maximum on.
    top = int(np.argmax(np.where(fit, dev, -np.inf)))
    k = top + int(np.argmin(np.where(fit[top:], dev[top:], np.inf)))
    return {'tau_s': tau, 'adev_rad_s': dev, 'adev_err_rad_s': err,
            'model_adev_rad_s': np.sqrt(model), 'arw_rad_sqrt_s': arw,
            'coefficients': coefficients, 'terms': names,
            'fit_tau_s': [float(tau[fit][0]), float(tau[fit][-1])],
            'slope_only': slope_only, 'minimum_rad_s': float(dev[k]),
            'minimum_tau_s': float(tau[k]), 'floor_reached': bool(k < np.flatnonzero(fit)[-1])}


def _bootstrap_arw(coefficients: Mapping[str, float], time_constant_s: float, rate_hz: float,
                   samples: int, skip: int, terms: Sequence[str], tau_min_s: float,
                   count: int, seed: int = 20260) -> Dict[str, float]:
    """Spread and bias of :func:`allan_fit`'s ARWs on records of the fitted model."""
    from scipy import signal
    a, b, c = (coefficients[n] for n in ('correlated', 'white', 'flicker'))
    arw = math.sqrt(a + b)
    if count < 2 or arw == 0.0:
        return {'relative_standard_error': math.nan, 'relative_bias': math.nan}
    rng = np.random.default_rng(seed)
    rho = math.exp(-1.0 / (rate_hz * time_constant_s))
    ratios, slope_only = [], []
    for _ in range(count):
        # a: x_k = rho x_{k-1} + sqrt(1 - rho^2) sigma e_k from 0 (the ring starts at rest),
        # stationary variance a / (2 Tc); b: white, density b two-sided; c: a random bias
        # of the flicker floor's order (a stand-in, flicker is not drawn here).
        e = rng.standard_normal(samples + skip) * math.sqrt(a / (2.0 * time_constant_s)
                                                            * (1.0 - rho * rho))
        x = signal.lfilter([1.0], [1.0, -rho], e)[skip:]
        if b > 0.0:
            x = x + rng.standard_normal(samples) * math.sqrt(b * rate_hz)
        if c > 0.0:
            x = x + rng.standard_normal() * math.sqrt(c)
        fit = allan_fit(x, rate_hz, time_constant_s, terms, tau_min_s)
        ratios.append(fit['arw_rad_sqrt_s'] / arw)
        if fit['slope_only'] is not None:
            slope_only.append(fit['slope_only']['arw_rad_sqrt_s'] / arw)
    out = {'relative_standard_error': float(np.std(ratios, ddof=1)),
           'relative_bias': float(np.mean(ratios)) - 1.0}
    if len(slope_only) > 1:
        out['slope_only_relative_standard_error'] = float(np.std(slope_only, ddof=1))
        out['slope_only_relative_bias'] = float(np.mean(slope_only)) - 1.0
    return out


def step_fit(t_s: np.ndarray, rate: np.ndarray, step_at_s: float,
             step_rad_s: float) -> Dict[str, float]:
    """
    First-order fit of a rate step response (module docstring, 1).

    Parameters
    ----------
    t_s, rate : ndarray
        Times (s) and rate output (rad/s), the second before the step included.
    step_at_s : float
        Time of the step, s.
    step_rad_s : float
        Size of the step, rad/s.

    Returns
    -------
    dict
        ``time_constant_s``, ``gain`` (of the step), ``baseline_rad_s``, ``bandwidth_hz``
        (``1 / (2 pi tau)``), ``t63_s`` (first time the output passes 63.2 % of the fitted
        step) and ``rms_residual`` (of the fit, over the step).

    """
    from scipy import optimize
    before = (t_s > step_at_s - 1.0) & (t_s <= step_at_s)
    baseline = float(np.mean(rate[before])) if np.any(before) else 0.0
    after = t_s > step_at_s
    dt = t_s[after] - step_at_s
    y = (rate[after] - baseline) / step_rad_s

    def model(x, gain, tau):
        return gain * (1.0 - np.exp(-x / tau))
    guess_tau = max(float(dt[np.argmax(y >= (1.0 - math.exp(-1.0)) * y[-1])]), 1e-3)
    (gain, tau), _ = optimize.curve_fit(model, dt, y, p0=(float(y[-1]), guess_tau))
    crossing = np.flatnonzero(y >= (1.0 - math.exp(-1.0)) * gain)
    t63 = float(dt[crossing[0]]) if crossing.size else math.nan
    return {'time_constant_s': float(tau), 'gain': float(gain), 'baseline_rad_s': baseline,
            'bandwidth_hz': 1.0 / (2.0 * math.pi * float(tau)), 't63_s': t63,
            'rms_residual': float(np.sqrt(np.mean((model(dt, gain, tau) - y) ** 2)))}


def scale_factor_fit(input_rad_s: np.ndarray, output_rad_s: np.ndarray) -> Dict[str, Any]:
    """
    Least-squares line of a rate table and its nonlinearity (module docstring, 2).

    Parameters
    ----------
    input_rad_s, output_rad_s : ndarray
        Applied rates and the outputs (on the table's one calibration), rad/s.

    Returns
    -------
    dict
        ``slope`` (output per input, 1 = the calibration), ``offset_rad_s``,
        ``residual_rad_s`` per point, ``full_scale_rad_s`` (``slope x max |input|``) and
        ``nonlinearity_ppm`` (largest ``|residual|`` over the full-scale output).

    """
    x = np.asarray(input_rad_s, dtype=np.float64)
    y = np.asarray(output_rad_s, dtype=np.float64)
    slope, offset = np.polyfit(x, y, 1)
    residual = y - (slope * x + offset)
    full_scale = abs(slope) * float(np.max(np.abs(x)))
    return {'slope': float(slope), 'offset_rad_s': float(offset), 'residual_rad_s': residual,
            'full_scale_rad_s': full_scale,
            'nonlinearity_ppm': float(np.max(np.abs(residual)) / full_scale * 1e6)}


def _mean_noise(arw_rad_sqrt_s: float, time_constant_s: float, window_s: float) -> float:
    """Return the standard deviation of a mean over ``window_s`` of first-order white noise."""
    r = time_constant_s / window_s
    return arw_rad_sqrt_s / math.sqrt(window_s) * math.sqrt(
        max(0.0, 1.0 - r * (1.0 - math.exp(-1.0 / r))))


def _drive_figures(rec: _Record, shock_s: float) -> Dict[str, Any]:
    before = (rec.t > shock_s - DRIVE_WINDOW_S) & (rec.t <= shock_s)
    reference = float(np.mean(rec.drive[before])) if np.any(before) else math.nan
    end = rec.t > rec.t[-1] - DRIVE_WINDOW_S if rec.t.size else np.zeros(0, bool)
    ratio_end = float(np.mean(rec.drive[end])) / reference if np.any(end) else math.nan
    after = rec.t > shock_s
    off = np.flatnonzero(np.abs(rec.drive[after] / reference - 1.0) > DRIVE_BAND)
    recovery = None
    if not off.size:
        recovery = 0.0
    elif rec.t[-1] - rec.t[after][off[-1]] >= HOLD_S:
        recovery = float(rec.t[after][off[-1]] - shock_s)
    return {'drive_ratio_end': ratio_end, 'drive_recovery_s': recovery}


# ----------------------------------------------------------------------------- the datasheet
def _noise_terms(config: SimConfig) -> List[str]:
    g = config.gyro
    terms = []
    if g.temperature > 0.0:
        terms.append('correlated')
    if g.input_noise_density > 0.0:
        terms.append('white')
    if g.bias_instability > 0.0:
        terms.append('flicker')
    return terms or ['correlated']


def characterize(params_path: str, out_dir: str, quick: bool = False,
                 loops: Optional[Sequence[str]] = None, progress: bool = True,
                 node_name: str = 'ring_gyro', plan: Optional[Plan] = None,
                 shock_peaks_g: Optional[Sequence[float]] = None,
                 workers: int = 1) -> Dict[str, Any]:
    """
    Measure the datasheet of the gyroscope of ``params_path``; write it to ``out_dir``.

    Parameters
    ----------
    params_path : str
        Params file (as ``ring_gyro run`` takes it) with ``gyro.enabled: true``.
    out_dir : str
        Directory for ``datasheet.md``, ``datasheet.json`` and the PNGs (created).
    quick : bool
        The :data:`QUICK` plan instead of :data:`FULL`.
    loops : sequence of str, optional
        Loop modes of the shock table (default :func:`available_loops`).
    progress : bool
        A progress bar on stderr.
    node_name : str
        Whose ``ros__parameters`` to read.
    plan : Plan, optional
        Overrides ``quick``.
    shock_peaks_g : sequence of float, optional
        Overrides the plan's shock amplitudes, g.
    workers : int
        Processes that run the tests (1: all in this process). The datasheet is the same
        for any number; ``ring_gyro characterize`` gives the cores.

    Returns
    -------
    dict
        The datasheet (what ``datasheet.json`` holds).

    Raises
    ------
    ParameterError
        Not a gyroscope, an invalid file, an unknown loop mode (the message names the field).
    OutputPathError
        ``out_dir`` is a file, cannot be created or is not writable (checked first).
    MissingDependencyError
        allantools is not installed (checked first).

    """
    wall0, cpu0, children0 = time.monotonic(), time.process_time(), _children_cpu_s()
    extras.require(NEEDS, 'characterize (the Allan deviation)')
    flat = load_device(params_path, node_name)
    loops = tuple(loops) if loops is not None else available_loops()
    parse_loops(','.join(loops))
    plan = plan or (QUICK if quick else FULL)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f'--workers: give a whole number of processes >= 1, not '
                             f'{workers!r}')
    if shock_peaks_g is not None:
        peaks = tuple(float(g) for g in shock_peaks_g)
        if not peaks or not all(math.isfinite(g) and g > 0.0 for g in peaks):
            raise ParameterError('--shock-g: give positive shock amplitudes in g')
        plan = replace(plan, shock_peaks_g=peaks)
    # integrator.fidelity: averaged refuses a device before any run or output directory
    refusal = averaged_refusal(flat)
    out = prepare_directory(out_dir)  # before computing: 20 minutes lost otherwise
    output_rate = build_config(flat).run.output_rate
    quiet = refusal is None
    drift_s = plan.zero_rate_s + plan.step_s
    bar = _Bar(plan.simulated_s(len(loops), output_rate) - (drift_s if quiet else 0.0), progress,
               averaged_s=(plan.long_record_s + drift_s) if quiet else 0.0)
    farm = _Farm(bar, workers)
    finished = False
    try:
        # the longest pieces first, so that the last to end is short
        environment = farm.submit(_environment, flat, plan)
        keys = [(loop, peak) for loop in loops for peak in plan.shock_peaks_g]
        # the rebalance loop's shock runs are averaged before the shock and after it
        shocks = {i: farm.submit(_shock, flat, plan, peak_g=keys[i][1], loop=keys[i][0])
                  for i in sorted(range(len(keys)), key=lambda i: keys[i][0] == 'rebalance')}
        points = farm.submit(_rate_points, flat, plan)
        long = farm.submit(_long_record, flat, plan, refusal=refusal)
        owned = farm.submit(_owned_device, flat, plan)
        drift = farm.submit(_drift_and_step, flat, plan, averaged=quiet)
        shocks = [farm.result(shocks[i]) for i in range(len(keys))]
        environment, points, long, owned, drift = (
            farm.result(f) for f in (environment, points, long, owned, drift))
        finished = True
    finally:
        farm.close(abort=not finished)
        bar.close()
    table = _rate_table(plan, points, drift)
    environment.update(_settled(plan, drift['step']['time_constant_s']))
    sheet = _assemble(params_path, flat, plan, quick, loops, drift, table, shocks)
    sheet.update(owned)
    sheet['environment'] = environment
    sheet['long_record'] = _long_allan(long, drift)
    sheet['white_noise'] = _white_noise(sheet)
    sheet['simulated_s'] = bar.done_s
    sheet['averaged_simulated_s'] = bar.averaged_s
    sheet['drift_model'] = drift['model']
    sheet['runs'] = bar.runs
    sheet['files'] = _write(out, sheet, drift, table, shocks, loops)
    sheet['wall_time_s'] = time.monotonic() - wall0
    sheet['cpu_time_s'] = time.process_time() - cpu0 + _children_cpu_s() - children0
    sheet['workers'] = farm.workers
    (out / 'datasheet.json').write_text(json.dumps(_jsonable(sheet), indent=1, sort_keys=True,
                                                   allow_nan=False) + '\n', encoding='utf-8')
    return _jsonable(sheet)


def _children_cpu_s() -> float:
    """Return the CPU time of this process's ended children (the farm's workers), s."""
    t = os.times()
    return t.children_user + t.children_system


def _drift_and_step(flat, plan: Plan, bar: _Bar, averaged: bool = False) -> Dict[str, Any]:
    step = plan.step_rate_dps * DEG
    t0 = plan.zero_rate_s
    values = _test_parameters(flat, plan.zero_rate_s + plan.step_s,
                              **{'scenario.rate_times': [t0, t0],
                                 'scenario.rate_values': [0.0, step]})
    run = _simulate_averaged if averaged else _simulate
    rec = run(values, plan.zero_rate_s + plan.step_s, bar, 'zero rate, step')
    el = rec.electronics
    fit = step_fit(rec.t, rec.rate, t0, step)
    tc = fit['time_constant_s']
    zero = (rec.t > plan.zero_rate_skip_s) & (rec.t <= t0)
    x = rec.rate[zero]
    rate_hz = rec.config.gyro.output_rate
    terms = _noise_terms(rec.config)
    tau_min = max(0.01, 1.0 / rec.config.gyro.filter_bandwidth)
    if modes.of(rec.config).rebalance:
        # The rebalance loop (a PI with a delay) is not a first-order pole: its response
        # peaks near its crossover, so the fit starts where the noise is white again.
        tau_min = max(tau_min, SLOPE_ONLY_TC * tc)
    allan = allan_fit(x, rate_hz, tc, terms, tau_min)
    skip = int(round(plan.zero_rate_skip_s * rate_hz))
    allan['bootstrap'] = _bootstrap_arw(allan['coefficients'], tc, rate_hz, x.size, skip,
                                        terms, tau_min, plan.bootstrap)
    return {'record': rec, 'step': fit, 'allan': allan, 'bias_rad_s': float(np.mean(x)),
            'bias_standard_error_rad_s': _mean_noise(allan['arw_rad_sqrt_s'], tc,
                                                     x.size / rate_hz),
            'zero_rate_s': x.size / rate_hz, 'scale_factor_v_per_rad_s': rec.scale_factor,
            'calibration': rec.scale_factor / rec.drive_amplitude_m,
            'drive_amplitude_m': rec.drive_amplitude_m,
            'predicted_arw_rad_sqrt_s': el.predicted_arw()[0],
            'predicted_bandwidth_hz': float(el.bandwidth_hz), 'step_at_s': t0,
            'step_rad_s': step, 'model': rec.model}


def _long_record(flat, plan: Plan, bar: _Bar, refusal: Optional[str]) -> Dict[str, Any]:
    """
    Record ``plan.long_record_s`` at zero rate on the averaged model (module docstring, 1b).

    The model runs when ``integrator.fidelity`` is ``auto`` or ``averaged`` and
    ``core.engine.averaged.AveragedGyro`` runs the device (the test is quiet: no shock, no base
    acceleration, no vibration, no rate). It reads the model's own readout, as the other tests
    (``gyro.calibration.source: ideal``: the loop's rebalance rate, C7), from the run's start
    state, with the device's noises (S9-S11, their own streams of ``gyro.noise_seed``).

    ``refusal``: :func:`averaged_refusal`'s answer.

    Returns
    -------
    dict
        ``run`` False with the ``reason``; or ``run`` True with ``rate`` (rad/s, the first
        ``zero_rate_skip_s`` left out), ``rate_hz``, ``config``, ``simulated_s`` and
        ``wall_s`` (of the averaged model: its start, the start state included, and run).

    """
    config = build_config(_test_parameters(flat, plan.long_record_s))
    fidelity = config.integrator.fidelity
    out: Dict[str, Any] = {'run': False, 'fidelity': fidelity, 'planned_s': plan.long_record_s}
    if fidelity == 'full':
        out['reason'] = ('integrator.fidelity: full. The long record runs on the averaged '
                         'model only: on the full model (~2x real time) it would take hours')
        return out
    if refusal is not None:
        out['reason'] = (f'{refusal}. integrator.fidelity: auto falls back to the full '
                         f'model, on which a record this long would take hours')
        return out
    if plan.long_record_s <= plan.zero_rate_skip_s:
        out['reason'] = 'the plan has no long record (long_record_s)'
        return out
    wall0 = time.monotonic()
    gyro = _averaged_gyro(config)
    rate_hz = float(config.gyro.output_rate)
    _, rate, _ = _advance_averaged(gyro, plan.long_record_s, bar,
                                   'long zero-rate record (averaged model)')
    wall = time.monotonic() - wall0
    skip = int(round(plan.zero_rate_skip_s * rate_hz))
    out.update(run=True, rate=rate[skip:], rate_hz=rate_hz, config=config,
               simulated_s=rate.size / rate_hz, skip_s=skip / rate_hz, wall_s=wall,
               model='averaged (core.averaged.AveragedGyro)')
    return out


def _long_allan(long, drift) -> Dict[str, Any]:
    """
    Return the long record's Allan analysis (module docstring, 1b), or why it was not run.

    The fit as the short record's (:func:`allan_fit`, the step's time constant, the same
    terms and shortest tau), the bias instability the minimum over the fit range / 0.664;
    beyond it the log-log slope over the
    last decade of tau, and where the curve rises beyond its minimum with a slope above
    :data:`RRW_MIN_SLOPE`, the rate random walk: the +1/2 line ``K sqrt(tau / 3)`` (IEEE Std
    952, C.1) fitted from :data:`RRW_START` times the minimum's tau on, weighted by the
    clusters ``T / tau``. The error bars are the 68.3 %
    confidence intervals of allantools (``confidence_interval``) at Greenhall's equivalent
    degrees of freedom of the overlapping estimator for white rate noise (``edf_greenhall``,
    alpha 0, d 2: the noise of the default device at long tau). ``oadev``'s own
    ``dev / sqrt(n)`` counts the overlapping (correlated) pairs as independent: at ``T / 8``
    it gives 0.3 % where the interval is -17 % .. +33 %.
    """
    if not long['run']:
        return {k: long[k] for k in ('run', 'fidelity', 'planned_s', 'reason')}
    x, rate_hz, config = long['rate'], long['rate_hz'], long['config']
    tc = drift['step']['time_constant_s']
    tau_min = max(0.01, 1.0 / config.gyro.filter_bandwidth)
    if modes.of(config).rebalance:
        tau_min = max(tau_min, SLOPE_ONLY_TC * tc)  # as _drift_and_step
    allan = allan_fit(x, rate_hz, tc, _noise_terms(config), tau_min)
    tau, dev = allan['tau_s'], allan['adev_rad_s']
    record_s = x.size / rate_hz
    interval = _allan_intervals(tau, dev, x.size, rate_hz)

    def line(region, exponent):
        # weighted by the clusters T / tau: exponent None, the slope of log(dev) on log(tau);
        # else the level L of dev = L tau^exponent
        w = record_s / tau[region]
        lt, ld = np.log(tau[region]), np.log(dev[region])
        if exponent is None:
            slope, _ = np.polyfit(lt, ld, 1, w=np.sqrt(w))
            return float(slope)
        return float(np.exp(np.sum(w * (ld - exponent * lt)) / np.sum(w)))
    last = tau >= tau[-1] / 10.0
    slope = line(last, None) if np.count_nonzero(last) >= 3 else None
    # the minimum over the whole fit range: it starts at 10 Tc, past the rebalance loop's
    # peak (the only loop the averaged model runs), and a rate random walk makes the curve's
    # maximum the last tau, where allan_fit's search from the maximum on would start
    first = int(np.flatnonzero(tau >= allan['fit_tau_s'][0] * (1.0 - 1e-9))[0])
    k = first + int(np.argmin(dev[first:]))
    floor_reached = k < tau.size - 1
    beyond = tau >= RRW_START * tau[k]
    rrw = None
    if floor_reached and np.count_nonzero(beyond) >= 3 and \
            line(beyond, None) > RRW_MIN_SLOPE:
        rrw = {'k_rad_s_per_sqrt_s': line(beyond, 0.5) * math.sqrt(3.0),
               'tau_s': [float(tau[beyond][0]), float(tau[beyond][-1])]}
    h = RAD_S_TO_DEG_H
    return {
        'run': True, 'fidelity': long['fidelity'], 'model': long['model'],
        'planned_s': long['planned_s'], 'simulated_s': long['simulated_s'],
        'skip_s': long['skip_s'], 'record_s': record_s, 'wall_s': long['wall_s'],
        'tau_max_s': float(tau[-1]),
        'adev_at_tau_max_deg_per_h': float(dev[-1]) * h,
        'adev_interval_at_tau_max_deg_per_h': [float(v) * h for v in interval[-1]],
        'arw_deg_per_sqrt_h': allan['arw_rad_sqrt_s'] * RAD_SQRT_S_TO_DEG_SQRT_H,
        'arw_fit_tau_s': allan['fit_tau_s'],
        'bias_instability_deg_per_h': float(dev[k]) / FLICKER_FLOOR * h,
        'bias_instability_interval_deg_per_h': [float(v) / FLICKER_FLOOR * h
                                                for v in interval[k]],
        'bias_instability_tau_s': float(tau[k]),
        'bias_instability_floor_reached': floor_reached,
        'long_tau_slope': slope,
        'long_tau_slope_tau_s': [float(tau[last][0]), float(tau[-1])],
        'rate_random_walk_deg_per_h_per_sqrt_h': (
            None if rrw is None else rrw['k_rad_s_per_sqrt_s'] * h * 60.0),
        'rate_random_walk_tau_s': None if rrw is None else rrw['tau_s'],
        'allan': {'tau_s': tau, 'adev_deg_per_h': dev * h,
                  'adev_interval_deg_per_h': interval * h,
                  'interval': '68.3 %, allantools.edf_greenhall (white rate noise, '
                              'overlapping) and confidence_interval'}}


def _allan_intervals(tau: np.ndarray, dev: np.ndarray, n_samples: int,
                     rate_hz: float) -> np.ndarray:
    """Return the 68.3 % intervals ``(K, 2)`` of an oadev curve (:func:`_long_allan`)."""
    import allantools
    out = np.empty((tau.size, 2))
    for j, (t, d) in enumerate(zip(tau, dev)):
        # the rate samples are frequency data: n_samples + 1 phase points
        edf = allantools.edf_greenhall(alpha=0, d=2, m=int(round(t * rate_hz)),
                                       N=n_samples + 1, overlapping=True)
        out[j] = allantools.confidence_interval(float(d), edf)
    return out


def _rate_points(flat, plan: Plan, bar: _Bar) -> List[Dict[str, Any]]:
    """Run the rate table: per rate, the mean of ``~/rate`` at its end and the run's scales."""
    points = []
    for dps in plan.rate_points_dps:
        rate = dps * DEG
        values = _test_parameters(flat, plan.rate_point_s,
                                  **({'scenario.rate_times': [0.0],
                                      'scenario.rate_values': [rate]} if rate else {}))
        rec = _simulate(values, plan.rate_point_s, bar, f'rate table {dps:+g} deg/s')
        window = rec.t > plan.rate_point_s - plan.rate_average_s
        points.append({'rate_deg_per_s': dps, 'mean_rad_s': float(np.mean(rec.rate[window])),
                       'rebalance': bool(modes.of(rec.config).rebalance),
                       'calibration': rec.scale_factor / rec.drive_amplitude_m,
                       'drive_amplitude_m': rec.drive_amplitude_m})
    return points


def _rate_table(plan: Plan, points: Sequence[Mapping[str, Any]], drift) -> Dict[str, Any]:
    """Return the rate table of :func:`_rate_points`, read with the step record's figures."""
    rows = []
    for point in points:
        dps = point['rate_deg_per_s']
        rate = dps * DEG
        # E14: the rebalance readout is not divided by the electronics' scale factor.
        recalibrate = (1.0 if point['rebalance'] else
                       point['calibration'] / drift['calibration'])
        amplitude_ratio = point['drive_amplitude_m'] / drift['drive_amplitude_m']
        rows.append({'rate_deg_per_s': dps, 'rate_rad_s': rate,
                     'output_rad_s': point['mean_rad_s'] * recalibrate,
                     'predicted_output_rad_s': rate * recalibrate,
                     'calibration_ratio': recalibrate, 'drive_amplitude_ratio': amplitude_ratio,
                     'standard_error_rad_s': _mean_noise(
                         drift['allan']['arw_rad_sqrt_s'], drift['step']['time_constant_s'],
                         plan.rate_average_s) / amplitude_ratio})
    x = np.array([r['rate_rad_s'] for r in rows])
    measured = scale_factor_fit(x, np.array([r['output_rad_s'] for r in rows]))
    predicted = scale_factor_fit(x, np.array([r['predicted_output_rad_s'] for r in rows]))
    for row, res, pres in zip(rows, measured['residual_rad_s'], predicted['residual_rad_s']):
        row['residual_ppm_fs'] = float(res / measured['full_scale_rad_s'] * 1e6)
        row['predicted_residual_ppm_fs'] = float(pres / predicted['full_scale_rad_s'] * 1e6)
        row['standard_error_ppm_fs'] = row['standard_error_rad_s'] / measured[
            'full_scale_rad_s'] * 1e6
    return {'rows': rows, 'measured': measured, 'predicted': predicted}


def _shock(flat, plan: Plan, bar: _Bar, peak_g: float, loop: str) -> Dict[str, Any]:
    rate = plan.shock_rate_dps * DEG
    length = plan.shock_at_s + plan.shock_after_s
    extra = _loop_parameters(loop)
    values = _test_parameters(flat, length, **{
        'scenario.rate_times': [0.0], 'scenario.rate_values': [rate],
        'scenario.shock_times': [plan.shock_at_s],
        'scenario.shock_peaks': [peak_g * STANDARD_GRAVITY]}, **extra)
    rec = _simulate(values, length, bar, f'shock {peak_g:g} g, {loop} loop')
    s = rec.summary
    fig = s.extra
    contact = bool(s.contact)
    drive = _drive_figures(rec, plan.shock_at_s)
    jumped = None if contact else bool(drive['drive_ratio_end'] < JUMP_RATIO)
    lost = fig.get('pll_lost_lock') if loop != 'open' else None
    peak_err = fig.get('rate_error_peak_rad_s')
    return {'peak_g': float(peak_g), 'loop': loop,
            'peak_rate_error_deg_per_s': None if peak_err is None else peak_err / DEG,
            'recovery_s': fig.get('rate_recovery_s'), 'recovered': fig.get('rate_recovered'),
            'jumped': jumped, 'lost_lock': None if lost is None else bool(lost),
            'lost_lock_at_s': fig.get('pll_lock_lost_at_s') if loop != 'open' else None,
            'relocked_at_s': fig.get('pll_relocked_at_s') if loop != 'open' else None,
            'contact': contact, 'status': s.status, 'min_gap_um': s.min_gap_m * 1e6,
            'drive_amplitude_recovery_s': fig.get('drive_amplitude_recovery_s'),
            **drive, 'rate_deg_per_s': plan.shock_rate_dps, 'shock_at_s': plan.shock_at_s,
            'record_after_s': plan.shock_after_s,
            '_series': (rec.t - plan.shock_at_s, rec.rate - rec.applied, rec.applied)}


def _owned_device(flat, plan: Plan, bar: _Bar) -> Dict[str, Any]:
    """
    Return the calibration and temperature entries: the device as owned (factory, K1-K3).

    The factory's calibration at the reference (its bias: the zero-rate output it removes),
    the quadrature the held calibration reads at zero rate (noise off, the last
    ``rate_average_s`` of a ``rate_point_s`` run), and the temperature series: the table
    (K2) at each of ``temperature_points_k`` with the reference's calibration held, without
    and with the compensation fitted at ``compensation_points_k`` (or the file's
    ``gyro.calibration.temperature_points``).
    """
    from ring_gyro_sim.core.bench import factory
    values = {k: v for k, v in flat.items() if not k.startswith('scenario.')}
    values.update({'gyro.calibration.source': 'factory', 'gyro.temperature': 0.0,
                   'gyro.input_noise_density': 0.0, 'gyro.bias_instability': 0.0})
    fit_points = list(values.get('gyro.calibration.temperature_points') or ())
    if not fit_points:
        fit_points = list(plan.compensation_points_k)
        values['gyro.calibration.temperature_points'] = fit_points
    bar.note('the device as owned: its factory calibration and temperature series')
    config = build_config(values)
    held = factory.factory(config)
    record = _simulate(dict(values, **{'duration': plan.rate_point_s}), plan.rate_point_s,
                       bar, 'quadrature at zero rate')
    window = record.t > record.t[-1] - plan.rate_average_s
    quadrature = float(np.mean(record.quadrature[window]))
    reference = held.reference_temperature
    bias0, scale0 = held.at(None)
    rows = []
    for kelvin in plan.temperature_points_k:
        bar.note(f'temperature series: the table at {kelvin - 273.15:g} deg C')
        scale_t, zero_t = factory.table_at(config, kelvin, held)
        bias_c, scale_c = held.at(kelvin)
        rows.append({'temperature_k': float(kelvin),
                     'bias_deg_per_h': (zero_t / scale0 - bias0) * RAD_S_TO_DEG_H,
                     'bias_compensated_deg_per_h': (zero_t / scale_c - bias_c)
                     * RAD_S_TO_DEG_H,
                     'scale_factor_error_ppm': (scale_t / scale0 - 1.0) * 1e6,
                     'scale_factor_error_compensated_ppm': (scale_t / scale_c - 1.0) * 1e6})
    d_t = np.array([r['temperature_k'] - reference for r in rows])

    def slope(key):
        y = np.array([r[key] for r in rows])
        return float(np.polyfit(d_t, y, 1)[0]) if len(rows) >= 2 else None

    def worst(key):
        return float(max(abs(r[key]) for r in rows)) if rows else None
    return {
        'calibration': {
            'source': 'factory', 'reference_temperature_k': reference,
            'bias_deg_per_h': held.bias * RAD_S_TO_DEG_H,
            'scale_factor': held.scale_factor, 'scale_factor_unit': f'{held.unit}/(rad/s)',
            'quadrature_deg_per_s': quadrature / DEG,
            'method': 'the factory rate table (0, +-10 deg/s, noise off) at the reference '
                      'temperature; the bias is the zero-rate output the calibration '
                      'removes, the quadrature what the held calibration reads at zero rate'},
        'temperature': {
            'points': rows, 'compensation_points_k': [float(t) for t in fit_points],
            'compensation_coefficients': list(held.temperature_coefficients),
            'bias_coefficient_deg_per_h_per_k': slope('bias_deg_per_h'),
            'scale_factor_coefficient_ppm_per_k': slope('scale_factor_error_ppm'),
            'largest_bias_deg_per_h': worst('bias_deg_per_h'),
            'largest_bias_compensated_deg_per_h': worst('bias_compensated_deg_per_h'),
            'largest_scale_factor_error_ppm': worst('scale_factor_error_ppm'),
            'largest_scale_factor_error_compensated_ppm':
                worst('scale_factor_error_compensated_ppm'),
            'method': 'IEEE Std 1431 temperature test: the die steady at each temperature, '
                      'the factory table there, read with the reference calibration held; '
                      'coefficients: least-squares line through the points'}}


def _settled(plan: Plan, time_constant_s: float) -> Dict[str, Any]:
    """Return the environment entry's words on its averaging window against the rate path."""
    settle = plan.environment_s - plan.environment_average_s
    return {'settled': bool(settle >= 5.0 * time_constant_s),
            'rate_path_time_constant_s': time_constant_s}


def _environment(flat, plan: Plan, bar: _Bar) -> Dict[str, Any]:
    """
    Return the environment tests: g-sensitivity and vibration rectification (noise off).

    Each run of :meth:`Plan.environment_runs` is the device of the file, quiet (noise off,
    the model's readout: ``analysis.environment``), for ``environment_s`` from the drive's
    orbit with the 1theta pair on its answer to the environment, read as the mean of
    ``~/rate`` over the last ``environment_average_s``; each test's figure is that mean less
    the reference run's (no environment): the shift the environment causes. The
    g-sensitivity is split into its odd part in the acceleration (the linear coefficient a
    datasheet quotes, per g and per m/s^2) and its even part (what does not change sign with
    it); the amplitude series gives the log-log slope (``analysis.environment.loglog_slope``).
    :func:`_settled` adds whether the averaging starts at least 5 time constants of the rate
    path (the step's) after the start. doc/environments.md explains the numbers.
    """
    from ring_gyro_sim.analysis import environment as env
    output_rate = build_config(flat).run.output_rate
    results = []
    stop_runs = []
    for run in plan.environment_runs(output_rate):
        if run['test'].startswith('stop_'):
            stop_runs.append(run)
            continue
        scenario = {k: v for k, v in run.items() if k.startswith('scenario.')}
        config = env.quiet(build_config(_test_parameters(flat, plan.environment_s,
                                                         **scenario)))
        note = ('environment: reference' if run['test'] == 'reference' else
                f'g-sensitivity {run["sign"] * plan.g_level_g:+g} g along {run["axis"]}'
                if run['test'] == 'g_sensitivity' else 'random vibration along x'
                if run['test'] == 'random' else
                f'vibration {run["amplitude_g"]:.3g} g at {run["frequency_hz"]:g} Hz, '
                f'{run["angle_deg"]:g} deg')
        out = env.mean_output(config, plan.environment_s, plan.environment_average_s,
                              log=bar.note, progress=lambda t, n=note: bar.update(t, n))
        bar.finish_run(plan.environment_s)
        results.append((run, out, config))
    ref = results[0][1]

    def shift(out, key='rate_rad_s'):
        return (out[key] - ref[key]) / DEG
    g_axes = []
    for axis in ('x', 'y'):
        plus, minus = (next(o for r, o, _ in results if r['test'] == 'g_sensitivity'
                            and r['axis'] == axis and r['sign'] == sign) for sign in (1.0, -1.0))
        b_plus, b_minus = shift(plus), shift(minus)
        odd, even = (b_plus - b_minus) / 2.0, (b_plus + b_minus) / 2.0
        g_axes.append({'axis': axis, 'bias_shift_plus_deg_per_s': b_plus,
                       'bias_shift_minus_deg_per_s': b_minus,
                       'linear_deg_per_s_per_g': odd / plan.g_level_g,
                       'linear_deg_per_s_per_m_s2': odd / (plan.g_level_g * STANDARD_GRAVITY),
                       'even_deg_per_s': even,
                       'quadratic_deg_per_s_per_g2': even / plan.g_level_g ** 2})
    sines = {}
    for run, out, config in results:
        if run['test'] != 'vibration':
            continue
        w1 = 2.0 * math.pi * config.modes.coordinate_frequencies()[0]
        w = 2.0 * math.pi * run['frequency_hz']
        bias = shift(out)
        sines[(run['amplitude_g'], run['frequency_hz'], run['angle_deg'])] = {
            'amplitude_g': run['amplitude_g'], 'frequency_hz': run['frequency_hz'],
            'angle_deg': run['angle_deg'], 'rectified_bias_deg_per_s': bias,
            'rectified_bias_deg_per_h': bias * 3600.0,
            'rectified_bias_deg_per_s_per_g2': bias / run['amplitude_g'] ** 2,
            'rectified_quadrature_deg_per_s': shift(out, 'quadrature_rad_s'),
            'q1_amplitude_m': run['amplitude_g'] * STANDARD_GRAVITY / (w1 * w1 - w * w)}
    middle = plan.vibration_frequencies_hz[len(plan.vibration_frequencies_hz) // 2]
    amp = plan.vibration_amplitude_g
    series = [sines[(a, middle, 0.0)] for a in plan.rectification_amplitudes_g
              if (a, middle, 0.0) in sines]
    fit = env.loglog_slope([r['amplitude_g'] for r in series],
                           [r['rectified_bias_deg_per_s'] * DEG for r in series])
    return {
        'stops': _stop_shock(flat, plan, bar, stop_runs) if stop_runs else None,
        'random': _random_entry(results, shift, series[0] if series else None),
        'method': 'noise off, the model readout; the mean of ~/rate over the last '
                  f'{plan.environment_average_s:g} s of {plan.environment_s:g} s runs from '
                  'the drive orbit with the 1theta pair on its linear answer to the '
                  'environment, less the same without it',
        'record_s': plan.environment_s, 'average_s': plan.environment_average_s,
        'zero_floor_deg_per_s': env.ZERO_RAD_S / DEG,
        'reference_rate_deg_per_s': ref['rate_rad_s'] / DEG,
        'contact': any(o['contact'] for _, o, _ in results),
        'g_sensitivity': {'acceleration_g': plan.g_level_g, 'axes': g_axes},
        'vibration': {'amplitude_g': amp, 'angle_deg': 0.0,
                      'points': [sines[(amp, f, 0.0)] for f in plan.vibration_frequencies_hz
                                 if (amp, f, 0.0) in sines]},
        'vibration_angle': {'amplitude_g': amp, 'frequency_hz': middle,
                            'points': [sines[(amp, middle, a)]
                                       for a in plan.vibration_angles_deg
                                       if (amp, middle, a) in sines]},
        'rectification': {
            'frequency_hz': middle, 'angle_deg': 0.0,
            'amplitudes_g': [r['amplitude_g'] for r in series],
            'rectified_bias_deg_per_s': [r['rectified_bias_deg_per_s'] for r in series],
            'log_log_slope': None if fit is None else fit['slope'],
            'log_log_slope_standard_error': None if fit is None else fit['standard_error'],
            'local_slopes': None if fit is None else fit['local_slopes'],
            'coefficient_deg_per_s_at_1_g': None if fit is None else fit['coefficient'] / DEG,
            'zero_by_symmetry': fit is None and all(
                abs(r['rectified_bias_deg_per_s']) * DEG < env.ZERO_RAD_S for r in series)}}


def _stop_shock(flat, plan: Plan, bar: _Bar, runs) -> Dict[str, Any]:
    """
    Return the shock survival test with stops: the no-impact threshold and each level.

    The device of the file, quiet (``analysis.environment.quiet``: noise off, the model's
    readout), from the drive's orbit, with the file's stops or, if it has none,
    stops at ``plan.stop_gap_fraction`` d_g (said in ``gap_source``); half-sine shocks along
    x of the file's ``shock.duration`` (eq. 32).

    **Threshold** (at rest). The closed form (``analysis.environment.stop_threshold``) gives the
    level at which the 1theta mode alone reaches the stop, linear and with its electrostatic
    softening; the runs (shock at :data:`STOP_THRESHOLD_AT_S`, ``stop_threshold_after_s``
    after it) start at :data:`STOP_BRACKET` times the latter and bisect on "impacts > 0":
    ``no_impact_g`` is the largest level run without an impact, ``first_impact_g`` the
    smallest with. The ring touches where its whole radial displacement ``|w|`` does, which
    adds to the 1theta peak the 2theta and 3theta deflections the electrostatic terms drive
    (doc/environments.md): the runs' threshold lies below the 1theta closed form.

    **Levels.** One run per ``stop_shock_peaks_g`` at ``stop_rate_dps`` (a shock along x
    leaves a perfect ring's zero-rate output at 0 by its mirror symmetry; at a rate the
    drive knocked off its orbit shows as a scale-factor error), shock at ``stop_shock_at_s``,
    recorded ``stop_shock_after_s`` after it: impacts, whether it survived (ran to its end free of
    the electrodes, no NaN), how long ``~/rate`` was not a measurement (its variance
    ``NOT_MEASURED_VARIANCE``) after the shock (None: to the end), the largest error, and
    the recovery time to within each of ``stop_tolerances_dps`` of the unshocked reading
    (the same run without the shock, first, sample by sample: the runs are the same up to
    the shock; None: not back by the end of the record). The error is what ``~/rate``
    publishes, whether or not it says it is a measurement.
    """
    from ring_gyro_sim.analysis import environment as env
    from ring_gyro_sim.core.gyro.validity import NOT_MEASURED_VARIANCE
    device = build_config(flat)
    gap = device.stops.gap
    source = 'params file'
    if gap <= 0.0:
        gap = plan.stop_gap_fraction * device.electrodes.gap
        source = f'default: {plan.stop_gap_fraction:g} d_g (the file has stops.gap: 0)'

    def config(duration_s, peak_g, at_s, rate_dps=0.0):
        shocked = peak_g > 0.0
        return env.quiet(build_config(_test_parameters(flat, duration_s, **{
            'stops.gap': gap, 'scenario.shock_times': [at_s] if shocked else [],
            'scenario.shock_peaks': [peak_g * STANDARD_GRAVITY] if shocked else [],
            'scenario.rate_times': [0.0], 'scenario.rate_values': [rate_dps * DEG]})))

    def record(run, peak_g, at_s, note, rate_dps=0.0):
        out = env.shock_record(config(run['duration_s'], peak_g, at_s, rate_dps),
                               run['duration_s'], log=bar.note,
                               progress=lambda t: bar.update(t, note))
        bar.finish_run(run['duration_s'])
        return out
    closed = env.stop_threshold(config(1.0, 0.0, 0.0))
    g = STANDARD_GRAVITY
    predicted_g = closed['electrostatic'] / g
    tried = []
    low = high = None
    for run in (r for r in runs if r['test'] == 'stop_threshold'):
        k = run['index']
        if k < 2:
            level = STOP_BRACKET[k] * predicted_g
        elif low is not None and high is not None:
            level = 0.5 * (low + high)
        else:
            level = (2.0 if low is not None else 0.5) * tried[-1]['peak_g']
        out = record(run, level, STOP_THRESHOLD_AT_S, f'stops: threshold run {level:.0f} g')
        impacts = out['impacts'] + (0 if out['survived'] else 1)
        tried.append({'peak_g': level, 'impact_count': out['impacts'],
                      'survived': out['survived'], 'q1_peak_m': out['q1_peak_m']})
        if impacts == 0 and (low is None or level > low):
            low = level
        if impacts > 0 and (high is None or level < high):
            high = level
    below = next((t for t in tried if t['peak_g'] == low), None)
    predicted_q1 = None if below is None else env.one_theta_peak(
        closed, low * g)
    threshold = {
        'closed_form_linear_g': closed['linear'] / g,
        'closed_form_electrostatic_g': predicted_g,
        'q1_per_g_m': closed['response_s2'] * g,
        'potential_over_linear_at_gap_ratio': closed['energy_ratio'],
        'no_impact_g': low, 'first_impact_g': high,
        'bracketed': low is not None and high is not None and low < high,
        'q1_peak_at_no_impact_m': None if below is None else below['q1_peak_m'],
        'q1_peak_closed_form_at_no_impact_m': predicted_q1,
        'window_s': plan.stop_threshold_after_s, 'runs': tried}
    levels = []
    at = plan.stop_shock_at_s
    reference = None
    for run in (r for r in runs if r['test'] == 'stop_shock'):
        note = f'stops: shock {run["peak_g"]:g} g' if run['peak_g'] else 'stops: unshocked'
        out = record(run, run['peak_g'], at, note, plan.stop_rate_dps)
        if reference is None:
            reference = out
            continue
        n = min(len(out['t']), len(reference['t']))
        t, flagged = out['t'][:n], out['variance'][:n] >= NOT_MEASURED_VARIANCE
        error = out['rate'][:n] - reference['rate'][:n]
        after = t > at
        flag_after = np.flatnonzero(flagged[after])
        not_measured = 0.0 if not flag_after.size else (
            None if flag_after[-1] == int(np.count_nonzero(after)) - 1
            else float(t[after][flag_after[-1]] - at))
        levels.append({
            'peak_g': run['peak_g'], 'impact_count': out['impacts'],
            'survived': out['survived'] and out['finite'], 'status': out['status'],
            'contact': out['contact'], 'q1_peak_m': out['q1_peak_m'],
            'unshocked_reading_deg_per_s': float(np.mean(reference['rate'][:n][after]))
            / DEG if np.any(after) else None,
            'peak_error_deg_per_s': float(np.max(np.abs(error[after]))) / DEG
            if np.any(after) else None,
            'not_a_measurement_s': not_measured,
            'recovery': [{'tolerance_deg_per_s': tol,
                          'recovery_s': env.recovery_time(t, error / DEG, at, tol)}
                         for tol in plan.stop_tolerances_dps]})
    return {'gap_m': gap, 'gap_source': source, 'electrode_gap_m': device.electrodes.gap,
            'restitution_ratio': device.stops.restitution,
            'stiffness_n_per_m2': device.stops.stiffness,
            'shock_duration_s': device.shock_duration_s, 'angle_deg': 0.0,
            'rate_deg_per_s': plan.stop_rate_dps, 'shock_at_s': plan.stop_shock_at_s,
            'record_after_s': plan.stop_shock_after_s,
            'threshold': threshold, 'levels': levels}


def _white_noise(sheet) -> Dict[str, Any]:
    """
    Return the white rate noise in the conventions datasheets use, from the measured ARW.

    The Allan variance of white rate noise is ``N^2 / tau`` (IEEE Std 952, C.1), ``N`` the
    ARW read on the -1/2 line at tau = 1 s; its two-sided power spectral density is ``N^2``,
    the one-sided ``2 N^2``. So the rate noise density a datasheet quotes per sqrt(Hz) is
    ``sqrt(2) N`` one-sided, ``N`` two-sided; in deg/sqrt(h), ``60 N`` with N in deg/sqrt(s).
    """
    arw = sheet['arw_deg_per_sqrt_h']
    n_deg_sqrt_s = arw / 60.0
    return {'arw_deg_per_sqrt_h': arw,
            'density_one_sided_deg_per_s_per_sqrt_hz': math.sqrt(2.0) * n_deg_sqrt_s,
            'density_two_sided_deg_per_s_per_sqrt_hz': n_deg_sqrt_s,
            'convention': 'ARW N read at tau = 1 s on the -1/2 line of the Allan deviation '
                          '(sigma^2 = N^2 / tau, IEEE Std 952); one-sided density '
                          'sqrt(2) N, two-sided N (deg/s/sqrt(Hz)); deg/sqrt(h) = 60 x '
                          'deg/sqrt(s)'}


def _assemble(path, flat, plan: Plan, quick: bool, loops, drift, table,
              shocks) -> Dict[str, Any]:
    allan = drift['allan']
    config = drift['record'].config
    sf0 = drift['scale_factor_v_per_rad_s']
    measured_sf = table['measured']['slope'] * sf0
    arw = allan['arw_rad_sqrt_s'] * RAD_SQRT_S_TO_DEG_SQRT_H
    arw_pred = drift['predicted_arw_rad_sqrt_s'] * RAD_SQRT_S_TO_DEG_SQRT_H
    bw = drift['step']['bandwidth_hz']
    bw_pred = drift['predicted_bandwidth_hz']
    slope_only = allan['slope_only']
    sheet: Dict[str, Any] = {
        'params_file': str(path), 'quick': bool(quick), 'loops': list(loops),
        'device': {'drive_amplitude_m_s2': config.drive.amplitude,
                   'drive_frequency_hz': config.drive.frequency,
                   'q2_amplitude_m': drift['drive_amplitude_m'],
                   'sense_quality_factor': float(drift['record'].electronics
                                                 .sense_quality_factor),
                   'temperature_k': config.gyro.temperature,
                   'input_noise_density_v_per_sqrt_hz': config.gyro.input_noise_density,
                   'noise_seed': config.gyro.noise_seed,
                   'output_rate_hz': config.gyro.output_rate},
        'scale_factor': measured_sf, 'scale_factor_unit': 'V/(rad/s)',
        'scale_factor_mv_per_deg_s': measured_sf * DEG * 1e3,
        'scale_factor_relative': table['measured']['slope'],
        'scale_factor_offset_deg_per_s': table['measured']['offset_rad_s'] / DEG,
        'scale_factor_nonlinearity_ppm': table['measured']['nonlinearity_ppm'],
        'rate_table': [{k: v for k, v in r.items() if not k.endswith('_rad_s')}
                       | {'output_deg_per_s': r['output_rad_s'] / DEG,
                          'standard_error_deg_per_s': r['standard_error_rad_s'] / DEG}
                       for r in table['rows']],
        'bias_deg_per_h': drift['bias_rad_s'] * RAD_S_TO_DEG_H,
        'bias_standard_error_deg_per_h': drift['bias_standard_error_rad_s'] * RAD_S_TO_DEG_H,
        'arw_deg_per_sqrt_h': arw,
        'arw_relative_standard_error': allan['bootstrap']['relative_standard_error'],
        'arw_bootstrap': dict(allan['bootstrap'], records=plan.bootstrap),
        'arw_fit': {'model': 'sigma^2 = a h(tau; Tc) + b / tau + c', 'terms': allan['terms'],
                    'tau_s': allan['fit_tau_s'], 'time_constant_s':
                        drift['step']['time_constant_s'],
                    'a_rad2_per_s': allan['coefficients']['correlated'],
                    'b_rad2_per_s': allan['coefficients']['white'],
                    'c_rad2_per_s2': allan['coefficients']['flicker']},
        'arw_slope_only_deg_per_sqrt_h': (slope_only['arw_rad_sqrt_s']
                                          * RAD_SQRT_S_TO_DEG_SQRT_H if slope_only else None),
        'arw_slope_only_tau_s': slope_only['tau_s'] if slope_only else None,
        'bias_instability_deg_per_h': allan['minimum_rad_s'] / FLICKER_FLOOR * RAD_S_TO_DEG_H,
        'bias_instability_tau_s': allan['minimum_tau_s'],
        'bias_instability_floor_reached': allan['floor_reached'],
        'allan': {'tau_s': allan['tau_s'],
                  'adev_deg_per_h': allan['adev_rad_s'] * RAD_S_TO_DEG_H,
                  'adev_err_deg_per_h': allan['adev_err_rad_s'] * RAD_S_TO_DEG_H},
        'bandwidth_hz': bw,
        'step': {'rate_deg_per_s': plan.step_rate_dps,
                 'time_constant_s': drift['step']['time_constant_s'],
                 'gain': drift['step']['gain'], 't63_s': drift['step']['t63_s'],
                 'rms_residual': drift['step']['rms_residual'],
                 'method': 'first-order fit of the step response, 1 / (2 pi tau)'},
        'shock': [{k: v for k, v in s.items() if not k.startswith('_')} for s in shocks],
        'predicted': {
            'scale_factor': sf0, 'scale_factor_unit': 'V/(rad/s)',
            'scale_factor_table': table['predicted']['slope'] * sf0,
            'scale_factor_nonlinearity_ppm': table['predicted']['nonlinearity_ppm'],
            'arw_deg_per_sqrt_h': arw_pred, 'bandwidth_hz': bw_pred, 'bias_deg_per_h': 0.0,
            'bias_instability_deg_per_h': config.gyro.bias_instability},
        'agreement': {'scale_factor': measured_sf / sf0 - 1.0,
                      'scale_factor_table': table['measured']['slope']
                      / table['predicted']['slope'] - 1.0,
                      'arw': arw / arw_pred - 1.0, 'bandwidth': bw / bw_pred - 1.0},
        'plan': {k: (list(v) if isinstance(v, tuple) else v)
                 for k, v in plan.__dict__.items()},
    }
    return sheet


def _write(out: Path, sheet, drift, table, shocks, loops) -> List[str]:
    from ring_gyro_sim.analysis import plotting
    files = ['datasheet.json', 'datasheet.md']
    allan = drift['allan']
    pngs = {}
    long = sheet['long_record']
    curve = None
    if long['run']:
        g = long['allan']
        curve = (g['tau_s'], g['adev_deg_per_h'],
                 np.abs(np.transpose(g['adev_interval_deg_per_h'])
                        - np.asarray(g['adev_deg_per_h'])),
                 f'averaged model, {_fmt(long["record_s"] / 3600.0, 3)} h (oadev)',
                 (long['bias_instability_tau_s'],
                  long['bias_instability_deg_per_h'] * FLICKER_FLOOR))
    if plotting.plot_allan(
            allan['tau_s'], allan['adev_rad_s'] * RAD_S_TO_DEG_H,
            allan['adev_err_rad_s'] * RAD_S_TO_DEG_H, out / 'allan.png',
            model=np.where((allan['tau_s'] >= allan['fit_tau_s'][0])
                           & (allan['tau_s'] <= allan['fit_tau_s'][1]),
                           allan['model_adev_rad_s'] * RAD_S_TO_DEG_H, np.nan),
            arw_deg_per_h=allan['arw_rad_sqrt_s'] * RAD_S_TO_DEG_H,
            predicted_arw_deg_per_h=drift['predicted_arw_rad_sqrt_s'] * RAD_S_TO_DEG_H,
            fit_tau_s=allan['fit_tau_s'],
            floor=(allan['minimum_tau_s'], allan['minimum_rad_s'] * RAD_S_TO_DEG_H),
            slope_only=None if allan['slope_only'] is None else (
                allan['slope_only']['tau_s'],
                allan['slope_only']['arw_rad_sqrt_s'] * RAD_S_TO_DEG_H),
            long_record=curve):
        pngs['allan'] = 'allan.png'
    rows = sheet['rate_table']
    if plotting.plot_scale_factor(
            [r['rate_deg_per_s'] for r in rows], [r['residual_ppm_fs'] for r in rows],
            [r['standard_error_ppm_fs'] for r in rows],
            [r['predicted_residual_ppm_fs'] for r in rows], out / 'scale_factor.png',
            nonlinearity_ppm=sheet['scale_factor_nonlinearity_ppm']):
        pngs['scale_factor'] = 'scale_factor.png'
    rec = drift['record']
    after = rec.t > drift['step_at_s'] - 1.0
    step = drift['step']
    if plotting.plot_step(rec.t[after] - drift['step_at_s'],
                          (rec.rate[after] - step['baseline_rad_s']) / drift['step_rad_s'],
                          step['gain'], step['time_constant_s'], out / 'step.png',
                          predicted_time_constant_s=1.0 / (2.0 * math.pi * drift[
                              'predicted_bandwidth_hz'])):
        pngs['step'] = 'step.png'
    series = sheet['temperature']['points']
    if len(series) >= 2 and plotting.plot_temperature_series(
            [r['temperature_k'] - 273.15 for r in series],
            [r['bias_deg_per_h'] for r in series],
            [r['bias_compensated_deg_per_h'] for r in series],
            [r['scale_factor_error_ppm'] for r in series],
            [r['scale_factor_error_compensated_ppm'] for r in series],
            [t - 273.15 for t in sheet['temperature']['compensation_points_k']],
            out / 'temperature.png'):
        pngs['temperature'] = 'temperature.png'
    panels = []
    for loop in LOOP_MODES:
        curves = [(f'{s["peak_g"]:g} g', s['_series'][0], s['_series'][1] / DEG,
                   s['_series'][2] / DEG) for s in shocks if s['loop'] == loop]
        panels.append((LOOP_TITLES[loop], curves, loop in available_loops()))
    if plotting.plot_shock_recovery(panels, out / 'shock_recovery.png'):
        pngs['shock_recovery'] = 'shock_recovery.png'
    rect = sheet['environment']['rectification']
    if rect['log_log_slope'] is not None and plotting.plot_rectification(
            rect['amplitudes_g'], [b * 3600.0 for b in rect['rectified_bias_deg_per_s']],
            out / 'rectification.png', slope=rect['log_log_slope'],
            coefficient=rect['coefficient_deg_per_s_at_1_g'] * 3600.0,
            title=f'Vibration rectification: sine at {_fmt(rect["frequency_hz"])} Hz along x '
                  f'(noise off)'):
        pngs['rectification'] = 'rectification.png'
    files += list(pngs.values())
    (out / 'datasheet.md').write_text(_markdown(sheet, pngs), encoding='utf-8')
    return files


def _fmt(value, digits: int = 4) -> str:
    """
    Format a number for the sheet with ``digits`` significant digits, never as ``1e+04``.

    A whole number, and one too large for ``digits`` without an exponent, is written as the
    nearest integer in groups of three (``10 000`` g, ``3 104`` deg/s).
    """
    if value is None:
        return '-'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, float) and not math.isfinite(value):
        return '-'
    if isinstance(value, float) and abs(value) < 1e15 and (
            value.is_integer() or abs(value) >= 10.0 ** digits):
        return f'{round(value):,}'.replace(',', ' ')
    if isinstance(value, float):
        return f'{value:.{digits}g}'
    return str(value)


def _markdown(sheet, pngs: Mapping[str, str]) -> str:
    p = sheet['predicted']
    a = sheet['agreement']
    d = sheet['device']
    plan = sheet['plan']
    lines = [f'# Gyroscope datasheet: `{sheet["params_file"]}`'
             + (' (`--quick`: short records)' if sheet['quick'] else ''), '',
             f'Measured by `ring_gyro characterize` (IEEE Std 1431 test procedures, Allan '
             f'analysis of IEEE Std 952; doc/datasheet.md). Device: drive '
             f'{_fmt(d["drive_amplitude_m_s2"])} m/s^2 at {_fmt(d["drive_frequency_hz"], 6)} '
             f'Hz (q2 = {_fmt(d["q2_amplitude_m"] * 1e6)} um), sense Q '
             f'{_fmt(d["sense_quality_factor"], 6)}, {_fmt(d["temperature_k"])} K, pick-off '
             f'{_fmt(d["input_noise_density_v_per_sqrt_hz"] * 1e9)} nV/sqrt(Hz), seed '
             f'{d["noise_seed"]}, output {_fmt(d["output_rate_hz"])} Hz.', '']
    if sheet['drift_model'] == 'averaged':
        lines += ['The zero-rate record and the step (bias, ARW, bias instability, bandwidth) ran '
                  'on the averaged model (`integrator.fidelity`; doc/averaged.md: it reproduces '
                  'the ARW of the full model within the statistics and its step response); the '
                  'other tests on the full model.', '']
    lines += ['| figure | measured | model | unit | measured / model - 1 | how |',
              '|---|---|---|---|---|---|']
    rng = plan['rate_points_dps']
    table_note = (f'{len(rng)} rates {_fmt(min(rng))} .. {_fmt(max(rng))} deg/s, '
                  f'{_fmt(plan["rate_average_s"])} s means, least-squares line')
    lines += [
        f'| scale factor | {_fmt(sheet["scale_factor"], 5)} | {_fmt(p["scale_factor"], 5)} '
        f'| V/(rad/s) | {a["scale_factor"]:+.2%} | {table_note} (model: small-signal, at '
        f'rest) |',
        f'| scale factor (table slope of the model) | {_fmt(sheet["scale_factor"], 5)} | '
        f'{_fmt(p["scale_factor_table"], 5)} | V/(rad/s) | {a["scale_factor_table"]:+.3%} | '
        'the reading of the model at each rate (E6b at the drive amplitude of that rate) |',
        f'| scale factor | {_fmt(sheet["scale_factor_mv_per_deg_s"], 5)} | '
        f'{_fmt(p["scale_factor"] * DEG * 1e3, 5)} | mV/(deg/s) | | |',
        f'| scale-factor nonlinearity | {_fmt(sheet["scale_factor_nonlinearity_ppm"], 3)} | '
        f'{_fmt(p["scale_factor_nonlinearity_ppm"], 3)} | ppm of full scale | | largest '
        f'residual / (slope x {_fmt(max(abs(r) for r in rng))} deg/s) |',
        f'| bias | {_fmt(sheet["bias_deg_per_h"], 3)} +- '
        f'{_fmt(sheet["bias_standard_error_deg_per_h"], 2)} | 0 | deg/h | | zero-rate mean '
        f'over {_fmt(plan["zero_rate_s"] - plan["zero_rate_skip_s"])} s (+- 1 standard '
        f'error) |',
        f'| angle random walk | {_fmt(sheet["arw_deg_per_sqrt_h"], 4)} +- '
        f'{_fmt(sheet["arw_relative_standard_error"] * sheet["arw_deg_per_sqrt_h"], 2)} | '
        f'{_fmt(p["arw_deg_per_sqrt_h"], 4)} | deg/sqrt(h) | {a["arw"]:+.1%} | Allan fit '
        f'over tau {_fmt(sheet["arw_fit"]["tau_s"][0], 3)} .. '
        f'{_fmt(sheet["arw_fit"]["tau_s"][1], 3)} s, -1/2 asymptote at 1 s |']
    boot = sheet['arw_bootstrap']
    if sheet['arw_slope_only_deg_per_sqrt_h'] is not None:
        lo, hi = sheet['arw_slope_only_tau_s']
        plain = sheet['arw_slope_only_deg_per_sqrt_h']
        expected = ''
        if boot.get('slope_only_relative_standard_error') is not None:
            expected = (f'; this estimator on the fitted noise: '
                        f'{boot["slope_only_relative_bias"]:+.1%} +- '
                        f'{boot["slope_only_relative_standard_error"]:.1%}')
        lines.append(f'| angle random walk, plain -1/2 line | {_fmt(plain, 4)} | '
                     f'{_fmt(p["arw_deg_per_sqrt_h"], 4)} | deg/sqrt(h) | '
                     f'{plain / p["arw_deg_per_sqrt_h"] - 1:+.1%} | over tau {_fmt(lo, 3)} .. '
                     f'{_fmt(hi, 3)} s (>= 10 Tc, where the pole still lowers the curve'
                     f'{expected}) |')
    bound = '' if sheet['bias_instability_floor_reached'] else '<= '
    lines += [
        f'| bias instability | {bound}{_fmt(sheet["bias_instability_deg_per_h"], 3)} | '
        f'{_fmt(p["bias_instability_deg_per_h"], 3)} | deg/h | | Allan minimum / 0.664 at '
        f'tau = {_fmt(sheet["bias_instability_tau_s"], 3)} s'
        + ('' if sheet['bias_instability_floor_reached'] else
           ' (no floor within the record: an upper bound)') + ' |',
        f'| bandwidth | {_fmt(sheet["bandwidth_hz"], 4)} | {_fmt(p["bandwidth_hz"], 4)} | Hz '
        f'| {a["bandwidth"]:+.2%} | {_fmt(sheet["step"]["rate_deg_per_s"])} deg/s step, '
        f'first-order fit tau = {_fmt(sheet["step"]["time_constant_s"], 4)} s '
        f'(63.2 % at {_fmt(sheet["step"]["t63_s"], 4)} s) |', '']
    lines += _long_markdown(sheet['long_record'], sheet['arw_deg_per_sqrt_h'])
    c = sheet['calibration']
    w = sheet['white_noise']
    th = sheet['temperature']
    lines += ['## The device as owned: calibration, quadrature, temperature', '',
              f'The factory calibration at {_fmt(c["reference_temperature_k"], 5)} K (a rate '
              f'table at 0 and +-10 deg/s, noise off): bias {_fmt(c["bias_deg_per_h"], 4)} '
              f'deg/h (the zero-rate output it removes), scale factor '
              f'{_fmt(c["scale_factor"], 6)} {c["scale_factor_unit"]}; quadrature read at zero '
              f'rate with it held: {_fmt(c["quadrature_deg_per_s"], 4)} deg/s. The tests above '
              f'read the model readout; this section reads the device as a user owns it.',
              '',
              f'White noise: ARW {_fmt(w["arw_deg_per_sqrt_h"], 4)} deg/sqrt(h) = rate noise '
              f'density {_fmt(w["density_one_sided_deg_per_s_per_sqrt_hz"], 4)} '
              f'deg/s/sqrt(Hz) one-sided ({_fmt(w["density_two_sided_deg_per_s_per_sqrt_hz"], 4)}'
              f' two-sided): {w["convention"]}.', '',
              f'Temperature series (IEEE Std 1431): the table at each die temperature, the '
              f'reference calibration held; the compensation (K3) fitted at '
              f'{", ".join(_fmt(t - 273.15, 4) for t in th["compensation_points_k"])} deg C '
              f'and the reference. Bias coefficient '
              f'{_fmt(th["bias_coefficient_deg_per_h_per_k"], 3)} deg/h/K, scale factor '
              f'{_fmt(th["scale_factor_coefficient_ppm_per_k"], 3)} ppm/K (least-squares '
              f'lines).', '',
              '| die (deg C) | bias (deg/h) | compensated | scale-factor error (ppm) | '
              'compensated |', '|---|---|---|---|---|']
    for r in th['points']:
        lines.append(f'| {_fmt(r["temperature_k"] - 273.15, 4)} | '
                     f'{_fmt(r["bias_deg_per_h"], 4)} | '
                     f'{_fmt(r["bias_compensated_deg_per_h"], 3)} | '
                     f'{_fmt(r["scale_factor_error_ppm"], 4)} | '
                     f'{_fmt(r["scale_factor_error_compensated_ppm"], 3)} |')
    lines += ['']
    lines += ['## Shock response', '',
              f'{_fmt(sheet["plan"]["shock_rate_dps"])} deg/s, half-sine along x at '
              f'{_fmt(plan["shock_at_s"])} s, recorded {_fmt(plan["shock_after_s"])} s after '
              f'it. Recovery: back within max(1 % of the rate, 4 sigma of the pre-shock '
              f'error) for good; jumped: drive pick-off at the end below '
              f'{JUMP_RATIO:g} of its pre-shock value.', '',
              '| shock (g) | loop | peak rate error (deg/s) | recovery (s) | drive back (s) | '
              'drive at end | jumped | lost lock | contact | smallest gap (um) |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for s in sheet['shock']:
        lines.append(
            f'| {_fmt(s["peak_g"])} | {s["loop"]} | {_fmt(s["peak_rate_error_deg_per_s"], 3)} | '
            f'{_fmt(s["recovery_s"], 4) if s["recovery_s"] is not None else "not yet"} | '
            f'{_fmt(s["drive_recovery_s"], 4) if s["drive_recovery_s"] is not None else "no"} | '
            f'{_fmt(s["drive_ratio_end"], 3)} | {_fmt(s["jumped"])} | '
            f'{_fmt(s["lost_lock"]) if s["loop"] != "open" else "n/a (no loop)"} | '
            f'{_fmt(s["contact"])} | {_fmt(s["min_gap_um"], 3)} |')
    missing = [m for m in LOOP_MODES if m not in sheet['loops']]
    if missing:
        lines += ['', f'Not measured: {", ".join(missing)} (not in this build, or `--loops` '
                      f'left it out).']
    lines += ['', '## Rate table', '',
              '| rate (deg/s) | output (deg/s) | residual (ppm FS) | +- 1 s.e. (ppm FS) | '
              'model residual (ppm FS) | drive amplitude / rest |', '|---|---|---|---|---|---|']
    for r in sheet['rate_table']:
        lines.append(f'| {_fmt(r["rate_deg_per_s"])} | {r["output_deg_per_s"]:.5f} | '
                     f'{r["residual_ppm_fs"]:.0f} | {r["standard_error_ppm_fs"]:.0f} | '
                     f'{r["predicted_residual_ppm_fs"]:.0f} | '
                     f'{r["drive_amplitude_ratio"]:.4f} |')
    lines += _environment_markdown(sheet['environment'])
    titles = {'allan': 'Allan deviation', 'scale_factor': 'Scale-factor error',
              'step': 'Rate step (bandwidth)', 'shock_recovery': 'Shock recovery',
              'temperature': 'Temperature series', 'rectification': 'Vibration rectification'}
    lines.append('')
    for key, name in pngs.items():
        lines += [f'![{titles[key]}]({name})', '']
    return '\n'.join(lines)


def _interval(pair) -> str:
    return f'{_fmt(pair[0], 3)} .. {_fmt(pair[1], 3)}'


def _long_markdown(g, arw_short) -> List[str]:
    """Return the long zero-rate record's section (module docstring, 1b)."""
    lines = ['## Long zero-rate record (averaged model)', '']
    if not g['run']:
        return lines + [f'Not run: {g["reason"]}.', '']
    bound = '' if g['bias_instability_floor_reached'] else '<= '
    lines += [f'{_fmt(g["record_s"], 6)} s ({_fmt(g["record_s"] / 3600.0, 3)} h) at zero '
              f'rate on the averaged model (`integrator.fidelity: {g["fidelity"]}`; '
              f'doc/averaged.md), the first {_fmt(g["skip_s"])} s left out; '
              f'{_fmt(g["wall_s"], 3)} s of wall time. Allan deviation (oadev) to tau = '
              f'{_fmt(g["tau_max_s"], 4)} s; the intervals are 68.3 % (allantools, '
              f'the degrees of freedom of Greenhall for white rate noise).', '',
              '| figure | value | unit | how |', '|---|---|---|---|',
              f'| angle random walk | {_fmt(g["arw_deg_per_sqrt_h"], 4)} | deg/sqrt(h) | '
              f'the same Allan fit over tau {_fmt(g["arw_fit_tau_s"][0], 3)} .. '
              f'{_fmt(g["arw_fit_tau_s"][1], 4)} s (the short record: '
              f'{_fmt(arw_short, 4)}) |',
              f'| bias instability | {bound}{_fmt(g["bias_instability_deg_per_h"], 3)} '
              f'({_interval(g["bias_instability_interval_deg_per_h"])}) | deg/h | Allan '
              f'minimum / 0.664 at tau = {_fmt(g["bias_instability_tau_s"], 4)} s'
              + ('' if g['bias_instability_floor_reached'] else
                 ' (no floor within the record: an upper bound)') + ' |',
              f'| Allan deviation at tau = {_fmt(g["tau_max_s"], 4)} s | '
              f'{_fmt(g["adev_at_tau_max_deg_per_h"], 3)} '
              f'({_interval(g["adev_interval_at_tau_max_deg_per_h"])}) | deg/h | the longest '
              f'tau |',
              f'| log-log slope, last decade | {_fmt(g["long_tau_slope"], 3)} | - | tau '
              f'{_fmt(g["long_tau_slope_tau_s"][0], 4)} .. '
              f'{_fmt(g["long_tau_slope_tau_s"][1], 4)} s (-1/2 white, 0 flicker, +1/2 rate '
              f'random walk) |']
    if g['rate_random_walk_deg_per_h_per_sqrt_h'] is None:
        lines.append('| rate random walk | - | deg/h/sqrt(h) | no +1/2 rise beyond the minimum '
                     'within the record |')
    else:
        lo, hi = g['rate_random_walk_tau_s']
        lines.append(f'| rate random walk | {_fmt(g["rate_random_walk_deg_per_h_per_sqrt_h"], 3)}'
                     f' | deg/h/sqrt(h) | +1/2 line K sqrt(tau / 3) over tau {_fmt(lo, 4)} .. '
                     f'{_fmt(hi, 4)} s |')
    return lines + ['']


def _random_entry(results, shift, sine) -> Optional[Dict[str, Any]]:
    """
    Return the random profile's entry, with its shift predicted from the sine's.

    What rectifies is the mean square of the 1theta answer (doc/environments.md): the
    multisine's is ``sum_k |sinc^2(f_k / f_s) A_k H(f_k)|^2 / 2`` over its lines (exact for
    the periodic profile, ``H = 1 / (omega_1^2 - omega^2 + i omega omega_1 / Q_1)``), the
    sine's ``A_1^2 / 2``; the prediction is the sine's shift per mean square (the smallest
    amplitude of the series) times the profile's.
    """
    from ring_gyro_sim.core.ring.environment import environment_of
    found = [(r, o, c) for r, o, c in results if r['test'] == 'random']
    if not found:
        return None
    run, out, config = found[0]
    rv = environment_of(config).random
    f = rv.lines * rv.df
    w = 2.0 * math.pi * f
    w1 = 2.0 * math.pi * config.modes.coordinate_frequencies()[0]
    h = 1.0 / (w1 * w1 - w * w + 1j * w * w1 / config.modes.coordinate_quality_factors()[0])
    line = rv.amplitudes * np.sinc(f / config.run.output_rate) ** 2 * np.abs(h)
    mean_square = float(np.sum(line * line) / 2.0)
    bias = shift(out)
    predicted = None
    if sine is not None:
        predicted = sine['rectified_bias_deg_per_s'] / (sine['q1_amplitude_m'] ** 2 / 2.0) \
            * mean_square
    return {'psd_frequencies_hz': list(run['scenario.vibration_psd_frequencies']),
            'psd_values_g2_per_hz': list(run['scenario.vibration_psd_values']),
            'rms_g': rv.rms_g, 'angle_deg': 0.0, 'rectified_bias_deg_per_s': bias,
            'rectified_bias_deg_per_h': bias * 3600.0,
            'rectified_quadrature_deg_per_s': shift(out, 'quadrature_rad_s'),
            'q1_rms_m': math.sqrt(mean_square),
            'predicted_from_sine_deg_per_s': predicted}


def _environment_markdown(e) -> List[str]:
    """Return the sheet's environment section (:func:`_environment`'s entries)."""
    g = e['g_sensitivity']
    settled = 'settled' if e['settled'] else (
        f'not settled: the rate path needs ~5 x {_fmt(e["rate_path_time_constant_s"], 3)} s, '
        f'the figures read low')
    lines = ['', '## Environment: g-sensitivity and vibration rectification', '',
             f'{e["method"]} ({settled}; doc/environments.md). Below '
             f'{_fmt(e["zero_floor_deg_per_s"], 2)} deg/s a shift is zero to rounding.', '',
             f'**g-sensitivity** (steady +-{_fmt(g["acceleration_g"])} g):', '',
             '| axis | shift at +a (deg/s) | at -a (deg/s) | linear (deg/s/g) | '
             'linear (deg/s/(m/s^2)) | even part (deg/s) |', '|---|---|---|---|---|---|']
    for r in g['axes']:
        lines.append(f'| {r["axis"]} | {_fmt(r["bias_shift_plus_deg_per_s"], 4)} | '
                     f'{_fmt(r["bias_shift_minus_deg_per_s"], 4)} | '
                     f'{_fmt(r["linear_deg_per_s_per_g"], 3)} | '
                     f'{_fmt(r["linear_deg_per_s_per_m_s2"], 3)} | '
                     f'{_fmt(r["even_deg_per_s"], 4)} |')
    v, a = e['vibration'], e['vibration_angle']
    lines += ['', f'**Sine vibration** ({_fmt(v["amplitude_g"])} g peak; along x at each '
                  f'frequency, at {_fmt(a["frequency_hz"])} Hz at each angle):', '',
              '| frequency (Hz) | angle (deg) | q1 amplitude (nm) | rectified bias (deg/h) | '
              '(deg/s/g^2) | quadrature shift (deg/s) |', '|---|---|---|---|---|---|']
    for r in v['points'] + [p for p in a['points'] if p['angle_deg'] != 0.0]:
        lines.append(f'| {_fmt(r["frequency_hz"])} | {_fmt(r["angle_deg"])} | '
                     f'{_fmt(r["q1_amplitude_m"] * 1e9, 4)} | '
                     f'{_fmt(r["rectified_bias_deg_per_h"], 4)} | '
                     f'{_fmt(r["rectified_bias_deg_per_s_per_g2"], 4)} | '
                     f'{_fmt(r["rectified_quadrature_deg_per_s"], 4)} |')
    r = e.get('random')
    if r is not None:
        lines += ['', f'**Random vibration** (along x, {_fmt(r["rms_g"], 4)} g rms, '
                      f'{" .. ".join(_fmt(x) for x in r["psd_frequencies_hz"])} Hz at '
                      f'{", ".join(_fmt(x, 3) for x in r["psd_values_g2_per_hz"])} g^2/Hz, '
                      f'log-log between): rectified bias '
                      f'{_fmt(r["rectified_bias_deg_per_h"], 4)} deg/h (q1 rms '
                      f'{_fmt(r["q1_rms_m"] * 1e9, 4)} nm; predicted from the sine by the mean '
                      f'square of q1: {_fmt(_per_h(r["predicted_from_sine_deg_per_s"]), 4)} '
                      f'deg/h).']
    rect = e['rectification']
    amps = ', '.join(_fmt(x, 3) for x in rect['amplitudes_g'])
    if rect['log_log_slope'] is not None:
        lines += ['', f'**Rectified bias against amplitude** ({amps} g at '
                      f'{_fmt(rect["frequency_hz"])} Hz along x): log-log slope '
                      f'{rect["log_log_slope"]:.4f} +- '
                      f'{rect["log_log_slope_standard_error"]:.1g} (local: '
                      f'{", ".join(f"{x:.4f}" for x in rect["local_slopes"])}), '
                      f'{_fmt(rect["coefficient_deg_per_s_at_1_g"] * 3600.0, 4)} deg/h at 1 g.']
    else:
        lines += ['', f'**Rectified bias against amplitude** ({amps} g at '
                      f'{_fmt(rect["frequency_hz"])} Hz along x): '
                      + ('zero at every amplitude (the mirror symmetry of a perfect ring '
                         'about x: no slope)' if rect['zero_by_symmetry'] else
                         'no power law (a shift changes sign or is not finite)') + '.']
    lines += _stops_markdown(e.get('stops'))
    return lines


def _stops_markdown(s) -> List[str]:
    """Return the sheet's shock survival with stops (:func:`_stop_shock`), [] without."""
    if s is None:
        return []
    th = s['threshold']
    tolerances = [r['tolerance_deg_per_s'] for r in
                  (s['levels'][0]['recovery'] if s['levels'] else [])]
    lines = ['', f'**Shock survival with stops** (stops at {_fmt(s["gap_m"] * 1e6, 3)} um = '
                 f'{_fmt(s["gap_m"] / s["electrode_gap_m"], 3)} d_g, {s["gap_source"]}; '
                 f'restitution {_fmt(s["restitution_ratio"], 3)}; half-sines of '
                 f'{_fmt(s["shock_duration_s"] * 1e6, 3)} us along x; noise off, the model '
                 f'readout; doc/environments.md). Largest shock without impact: closed form '
                 f'of the 1theta mode alone {_fmt(th["closed_form_linear_g"], 5)} g (linear), '
                 f'{_fmt(th["closed_form_electrostatic_g"], 5)} g (with its electrostatic '
                 f'softening); the runs ({_fmt(th["window_s"] * 1e3, 3)} ms after the shock, '
                 f'bisected): no impact at {_fmt(th["no_impact_g"], 5)} g, impacts at '
                 f'{_fmt(th["first_impact_g"], 5)} g (below the closed form: the 2theta and '
                 f'3theta deflections the electrostatic terms drive add to the 1theta peak; '
                 f'its q1 peak there {_fmt(_times(th["q1_peak_at_no_impact_m"], 1e6), 4)} um, '
                 f'closed form {_fmt(_times(th["q1_peak_closed_form_at_no_impact_m"], 1e6), 4)}'
                 f' um).', '',
             f'At {_fmt(s["rate_deg_per_s"])} deg/s, shock at {_fmt(s["shock_at_s"])} s, '
             f'{_fmt(s["record_after_s"])} s recorded after it (recovery: back within the '
             'tolerance of the same run without the shock for good; "not by the end": the '
             'record is too short to see it):', '',
             '| shock (g) | impacts | survived | ~/rate not a measurement for (s) | '
             'largest error (deg/s) | '
             + ' | '.join(f'recovery to {_fmt(tol)} deg/s (s)' for tol in tolerances)
             + ' |', '|---|---|---|---|---|' + '---|' * len(tolerances)]

    def until(value, end):
        return end if value is None else _fmt(value, 3)
    for r in s['levels']:
        lines.append(f'| {_fmt(r["peak_g"])} | {r["impact_count"]} | '
                     f'{"yes" if r["survived"] else "no: " + r["status"]} | '
                     f'{until(r["not_a_measurement_s"], "to the end")} | '
                     f'{_fmt(r["peak_error_deg_per_s"], 3)} | '
                     + ' | '.join(until(x['recovery_s'], 'not by the end')
                                  for x in r['recovery']) + ' |')
    return lines


def _times(value: Optional[float], factor: float) -> Optional[float]:
    return None if value is None else value * factor


def _per_h(deg_per_s: Optional[float]) -> Optional[float]:
    return None if deg_per_s is None else deg_per_s * 3600.0


def _jsonable(value):
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_jsonable(v) for v in value.tolist()]
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value
