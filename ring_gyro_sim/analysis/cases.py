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
The paper's time-domain cases: drive + shock (section 3.4), N_R study and inner electrodes.

Every case is a :class:`CaseSpec` (shock amplitude in g, Q_1, duration, start state, extra
parameters) run by :func:`run_case` through the one run path (:class:`~ring_gyro_sim.run.Run`)
and summarised in a :class:`CaseResult`: windowed positive envelopes of every coordinate and
of the radial displacement (decimated, :mod:`ring_gyro_sim.analysis.envelope`), the branch
the 2theta drive ends on, the time it returns to the upper branch, the smallest gap and
whether the ring touched an electrode.

Conventions
-----------
* The shock is the half-sine of eq. (32) on q_1 at t = 0 (drive phase 0), duration
  ``shock.duration`` (default one tenth of the 2theta period), peak ``A_s`` g with
  g = 9.80665 m/s^2 (converted here, the boundary). A sweep may move it: it then starts at
  ``shock_phase`` drive periods (t = phase / f_drive, exact, between samples) and points
  ``shock_angle_deg`` from x towards y (needs ``modes.companions``); 0 and 0 are the paper's.
* Branches: the upper and lower periodic responses to the drive with the ring otherwise at
  rest (q1 = q3 = 0 is invariant under the drive alone, so they do not depend on Q_1) are
  found by shooting (:func:`ring_gyro_sim.core.gyro.operating_point.forced_orbit`). The threshold
  between them is their geometric mean (0.11 um for the defaults): the q2 envelope is
  "on the upper branch" above it.
* Final values are means of the envelope over the last :data:`FINAL_WINDOW_S`; the run is
  ``settled`` when the q2 envelope varies by less than :data:`SETTLED_SPREAD` there.
* The radial displacement of Fig. 5 is ``w(theta = 0, t) = sum_n q_n`` (eq. 2, the shock
  direction); ``wmax = d_g - min gap`` is its maximum over the ring.
* Output rate: the integration step does not depend on ``output.rate`` (5 us for the
  defaults; samples at 50 and 200 kHz agree to 1e-16 m). Only the envelope does: against a
  1 MHz record of the first 0.5 s of Case 3 (q1, q2, q3 multi-frequency after the shock),
  the 1 ms envelopes differ by a median 0.08 / 0.5 / 1.1 % (q1 / q2 / q3) at 100 kHz (the
  default, :data:`DEFAULT_OUTPUT_RATE_HZ`), 0.04 / 0.03 / 0.2 % at 200 kHz and 0.2 / 3.7 /
  5 % at 50 kHz. On a branch, with q2 a single line (what decides the branch), the q2
  envelope at 100 kHz is within 2e-7 of the 1 MHz one (2e-3 at 50 kHz, below 4 samples
  per period, where the sine fit is not used).
