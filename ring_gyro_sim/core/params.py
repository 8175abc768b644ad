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
Parameters of a run: one table, frozen dataclasses, one loader.

The single table :data:`PARAMETERS` lists every parameter once: its dotted ROS name, type,
default, unit, description, allowed range and whether a change needs a restart. The ROS node
declares its parameters from this table (``ros/parameters.py``) and the offline command line
reads the same YAML file through :func:`ring_gyro_sim.paramfile.load_yaml`, so one file drives
both.

:func:`build_config` turns a flat ``{dotted name: value}`` mapping into a :class:`SimConfig`
of frozen dataclasses grouped by concern; each dataclass validates itself in
``__post_init__`` and raises :class:`~ring_gyro_sim.core.errors.ParameterError` naming the
parameter and the reason. Everything is SI (m, s, kg, V, Hz where the name says *frequency*).

Defaults are the studied device of the paper (section 3.1, Table 1), N_R = 3, N_T = 10, with
the calibrated outer voltage (see ``config/default.yaml`` and the README for how it was
obtained).
"""

from dataclasses import dataclass, field
import math
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from ring_gyro_sim.core import structure
from ring_gyro_sim.core.errors import ParameterError

EPSILON_0 = 8.8541878128e-12
"""Vacuum permittivity, F/m."""

STANDARD_GRAVITY = 9.80665
"""Standard gravity, m/s^2 (only for conversions from g at the boundaries)."""

# Calibrated outer voltage (V), see config/default.yaml and README "Calibration": with
# N_R = 3, N_T = 10 the 1theta backbone is at 10.685 kHz at 6 um (Fig. 4: ~10.6 kHz), and a
# 10 000 g shock on top of the upper-branch drive leaves the ring free of contact at every
# drive phase (at 80 V, 3 phases in 16 pull in; the exact Fig. 4 fit, 83.5 V, pulls in from rest).
DEFAULT_OUTER_VOLTAGE = 78.0
# Drive (README "Calibration"): A_e per unit modal mass (m/s^2) at 15798.6 Hz puts the upper
# branch at q2 = 0.394 um and the lower one at 0.037 um (paper: ~0.39 um and ~0.03 um at
# 15798.3 Hz). Our upper branch ends at 15798.29 Hz: at the paper's 15798.3 Hz it is 9 mHz
# from its fold, and a 2 000 g shock knocks it down for good (Case 1 then disagrees).
DEFAULT_DRIVE_AMPLITUDE = 0.065
DEFAULT_DRIVE_FREQUENCY = 15798.6
DRIVE_START_CHOICES = ('rest', 'upper_branch', 'lower_branch')


@dataclass(frozen=True)
class ParamSpec:
    """One row of the parameter table."""

    name: str
    kind: str  # 'float', 'int', 'bool', 'str', 'float_list', 'str_list'
    default: Any
    unit: str
    description: str
    minimum: Optional[float] = None
    maximum: Optional[float] = None
    read_only: bool = True


PARAMETERS: Tuple[ParamSpec, ...] = (
    ParamSpec('modes.frequencies', 'float_list', [11200.0, 15800.0, 22000.0], 'Hz',
              'natural frequency of each n-theta mode, n = 1..N_R (length = N_R); '
              'empty = computed from ring and legs'),
    ParamSpec('modes.quality_factors', 'float_list', [120000.0, 64700.0, 170000.0], '-',
              'quality factor Q_n of each mode (same length as modes.frequencies)',
              read_only=False),
    ParamSpec('modes.count', 'int', 0, '-',
              'number of modes N_R when modes.frequencies is empty (0 = use its length)', 0, 20),
    ParamSpec('modes.companions', 'bool', False, '-',
              'also simulate the sin(n theta) companion coordinates q_n^s'),
    ParamSpec('modes.companion_frequencies', 'float_list', [], 'Hz',
              'frequencies of the companions (empty = same as modes.frequencies)'),
    ParamSpec('modes.companion_quality_factors', 'float_list', [], '-',
              'Q of the companions (empty = same as modes.quality_factors)', read_only=False),
    ParamSpec('ring.radius', 'float', 1.5e-3, 'm', 'mean ring radius r', 0.0),
    ParamSpec('ring.thickness', 'float', 18e-6, 'm', 'radial thickness h', 0.0),
    ParamSpec('ring.length', 'float', 150e-6, 'm', 'axial length l', 0.0),
    ParamSpec('ring.youngs_modulus', 'float', 150e9, 'Pa', 'Young modulus E', 0.0),
    ParamSpec('ring.density', 'float', 2330.0, 'kg/m^3', 'density rho', 0.0),
    ParamSpec('legs.count', 'int', 8, '-', 'number of (pairs of) support legs N_l', 0, 64),
    ParamSpec('legs.angle', 'float', 0.0, 'rad', 'angle alpha of the last leg'),
    ParamSpec('legs.mass', 'float', 0.0, 'kg',
              'point mass m_l of one leg (0 = neglected in the modal masses, as the paper)', 0.0),
    ParamSpec('legs.radial_stiffness', 'float', 0.0, 'N/m',
              'radial stiffness k_r of one leg (used only when modes.frequencies is empty)', 0.0),
    ParamSpec('legs.tangential_stiffness', 'float', 0.0, 'N/m',
              'tangential stiffness k_t of one leg (used only when modes.frequencies is empty)',
              0.0),
    ParamSpec('electrodes.outer_voltage', 'float', DEFAULT_OUTER_VOLTAGE, 'V',
              'outer electrode bias V_o', read_only=False),
    ParamSpec('electrodes.inner_voltage', 'float', 0.0, 'V', 'inner electrode bias V_i',
              read_only=False),
    ParamSpec('electrodes.gap', 'float', 10e-6, 'm', 'nominal electrode gap d_g', 0.0),
    ParamSpec('electrodes.outer_radius', 'float', 0.0, 'm',
              'mean radius r_o of the outer capacitors (0 = r + (h + d_g)/2)', 0.0),
    ParamSpec('electrodes.inner_radius', 'float', 0.0, 'm',
              'mean radius r_i of the inner capacitors (0 = r - (h + d_g)/2)', 0.0),
    ParamSpec('electrodes.relative_permittivity', 'float', 1.0, '-',
              'relative permittivity eps of eq. (18)', 0.0),
    ParamSpec('electrodes.taylor_terms', 'int', 10, '-',
              'N_T, order of the Taylor series of the force (0 = untruncated parallel plate)',
              0, 40),
    ParamSpec('electrodes.fold_linear_stiffness', 'bool', True, '-',
              'true: modes.frequencies already contain the linear electrostatic stiffness '
              '(paper, section 3.1); false: they are mechanical and K_c (eq. 26) is added'),
    ParamSpec('electrodes.count', 'int', 8, '-',
              'number K of outer sense electrodes (outputs e0..e{K-1})', 1, 360),
    ParamSpec('electrodes.span', 'float', 0.0, 'rad',
              'angular span of one sense electrode (0 = 2 pi / K)', 0.0, 2.0 * math.pi),
    ParamSpec('shock.duration', 'float', 0.0, 's',
              'half-sine shock duration T_s (0 = one tenth of the 2theta period)', 0.0,
              read_only=False),
    ParamSpec('drive.amplitude', 'float', DEFAULT_DRIVE_AMPLITUDE, 'm/s^2',
              'harmonic drive on the 2theta mode per unit modal mass (A_e)', read_only=False),
    ParamSpec('drive.frequency', 'float', DEFAULT_DRIVE_FREQUENCY, 'Hz', 'drive frequency',
              0.0, read_only=False),
    ParamSpec('drive.start_on', 'str', 'upper_branch', '-',
              'initial state: rest, or the periodic response to the initial drive on its '
              'upper_branch or lower_branch (as the paper starts Cases 1-4)'),
    ParamSpec('integrator.method', 'str', 'bm6', '-',
              'splitting method: bm6 (order 6, 11 forces per step), bm4 (order 4, 6) or strang '
              '(order 2, 1); see core/kernels.py'),
    ParamSpec('integrator.max_step', 'float', 0.0, 's',
              'largest integration step (0 = automatic, see core/kernels.py)', 0.0),
    ParamSpec('real_time_factor', 'float', 1.0, '-',
              'simulated seconds per wall second (0 = as fast as possible)', 0.0,
              read_only=False),
    ParamSpec('duration', 'float', 0.0, 's',
              'stop after this much simulated time (0 = run until shut down)', 0.0),
    ParamSpec('output.rate', 'float', 200000.0, 'Hz',
              'samples per second in the published blocks (1e9 / rate must be whole ns)', 0.0),
    ParamSpec('output.block_duration', 'float', 0.01, 's',
              'simulated time covered by one published block', 0.0),
    ParamSpec('record.path', 'str', '', '-', 'MCAP file to record the run to (empty = none)'),
    ParamSpec('record.topics', 'str_list', [], '-',
              'topics a recording holds, relative names as published (e.g. modal_displacement, '
              'shock, /diagnostics); empty = all. Inputs needed to re-simulate are always kept'),
    ParamSpec('record.decimation', 'int', 1, '-',
              'record every N-th sample of the block topics (1 = every sample)', 1, 1000000),
    ParamSpec('record.compression', 'str', 'zstd', '-',
              'chunk compression of the recording: zstd, lz4 or none (as rosbag2 offers)'),
    ParamSpec('record.overwrite', 'bool', False, '-',
              'replace an existing file at record.path (false: refuse it, as rosbag2 does)'),
    ParamSpec('inputs.horizon', 'float', 60.0, 's',
              'inputs stamped further ahead of the simulation time than this are refused', 0.0,
              read_only=False),
    ParamSpec('publish_clock', 'bool', False, '-', 'publish the simulation time on /clock'),
    ParamSpec('scenario.shock_times', 'float_list', [], 's',
              'simulation times of scheduled x shocks'),
    ParamSpec('scenario.shock_peaks', 'float_list', [], 'm/s^2',
              'peak base accelerations of the scheduled shocks (same length)'),
    ParamSpec('scenario.shock_angles', 'float_list', [], 'deg',
              'direction of each scheduled shock, from x towards y (empty = all along x; '
              'else the same length as scenario.shock_times)'),
)

SPECS: Dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}


def _fail(name: str, reason: str) -> ParameterError:
    return ParameterError(f'{name}: {reason}')


def _finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise _fail(name, f'must be finite, got {value!r}')


def _positive(name: str, value: float) -> None:
    _finite(name, value)
    if value <= 0.0:
        raise _fail(name, f'must be > 0, got {value!r}')


def coerce(name: str, value: Any) -> Any:
    """
    Convert a raw YAML / ROS value to the kind of parameter ``name``.

    Integer literals are accepted for floats; ``None`` (rcl's "not set", e.g. an empty YAML
    list) gives the empty list for list parameters and the default otherwise.

    Raises
    ------
    ParameterError
        Unknown name or a value of the wrong kind.

    """
    spec = SPECS.get(name)
    if spec is None:
        raise _fail(name, 'unknown parameter')
    if value is None:
        return [] if spec.kind in ('float_list', 'str_list') else spec.default
    if spec.kind == 'float':
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(name, f'expected a number, got {value!r}')
        return float(value)
    if spec.kind == 'int':
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _fail(name, f'expected an integer, got {value!r}')
        if isinstance(value, float) and not value.is_integer():
            raise _fail(name, f'expected an integer, got {value!r}')
        return int(value)
    if spec.kind == 'bool':
        if not isinstance(value, bool):
            raise _fail(name, f'expected true or false, got {value!r}')
        return value
    if spec.kind == 'str':
        if not isinstance(value, str):
            raise _fail(name, f'expected a string, got {value!r}')
        return value
    if spec.kind == 'str_list':
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or not all(
                isinstance(item, str) for item in value):
            raise _fail(name, f'expected a list of strings, got {value!r}')
        return list(value)
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise _fail(name, f'expected a list of numbers, got {value!r}')
    out = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, (int, float)):
            raise _fail(name, f'expected a list of numbers, got element {item!r}')
        out.append(float(item))
    return out


def _check_range(spec: ParamSpec, value: Any) -> None:
    values = value if spec.kind == 'float_list' else [value]
    for v in values:
        if spec.kind in ('float', 'float_list'):
            _finite(spec.name, v)
        if spec.kind in ('float', 'int', 'float_list'):
            if spec.minimum is not None and v < spec.minimum:
                raise _fail(spec.name, f'must be >= {spec.minimum}, got {v!r}')
            if spec.maximum is not None and v > spec.maximum:
                raise _fail(spec.name, f'must be <= {spec.maximum}, got {v!r}')


@dataclass(frozen=True)
class RingParams:
    """Ring geometry and material (section 3.1), SI units."""

    radius: float = 1.5e-3
    thickness: float = 18e-6
    length: float = 150e-6
    youngs_modulus: float = 150e9
    density: float = 2330.0

    def __post_init__(self) -> None:
        for name in ('radius', 'thickness', 'length', 'youngs_modulus', 'density'):
            _positive(f'ring.{name}', getattr(self, name))

    @property
    def mass(self) -> float:
        """Physical ring mass m_r = rho 2 pi r h l, kg."""
        return self.density * 2.0 * math.pi * self.radius * self.thickness * self.length


@dataclass(frozen=True)
class LegParams:
    """Support legs (section 2.3)."""

    count: int = 8
    angle: float = 0.0
    mass: float = 0.0
    radial_stiffness: float = 0.0
    tangential_stiffness: float = 0.0

    def __post_init__(self) -> None:
        if self.count < 0:
            raise _fail('legs.count', f'must be >= 0, got {self.count}')
        _finite('legs.angle', self.angle)
        for name in ('mass', 'radial_stiffness', 'tangential_stiffness'):
            v = getattr(self, name)
            _finite(f'legs.{name}', v)
            if v < 0.0:
                raise _fail(f'legs.{name}', f'must be >= 0, got {v!r}')


@dataclass(frozen=True)
class ModeParams:
    """
    Linear modes: frequency (Hz) and Q of every coordinate.

    ``frequencies[i]`` is the (n = i + 1)-theta mode. With companions the sin(n theta)
    coordinates follow, with their own frequencies (for split pairs such as 4theta with 8 legs).
    """

    frequencies: Tuple[float, ...] = (11200.0, 15800.0, 22000.0)
    quality_factors: Tuple[float, ...] = (120000.0, 64700.0, 170000.0)
    companions: bool = False
    companion_frequencies: Tuple[float, ...] = ()
    companion_quality_factors: Tuple[float, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.frequencies)
        if n == 0:
            raise _fail('modes.frequencies', 'needs at least one mode')
        if n > 20:
            raise _fail('modes.frequencies', f'at most 20 modes are supported, got {n}')
        for f in self.frequencies:
            _positive('modes.frequencies', f)
        if len(self.quality_factors) != n:
            raise _fail('modes.quality_factors',
                        f'has {len(self.quality_factors)} values but modes.frequencies has {n}')
        for q in self.quality_factors:
            _check_q('modes.quality_factors', q)
        for name, values, check in (
                ('modes.companion_frequencies', self.companion_frequencies, _positive),
                ('modes.companion_quality_factors', self.companion_quality_factors, _check_q)):
            if values and len(values) != n:
                raise _fail(name, f'has {len(values)} values but modes.frequencies has {n}')
            for v in values:
                check(name, v)

    @property
    def count(self) -> int:
        """Ritz order N_R."""
        return len(self.frequencies)

    def coordinate_frequencies(self) -> List[float]:
        """Frequency (Hz) of every simulated coordinate, cos modes then companions."""
        f = list(self.frequencies)
        if self.companions:
            f += list(self.companion_frequencies or self.frequencies)
        return f

    def coordinate_quality_factors(self) -> List[float]:
        """Q of every simulated coordinate, cos modes then companions."""
        q = list(self.quality_factors)
        if self.companions:
            q += list(self.companion_quality_factors or self.quality_factors)
        return q


def _check_q(name: str, q: float) -> None:
    _finite(name, q)
    if q <= 0.5:
        raise _fail(name, f'must be > 0.5 (underdamped modes only), got {q!r}')


@dataclass(frozen=True)
class ElectrodeParams:
    """Electrodes and electrostatic force model (section 2.4)."""

    outer_voltage: float = DEFAULT_OUTER_VOLTAGE
    inner_voltage: float = 0.0
    gap: float = 10e-6
    outer_radius: float = 0.0
    inner_radius: float = 0.0
    relative_permittivity: float = 1.0
    taylor_terms: int = 10
    fold_linear_stiffness: bool = True
    count: int = 8
    span: float = 0.0

    def __post_init__(self) -> None:
        _finite('electrodes.outer_voltage', self.outer_voltage)
        _finite('electrodes.inner_voltage', self.inner_voltage)
        _positive('electrodes.gap', self.gap)
        for name in ('outer_radius', 'inner_radius'):
            v = getattr(self, name)
            _finite(f'electrodes.{name}', v)
            if v < 0.0:
                raise _fail(f'electrodes.{name}', f'must be >= 0 (0 = default), got {v!r}')
        _positive('electrodes.relative_permittivity', self.relative_permittivity)
        if self.taylor_terms != 0 and not 3 <= self.taylor_terms <= 40:
            raise _fail('electrodes.taylor_terms',
                        f'must be 0 (untruncated) or between 3 and 40, got {self.taylor_terms}')
        if self.count < 1:
            raise _fail('electrodes.count', f'must be >= 1, got {self.count}')
        _finite('electrodes.span', self.span)
        if not 0.0 <= self.span <= 2.0 * math.pi / self.count + 1e-12:
            raise _fail('electrodes.span',
                        f'must be between 0 and 2 pi / electrodes.count, got {self.span!r}')


@dataclass(frozen=True)
class DriveParams:
    """Harmonic drive F_ext,2 = A_e cos(2 pi f t) of the 2theta mode (section 3.4)."""

    amplitude: float = DEFAULT_DRIVE_AMPLITUDE
    frequency: float = DEFAULT_DRIVE_FREQUENCY
    start_on: str = 'upper_branch'

    def __post_init__(self) -> None:
        if self.start_on not in DRIVE_START_CHOICES:
            raise _fail('drive.start_on', f'must be one of {", ".join(DRIVE_START_CHOICES)}, '
                        f'got {self.start_on!r}')
        _finite('drive.amplitude', self.amplitude)
        _finite('drive.frequency', self.frequency)
        if self.frequency < 0.0:
            raise _fail('drive.frequency', f'must be >= 0, got {self.frequency!r}')


INTEGRATOR_METHODS = ('bm6', 'bm4', 'strang')
RECORD_COMPRESSIONS = ('zstd', 'lz4', 'none')


@dataclass(frozen=True)
class IntegratorParams:
    """Choice of the splitting method and of the largest step, s."""

    method: str = 'bm6'
    max_step: float = 0.0

    def __post_init__(self) -> None:
        if self.method not in INTEGRATOR_METHODS:
            raise _fail('integrator.method',
                        f'must be one of {", ".join(INTEGRATOR_METHODS)}, got {self.method!r}')
        _finite('integrator.max_step', self.max_step)
        if self.max_step < 0.0:
            raise _fail('integrator.max_step', f'must be >= 0, got {self.max_step!r}')


@dataclass(frozen=True)
class RunParams:
    """Pacing, output, recording and scheduled inputs."""

    real_time_factor: float = 1.0
    duration: float = 0.0
    output_rate: float = 200000.0
    block_duration: float = 0.01
    record_path: str = ''
    publish_clock: bool = False
    shock_duration: float = 0.0
    shock_times: Tuple[float, ...] = ()
    shock_peaks: Tuple[float, ...] = ()
    shock_angles: Tuple[float, ...] = ()
    record_topics: Tuple[str, ...] = ()
    record_decimation: int = 1
    record_compression: str = 'zstd'
    record_overwrite: bool = False
    input_horizon: float = 60.0

    def __post_init__(self) -> None:
        for name, v in (('real_time_factor', self.real_time_factor),
                        ('duration', self.duration), ('shock.duration', self.shock_duration)):
            _finite(name, v)
            if v < 0.0:
                raise _fail(name, f'must be >= 0, got {v!r}')
        _positive('output.rate', self.output_rate)
        period_ns = 1e9 / self.output_rate
        if abs(period_ns - round(period_ns)) > 1e-6 * period_ns or round(period_ns) < 1:
            raise _fail('output.rate',
                        f'1e9 / rate must be a whole number of ns, got rate {self.output_rate!r}')
        _positive('output.block_duration', self.block_duration)
        if self.block_duration * self.output_rate < 1.0 - 1e-9:
            raise _fail('output.block_duration', 'must hold at least one output sample')
        if len(self.shock_times) != len(self.shock_peaks):
            raise _fail('scenario.shock_peaks',
                        f'has {len(self.shock_peaks)} values but scenario.shock_times has '
                        f'{len(self.shock_times)}')
        for t in self.shock_times:
            _finite('scenario.shock_times', t)
            if t < 0.0:
                raise _fail('scenario.shock_times', f'must be >= 0, got {t!r}')
        for a in self.shock_peaks:
            _finite('scenario.shock_peaks', a)
        if self.shock_angles and len(self.shock_angles) != len(self.shock_times):
            raise _fail('scenario.shock_angles',
                        f'has {len(self.shock_angles)} values but scenario.shock_times has '
                        f'{len(self.shock_times)}')
        for a in self.shock_angles:
            _finite('scenario.shock_angles', a)
        if self.record_compression not in RECORD_COMPRESSIONS:
            raise _fail('record.compression',
                        f'must be one of {", ".join(RECORD_COMPRESSIONS)}, '
                        f'got {self.record_compression!r}')
        if self.record_decimation < 1:
            raise _fail('record.decimation', f'must be >= 1, got {self.record_decimation}')
        _finite('inputs.horizon', self.input_horizon)
        if self.input_horizon < 0.0:
            raise _fail('inputs.horizon', f'must be >= 0, got {self.input_horizon!r}')

    def scheduled_shocks(self) -> List[Tuple[int, float, float]]:
        """Return the scheduled shocks as ``(start ns, peak x, peak y)`` (m/s^2)."""
        angles = self.shock_angles or (0.0,) * len(self.shock_times)
        out = []
        for t_s, peak, deg in zip(self.shock_times, self.shock_peaks, angles):
            if deg == 0.0:
                x, y = peak, 0.0
            else:
                x, y = peak * math.cos(math.radians(deg)), peak * math.sin(math.radians(deg))
            out.append((int(round(t_s * 1e9)), x, y))
        return out

    @property
    def output_period_ns(self) -> int:
        """Output sample period, integer ns."""
        return int(round(1e9 / self.output_rate))


@dataclass(frozen=True)
class SimConfig:
    """The full resolved configuration of a run."""

    ring: RingParams = field(default_factory=RingParams)
    legs: LegParams = field(default_factory=LegParams)
    modes: ModeParams = field(default_factory=ModeParams)
    electrodes: ElectrodeParams = field(default_factory=ElectrodeParams)
    drive: DriveParams = field(default_factory=DriveParams)
    integrator: IntegratorParams = field(default_factory=IntegratorParams)
    run: RunParams = field(default_factory=RunParams)

    def __post_init__(self) -> None:
        e = self.electrodes
        if self.outer_radius <= self.ring.radius:
            raise _fail('electrodes.outer_radius',
                        f'must be larger than ring.radius, got {self.outer_radius!r}')
        if e.inner_radius and e.inner_radius >= self.ring.radius:
            raise _fail('electrodes.inner_radius',
                        f'must be smaller than ring.radius, got {e.inner_radius!r}')
        if self.drive.amplitude != 0.0 and self.modes.count < 2:
            raise _fail('drive.amplitude', 'drives the 2theta mode: needs at least 2 modes')
        # Static pull-in (linear stability): the softest coordinate must keep a positive
        # linear stiffness once the electrostatic stiffness K_c (eq. 26) is in. With
        # fold_linear_stiffness the frequencies are the electrically softened ones (the paper's
        # Table 1), so a positive frequency is already linearly stable and no voltage is refused
        # here: the mechanical stiffness implied is m omega^2 + K_c. What remains is dynamic
        # pull-in (the well narrows as V_o grows), which the Simulator reports as contact.
        for i, (f_hz, ratio) in enumerate(zip(self.modes.coordinate_frequencies(),
                                              self.electrostatic_softening_ratios())):
            if ratio >= 1.0:
                raise _fail('electrodes.outer_voltage',
                            f'at or beyond static pull-in: the electrostatic stiffness is '
                            f'{ratio:.3g} times the stiffness of coordinate {i} ({f_hz} Hz)')

    @property
    def outer_radius(self) -> float:
        """r_o, m (default r + (h + d_g) / 2)."""
        e = self.electrodes
        return e.outer_radius or self.ring.radius + 0.5 * (self.ring.thickness + e.gap)

    @property
    def inner_radius(self) -> float:
        """r_i, m (default r - (h + d_g) / 2)."""
        e = self.electrodes
        return e.inner_radius or self.ring.radius - 0.5 * (self.ring.thickness + e.gap)

    @property
    def a_eps(self) -> float:
        """A_eps = eps eps_0 l / (2 d_g) of eq. (22), F/m^... (J per V^2 per m of radius)."""
        e = self.electrodes
        return e.relative_permittivity * EPSILON_0 * self.ring.length / (2.0 * e.gap)

    def modal_masses(self) -> List[float]:
        """Generalised mass of every coordinate, kg: (m_r + N_l m_l)(n^2 + 1)/(2 n^2)."""
        total = self.ring.mass + self.legs.count * self.legs.mass
        n_modes = self.modes.count
        masses = [total * (n * n + 1.0) / (2.0 * n * n) for n in range(1, n_modes + 1)]
        return masses + (masses if self.modes.companions else [])

    def electrostatic_softening_ratios(self) -> List[float]:
        """
        Return K_c / k_mech per coordinate, eq. (26) (>= 1 means static pull-in).

        k_mech = m omega^2, or m omega^2 + K_c when the frequencies already contain K_c
        (``fold_linear_stiffness``), in which case the ratio is below 1 for any voltage.
        """
        e = self.electrodes
        kc = 2.0 * math.pi * self.a_eps * (
            self.outer_radius * e.outer_voltage ** 2
            + self.inner_radius * e.inner_voltage ** 2) / e.gap ** 2
        out = []
        for m, f in zip(self.modal_masses(), self.modes.coordinate_frequencies()):
            k_mech = m * (2.0 * math.pi * f) ** 2
            if e.fold_linear_stiffness:
                k_mech += kc  # Table 1 frequencies already include -K_c.
            out.append(kc / k_mech)
        return out

    @property
    def shock_duration_s(self) -> float:
        """Half-sine duration, s: ``shock.duration`` or one tenth of the 2theta period."""
        if self.run.shock_duration > 0.0:
            return self.run.shock_duration
        freqs = self.modes.frequencies
        f2 = freqs[1] if len(freqs) > 1 else freqs[0]
        return 0.1 / f2


def defaults() -> Dict[str, Any]:
    """Flat mapping of every parameter to its default."""
    return {p.name: (list(p.default) if isinstance(p.default, list) else p.default)
            for p in PARAMETERS}


def build_config(values: Mapping[str, Any], *, frequencies_from_legs=None) -> SimConfig:
    """
    Build and validate a :class:`SimConfig` from a flat ``{dotted name: value}`` mapping.

    Missing names take their defaults. ``modes.frequencies`` empty means: compute them from
    ring and legs (eqs. 7-17), which needs ``legs.radial_stiffness`` > 0.

    Raises
    ------
    ParameterError
        Unknown name, wrong kind, out of range, or an inconsistent set; the message starts with
        the parameter name.

    """
    flat = defaults()
    for name, raw in values.items():
        flat[name] = coerce(name, raw)
    for name, value in flat.items():
        _check_range(SPECS[name], value)
    ring = RingParams(**{k: flat[f'ring.{k}'] for k in
                         ('radius', 'thickness', 'length', 'youngs_modulus', 'density')})
    legs = LegParams(count=flat['legs.count'], angle=flat['legs.angle'], mass=flat['legs.mass'],
                     radial_stiffness=flat['legs.radial_stiffness'],
                     tangential_stiffness=flat['legs.tangential_stiffness'])
    freqs = tuple(flat['modes.frequencies'])
    if not freqs:
        freqs = _frequencies_from_structure(ring, legs, flat['modes.count'])
    modes = ModeParams(frequencies=freqs,
                       quality_factors=tuple(flat['modes.quality_factors']),
                       companions=flat['modes.companions'],
                       companion_frequencies=tuple(flat['modes.companion_frequencies']),
                       companion_quality_factors=tuple(flat['modes.companion_quality_factors']))
    electrodes = ElectrodeParams(
        outer_voltage=flat['electrodes.outer_voltage'],
        inner_voltage=flat['electrodes.inner_voltage'],
        gap=flat['electrodes.gap'], outer_radius=flat['electrodes.outer_radius'],
        inner_radius=flat['electrodes.inner_radius'],
        relative_permittivity=flat['electrodes.relative_permittivity'],
        taylor_terms=flat['electrodes.taylor_terms'],
        fold_linear_stiffness=flat['electrodes.fold_linear_stiffness'],
        count=flat['electrodes.count'], span=flat['electrodes.span'])
    drive = DriveParams(amplitude=flat['drive.amplitude'], frequency=flat['drive.frequency'],
                        start_on=flat['drive.start_on'])
    integrator = IntegratorParams(method=flat['integrator.method'],
                                  max_step=flat['integrator.max_step'])
    run = RunParams(real_time_factor=flat['real_time_factor'], duration=flat['duration'],
                    output_rate=flat['output.rate'],
                    block_duration=flat['output.block_duration'],
                    record_path=flat['record.path'], publish_clock=flat['publish_clock'],
                    shock_duration=flat['shock.duration'],
                    shock_times=tuple(flat['scenario.shock_times']),
                    shock_peaks=tuple(flat['scenario.shock_peaks']),
                    shock_angles=tuple(flat['scenario.shock_angles']),
                    record_topics=tuple(flat['record.topics']),
                    record_decimation=flat['record.decimation'],
                    record_compression=flat['record.compression'],
                    record_overwrite=flat['record.overwrite'],
                    input_horizon=flat['inputs.horizon'])
    return SimConfig(ring=ring, legs=legs, modes=modes, electrodes=electrodes, drive=drive,
                     integrator=integrator, run=run)


def _frequencies_from_structure(ring: RingParams, legs: LegParams,
                                count: int) -> Tuple[float, ...]:
    if count < 1:
        raise _fail('modes.count', 'must be >= 1 when modes.frequencies is empty')
    if legs.radial_stiffness <= 0.0:
        raise _fail('legs.radial_stiffness',
                    'must be > 0 when modes.frequencies is empty (frequencies from the legs)')
    f = structure.natural_frequencies_hz(
        count, ring.mass, ring.youngs_modulus,
        structure.second_moment_of_area(ring.thickness, ring.length), ring.radius,
        legs.count, legs.angle, legs.radial_stiffness, legs.tangential_stiffness, legs.mass)
    return tuple(float(x) for x in f[:count])  # the cosine slots (core's coordinate order)


def to_flat(config: SimConfig) -> Dict[str, Any]:
    """Return the flat ``{dotted name: value}`` mapping that rebuilds ``config`` (for metadata)."""
    c = config
    return {
        'modes.frequencies': list(c.modes.frequencies),
        'modes.quality_factors': list(c.modes.quality_factors),
        'modes.count': c.modes.count,
        'modes.companions': c.modes.companions,
        'modes.companion_frequencies': list(c.modes.companion_frequencies),
        'modes.companion_quality_factors': list(c.modes.companion_quality_factors),
        'ring.radius': c.ring.radius, 'ring.thickness': c.ring.thickness,
        'ring.length': c.ring.length, 'ring.youngs_modulus': c.ring.youngs_modulus,
        'ring.density': c.ring.density,
        'legs.count': c.legs.count, 'legs.angle': c.legs.angle, 'legs.mass': c.legs.mass,
        'legs.radial_stiffness': c.legs.radial_stiffness,
        'legs.tangential_stiffness': c.legs.tangential_stiffness,
        'electrodes.outer_voltage': c.electrodes.outer_voltage,
        'electrodes.inner_voltage': c.electrodes.inner_voltage,
        'electrodes.gap': c.electrodes.gap,
        'electrodes.outer_radius': c.electrodes.outer_radius,
        'electrodes.inner_radius': c.electrodes.inner_radius,
        'electrodes.relative_permittivity': c.electrodes.relative_permittivity,
        'electrodes.taylor_terms': c.electrodes.taylor_terms,
        'electrodes.fold_linear_stiffness': c.electrodes.fold_linear_stiffness,
        'electrodes.count': c.electrodes.count, 'electrodes.span': c.electrodes.span,
        'shock.duration': c.run.shock_duration,
        'drive.amplitude': c.drive.amplitude, 'drive.frequency': c.drive.frequency,
        'drive.start_on': c.drive.start_on,
        'integrator.method': c.integrator.method, 'integrator.max_step': c.integrator.max_step,
        'real_time_factor': c.run.real_time_factor, 'duration': c.run.duration,
        'output.rate': c.run.output_rate, 'output.block_duration': c.run.block_duration,
        'record.path': c.run.record_path, 'publish_clock': c.run.publish_clock,
        'scenario.shock_times': list(c.run.shock_times),
        'scenario.shock_peaks': list(c.run.shock_peaks),
        'scenario.shock_angles': list(c.run.shock_angles),
        'record.topics': list(c.run.record_topics),
        'record.decimation': c.run.record_decimation,
        'record.compression': c.run.record_compression,
        'record.overwrite': c.run.record_overwrite,
        'inputs.horizon': c.run.input_horizon,
    }


def flatten(tree: Mapping[str, Any], prefix: str = '') -> Dict[str, Any]:
    """Flatten nested YAML mappings into dotted names (``{'a': {'b': 1}}`` -> ``{'a.b': 1}``)."""
    out: Dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            out.update(flatten(value, name + '.'))
        else:
            out[name] = value
    return out