"""

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
import json
import math
import multiprocessing
import sys
import time
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim.analysis import envelope as env
from ring_gyro_sim.analysis import plotting
from ring_gyro_sim.core.engine.full import coordinate_names, Status
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.gyro import operating_point
from ring_gyro_sim.core.params import paper_config, SimConfig, STANDARD_GRAVITY
from ring_gyro_sim.progress import Progress
from ring_gyro_sim.run import format_number, Run, Shock

FINAL_WINDOW_S = 0.2
"""Final values: mean envelope over the last 0.2 s."""
SETTLED_SPREAD = 0.05
"""Settled: (max - min) / mean of the final q2 envelope below 5 %."""
AFTER_SHOCK_S = 0.01
"""``q2_after_shock``: largest q2 envelope in the first 10 ms."""
DEFAULT_OUTPUT_RATE_HZ = 100000.0
"""Output rate of the case runs (the integration step is set apart, ``integrator.max_step``)."""
CHUNK_S = 0.05

PAPER_Q1 = 120000.0
FIVE_MODE_FREQUENCIES_HZ = (11200.0, 15800.0, 22000.0, 36300.0, 59200.0)
"""Table 1, the 4theta mode aligned with alpha = 0 (36.3 kHz), as Figs. 5-8."""
FIVE_MODE_QUALITY = (PAPER_Q1, 64700.0, 170000.0, 80000.0, 50000.0)


@dataclass(frozen=True)
class CaseSpec:
    """
    One time-domain case.

    Attributes
    ----------
    name : str
        Short identifier (``case1``, ``case4_q5000``, ``nr3``, ...).
    description : str
        One line for plots and reports.
    shock_g : float
        Half-sine peak A_s, g (9.80665 m/s^2).
    q1_quality : float or None
        Q_1 (None: from the parameters).
    duration_s : float
        Simulated time, s.
    start_on : str
        ``drive.start_on``: 'upper_branch', 'lower_branch' or 'rest'.
    overrides : tuple of (str, value)
        Further flat parameters (``electrodes.inner_voltage``, ``drive.amplitude``, ...).
    paper : str
        What the paper reports for this case.
    expected_branch : str or None
        Branch the paper ends on ('upper', 'lower'), None if not applicable.
    keep_raw_s : float
        Keep the full-rate record of the first ``keep_raw_s`` seconds (spectrogram, zooms).
    shock_phase : float
        Start of the shock in drive periods, in [0, 1) (0: t = 0, the paper's cases).
    shock_angle_deg : float
        Direction of the shock from x towards y, deg (0: along x, the paper's cases).

    """

    name: str
    description: str
    shock_g: float
    q1_quality: Optional[float]
    duration_s: float
    start_on: str = 'upper_branch'
    overrides: Tuple[Tuple[str, Any], ...] = ()
    paper: str = ''
    expected_branch: Optional[str] = None
    keep_raw_s: float = 0.0
    shock_phase: float = 0.0
    shock_angle_deg: float = 0.0

    def config(self, base: Optional[Mapping[str, Any]] = None,
               output_rate_hz: float = DEFAULT_OUTPUT_RATE_HZ) -> SimConfig:
        """
        Build the configuration of this case on top of ``base`` (flat dotted names).

        ``base`` is laid over the paper's resonator (``core.params.paper_config``), whatever
        the package's defaults; ``modes.quality_factors[0]`` is replaced by
        :attr:`q1_quality`, ``drive.start_on`` and ``output.rate`` are set; :attr:`overrides`
        win over ``base``.
        """
        flat = dict(base or {})
        flat.update(dict(self.overrides))
        flat['drive.start_on'] = self.start_on
        flat['output.rate'] = float(output_rate_hz)
        cfg = paper_config(flat)
        if self.q1_quality is not None:
            qf = list(cfg.modes.quality_factors)
            qf[0] = float(self.q1_quality)
            flat['modes.quality_factors'] = qf
            cfg = paper_config(flat)
        return cfg


def paper_cases(duration_scale: float = 1.0) -> Dict[str, CaseSpec]:
    """
    Cases 1-3 of section 3.4 (Figs. 10-12) and the inner-electrode cases (Figs. 14-15).

    Parameters
    ----------
    duration_scale : float
        Multiplies every duration (``< 1`` for quick runs that cannot decide the branch).

    """
    s = float(duration_scale)
    return {
        'case1': CaseSpec('case1', 'Case 1: A_s = 2 000 g, Q_1 = 120 000', 2000.0, 120000.0,
                          24.0 * s, paper='q2 back on the upper branch after about 7 s',
                          expected_branch='upper'),
        'case2': CaseSpec('case2', 'Case 2: A_s = 10 000 g, Q_1 = 120 000', 10000.0,
                          120000.0, 30.0 * s,
                          paper='q2 falls to about 0.03 um (lower branch) for about 5 s, '
                                'then returns to the upper branch as q1 decays',
                          expected_branch='upper'),
        'case3': CaseSpec('case3', 'Case 3: A_s = 10 000 g, Q_1 = 40 000', 10000.0, 40000.0,
                          20.0 * s, paper='q2 jumps to the lower branch and stays there',
                          expected_branch='lower'),
    }


def symmetric_inner_voltage(config: SimConfig) -> float:
    """
    Inner voltage V_i, V, with ``r_i V_i^2 = r_o V_o^2`` (eq. 36: no even-order terms).

    Radii from :attr:`SimConfig.outer_radius` / :attr:`SimConfig.inner_radius` (m).
    """
    return config.electrodes.outer_voltage * math.sqrt(config.outer_radius / config.inner_radius)


def inner_electrode_cases(base: Optional[Mapping[str, Any]] = None,
                          duration_scale: float = 1.0) -> Dict[str, CaseSpec]:
    """
    Symmetric inner + outer electrodes (section 3.5): Fig. 14 (rest) and Fig. 15 (drive).

    ``electrodes.inner_voltage`` is set by :func:`symmetric_inner_voltage` for the
    configuration ``base``; the shock is 10 000 g, Q_1 from the parameters.
    """
    cfg = paper_config(base)
    vi = symmetric_inner_voltage(cfg)
    s = float(duration_scale)
    return {
        'symmetric_rest': CaseSpec(
            'symmetric_rest', f'Inner + outer electrodes (V_i = {vi:.2f} V), 10 000 g from rest',
            10000.0, None, 2.0 * s, start_on='rest',
            overrides=(('electrodes.inner_voltage', vi), ('drive.amplitude', 0.0)),
            paper='q2 = 0 for all t (Fig. 14)'),
        'symmetric_drive': CaseSpec(
            'symmetric_drive', f'Inner + outer electrodes (V_i = {vi:.2f} V), drive on, '
                               '10 000 g', 10000.0, None, 20.0 * s,
            overrides=(('electrodes.inner_voltage', vi),),
            paper='q2 varies and jumps as in Fig. 13; q1 -> q3 energy transfer near 0.1 s '
                  '(Fig. 15)'),
    }


def case4_specs(q1_values: Sequence[float] = (5000.0, 20000.0, 40000.0, 80000.0, 120000.0,
                                              180000.0),
                duration_s: float = 30.0) -> List[CaseSpec]:
    """Case 4 (Fig. 13): 10 000 g for each Q_1 of ``q1_values``."""
    return [CaseSpec(f'case4_q{int(q)}', f'Case 4: A_s = 10 000 g, Q_1 = {q:g}', 10000.0,
                     float(q), float(duration_s),
                     paper='low Q_1 ends on the lower branch, high Q_1 returns to the upper')
            for q in q1_values]


def ritz_order_specs(orders: Sequence[int] = (1, 2, 3, 4, 5), duration_s: float = 2.0,
                     keep_raw_s: float = 0.0) -> List[CaseSpec]:
    """
    Fig. 5: 10 000 g from rest, no drive, N_R = 1..5 (Table 1 frequencies and Q).

    The modes beyond N_R are dropped; the 4theta mode is the 36.3 kHz one (alpha = 0).
    """
    specs = []
    for n in orders:
        if not 1 <= int(n) <= len(FIVE_MODE_FREQUENCIES_HZ):
            raise ValueError(f'orders: N_R must be in 1..5, got {n!r}')
        n = int(n)
        specs.append(CaseSpec(
            f'nr{n}', f'N_R = {n}, 10 000 g from rest', 10000.0, None, float(duration_s),
            start_on='rest',
            overrides=(('modes.frequencies', list(FIVE_MODE_FREQUENCIES_HZ[:n])),
                       ('modes.quality_factors', list(FIVE_MODE_QUALITY[:n])),
                       ('drive.amplitude', 0.0)),
            paper='radial displacement envelope converged with N_R = 3 (Fig. 5)',
            keep_raw_s=keep_raw_s))
    return specs


@dataclass(frozen=True)
class Branches:
    """
    Amplitudes of the periodic responses to the drive alone (Fig. 9), m.

    Attributes
    ----------
    upper_m, lower_m : float
        max |q2| over a period on each branch (nan when that branch was not found).
    threshold_m : float
        Boundary used to classify the q2 envelope (geometric mean, or half the upper).

    """

    upper_m: float
    lower_m: float
    threshold_m: float

    def classify(self, q2_m: float) -> str:
        """Return 'upper' or 'lower' for a q2 envelope value (m)."""
        return 'upper' if q2_m >= self.threshold_m else 'lower'


def drive_branches(config: SimConfig) -> Optional[Branches]:
    """
    Upper and lower branch amplitudes of q2 at the drive of ``config`` (None: no drive).

    Shooting from ``A_e Q_2 / (omega omega_2)`` (upper) and a tenth of it (lower), as
    ``drive.start_on``; an orbit that is not stable does not count as a branch.
    """
    d = config.drive
    if d.amplitude == 0.0 or d.frequency == 0.0 or config.modes.count < 2:
        return None
    w2 = 2.0 * math.pi * config.modes.coordinate_frequencies()[1]
    w = 2.0 * math.pi * d.frequency
    peak = abs(d.amplitude) * config.modes.coordinate_quality_factors()[1] / (w * w2)
    found = []
    for guess in (peak, 0.1 * peak):
        try:
            orbit = operating_point.forced_orbit(config, d.frequency, guess, d.amplitude)
        except SimulationError:
            found.append(math.nan)
            continue
        found.append(float(orbit.amplitude_m[1]) if orbit.stable else math.nan)
    upper, lower = found
    if math.isfinite(upper) and math.isfinite(lower) and upper > 1.5 * lower:
        threshold = math.sqrt(upper * lower)
    elif math.isfinite(upper):
        lower = math.nan if not math.isfinite(lower) or lower > 0.67 * upper else lower
        threshold = 0.5 * upper
    else:
        threshold = 0.5 * lower if math.isfinite(lower) else math.nan
    return Branches(upper_m=upper, lower_m=lower, threshold_m=threshold)


@dataclass(frozen=True)
class DriveSetup:
    """
    What a case computes before it runs: the drive branches and the drive's orbit.

    Both depend on the configuration only (shooting, about 1.5 s): :func:`drive_setup`
    computes them, a caller that runs many cases on one configuration (a sweep over the
    shock, on several workers) may compute them once and pass them to :func:`run_case`.

    Attributes
    ----------
    branches : Branches or None
        :func:`drive_branches` of the configuration.
    orbit : (ndarray, ndarray) or None
        ``(q m, v m/s)`` of the resting sensor on ``drive.start_on``
        (``core.gyro.operating_point.resting_orbit``; None: rest), which the case's ``Run``
        starts from.

    """

    branches: Optional[Branches]
    orbit: Optional[Tuple[np.ndarray, np.ndarray]]


def drive_setup(config: SimConfig) -> DriveSetup:
    """Return the :class:`DriveSetup` of ``config`` (branches, then the drive's orbit)."""
    return DriveSetup(branches=drive_branches(config),
                      orbit=operating_point.resting_orbit(config))


def envelope_channels(config: SimConfig) -> List[str]:
    """Return the envelope channels of a case run: the coordinates, then ``w0``, ``wmax``."""
    return coordinate_names(config) + ['w0', 'wmax']


def shock_input(spec: CaseSpec, config: SimConfig) -> Shock:
    """
    Return the shock of ``spec`` for the run: m/s^2 along x and y, start time in ns.

    ``shock_phase`` p starts it at ``round(p / f_drive)`` (ns); p = 0 is t = 0.

    Raises
    ------
    ValueError
        ``shock_phase`` outside [0, 1), or not 0 without a drive frequency.

    """
    phase = float(spec.shock_phase)
    if not 0.0 <= phase < 1.0:
        raise ValueError(f'shock_phase: must be in [0, 1) drive periods, got {phase!r}')
    at_ns = None
    if phase:
        if config.drive.frequency <= 0.0:
            raise ValueError('shock_phase: needs a drive frequency (drive.frequency > 0)')
        at_ns = int(round(phase / config.drive.frequency * 1e9))
    peak = spec.shock_g * STANDARD_GRAVITY
    angle = math.radians(float(spec.shock_angle_deg))
    if angle:
        return Shock(peak * math.cos(angle), peak * math.sin(angle), at_ns=at_ns)
    return Shock(peak, at_ns=at_ns)


@dataclass
class CaseResult:
    """
    Outcome of one case (SI units; ``*_m`` metres, ``*_s`` seconds).

    Attributes
    ----------
    spec : CaseSpec
        The case.
    envelope : Envelope
        Windowed positive envelopes, channels ``q1..qN``, ``w0`` (sum of q_n) and ``wmax``
        (d_g - min gap), m.
    branches : Branches or None
        Drive branches (None without drive).
    gap_m : float
        Nominal gap d_g, m.
    min_gap_m : float
        Smallest outer gap over the run, m.
    contact : bool
        The ring touched an electrode (or the series left its range); the run stopped there.
    status, message : str
        Simulator status and its message.
    contact_time_s : float
        Time of the contact, s (nan without contact).
    contact_theta_rad : float
        Where the ring touched: angle from x, rad (nan without contact).
    sim_time_s, wall_time_s : float
        Simulated and wall-clock time, s.
    raw_t, raw_q : ndarray or None
        Full-rate record of the first ``spec.keep_raw_s`` s (times s, coordinates m).
    sample_rate_hz : float
        Output rate of the run, Hz.
    numbers : dict
        The key numbers (see :meth:`summary`).

    """

    spec: CaseSpec
    envelope: env.Envelope
    branches: Optional[Branches]
    gap_m: float
    min_gap_m: float
    contact: bool
    status: str
    message: str
    contact_time_s: float
    sim_time_s: float
    wall_time_s: float
    sample_rate_hz: float
    contact_theta_rad: float = math.nan
    raw_t: Optional[np.ndarray] = None
    raw_q: Optional[np.ndarray] = None
    numbers: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.numbers:
            self.numbers = _key_numbers(self)

    @property
    def final_branch(self) -> Optional[str]:
        """'upper', 'lower', 'contact' or None (no drive)."""
        return self.numbers.get('final_branch')

    @property
    def final_q2_m(self) -> float:
        """Mean q2 envelope over the last :data:`FINAL_WINDOW_S`, m."""
        return self.numbers.get('final_q2_m', math.nan)

    def summary(self) -> Dict[str, Any]:
        """Key numbers and the case definition, JSON-ready (nan -> None)."""
        out = {'name': self.spec.name, 'description': self.spec.description,
               'shock_g': self.spec.shock_g, 'q1_quality': self.spec.q1_quality,
               'duration_s': self.spec.duration_s, 'paper': self.spec.paper,
               'expected_branch': self.spec.expected_branch}
        out.update(self.numbers)
        return {k: _jsonable(v) for k, v in out.items()}

    def to_csv(self, path) -> None:
        """Write the envelopes: ``t_s`` then one column per channel (m)."""
        e = self.envelope
        header = ','.join(['t_s'] + [f'{n}_m' for n in e.names])
        np.savetxt(path, np.column_stack([e.t, e.values]), delimiter=',', header=header,
                   comments='', fmt='%.9g')

    def to_json(self) -> str:
        """Return the :meth:`summary` as one JSON object."""
        return json.dumps(self.summary(), sort_keys=True)

    def plot(self, path, **kwargs) -> None:
        """Save the envelopes (Figs. 10-12, 14-15) to ``path``; see ``plotting``."""
        plotting.plot_case(self, path, **kwargs)


def _jsonable(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (np.floating, np.integer)):
        return _jsonable(v.item())
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _key_numbers(r: CaseResult) -> Dict[str, Any]:
    """Numbers of a run from its envelope (definitions in the module docstring)."""
    e = r.envelope
    out: Dict[str, Any] = {'contact': r.contact, 'status': r.status, 'message': r.message,
                           'contact_time_s': r.contact_time_s,
                           'contact_theta_deg': math.degrees(r.contact_theta_rad),
                           'min_gap_m': r.min_gap_m,
                           'min_gap_fraction': r.min_gap_m / r.gap_m,
                           'sim_time_s': r.sim_time_s, 'wall_time_s': r.wall_time_s,
                           'final_branch': 'contact' if r.contact else None}
    if e.t.size == 0:
        return out
    t_end = e.t[-1]
    final = (e.t >= t_end - FINAL_WINDOW_S)
    for name in e.names:
        x = e.channel(name)
        out[f'peak_{name}_m'] = float(np.max(x))
        out[f'final_{name}_m'] = float(np.mean(x[final]))
    out['peak_w0_fraction'] = out['peak_w0_m'] / r.gap_m
    out['peak_wmax_fraction'] = out['peak_wmax_m'] / r.gap_m
    if 'q2' not in e.names:
        return out
    q2 = e.channel('q2')
    early = e.t <= AFTER_SHOCK_S
    out['q2_after_shock_m'] = float(np.max(q2[early])) if np.any(early) else math.nan
    i_min = int(np.argmin(q2))
    out['min_q2_m'] = float(q2[i_min])
    out['min_q2_time_s'] = float(e.t[i_min])
    tail = q2[final]
    spread = float((tail.max() - tail.min()) / max(tail.mean(), 1e-30))
    out['final_q2_spread'] = spread
    out['settled'] = bool(spread < SETTLED_SPREAD and not r.contact)
    out['final_q1_over_peak'] = out['final_q1_m'] / max(out['peak_q1_m'], 1e-30)
    b = r.branches
    if b is None:
        out['final_branch'] = 'contact' if r.contact else None
        return out
    out['upper_branch_m'] = b.upper_m
    out['lower_branch_m'] = b.lower_m
    out['threshold_m'] = b.threshold_m
    below = q2 < b.threshold_m
    out['left_upper'] = bool(np.any(below))
    out['time_below_threshold_s'] = float(np.count_nonzero(below) * e.window_s)
    if r.contact:
        out['final_branch'] = 'contact'
    else:
        out['final_branch'] = b.classify(out['final_q2_m'])
    out['return_time_s'] = math.nan
    if out['final_branch'] == 'upper' and out['left_upper']:
        last_below = int(np.flatnonzero(below)[-1])
        out['return_time_s'] = float(e.t[min(last_below + 1, e.t.size - 1)])
    # last time the q2 envelope was more than 5 % away from its final value
    off = np.abs(q2 - out['final_q2_m']) > SETTLED_SPREAD * out['final_q2_m']
    out['settle_time_s'] = float(e.t[np.flatnonzero(off)[-1]]) if np.any(off) else 0.0
    for t_probe in (0.1, 1.0, 3.0, 5.0, 7.0, 10.0):
        if t_probe <= t_end:
            out[f'q2_at_{t_probe:g}s_m'] = float(q2[np.searchsorted(e.t, t_probe)
                                                    if t_probe < t_end else -1])
    return out


def run_case(spec: CaseSpec, base: Optional[Mapping[str, Any]] = None,
             output_rate_hz: float = DEFAULT_OUTPUT_RATE_HZ,
             window_s: float = env.DEFAULT_WINDOW_S, progress: bool = True,
             setup: Optional[DriveSetup] = None) -> CaseResult:
    """
    Run one case and return its envelopes and numbers.

    Parameters
    ----------
    spec : CaseSpec
        The case.
    base : mapping, optional
        Flat parameters under the case (default: the package defaults).
    output_rate_hz : float
        Sampling rate of the envelope input, Hz (the integration step does not depend on
        it; it must resolve the fastest mode, > 2 f_max).
    window_s : float
        Envelope window, s.
    progress : bool
        Print a progress line on stderr every few wall seconds.
    setup : DriveSetup, optional
        :func:`drive_setup` of this case's configuration, computed before (None: here).

    Returns
    -------
    CaseResult

    """
    config = spec.config(base, output_rate_hz)
    f_max = max(config.modes.coordinate_frequencies())
    if output_rate_hz <= 2.0 * f_max:
        raise ValueError(f'output_rate_hz: must exceed twice the fastest mode '
                         f'({2.0 * f_max:.0f} Hz), got {output_rate_hz!r}')
    shock = shock_input(spec, config)
    if setup is None:
        setup = drive_setup(config)
    else:  # computed elsewhere (a sweep's setup task): the run here starts from it
        operating_point.remember_orbit(config, setup.orbit)
    branches = setup.branches
    run = Run(config)
    sim = run.full_model()
    if spec.shock_g:
        run.apply(shock)
    acc = env.StreamingEnvelope(1.0 / sim.period_s, envelope_channels(config), window_s,
                                t0_s=sim.time_s)
    gap = config.electrodes.gap
    cos_cols = [i for i, n in enumerate(sim.coordinates) if not n.endswith('s')]
    min_gap = math.inf
    raw_t: List[np.ndarray] = []
    raw_q: List[np.ndarray] = []
    bar = Progress(spec.duration_s, progress, name=spec.name)
    wall0 = time.perf_counter()
    n_total = int(round(spec.duration_s / sim.period_s))
    chunk = max(1, int(round(CHUNK_S / sim.period_s)))
    done = 0
    contact_time = math.nan
    contact_theta = math.nan
    while done < n_total:
        size = min(chunk, n_total - done)
        s = run.advance(size).samples
        done += size
        if sim.status != Status.RUNNING:
            keep = s.t < sim.contact_time_s if math.isfinite(sim.contact_time_s) else \
                np.ones(len(s), bool)
            s = replace(s, t=s.t[keep], q=s.q[keep], v=s.v[keep], gap=s.gap[keep],
                        min_gap=s.min_gap[keep], capacitance=s.capacitance[keep])
            contact_time = sim.contact_time_s
            contact_theta = sim.contact_theta_rad
        if len(s):
            w0 = np.sum(s.q[:, cos_cols], axis=1)
            acc.add(np.column_stack([s.q, w0, gap - s.min_gap]))
            min_gap = min(min_gap, float(np.min(s.min_gap)))
            if s.t[0] < spec.keep_raw_s:
                sel = s.t < spec.keep_raw_s
                raw_t.append(s.t[sel])
                raw_q.append(s.q[sel])
            amps = np.max(np.abs(s.q), axis=0)
            bar.update(sim.time_s, 'um: ' + ' '.join(format_number(a, 1e6, 3) for a in amps))
        if sim.status != Status.RUNNING:
            min_gap = 0.0
            break
    wall = time.perf_counter() - wall0
    bar.close()
    result = CaseResult(
        spec=spec, envelope=acc.result(), branches=branches, gap_m=gap, min_gap_m=min_gap,
        contact=sim.status != Status.RUNNING, status=sim.status, message=sim.message,
        contact_time_s=contact_time, contact_theta_rad=contact_theta, sim_time_s=sim.time_s,
        wall_time_s=wall,
        sample_rate_hz=1.0 / sim.period_s,
        raw_t=np.concatenate(raw_t) if raw_t else None,
        raw_q=np.concatenate(raw_q) if raw_q else None)
    if progress:
        n = result.numbers
        sys.stderr.write(f'[{spec.name}] done: {sim.time_s:.2f} s simulated in {wall:.1f} s, '
                         f'final q2 {format_number(n.get("final_q2_m", math.nan), 1e6)} um '
                         f'({n.get("final_branch")}), min gap '
                         f'{format_number(min_gap, 1e6, 3)} um'
                         f'{", CONTACT" if result.contact else ""}\n')
    return result


def _run_one(args):
    spec, base, rate, window, progress = args
    return run_case(spec, base, rate, window, progress)


def run_cases(specs: Sequence[CaseSpec], base: Optional[Mapping[str, Any]] = None,
              output_rate_hz: float = DEFAULT_OUTPUT_RATE_HZ,
              window_s: float = env.DEFAULT_WINDOW_S, workers: int = 2,
              progress: bool = True) -> List[CaseResult]:
    """
    Run several cases, in parallel processes when ``workers > 1`` (Case 4 sweep).

    The processes are started with 'spawn' (no state shared with the caller); the results
    come back in the order of ``specs``.
    """
    jobs = [(spec, dict(base or {}), output_rate_hz, window_s, progress) for spec in specs]
    if workers <= 1 or len(jobs) <= 1:
        return [_run_one(j) for j in jobs]
    ctx = multiprocessing.get_context('spawn')
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx) as pool:
        return list(pool.map(_run_one, jobs))


def case_table(results: Sequence[CaseResult]) -> List[Dict[str, Any]]:
    """One JSON-ready row of key numbers per result."""
    return [r.summary() for r in results]


__all__ = ['Branches', 'CaseResult', 'CaseSpec', 'DriveSetup', 'case4_specs', 'case_table',
           'drive_branches', 'drive_setup', 'envelope_channels', 'inner_electrode_cases',
           'paper_cases', 'ritz_order_specs', 'run_case', 'run_cases', 'shock_input',
           'symmetric_inner_voltage']
