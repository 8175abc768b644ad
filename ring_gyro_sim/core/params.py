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
Parameters of a run: one table, frozen dataclasses generated from it, one loader.

The table :data:`PARAMETERS` is the single source: each row gives a parameter's dotted ROS
name, the dataclass field it fills (``field``, e.g. ``'run.record_path'``), its kind, default,
unit, description, allowed range with the reason for it, the allowed choices and whether a
change needs a restart. From the rows come

* the defaults of the dataclasses (:class:`RingParams`, ..., :class:`RunParams`; each class
  only lists its field names and types, :func:`_parameter_group` fills in the defaults and
  refuses a class field no row fills, or a row whose field does not exist);
* the per-value checks (finite, range, choices), run by each dataclass's ``__post_init__``;
  a class adds only what one row cannot say (list lengths, span vs count, ...), and
  :class:`SimConfig` the checks across groups (static pull-in, memory of a block);
* :func:`build_config` (flat ``{dotted name: value}`` -> :class:`SimConfig`) and
  :func:`to_flat` (its inverse: ``build_config(to_flat(c)) == c``);
* the ROS parameter descriptors (``ros/parameters.py``).

Every check raises :class:`~ring_gyro_sim.core.errors.ParameterError` with the text
``'<dotted name>: <reason>'``. Everything is SI (m, s, kg, V, Hz where the name says
*frequency*). The ROS node declares its parameters from the table and ``ring_gyro run`` reads
the same YAML file through :func:`ring_gyro_sim.paramfile.check_params_file`, so one file
drives both with one verdict.

Physical limits (see each row's ``range_note``)
    * ``electrodes.outer_voltage`` / ``inner_voltage``: the electrostatic stiffness
      ``K_c = 2 pi A_eps (r_o V_o^2 + r_i V_i^2) / d_g^2`` (eq. 26) must stay below the
      stiffness ``m_i omega_i^2`` of every coordinate (:meth:`SimConfig.voltage_limits`).
      With mechanical frequencies (``fold_linear_stiffness: false``) that is static pull-in.
      With the paper's softened frequencies (the default) it is the static pull-in voltage of
      the same ring with its frequencies taken as mechanical: beyond it the folded model
      stands for a ring more than half of whose mechanical stiffness the bias cancels, and
      the rest state's escape displacement along q1 shrinks like ``d_g sqrt(m omega^2 / K_c)``
      (default device, untruncated force: 0.87 d_g at the calibrated 78 V, 0.61 d_g at the
      limit, 0.17 d_g at 1 kV, 2 nm at 1 MV). Default device: |V_o| <= 215.6 V (V_i = 0),
      |V_i| <= 217.6 V (V_o = 0); the calibrated 78 V is at K_c / (m_1 omega_1^2) = 0.13.
    * ``output.rate`` <= 10 MHz, ``output.block_duration`` <= 1 s and at most
      :data:`MAX_BLOCK_BYTES` of block messages per block: see :data:`MAX_BLOCK_BYTES`.
    * times (``duration``, ``scenario.shock_times``, ``inputs.horizon``) <=
      :data:`MAX_TIME_S`: ROS stamps (``builtin_interfaces/Time.sec``) are int32.
    * accelerations (shock peaks, base-acceleration samples, the drive force per unit mass and
      its limit): at most :data:`MAX_ACCELERATION` (10^6 g), beyond any shock a ring
      survives and within what the arithmetic of a contact holds.
    * the angular rate of the sensor frame (``scenario.rate_values``, ``~/angular_rate``):
      |Omega| <= :data:`MAX_RATE_FRACTION` of the lowest coordinate's angular frequency
      (:meth:`SimConfig.max_input_rate`; 703.7 rad/s = 40 320 deg/s on the default device),
      the range in which the model of the rotating ring holds (:data:`MAX_RATE_FRACTION`).
      It is the model's range, not the sensor's: the rate output's full scale
      (``gyro.range``, where ``~/rate`` saturates) is a property of the electronics,
      hundreds to thousands of deg/s, and a rate between the two is simulated while the
      output saturates.

Defaults are **the gyroscope**: the studied device of the paper (section 3.1, Table 1),
N_R = 3, N_T = 10, with the calibrated outer voltage and drive (``doc/calibration.md``), its sine
companions (the sense mode is the sin 2theta companion), the sense electronics and the closed
loops the paper calls for (section 3.4): a PLL and an AGC hold the drive on its backbone at the
paper's amplitude (q2 = 0.39 um), force-to-rebalance holds the sense mode at zero and gives the
rate (``config/default.yaml`` says why this operating point). :data:`PAPER_RESONATOR` (and
``config/paper.yaml``) is the paper's resonator as the paper runs it: no companions, no
gyroscope, the drive open loop.
"""

from dataclasses import dataclass, field, fields
import math
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim.core import structure, vibration
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro.modes import MODES
import scipy.constants

EPSILON_0 = 8.8541878128e-12
"""Vacuum permittivity, F/m."""

BOLTZMANN = scipy.constants.k
"""Boltzmann constant, J/K (exact since SI 2019; ``scipy.constants``)."""

STANDARD_GRAVITY = 9.80665
"""Standard gravity, m/s^2 (only for conversions from g at the boundaries)."""

# Calibrated outer voltage (V), see config/default.yaml and doc/calibration.md: with
# N_R = 3, N_T = 10 the 1theta backbone is at 10.685 kHz at 6 um (Fig. 4: ~10.6 kHz), and a
# 10 000 g shock on top of the upper-branch drive leaves the ring free of contact at every
# drive phase (at 80 V, 3 phases in 16 pull in; the exact Fig. 4 fit, 83.5 V, pulls in from rest).
DEFAULT_OUTER_VOLTAGE = 78.0
# Drive (doc/calibration.md): A_e per unit modal mass (m/s^2) at 15798.6 Hz puts the upper
# branch at q2 = 0.394 um and the lower one at 0.037 um (paper: ~0.39 um and ~0.03 um at
# 15798.3 Hz). Our upper branch ends at 15798.29 Hz: at the paper's 15798.3 Hz it is 9 mHz
# from its fold, and a 2 000 g shock knocks it down for good (Case 1 then disagrees).
DEFAULT_DRIVE_AMPLITUDE = 0.065
DEFAULT_DRIVE_FREQUENCY = 15798.6
PAPER_RESONATOR: Dict[str, Any] = {
    'modes.companions': False,
    'gyro.enabled': False,
    'control.mode': 'open_loop',
}
"""
What the paper's resonator sets over the defaults (``config/paper.yaml``): the cos modes only,
no rotation or electronics, the 2theta drive open loop at ``drive.amplitude`` and
``drive.frequency`` (section 3.4). Everything that reproduces the paper starts from it
(:func:`paper_config`).
"""
DRIVE_START_CHOICES = ('rest', 'upper_branch', 'lower_branch')
INTEGRATOR_METHODS = ('bm6', 'bm4', 'strang')
FIDELITIES = ('auto', 'full', 'averaged')
"""``integrator.fidelity``: which model the offline analyses may run (doc/averaged.md)."""
RECORD_COMPRESSIONS = ('zstd', 'lz4', 'none')

MAX_MODES = 20
"""Largest Ritz order N_R the kernels support."""
MAX_ACCELERATION = 1e6 * STANDARD_GRAVITY
"""
Largest base acceleration or drive force per unit modal mass, m/s^2 (10^6 g): a shock's
peak (``~/shock``, ``scenario.shock_peaks``: the magnitude of x and y), a
``~/base_acceleration`` sample, ``drive.amplitude`` and ``~/drive/amplitude``,
``control.drive_limit``.

A tenth of it already closes the default device's gap (10^5 g: contact within the pulse), no
MEMS die survives it and no shock machine makes it; up to it the ring that touches is held
within 2 d_g of rest, so contact stays a defined state with finite numbers. Far beyond it the
arithmetic overflows (1.7e308 m/s^2: a held displacement of 3e292 m and non-finite gaps).
"""
MAX_RANDOM_RMS = 1e5 * STANDARD_GRAVITY
"""
Largest rms of a random vibration (``scenario.vibration_psd_*``), m/s^2 (10^5 g): a
multisine of thousands of lines peaks at 4-5 times its rms, so its peaks stay within
:data:`MAX_ACCELERATION`.
"""
MAX_RATE_FRACTION = 0.01
"""
Largest angular rate of the sensor frame, as a fraction of the lowest coordinate's angular
frequency (:meth:`SimConfig.max_input_rate`).

The rotating-frame terms (``core/structure.py``, G1-G6: gyroscopic, centrifugal,
angular-acceleration) are exact for the inextensible ring of the model, but the model leaves
out what grows with ``(Omega / omega)^2``: the hoop tension of a spinning ring stiffens its
bending modes by about ``n^2 (n^2 - 1) / (n^2 + 1) (Omega / omega_n)^2`` of their stiffness,
and the modal truncation ignores the extension the centrifugal load causes. At 1 % of the
lowest mode these stay below 3e-4 of a mode's stiffness. Far beyond, the equations are those of
no physical ring: 1e6 rad/s drives the default device into contact within 30 us, which no
``~/reset`` undoes while the rate is in force.
"""
MAX_TIME_S = float(2 ** 31 - 1)
"""Latest simulation time, s: ``builtin_interfaces/Time.sec`` is int32 (68 years)."""
MAX_OUTPUT_RATE_HZ = 1e7
"""
Highest ``output.rate``, Hz (period 100 ns).

450 samples per period of the paper's fastest mode (22 kHz) and 10x the bandwidth of any
sense electronics a 10-100 kHz ring gyroscope has; every sample costs at least one
integration step and ``8 (4 + n + 2 K)`` bytes of messages, so a higher rate only costs.
"""
MAX_BLOCK_DURATION_S = 1.0
"""
Longest ``output.block_duration``, s.

A block is published once its last sample time is reached, so its first sample is
``block_duration`` old when it goes out, inputs stamped up to one block in the past are
accepted as late arrivals, and a stop waits for the block boundary: 1 s is the most a live
consumer can be asked to wait (``/diagnostics`` comes at 1 Hz).
"""
MAX_BLOCK_BYTES = 4 * 2 ** 20
"""
Most bytes of the three block messages of one block (``8 (4 + n + 2 K)`` per sample).

The block publishers keep up to 50 blocks each for a slow reliable subscriber (``ros/node.py``),
so the node's memory for them stays below 50 x 4 MiB = 200 MiB whatever the rate; the default
block (2000 samples x 23 values) is 368 kB. ``output.rate: 1e9`` with 10 ms blocks (1.8 GB per
block) is refused before anything is allocated.
"""

MIN_RESOLUTION = 1e-12
"""
Finest ``gyro.resolution`` but 0 (none), rad/s.

A 32-bit output word over +-300 deg/s has an LSB of 2.4e-9 rad/s; a thousand times finer is
still above what dividing a rate by it can overflow (a subnormal LSB turns ``rate / LSB``
into infinity).
"""

LIST_KINDS = ('float_list', 'str_list')


@dataclass(frozen=True)
class ParamSpec:
    """
    One row of the parameter table.

    Attributes
    ----------
    name : str
        Dotted ROS parameter name (``'record.path'``).
    field : str
        ``'<group>.<attribute>'`` of :class:`SimConfig` the value fills (``'run.record_path'``);
        a property instead of a dataclass field for a value derived from others
        (``modes.count``: the length of ``modes.frequencies``).
    kind : str
        ``'float'``, ``'int'``, ``'bool'``, ``'str'``, ``'float_list'`` or ``'str_list'``.
    default, unit, description
        As the ROS descriptor shows them.
    minimum, maximum : float or None
        Allowed range of the value (of every element of a list); ``open_minimum``: the
        minimum itself is refused (``> minimum``).
    range_note : str
        Why the range is what it is (in the refusal message and the descriptor).
    choices : tuple of str
        Allowed values of a ``'str'`` parameter (empty: any).
    read_only : bool
        A change needs a restart (the node refuses it at run time).

    """

    name: str
    field: str
    kind: str
    default: Any
    unit: str
    description: str
    minimum: Optional[float] = None
    maximum: Optional[float] = None
    open_minimum: bool = False
    range_note: str = ''
    choices: Tuple[str, ...] = ()
    read_only: bool = True

    @property
    def group(self) -> str:
        """Return the :class:`SimConfig` attribute holding the field (``'run'``)."""
        return self.field.split('.', 1)[0]

    @property
    def attribute(self) -> str:
        """Return the attribute of the group's dataclass (``'record_path'``)."""
        return self.field.split('.', 1)[1]


# The manufacturing spread a device.seed draws (core/device.py, D1-D5): representative of a
# trimmed MEMS ring, not measurements of a part (doc/populations.md says why each).
DEFAULT_SPLIT_SPREAD = 0.01
DEFAULT_Q_MISMATCH_SPREAD = 0.01
DEFAULT_MISALIGNMENT_SPREAD = 0.01
DEFAULT_PHASE_ERROR_SPREAD = 0.005
DEFAULT_GAIN_MISMATCH_SPREAD = 0.01

# The mechanical stops' contact law (core/kernels/stops.py): a restitution typical of a hard
# stop and a penalty stiffness that keeps a 30 000 g impact within a few % of d_g at 0.6 d_g
# (doc/environments.md, "Mechanical stops", says why each).
DEFAULT_STOP_RESTITUTION = 0.5
DEFAULT_STOP_STIFFNESS = 1e10

TEMPERATURE_RANGE_K = (150.0, 500.0)
"""Temperatures (K) the parameters and ``~/temperature`` take (:data:`_TEMPERATURE_NOTE`)."""
_TEMPERATURE_NOTE = ("the device's temperature laws are linear about the reference; a "
                     'silicon die works from about 230 K to 400 K')
_POSITIVE = {'minimum': 0.0, 'open_minimum': True}
_NON_NEGATIVE = {'minimum': 0.0}
_TIME = {'minimum': 0.0, 'maximum': MAX_TIME_S,
         'range_note': 'ROS stamps (builtin_interfaces/Time.sec) are int32'}
_ACCELERATION_NOTE = ('10^6 g: beyond any shock a ring survives (10^5 g closes the default '
                      'gap); far beyond it the arithmetic of a contact overflows')
_ACCELERATION = {'minimum': -MAX_ACCELERATION, 'maximum': MAX_ACCELERATION,
                 'range_note': _ACCELERATION_NOTE}
_VOLTAGE_NOTE = ('K_c (eq. 26) of both voltages below m omega^2 of every coordinate: the static '
                 'pull-in voltage of the ring with its frequencies taken as mechanical, '
                 '215.6 V for the default device')

PARAMETERS: Tuple[ParamSpec, ...] = (
    ParamSpec('modes.frequencies', 'modes.frequencies', 'float_list',
              [11200.0, 15800.0, 22000.0], 'Hz',
              'natural frequency of each n-theta mode, n = 1..N_R (length = N_R); '
              'empty = computed from ring and legs', **_POSITIVE),
    ParamSpec('modes.quality_factors', 'modes.quality_factors', 'float_list',
              [120000.0, 64700.0, 170000.0], '-',
              'quality factor Q_n of each mode (same length as modes.frequencies)',
              minimum=0.5, open_minimum=True, range_note='underdamped modes only',
              read_only=False),
    ParamSpec('modes.count', 'modes.count', 'int', 0, '-',
              'number of modes N_R when modes.frequencies is empty (0 = use its length)',
              0, MAX_MODES, range_note='the kernels support up to 20 modes'),
    ParamSpec('modes.companions', 'modes.companions', 'bool', True, '-',
              'also simulate the sin(n theta) companion coordinates q_n^s'),
    ParamSpec('modes.companion_frequencies', 'modes.companion_frequencies', 'float_list', [],
              'Hz', 'frequencies of the companions (empty = same as modes.frequencies)',
              **_POSITIVE),
    ParamSpec('modes.companion_quality_factors', 'modes.companion_quality_factors',
              'float_list', [], '-',
              'Q of the companions (empty = same as modes.quality_factors)',
              minimum=0.5, open_minimum=True, range_note='underdamped modes only',
              read_only=False),
    ParamSpec('modes.frequency_axes', 'modes.frequency_axes', 'float_list', [], 'deg',
              'per mode: ring angle of the principal axis whose frequency is '
              'modes.frequencies[n]; the companion frequency lies 90/n deg further on '
              '(empty = all 0: the axes on the electrodes)'),
    ParamSpec('modes.damping_axes', 'modes.damping_axes', 'float_list', [], 'deg',
              'per mode: ring angle of the principal axis whose Q is modes.quality_factors[n]; '
              'the companion Q lies 90/n deg further on (empty = all 0)'),
    ParamSpec('ring.radius', 'ring.radius', 'float', 1.5e-3, 'm', 'mean ring radius r',
              **_POSITIVE),
    ParamSpec('ring.thickness', 'ring.thickness', 'float', 18e-6, 'm', 'radial thickness h',
              **_POSITIVE),
    ParamSpec('ring.length', 'ring.length', 'float', 150e-6, 'm', 'axial length l',
              **_POSITIVE),
    ParamSpec('ring.youngs_modulus', 'ring.youngs_modulus', 'float', 150e9, 'Pa',
              'Young modulus E', **_POSITIVE),
    ParamSpec('ring.density', 'ring.density', 'float', 2330.0, 'kg/m^3', 'density rho',
              **_POSITIVE),
    ParamSpec('legs.count', 'legs.count', 'int', 8, '-', 'number of (pairs of) support legs N_l',
              0, 64),
    ParamSpec('legs.angle', 'legs.angle', 'float', 0.0, 'rad', 'angle alpha of the last leg'),
    ParamSpec('legs.mass', 'legs.mass', 'float', 0.0, 'kg',
              'point mass m_l of one leg (0 = neglected in the modal masses, as the paper)',
              **_NON_NEGATIVE),
    ParamSpec('legs.radial_stiffness', 'legs.radial_stiffness', 'float', 0.0, 'N/m',
              'radial stiffness k_r of one leg (used only when modes.frequencies is empty)',
              **_NON_NEGATIVE),
    ParamSpec('legs.tangential_stiffness', 'legs.tangential_stiffness', 'float', 0.0, 'N/m',
              'tangential stiffness k_t of one leg (used only when modes.frequencies is empty)',
              **_NON_NEGATIVE),
    ParamSpec('electrodes.outer_voltage', 'electrodes.outer_voltage', 'float',
              DEFAULT_OUTER_VOLTAGE, 'V', 'outer electrode bias V_o',
              range_note=_VOLTAGE_NOTE, read_only=False),
    ParamSpec('electrodes.inner_voltage', 'electrodes.inner_voltage', 'float', 0.0, 'V',
              'inner electrode bias V_i', range_note=_VOLTAGE_NOTE, read_only=False),
    ParamSpec('electrodes.gap', 'electrodes.gap', 'float', 10e-6, 'm',
              'nominal electrode gap d_g', **_POSITIVE),
    ParamSpec('electrodes.outer_radius', 'electrodes.outer_radius', 'float', 0.0, 'm',
              'mean radius r_o of the outer capacitors (0 = r + (h + d_g)/2)',
              range_note='0 = default', **_NON_NEGATIVE),
    ParamSpec('electrodes.inner_radius', 'electrodes.inner_radius', 'float', 0.0, 'm',
              'mean radius r_i of the inner capacitors (0 = r - (h + d_g)/2)',
              range_note='0 = default', **_NON_NEGATIVE),
    ParamSpec('electrodes.relative_permittivity', 'electrodes.relative_permittivity', 'float',
              1.0, '-', 'relative permittivity eps of eq. (18)', minimum=1.0,
              range_note='no dielectric in the gap has eps < 1 (vacuum: 1)'),
    ParamSpec('electrodes.taylor_terms', 'electrodes.taylor_terms', 'int', 10, '-',
              'N_T, order of the Taylor series of the force (0 = untruncated parallel plate)',
              0, 40, range_note='0 (untruncated) or 3..40'),
    ParamSpec('electrodes.fold_linear_stiffness', 'electrodes.fold_linear_stiffness', 'bool',
              True, '-',
              'true: modes.frequencies already contain the linear electrostatic stiffness '
              '(paper, section 3.1); false: they are mechanical and K_c (eq. 26) is added'),
    ParamSpec('electrodes.count', 'electrodes.count', 'int', 8, '-',
              'number K of outer sense electrodes (outputs e0..e{K-1})', 1, 360),
    ParamSpec('electrodes.span', 'electrodes.span', 'float', 0.0, 'rad',
              'angular span of one sense electrode (0 = 2 pi / K)', 0.0, 2.0 * math.pi,
              range_note='at most 2 pi / electrodes.count: electrodes do not overlap'),
    ParamSpec('shock.duration', 'run.shock_duration', 'float', 0.0, 's',
              'half-sine shock duration T_s (0 = one tenth of the 2theta period)',
              **_NON_NEGATIVE, read_only=False),
    ParamSpec('drive.amplitude', 'drive.amplitude', 'float', DEFAULT_DRIVE_AMPLITUDE, 'm/s^2',
              'harmonic drive on the 2theta mode per unit modal mass (A_e)', **_ACCELERATION,
              read_only=False),
    ParamSpec('drive.frequency', 'drive.frequency', 'float', DEFAULT_DRIVE_FREQUENCY, 'Hz',
              'drive frequency', **_NON_NEGATIVE, read_only=False),
    ParamSpec('drive.start_on', 'drive.start_on', 'str', 'upper_branch', '-',
              'initial state: rest, or the periodic response to the initial drive on its '
              'upper_branch or lower_branch (as the paper starts Cases 1-4)',
              choices=DRIVE_START_CHOICES),
    ParamSpec('integrator.method', 'integrator.method', 'str', 'bm6', '-',
              'splitting method: bm6 (order 6, 11 forces per step), bm4 (order 4, 6) or strang '
              '(order 2, 1); see core/kernels/', choices=INTEGRATOR_METHODS),
    ParamSpec('integrator.max_step', 'integrator.max_step', 'float', 0.0, 's',
              'largest integration step (0 = automatic, see core/kernels/)', **_NON_NEGATIVE),
    ParamSpec('integrator.fidelity', 'integrator.fidelity', 'str', 'auto', '-',
              'model of the quiet stretches: auto or averaged let the offline analyses '
              '(characterize) run their quiet tests on the averaged model (auto falls back '
              'to the full model where it cannot, averaged refuses), full never; ring_gyro '
              'run and the node run the full model (doc/averaged.md)', choices=FIDELITIES),
    ParamSpec('real_time_factor', 'run.real_time_factor', 'float', 1.0, '-',
              'simulated seconds per wall second (0 = as fast as possible)', **_NON_NEGATIVE,
              read_only=False),
    ParamSpec('duration', 'run.duration', 'float', 0.0, 's',
              'stop after this much simulated time (0 = run until shut down)', **_TIME),
    ParamSpec('output.rate', 'run.output_rate', 'float', 200000.0, 'Hz',
              'samples per second in the published blocks (1e9 / rate must be whole ns)',
              0.0, MAX_OUTPUT_RATE_HZ, open_minimum=True,
              range_note='at most 10 MHz: 450 samples per period of the fastest mode; a '
              'higher rate costs steps and memory and shows nothing new'),
    ParamSpec('output.block_duration', 'run.block_duration', 'float', 0.01, 's',
              'simulated time covered by one published block', 0.0, MAX_BLOCK_DURATION_S,
              open_minimum=True,
              range_note='at most 1 s: a block goes out when its last sample is due, so its '
              'first sample waits this long; at most 4 MiB of messages per block'),
    ParamSpec('record.path', 'run.record_path', 'str', '', '-',
              'MCAP file to record the run to (empty = none)'),
    ParamSpec('record.topics', 'run.record_topics', 'str_list', [], '-',
              'topics a recording holds, relative names as published (e.g. modal_displacement, '
              'shock, /diagnostics); empty = all. Inputs needed to re-simulate are always kept'),
    ParamSpec('record.decimation', 'run.record_decimation', 'int', 200, '-',
              'record every N-th output sample of the block topics modal_displacement, '
              'radial_gap, sense_electrodes and demodulator; default 200: 1 kHz at the default '
              '200 kHz, the rate of ~/rate and ~/control, which are recorded whole (so are the '
              'inputs and /diagnostics); 1 = every sample. Any recording re-simulates bit for '
              'bit with every sample: ring_gyro run --from FILE --decimation 1', 1, 1000000,
              range_note='N counts output samples; the default keeps ~0.35 MB per simulated '
              'second of the gyroscope instead of 44 MB at N = 1'),
    ParamSpec('record.compression', 'run.record_compression', 'str', 'zstd', '-',
              'chunk compression of the recording: zstd, lz4 or none (as rosbag2 offers)',
              choices=RECORD_COMPRESSIONS),
    ParamSpec('record.overwrite', 'run.record_overwrite', 'bool', False, '-',
              'replace an existing file at record.path (false: refuse it, as rosbag2 does)'),
    ParamSpec('inputs.horizon', 'run.input_horizon', 'float', 60.0, 's',
              'inputs stamped further ahead of the simulation time than this are refused',
              **_TIME, read_only=False),
    ParamSpec('publish_clock', 'run.publish_clock', 'bool', False, '-',
              'publish the simulation time on /clock'),
    ParamSpec('scenario.shock_times', 'run.shock_times', 'float_list', [], 's',
              'simulation times of scheduled x shocks', **_TIME),
    ParamSpec('scenario.shock_peaks', 'run.shock_peaks', 'float_list', [], 'm/s^2',
              'peak base accelerations of the scheduled shocks (same length)', **_ACCELERATION),
    ParamSpec('scenario.shock_angles', 'run.shock_angles', 'float_list', [], 'deg',
              'direction of each scheduled shock, from x towards y (empty = all along x; '
              'else the same length as scenario.shock_times)'),
    ParamSpec('scenario.rate_times', 'run.rate_times', 'float_list', [], 's',
              'knots of the scheduled angular-rate profile (non-decreasing; a repeated time '
              'is a step); the rate is linear between knots and held after the last',
              **_TIME),
    ParamSpec('scenario.rate_values', 'run.rate_values', 'float_list', [], 'rad/s',
              'angular rate about z (REP-103: counter-clockwise seen from +z) at each knot '
              '(same length as scenario.rate_times); needs gyro.enabled',
              range_note='|Omega| at most 1 % of the angular frequency of the lowest mode '
              '(703.7 rad/s on the default device): the range of the model, not of the '
              'sensor'),
    ParamSpec('scenario.vibration_frequency', 'run.vibration_frequency', 'float', 0.0, 'Hz',
              'frequency of a sine base vibration in the plane of the ring (0 = none); made '
              'inside at every output sample, so at most output.rate / 40; live: its phase '
              'runs on continuously',
              minimum=0.0, maximum=MAX_OUTPUT_RATE_HZ / 40.0,
              range_note='sampled at output.rate and interpolated linearly: 40 samples per '
              'period keep its amplitude within 0.2 %', read_only=False),
    ParamSpec('scenario.vibration_amplitude', 'run.vibration_amplitude', 'float', 0.0, 'm/s^2',
              'peak base acceleration of the sine vibration', minimum=0.0,
              maximum=MAX_ACCELERATION, range_note=_ACCELERATION_NOTE, read_only=False),
    ParamSpec('scenario.vibration_angle', 'run.vibration_angle', 'float', 0.0, 'deg',
              'direction of the vibration (sine and random) in the plane of the ring, from x '
              'towards y', read_only=False),
    ParamSpec('scenario.vibration_psd_frequencies', 'run.vibration_psd_frequencies',
              'float_list', [], 'Hz',
              'break points of a random base vibration along scenario.vibration_angle '
              '(strictly increasing, at least 2, at most output.rate / 40; empty = none); the '
              'PSD is log-log between them and zero outside (core/vibration.py)',
              minimum=0.0, open_minimum=True, maximum=MAX_OUTPUT_RATE_HZ / 40.0,
              range_note='log-log needs f > 0; sampled at output.rate and interpolated '
              'linearly, as the sine', read_only=False),
    ParamSpec('scenario.vibration_psd_values', 'run.vibration_psd_values', 'float_list', [],
              'g^2/Hz', 'one-sided acceleration PSD of the random vibration at each break '
              'point (same length as scenario.vibration_psd_frequencies)',
              minimum=0.0, open_minimum=True,
              range_note='log-log needs S > 0; its rms at most 10^5 g', read_only=False),
    ParamSpec('scenario.acceleration', 'run.acceleration', 'float_list', [], 'm/s^2',
              'steady base acceleration [x, y] in the plane of the ring from t = 0 (live: from '
              'the change; empty = none; z is not in the model)', **_ACCELERATION,
              read_only=False),
    ParamSpec('scenario.temperature_times', 'run.temperature_times', 'float_list', [], 's',
              'knots of the ambient temperature (non-decreasing; a repeated time is a step); '
              'linear between knots, the first value before the first and the last after the '
              'last (empty = thermal.reference_temperature)', **_TIME),
    ParamSpec('scenario.temperature_values', 'run.temperature_values', 'float_list', [], 'K',
              'ambient temperature at each knot (same length as scenario.temperature_times)',
              *TEMPERATURE_RANGE_K, range_note=_TEMPERATURE_NOTE),
    ParamSpec('thermal.reference_temperature', 'thermal.reference_temperature', 'float',
              298.15, 'K', 'the die temperature at which modes.*, gyro.feedback_capacitance '
              'and gyro.temperature hold, and the calibration is made',
              *TEMPERATURE_RANGE_K, range_note=_TEMPERATURE_NOTE),
    ParamSpec('thermal.time_constant', 'thermal.time_constant', 'float', 30.0, 's',
              'time constant of the die temperature behind the ambient (0 = the ambient)',
              **_NON_NEGATIVE),
    ParamSpec('thermal.frequency_coefficient', 'thermal.frequency_coefficient', 'float',
              -30e-6, '1/K', 'relative change of every frequency per K of die temperature '
              '(silicon: about -30e-6)', -1e-3, 1e-3,
              range_note='a linear law; silicon is near -30e-6 /K'),
    ParamSpec('thermal.quality_factor_exponent', 'thermal.quality_factor_exponent', 'float',
              1.0, '-', 'Q of every principal axis times (T / T_ref)^-exponent', -5.0, 5.0,
              range_note='a power law over a narrow range'),
    ParamSpec('thermal.gain_coefficient', 'thermal.gain_coefficient', 'float', 50e-6, '1/K',
              "relative change of the charge amplifiers' gain per K (their feedback "
              'capacitance)', -1e-2, 1e-2, range_note='a linear law'),
    ParamSpec('gyro.enabled', 'gyro.enabled', 'bool', True, '-',
              'the gyroscope: rotation of the sensor frame (Coriolis coupling), sense '
              'electronics, ~/rate and ~/demodulator; needs modes.companions (the sense mode '
              'is the sin 2theta companion)'),
    ParamSpec('gyro.frame_id', 'gyro.frame_id', 'str', 'ring_gyro', '-',
              'header.frame_id of ~/rate and of the recorded ~/angular_rate (REP-105: the '
              'sensor frame, z along the ring axis)'),
    ParamSpec('gyro.output_rate', 'gyro.output_rate', 'float', 1000.0, 'Hz',
              'rate samples per second on ~/rate (output.rate must be a whole multiple)',
              **_POSITIVE),
    ParamSpec('gyro.filter_bandwidth', 'gyro.filter_bandwidth', 'float', 100.0, 'Hz',
              '-3 dB cut-off of the demodulator low-pass (Butterworth); below half of '
              'gyro.output_rate', **_POSITIVE),
    ParamSpec('gyro.filter_order', 'gyro.filter_order', 'int', 4, '-',
              'order of the demodulator low-pass', 1, 8,
              range_note='a Butterworth of order 1-8 in second-order sections'),
    ParamSpec('gyro.bias_voltage', 'gyro.bias_voltage', 'float', 0.0, 'V',
              'bias of the sense electrodes seen by the charge amplifier '
              '(0 = electrodes.outer_voltage)', **_NON_NEGATIVE),
    ParamSpec('gyro.feedback_capacitance', 'gyro.feedback_capacitance', 'float', 1e-12, 'F',
              'feedback capacitance C_f of the charge amplifier', **_POSITIVE),
    ParamSpec('gyro.parasitic_capacitance', 'gyro.parasitic_capacitance', 'float', 1e-12,
              'F', 'parasitic capacitance at the charge amplifier input (noise gain)',
              **_NON_NEGATIVE),
    ParamSpec('gyro.input_noise_density', 'gyro.input_noise_density', 'float', 10e-9,
              'V/sqrt(Hz)', 'input-referred voltage noise density of the charge amplifier '
              '(white; 0 = none)', **_NON_NEGATIVE),
    ParamSpec('gyro.temperature', 'gyro.temperature', 'float', 300.0, 'K',
              'temperature of the thermomechanical (Brownian) force noise of every mode '
              '(0 = none)', **_NON_NEGATIVE),
    ParamSpec('gyro.bias_instability', 'gyro.bias_instability', 'float', 0.0, 'deg/h',
              'flicker (1/f) rate noise stated as the datasheet bias instability (0 = none)',
              **_NON_NEGATIVE),
    ParamSpec('gyro.noise_seed', 'gyro.noise_seed', 'int', 0, '-',
              'seed of every random stream (recorded with the run; same seed, same noise)',
              0, 2 ** 63 - 1, range_note='a 64-bit key of the counter-based generator'),
    ParamSpec('gyro.phase_error', 'gyro.phase_error', 'float', 0.0, 'rad',
              "error of the sense channel's demodulation reference phase (E3; the rebalance "
              "loop's sense demodulation and modulation share it, C2, C6)",
              -math.pi / 2.0, math.pi / 2.0,
              range_note='beyond +-90 deg the channel reads the rate with the wrong sign'),
    ParamSpec('gyro.sense_misalignment', 'gyro.sense_misalignment', 'float', 0.0, 'deg',
              "angle error of the sense electrodes' axis: the sense amplifier reads "
              'sin(2 (theta_e - delta)) (E1)', -22.5, 22.5,
              range_note='half the angle between a sense and a drive electrode'),
    ParamSpec('gyro.pickoff_gain_mismatch', 'gyro.pickoff_gain_mismatch', 'float', 0.0, '-',
              'relative gain error of the sense amplifier against the drive amplifier (E1)',
              -0.5, 0.5, range_note='a gain error of the order of the gain is a broken part'),
    ParamSpec('gyro.range', 'gyro.range', 'float', 0.0, 'rad/s',
              'full scale of ~/rate: beyond +-range the output reads +-range, and the sample '
              'is not a measurement (reason saturated, covariance 1e6, counted on '
              '/diagnostics); 0 = none (the model reads up to its own input range)',
              **_NON_NEGATIVE),
    ParamSpec('gyro.resolution', 'gyro.resolution', 'float', 0.0, 'rad/s',
              'LSB of ~/rate: the output is rounded to a whole number of it (half to even), '
              'before the saturation, and its variance gains LSB^2 / 12; 0 = none',
              **_NON_NEGATIVE),
    ParamSpec('gyro.calibration.source', 'gyro.calibration_source', 'str', 'factory', '-',
              "where the rate output's bias and scale factor come from: factory (measured "
              'on a simulated rate table at the start, then held), given '
              "(gyro.calibration.bias and .scale_factor as set) or ideal (the model's own "
              'scale factor of the device in force, no bias: the mechanics alone)',
              choices=('factory', 'given', 'ideal')),
    ParamSpec('gyro.calibration.bias', 'gyro.calibration_bias', 'float', 0.0, 'rad/s',
              'with source given: the zero-rate output subtracted from the rate',
              -10.0, 10.0, range_note='beyond the rate range of the model'),
    ParamSpec('gyro.calibration.scale_factor', 'gyro.calibration_scale_factor', 'float', 0.0,
              'readout/(rad/s)',
              'with source given: the readout per rad/s (V per rad/s of the sense '
              'demodulator open loop, m/s^2 per rad/s of the rebalance force with '
              'control.mode: rebalance; 0 = not set)', **_NON_NEGATIVE),
    ParamSpec('gyro.calibration.temperature_points', 'gyro.calibration_temperature_points',
              'float_list', [], 'K', 'with source factory: die temperatures of a temperature '
              'series whose bias and scale factor the compensation fits (empty = no '
              'compensation; 1 point fits a line through the reference, 2 or more a '
              'parabola in T - T_ref)',
              *TEMPERATURE_RANGE_K, range_note=_TEMPERATURE_NOTE),
    ParamSpec('gyro.calibration.temperature_coefficients',
              'gyro.calibration_temperature_coefficients', 'float_list', [], '-',
              'with source given: the compensation [b_1, .., b_k, s_1, .., s_k]: bias '
              'b + sum b_i dT^i (rad/s per K^i) and scale factor S (1 + sum s_i dT^i) '
              '(per K^i), dT = die - thermal.reference_temperature (empty = none)'),
    ParamSpec('device.seed', 'device.seed', 'int', 0, '-',
              'seed of the draw of this device from its manufacturing spread (device.*_spread '
              'added to the configured imperfections; 0 = the device as configured, no draw; '
              'the same file and seed are the same device)', 0, 2 ** 63 - 1,
              range_note='a 64-bit key of the counter-based generator'),
    ParamSpec('device.split_spread', 'device.split_spread', 'float', DEFAULT_SPLIT_SPREAD,
              'Hz', 'one sigma of the drawn frequency split of the 2theta pair, at an axis '
              'drawn uniformly over 45 deg (with device.seed)', 0.0, 100.0,
              range_note='an untrimmed ring splits by a few Hz at most'),
    ParamSpec('device.q_mismatch_spread', 'device.q_mismatch_spread', 'float',
              DEFAULT_Q_MISMATCH_SPREAD, '-',
              'one sigma of the drawn Q_y / Q_x - 1 of the 2theta pair, at an axis drawn '
              'uniformly over 45 deg (with device.seed)', 0.0, 0.5,
              range_note='a spread of half the Q is a broken part'),
    ParamSpec('device.misalignment_spread', 'device.misalignment_spread', 'float',
              DEFAULT_MISALIGNMENT_SPREAD, 'deg',
              'one sigma of the drawn sense misalignment, added to gyro.sense_misalignment '
              '(with device.seed)', 0.0, 22.5, range_note='that of gyro.sense_misalignment'),
    ParamSpec('device.phase_error_spread', 'device.phase_error_spread', 'float',
              DEFAULT_PHASE_ERROR_SPREAD, 'rad',
              'one sigma of the drawn phase error, added to gyro.phase_error (with '
              'device.seed)', 0.0, math.pi / 2.0, range_note='that of gyro.phase_error'),
    ParamSpec('device.gain_mismatch_spread', 'device.gain_mismatch_spread', 'float',
              DEFAULT_GAIN_MISMATCH_SPREAD, '-',
              'one sigma of the drawn pick-off gain mismatch, added to '
              'gyro.pickoff_gain_mismatch (with device.seed)', 0.0, 0.5,
              range_note='that of gyro.pickoff_gain_mismatch'),
    ParamSpec('stops.gap', 'stops.gap', 'float', 0.0, 'm',
              'radial clearance of the mechanical stops, on both sides of the ring (outer '
              'and inner): where |w| reaches it the contact law pushes the ring back and the '
              'run goes on; 0 = no stops (contact with an electrode ends the run); when set, '
              'below electrodes.gap (doc/environments.md)', **_NON_NEGATIVE),
    ParamSpec('stops.restitution', 'stops.restitution', 'float', DEFAULT_STOP_RESTITUTION,
              '-', 'coefficient of restitution e of the stops: at every angle in contact the '
              'stop gives back e^2 of the elastic energy the ring stored in it (loading '
              'stiffness stops.stiffness, unloading e^2 stops.stiffness)', 0.0, 1.0,
              open_minimum=True, range_note='0 would hold the ring in the stop, above 1 '
              'would create energy'),
    ParamSpec('stops.stiffness', 'stops.stiffness', 'float', DEFAULT_STOP_STIFFNESS, 'N/m^2',
              "contact stiffness of the stops per unit length of the ring's circumference "
              '(force per unit length per m of penetration, a penalty: large enough that the '
              'penetration is small, doc/environments.md)', 1e6, 1e14,
              range_note='below, a 30 000 g shock goes through the stop; above, the contact '
              'sub-step becomes impractically short'),
    ParamSpec('control.mode', 'control.mode', 'str', 'rebalance', '-',
              "the gyroscope's mode of operation (core/gyro/modes, doc/control.md): "
              "open_loop (the paper's drive.amplitude at drive.frequency, the sense mode "
              'read open loop), closed_loop (a PLL on the drive pick-off sets the frequency, '
              'an AGC the amplitude; the sense mode read open loop) or rebalance (closed_loop '
              'and a loop that nulls the sense mode q2s: ~/rate is read from its force; '
              'needs gyro.enabled)', choices=tuple(MODES)),
    ParamSpec('control.rate', 'control.rate', 'float', 1000.0, 'Hz',
              'update rate of the loops (integrate-and-dump demodulation over one period; '
              'output.rate must be a whole multiple)', **_POSITIVE),
    ParamSpec('control.pll_bandwidth', 'control.pll_bandwidth', 'float', 20.0, 'Hz',
              'PLL loop bandwidth (crossover of the PI loop filter)', **_POSITIVE),
    ParamSpec('control.pll_range', 'control.pll_range', 'float', 200.0, 'Hz',
              'the NCO stays within drive.frequency +- this (at the limit: out of lock)',
              **_POSITIVE),
    ParamSpec('control.lock_threshold', 'control.lock_threshold', 'float', 0.5, 'rad',
              'phase error beyond which the PLL counts as out of lock', minimum=0.0,
              maximum=math.pi, open_minimum=True),
    ParamSpec('control.agc_bandwidth', 'control.agc_bandwidth', 'float', 5.0, 'Hz',
              'AGC loop bandwidth (crossover of the PI amplitude loop)', **_POSITIVE),
    ParamSpec('control.agc_setpoint', 'control.agc_setpoint', 'float', 0.0, 'm',
              'drive amplitude the AGC holds (q2 amplitude; 0 = that of the start state, or '
              'the linear response to drive.amplitude from rest)', **_NON_NEGATIVE),
    ParamSpec('control.drive_limit', 'control.drive_limit', 'float', 1.0, 'm/s^2',
              'largest drive force amplitude the AGC may command (the DAC range)',
              minimum=0.0, open_minimum=True, maximum=MAX_ACCELERATION,
              range_note=_ACCELERATION_NOTE),
    ParamSpec('control.rebalance_bandwidth', 'control.rebalance_bandwidth', 'float', 20.0,
              'Hz', 'force-to-rebalance loop bandwidth (the rate bandwidth with it on)',
              **_POSITIVE),
)

SPECS: Dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}

REPLACED: Dict[str, str] = {
    'control.drive_loop': 'replaced by control.mode (drive_loop: open is mode: open_loop; '
                          'closed is mode: closed_loop, or rebalance with control.rebalance)',
    'control.rebalance': 'replaced by control.mode (rebalance: true is mode: rebalance; '
                         'false is mode: closed_loop or open_loop)',
}
"""Parameters that are gone, each with what replaces it (a file that sets one is refused)."""


def upgraded(values: Mapping[str, Any]) -> Dict[str, Any]:
    """
    Return flat ``values`` with the replaced parameters turned into their new ones.

    For what was written before the replacement (a recording's configuration): the drive loop
    and the rebalance flag become ``control.mode``. Files and parameters given now are refused
    instead (:data:`REPLACED`), so that a user learns the new name.
    """
    out = {k: v for k, v in values.items() if k not in REPLACED}
    if any(k in values for k in REPLACED) and 'control.mode' not in values:
        loop = values.get('control.drive_loop', SPECS['control.mode'].default)
        closed = loop in ('closed', 'closed_loop', 'rebalance')
        rebalance = bool(values.get('control.rebalance', closed))
        out['control.mode'] = ('rebalance' if closed and rebalance else
                               'closed_loop' if closed else 'open_loop')
    return out


CONTROL_BANDWIDTH_RATIO = 20.0
"""A loop's bandwidth is at most ``control.rate`` over this (doc/control.md, stability)."""


def _fail(name: str, reason: str) -> ParameterError:
    return ParameterError(f'{name}: {reason}')


def format_number(x: float) -> str:
    """Return ``x`` short (``%g``) when that is exact, else in full (``repr``)."""
    if isinstance(x, int) and not isinstance(x, bool):
        return str(x)
    short = f'{x:g}'
    return short if float(short) == x else repr(float(x))


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
        raise _fail(name, REPLACED.get(name, 'unknown parameter'))
    if value is None:
        return [] if spec.kind in LIST_KINDS else spec.default
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


def check_value(spec: ParamSpec, value: Any) -> None:
    """
    Check one value (of its kind already) against its row: finite, range, choices.

    Raises
    ------
    ParameterError
        ``'<name>: must be ... , got <value>'``, with the row's ``range_note``.

    """
    note = f' ({spec.range_note})' if spec.range_note else ''
    if spec.choices and value not in spec.choices:
        raise _fail(spec.name, f'must be one of {", ".join(spec.choices)}, got {value!r}')
    if spec.kind not in ('float', 'int', 'float_list'):
        return
    for v in (value if spec.kind == 'float_list' else (value,)):
        if spec.kind != 'int' and not math.isfinite(v):
            raise _fail(spec.name, f'must be finite, got {v!r}')
        low, high = spec.minimum, spec.maximum
        if low is not None and (v <= low if spec.open_minimum else v < low):
            sign = '>' if spec.open_minimum else '>='
            raise _fail(spec.name, f'must be {sign} {format_number(low)}{note}, got {v!r}')
        if high is not None and v > high:
            raise _fail(spec.name, f'must be <= {format_number(high)}{note}, got {v!r}')


def _field_value(spec: ParamSpec, value: Any) -> Any:
    """Return a flat value as the dataclass holds it (lists as tuples)."""
    return tuple(value) if spec.kind in LIST_KINDS else value


_DERIVED: Tuple[ParamSpec, ...] = ()
"""Rows whose field is a property computed from other fields (checked by build_config)."""


def _parameter_group(group: str):
    """
    Make a frozen dataclass of the rows of ``group`` (class decorator).

    The class lists its field names and types; the decorator sets each field's default from
    its row and a ``__post_init__`` that checks every field against its row, then calls the
    class's own ``_check`` (what no single row can say). A class field that no row fills, or
    a row whose field is neither a class field nor a property, is a ``TypeError`` at import.
    """
    def make(cls):
        global _DERIVED
        rows = [p for p in PARAMETERS if p.group == group]
        annotations = cls.__dict__.get('__annotations__', {})
        by_attribute = {p.attribute: p for p in rows}
        for name in annotations:
            if name not in by_attribute:
                raise TypeError(f'{cls.__name__}.{name}: no row of PARAMETERS fills it')
        checked = []
        for spec in rows:
            if spec.attribute in annotations:
                setattr(cls, spec.attribute, _field_value(spec, spec.default))
                checked.append(spec)
            elif isinstance(cls.__dict__.get(spec.attribute), property):
                _DERIVED += (spec,)
            else:
                raise TypeError(f'{spec.name}: {cls.__name__} has no field {spec.attribute!r}')
        own_check = cls.__dict__.get('_check')

        def __post_init__(self) -> None:
            for spec in checked:
                check_value(spec, getattr(self, spec.attribute))
            if own_check is not None:
                own_check(self)

        cls.__post_init__ = __post_init__
        return dataclass(frozen=True)(cls)
    return make


@_parameter_group('ring')
class RingParams:
    """Ring geometry and material (section 3.1), SI units."""

    radius: float
    thickness: float
    length: float
    youngs_modulus: float
    density: float

    @property
    def mass(self) -> float:
        """Physical ring mass m_r = rho 2 pi r h l, kg."""
        return self.density * 2.0 * math.pi * self.radius * self.thickness * self.length


@_parameter_group('legs')
class LegParams:
    """Support legs (section 2.3)."""

    count: int
    angle: float
    mass: float
    radial_stiffness: float
    tangential_stiffness: float


@_parameter_group('modes')
class ModeParams:
    """
    Linear modes: frequency (Hz) and Q of every coordinate.

    ``frequencies[i]`` is the (n = i + 1)-theta mode. With companions the sin(n theta)
    coordinates follow, with their own frequencies (for split pairs such as 4theta with 8 legs).
    """

    frequencies: Tuple[float, ...]
    quality_factors: Tuple[float, ...]
    companions: bool
    companion_frequencies: Tuple[float, ...]
    companion_quality_factors: Tuple[float, ...]
    frequency_axes: Tuple[float, ...]
    damping_axes: Tuple[float, ...]

    def _check(self) -> None:
        n = len(self.frequencies)
        if n == 0:
            raise _fail('modes.frequencies', 'needs at least one mode')
        if n > MAX_MODES:
            raise _fail('modes.frequencies', f'at most {MAX_MODES} modes are supported, got {n}')
        for name, values in (('modes.quality_factors', self.quality_factors),
                             ('modes.companion_frequencies', self.companion_frequencies),
                             ('modes.companion_quality_factors',
                              self.companion_quality_factors),
                             ('modes.frequency_axes', self.frequency_axes),
                             ('modes.damping_axes', self.damping_axes)):
            if (values or name == 'modes.quality_factors') and len(values) != n:
                raise _fail(name, f'has {len(values)} values but modes.frequencies has {n}')

    @property
    def count(self) -> int:
        """Ritz order N_R."""
        return len(self.frequencies)

    def principal_frequencies(self) -> List[float]:
        """Principal frequency (Hz) of every coordinate as given, cos modes then companions."""
        f = list(self.frequencies)
        if self.companions:
            f += list(self.companion_frequencies or self.frequencies)
        return f

    def principal_quality_factors(self) -> List[float]:
        """Principal Q of every coordinate as given, cos modes then companions."""
        q = list(self.quality_factors)
        if self.companions:
            q += list(self.companion_quality_factors or self.quality_factors)
        return q

    def coordinate_frequencies(self) -> List[float]:
        """
        Frequency (Hz) of every simulated coordinate, cos modes then companions.

        Each coordinate's own stiffness: the principal values, except in a pair whose axes
        are off the electrodes (``coupled_pairs``), where it is the diagonal of the pair's
        stiffness (P2), ``sqrt(K_ii) / 2 pi``.
        """
        f = self.principal_frequencies()
        for n in self.coupled_pairs():
            stiffness, _ = self.pair_matrices(n)
            f[n - 1] = math.sqrt(stiffness[0, 0]) / (2.0 * math.pi)
            f[self.count + n - 1] = math.sqrt(stiffness[1, 1]) / (2.0 * math.pi)
        return f

    def coordinate_quality_factors(self) -> List[float]:
        """
        Q of every simulated coordinate, cos modes then companions.

        The principal values, except in a coupled pair (``coupled_pairs``), where it is
        ``sqrt(K_ii) / C_ii`` of the pair's diagonal (P2, P3).
        """
        q = self.principal_quality_factors()
        for n in self.coupled_pairs():
            stiffness, damping = self.pair_matrices(n)
            q[n - 1] = math.sqrt(stiffness[0, 0]) / damping[0, 0]
            q[self.count + n - 1] = math.sqrt(stiffness[1, 1]) / damping[1, 1]
        return q

    def pair_matrices(self, n: int) -> Tuple[np.ndarray, np.ndarray]:
        """
        ``(K, C)`` of the n-theta pair per unit modal mass, (rad/s)^2 and 1/s, 2x2.

        ``structure.pair_matrices`` with the principal values and axes of mode ``n``
        (1-based); needs the companions.
        """
        i = n - 1
        f = self.principal_frequencies()
        q = self.principal_quality_factors()
        m = self.count
        return structure.pair_matrices(
            n, 2.0 * math.pi * f[i], 2.0 * math.pi * f[m + i], q[i], q[m + i],
            self.frequency_axes[i] if self.frequency_axes else 0.0,
            self.damping_axes[i] if self.damping_axes else 0.0)

    def coupled_pairs(self) -> List[int]:
        """
        Return the n of every pair whose stiffness or damping couples its coordinates.

        Those whose principal axes are off the electrodes (``modes.frequency_axes``,
        ``modes.damping_axes``) with unequal principal values; none without companions.
        """
        if not self.companions:
            return []
        out = []
        for n in range(1, self.count + 1):
            k, c = self.pair_matrices(n)
            if k[0, 1] != 0.0 or c[0, 1] != 0.0:
                out.append(n)
        return out


@_parameter_group('electrodes')
class ElectrodeParams:
    """Electrodes and electrostatic force model (section 2.4)."""

    outer_voltage: float
    inner_voltage: float
    gap: float
    outer_radius: float
    inner_radius: float
    relative_permittivity: float
    taylor_terms: int
    fold_linear_stiffness: bool
    count: int
    span: float

    def _check(self) -> None:
        if self.taylor_terms in (1, 2):
            raise _fail('electrodes.taylor_terms',
                        f'must be 0 (untruncated) or between 3 and 40, got {self.taylor_terms}')
        if self.span > 2.0 * math.pi / self.count + 1e-12:
            raise _fail('electrodes.span',
                        f'must be between 0 and 2 pi / electrodes.count, got {self.span!r}')


@_parameter_group('drive')
class DriveParams:
    """Harmonic drive F_ext,2 = A_e cos(2 pi f t) of the 2theta mode (section 3.4)."""

    amplitude: float
    frequency: float
    start_on: str


@_parameter_group('gyro')
class GyroParams:
    """
    The gyroscope: rotation input, sense electronics, rate output and noise (doc/gyroscope.md).

    Off by default (the paper's resonator). On, the sensor frame rotates at the scheduled or
    streamed rate, the Coriolis coupling acts between every q_n and q_n^s, and the sense
    electronics turn the sense electrodes' capacitances into ``~/rate``.
    """

    enabled: bool
    frame_id: str
    output_rate: float
    filter_bandwidth: float
    filter_order: int
    bias_voltage: float
    feedback_capacitance: float
    parasitic_capacitance: float
    input_noise_density: float
    temperature: float
    bias_instability: float
    noise_seed: int
    phase_error: float
    sense_misalignment: float
    pickoff_gain_mismatch: float
    range: float
    resolution: float
    calibration_source: str
    calibration_bias: float
    calibration_scale_factor: float
    calibration_temperature_points: Tuple[float, ...]
    calibration_temperature_coefficients: Tuple[float, ...]

    def _check(self) -> None:
        if self.filter_bandwidth >= 0.5 * self.output_rate:
            raise _fail('gyro.filter_bandwidth',
                        f'must be below half of gyro.output_rate ({self.output_rate:g} Hz): '
                        f'the low-pass is the anti-alias filter of ~/rate')
        if len(self.calibration_temperature_coefficients) % 2:
            raise _fail('gyro.calibration.temperature_coefficients',
                        f'needs as many scale-factor as bias coefficients (an even count), '
                        f'got {len(self.calibration_temperature_coefficients)}')
        if len(set(self.calibration_temperature_points)) != len(
                self.calibration_temperature_points):
            raise _fail('gyro.calibration.temperature_points', 'has a temperature twice')
        if 0.0 < self.resolution < MIN_RESOLUTION:
            raise _fail('gyro.resolution',
                        f'must be 0 (none) or >= {MIN_RESOLUTION:g} rad/s, finer than any '
                        f'output word (32 bits over +-300 deg/s: 2.4e-9 rad/s), got '
                        f'{self.resolution!r}')
        if self.range and self.resolution >= self.range:
            raise _fail('gyro.resolution',
                        f'must be below gyro.range ({self.range:g} rad/s): a full scale of '
                        f'less than one LSB has no code but 0, got {self.resolution!r}')
        if self.calibration_source == 'given' and self.calibration_scale_factor == 0.0:
            raise _fail('gyro.calibration.scale_factor',
                        'must be set (> 0) with gyro.calibration.source: given')


@_parameter_group('device')
class DeviceParams:
    """
    The seeded draw of the device from its manufacturing spread (``core.device``, D1-D5).

    ``seed`` 0: the device as configured. Otherwise :func:`build_config` adds the draw to the
    configured imperfections; the spreads are one sigma each.
    """

    seed: int
    split_spread: float
    q_mismatch_spread: float
    misalignment_spread: float
    phase_error_spread: float
    gain_mismatch_spread: float


@_parameter_group('stops')
class StopParams:
    """The mechanical stops: clearance and contact law (``core/kernels/stops.py``)."""

    gap: float
    restitution: float
    stiffness: float

    @property
    def enabled(self) -> bool:
        """Whether there are stops (``stops.gap`` > 0)."""
        return self.gap > 0.0


@_parameter_group('control')
class ControlParams:
    """
    The gyroscope's mode of operation and its loops (``core.gyro.modes``, ``core.gyro.control``).

    ``mode`` names one of :data:`~ring_gyro_sim.core.gyro.modes.MODES`: ``open_loop`` is the
    paper's fixed-frequency drive; ``closed_loop`` locks an NCO to the drive mode and holds its
    amplitude; ``rebalance`` adds the loop that nulls the sense mode (doc/control.md).
    """

    mode: str
    rate: float
    pll_bandwidth: float
    pll_range: float
    lock_threshold: float
    agc_bandwidth: float
    agc_setpoint: float
    drive_limit: float
    rebalance_bandwidth: float

    def _check(self) -> None:
        top = max(self.pll_bandwidth, self.agc_bandwidth, self.rebalance_bandwidth)
        if MODES[self.mode].closed and top > self.rate / CONTROL_BANDWIDTH_RATIO:
            name = ('control.pll_bandwidth' if top == self.pll_bandwidth else
                    'control.agc_bandwidth' if top == self.agc_bandwidth else
                    'control.rebalance_bandwidth')
            raise _fail(name, f'must be at most control.rate / {CONTROL_BANDWIDTH_RATIO:g} '
                        f'({self.rate / CONTROL_BANDWIDTH_RATIO:g} Hz): a sampled loop with '
                        f'a delay of 1.5 periods needs it, got {top:g} Hz')


@_parameter_group('integrator')
class IntegratorParams:
    """Choice of the splitting method, of the largest step (s) and of the model's fidelity."""

    method: str
    max_step: float
    fidelity: str


@_parameter_group('thermal')
class ThermalParams:
    """The die temperature and the device's dependences on it (``core.thermal``)."""

    reference_temperature: float
    time_constant: float
    frequency_coefficient: float
    quality_factor_exponent: float
    gain_coefficient: float


@_parameter_group('run')
class RunParams:
    """Pacing, output, recording and scheduled inputs."""

    real_time_factor: float
    duration: float
    output_rate: float
    block_duration: float
    record_path: str
    publish_clock: bool
    shock_duration: float
    shock_times: Tuple[float, ...]
    shock_peaks: Tuple[float, ...]
    shock_angles: Tuple[float, ...]
    rate_times: Tuple[float, ...]
    rate_values: Tuple[float, ...]
    temperature_times: Tuple[float, ...]
    temperature_values: Tuple[float, ...]
    vibration_frequency: float
    vibration_amplitude: float
    vibration_angle: float
    vibration_psd_frequencies: Tuple[float, ...]
    vibration_psd_values: Tuple[float, ...]
    acceleration: Tuple[float, ...]
    record_topics: Tuple[str, ...]
    record_decimation: int
    record_compression: str
    record_overwrite: bool
    input_horizon: float

    def _check(self) -> None:
        period_ns = 1e9 / self.output_rate
        if abs(period_ns - round(period_ns)) > 1e-6 * period_ns or round(period_ns) < 1:
            raise _fail('output.rate',
                        f'1e9 / rate must be a whole number of ns, got rate {self.output_rate!r}')
        if self.block_duration * self.output_rate < 1.0 - 1e-9:
            raise _fail('output.block_duration', 'must hold at least one output sample')
        if len(self.shock_times) != len(self.shock_peaks):
            raise _fail('scenario.shock_peaks',
                        f'has {len(self.shock_peaks)} values but scenario.shock_times has '
                        f'{len(self.shock_times)}')
        if len(self.rate_values) != len(self.rate_times):
            raise _fail('scenario.rate_values',
                        f'has {len(self.rate_values)} values but scenario.rate_times has '
                        f'{len(self.rate_times)}')
        if any(b < a for a, b in zip(self.rate_times, self.rate_times[1:])):
            raise _fail('scenario.rate_times', 'must not decrease (a repeated time is a step)')
        if len(self.acceleration) not in (0, 2):
            raise _fail('scenario.acceleration',
                        f'give [x, y] in m/s^2 (or nothing), got {len(self.acceleration)} '
                        f'values')
        if self.vibration_frequency > self.output_rate / 40.0:
            raise _fail('scenario.vibration_frequency',
                        f'{self.vibration_frequency:g} Hz is above output.rate / 40 = '
                        f'{self.output_rate / 40.0:g} Hz: the vibration is sampled at '
                        f'output.rate and interpolated linearly')
        self._check_psd()
        if len(self.temperature_values) != len(self.temperature_times):
            raise _fail('scenario.temperature_values',
                        f'has {len(self.temperature_values)} values but '
                        f'scenario.temperature_times has {len(self.temperature_times)}')
        if any(b < a for a, b in zip(self.temperature_times, self.temperature_times[1:])):
            raise _fail('scenario.temperature_times',
                        'must not decrease (a repeated time is a step)')
        if self.shock_angles and len(self.shock_angles) != len(self.shock_times):
            raise _fail('scenario.shock_angles',
                        f'has {len(self.shock_angles)} values but scenario.shock_times has '
                        f'{len(self.shock_times)}')

    def _check_psd(self) -> None:
        """Refuse a random-vibration profile that is not a band (``core.vibration``)."""
        freqs, values = self.vibration_psd_frequencies, self.vibration_psd_values
        if len(values) != len(freqs):
            raise _fail('scenario.vibration_psd_values',
                        f'has {len(values)} values but scenario.vibration_psd_frequencies has '
                        f'{len(freqs)}')
        if not freqs:
            return
        if len(freqs) < 2:
            raise _fail('scenario.vibration_psd_frequencies',
                        f'needs at least 2 points (a band, log-log between them), got '
                        f'{len(freqs)}')
        if any(b <= a for a, b in zip(freqs, freqs[1:])):
            raise _fail('scenario.vibration_psd_frequencies', 'must increase strictly')
        if freqs[-1] > self.output_rate / 40.0:
            raise _fail('scenario.vibration_psd_frequencies',
                        f'{freqs[-1]:g} Hz is above output.rate / 40 = '
                        f'{self.output_rate / 40.0:g} Hz: the vibration is sampled at '
                        f'output.rate and interpolated linearly')
        df = self.output_rate / vibration.period_samples(self.output_rate)
        lines = math.floor(freqs[-1] / df + 1e-9) - math.ceil(freqs[0] / df - 1e-9) + 1
        if lines < vibration.MIN_LINES:
            raise _fail('scenario.vibration_psd_frequencies',
                        f'the band {freqs[0]:g} .. {freqs[-1]:g} Hz holds {max(lines, 0)} '
                        f'lines of the multisine (spacing {df:.6g} Hz at this output.rate), '
                        f'fewer than {vibration.MIN_LINES}')
        rms = math.sqrt(vibration.psd_mean_square(freqs, values)) * STANDARD_GRAVITY
        if not rms <= MAX_RANDOM_RMS:
            raise _fail('scenario.vibration_psd_values',
                        f'the rms of the profile, {rms / STANDARD_GRAVITY:.6g} g, is beyond '
                        f'{MAX_RANDOM_RMS / STANDARD_GRAVITY:.6g} g: its peaks (several rms) '
                        f'would pass the physical bound of 10^6 g')

    @property
    def random_vibration_rms_g(self) -> float:
        """Return the random vibration's rms, g (the integral of its PSD; 0 without one)."""
        if not self.vibration_psd_frequencies:
            return 0.0
        return math.sqrt(vibration.psd_mean_square(self.vibration_psd_frequencies,
                                                   self.vibration_psd_values))

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

    @property
    def block_samples(self) -> int:
        """Output samples per published block (at least one)."""
        return max(1, int(round(self.block_duration / (self.output_period_ns * 1e-9))))


@dataclass(frozen=True)
class SimConfig:
    """
    The full resolved configuration of a run.

    The groups hold the device as simulated: with ``device.seed`` > 0, the drawn one
    (``core.device``). ``configured`` holds, for each parameter the draw changed, its value as
    configured (lists as tuples), which :func:`to_flat` returns: the configuration that
    draws this device again.
    """

    ring: RingParams = field(default_factory=RingParams)
    legs: LegParams = field(default_factory=LegParams)
    modes: ModeParams = field(default_factory=ModeParams)
    electrodes: ElectrodeParams = field(default_factory=ElectrodeParams)
    drive: DriveParams = field(default_factory=DriveParams)
    gyro: GyroParams = field(default_factory=GyroParams)
    control: ControlParams = field(default_factory=ControlParams)
    integrator: IntegratorParams = field(default_factory=IntegratorParams)
    stops: StopParams = field(default_factory=StopParams)
    run: RunParams = field(default_factory=RunParams)
    thermal: ThermalParams = field(default_factory=ThermalParams)
    device: DeviceParams = field(default_factory=DeviceParams)
    configured: Tuple[Tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        e = self.electrodes
        if self.outer_radius <= self.ring.radius:
            raise _fail('electrodes.outer_radius',
                        f'must be larger than ring.radius, got {self.outer_radius!r}')
        if e.inner_radius and e.inner_radius >= self.ring.radius:
            raise _fail('electrodes.inner_radius',
                        f'must be smaller than ring.radius, got {e.inner_radius!r}')
        if not self.modes.companions and any(
                y != 0.0 for _, _, y in self.run.scheduled_shocks()):
            raise _fail('scenario.shock_angles',
                        'a shock off the x axis drives q1s: needs modes.companions')
        if self.gyro.enabled and not self.modes.companions:
            raise _fail('gyro.enabled', 'needs modes.companions: true (the sense mode is the '
                        'sin 2theta companion q2s)')
        if self.run.rate_values and not self.gyro.enabled:
            raise _fail('scenario.rate_values', 'a rate acts on the gyroscope: needs '
                        'gyro.enabled: true')
        for rate in self.run.rate_values:
            refusal = self.rate_range_refusal('scenario.rate_values', rate)
            if refusal is not None:
                raise ParameterError(refusal)
        if self.gyro.enabled:
            if self.modes.count < 2:
                raise _fail('gyro.enabled', 'needs at least 2 modes (the 2theta pair)')
            ratio = self.run.output_rate / self.gyro.output_rate
            if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
                raise _fail('gyro.output_rate',
                            f'output.rate ({self.run.output_rate:g} Hz) must be a whole '
                            f'multiple of it, got {self.gyro.output_rate:g} Hz')
        if self.drive.amplitude != 0.0 and self.modes.count < 2:
            raise _fail('drive.amplitude', 'drives the 2theta mode: needs at least 2 modes')
        if self.stops.enabled and self.stops.gap >= self.electrodes.gap:
            raise _fail('stops.gap', f'must be below electrodes.gap '
                        f'({format_number(self.electrodes.gap)} m): a stop beyond the '
                        f'electrodes never acts, got {format_number(self.stops.gap)} m')
        self._check_control()
        self._check_voltages()
        self._check_block_memory()

    def _check_control(self) -> None:
        c = self.control
        refused = MODES[c.mode].refusal(self)
        if refused is not None:
            raise _fail(*refused)
        if not MODES[c.mode].closed:
            return
        if not (self.gyro.bias_voltage or self.electrodes.outer_voltage):
            raise _fail('electrodes.outer_voltage', f'must not be 0 with control.mode: '
                        f'{c.mode}: the loops read the drive through the pick-off, whose gain is '
                        'the bias voltage (gyro.bias_voltage, 0 = electrodes.outer_voltage), and '
                        'at 0 V they would divide by zero (bias the pick-off with '
                        'gyro.bias_voltage to run without V_o)')

    def _check_voltages(self) -> None:
        # K_c (eq. 26) below m omega^2 of every coordinate: static pull-in with mechanical
        # frequencies; with folded (electrically softened) ones the static pull-in voltage of
        # the ring with its frequencies taken as mechanical (module docstring).
        e = self.electrodes
        kc = self.electrostatic_stiffness()
        for i, (f_hz, k) in enumerate(zip(self.modes.coordinate_frequencies(),
                                          self.linear_stiffnesses())):
            if kc < k:
                continue
            inner = self.inner_radius * e.inner_voltage ** 2
            outer = self.outer_radius * e.outer_voltage ** 2
            name = 'electrodes.inner_voltage' if inner > outer else 'electrodes.outer_voltage'
            v_o, v_i = self.voltage_limits()
            limits = f'|V_o| < {v_o:.4g} V with V_i = 0, |V_i| < {v_i:.4g} V with V_o = 0'
            if e.fold_linear_stiffness:
                raise _fail(name, f'beyond the static pull-in voltage of the ring with these '
                            f'frequencies taken as mechanical: the electrostatic stiffness '
                            f'K_c (eq. 26) is {kc / k:.3g} times m omega^2 of coordinate {i} '
                            f'({f_hz} Hz), the model needs it below ({limits})')
            raise _fail(name, f'at or beyond static pull-in: the electrostatic stiffness is '
                        f'{kc / k:.3g} times the stiffness of coordinate {i} ({f_hz} Hz) '
                        f'({limits})')

    def _check_block_memory(self) -> None:
        r = self.run
        values = self.block_values_per_sample()
        size = 8 * values * r.block_samples
        if size > MAX_BLOCK_BYTES:
            most = MAX_BLOCK_BYTES // (8 * values)
            raise _fail('output.block_duration',
                        f'a block of {r.block_samples} samples (output.rate '
                        f'{format_number(r.output_rate)} Hz x {format_number(r.block_duration)}'
                        f' s) of {values} values is {size / 2 ** 20:.4g} MiB of messages, more '
                        f'than the {MAX_BLOCK_BYTES // 2 ** 20} MiB a block may hold: at most '
                        f'{most} samples per block here (output.block_duration <= '
                        f'{format_number(most / r.output_rate)} s at this rate)')

    def block_values_per_sample(self) -> int:
        """
        Values per sample in the block messages: t + q, t + K gaps + min, t + K C.

        With the gyroscope also ``~/demodulator`` (t + 4 channels at every sample);
        ``~/control`` has a row per loop update, not per sample, and is left out.
        """
        n = self.modes.count * (2 if self.modes.companions else 1)
        return 4 + n + 2 * self.electrodes.count + (5 if self.gyro.enabled else 0)

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

    def linear_stiffnesses(self) -> List[float]:
        """Return m omega^2 of every coordinate, N/m (the frequencies as given)."""
        return [m * (2.0 * math.pi * f) ** 2
                for m, f in zip(self.modal_masses(), self.modes.coordinate_frequencies())]

    def electrostatic_stiffness(self) -> float:
        """K_c = 2 pi A_eps (r_o V_o^2 + r_i V_i^2) / d_g^2 of eq. (26), N/m."""
        e = self.electrodes
        return 2.0 * math.pi * self.a_eps * (
            self.outer_radius * e.outer_voltage ** 2
            + self.inner_radius * e.inner_voltage ** 2) / e.gap ** 2

    def max_input_rate(self) -> float:
        """
        Return the largest |angular rate| of the sensor frame the model takes, rad/s.

        :data:`MAX_RATE_FRACTION` of the lowest coordinate's angular frequency: 703.7 rad/s
        (40 320 deg/s) on the default device (1theta at 11.2 kHz).
        """
        return MAX_RATE_FRACTION * 2.0 * math.pi * min(self.modes.coordinate_frequencies())

    def rate_range_refusal(self, name: str, rate: float) -> Optional[str]:
        """Return why the angular rate ``rate`` (rad/s) is refused, naming ``name`` (None: ok)."""
        limit = self.max_input_rate()
        if abs(rate) <= limit:
            return None
        f_min = min(self.modes.coordinate_frequencies())
        return (f'{name}: {rate:.6g} rad/s is beyond the range of the model, |Omega| <= '
                f'{limit:.4g} rad/s ({math.degrees(limit):.0f} deg/s: '
                f'{100 * MAX_RATE_FRACTION:g} % of the lowest mode, 2 pi {f_min:g} Hz; beyond '
                f'it the hoop stiffening the model leaves out matters)')

    def voltage_limits(self) -> Tuple[float, float]:
        """
        Return the largest |V_o| (with V_i = 0) and |V_i| (with V_o = 0) the model takes, V.

        Both voltages together must keep K_c (eq. 26) below ``min(m omega^2)``; see the module
        docstring for why. Default device: 215.6 V and 217.6 V.
        """
        k_min = min(self.linear_stiffnesses())
        unit = 2.0 * math.pi * self.a_eps / self.electrodes.gap ** 2
        return (math.sqrt(k_min / (unit * self.outer_radius)),
                math.sqrt(k_min / (unit * self.inner_radius)))

    def electrostatic_softening_ratios(self) -> List[float]:
        """
        Return K_c / k_mech per coordinate, eq. (26) (>= 1 means static pull-in).

        k_mech = m omega^2, or m omega^2 + K_c when the frequencies already contain K_c
        (``fold_linear_stiffness``), in which case the ratio is below 1 for any voltage.
        """
        kc = self.electrostatic_stiffness()
        fold = self.electrodes.fold_linear_stiffness
        return [kc / (k + kc if fold else k) for k in self.linear_stiffnesses()]

    @property
    def shock_duration_s(self) -> float:
        """Half-sine duration, s: ``shock.duration`` or one tenth of the 2theta period."""
        if self.run.shock_duration > 0.0:
            return self.run.shock_duration
        freqs = self.modes.frequencies
        f2 = freqs[1] if len(freqs) > 1 else freqs[0]
        return 0.1 / f2


_GROUPS = {f.name: f.default_factory for f in fields(SimConfig) if f.name != 'configured'}


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
    for spec in _DERIVED:
        check_value(spec, flat[spec.name])
    config = _build(flat)
    if config.device.seed == 0:
        return config
    return _draw_device(config, flat)


def _build(flat: Mapping[str, Any], configured: Tuple[Tuple[str, Any], ...] = ()) -> SimConfig:
    """Build and check the configuration of a complete flat mapping (coerced values)."""
    kwargs: Dict[str, Dict[str, Any]] = {group: {} for group in _GROUPS}
    for spec in PARAMETERS:
        if spec not in _DERIVED:
            kwargs[spec.group][spec.attribute] = _field_value(spec, flat[spec.name])
    built: Dict[str, Any] = {}
    for group, cls in _GROUPS.items():
        if group == 'modes' and not kwargs[group]['frequencies']:
            kwargs[group]['frequencies'] = _frequencies_from_structure(
                built['ring'], built['legs'], flat['modes.count'])
        built[group] = cls(**kwargs[group])
    return SimConfig(**built, configured=configured)


def _draw_device(config: SimConfig, flat: Mapping[str, Any]) -> SimConfig:
    """
    Return the device ``device.seed`` draws from ``config`` (``core.device``, D1-D5).

    ``config`` is the device as configured, already checked; the drawn values go through the
    same checks, and a refusal names the seed and the check.
    """
    from ring_gyro_sim.core import device
    seed = config.device.seed
    try:
        changed = device.drawn_values(config)
        if not changed:
            return config
        configured = tuple(sorted((name, _field_value(SPECS[name], flat[name]))
                                  for name in changed))
        return _build({**flat, **changed}, configured)
    except ParameterError as exc:
        raise _fail('device.seed', f'seed {seed} draws an invalid device: {exc}') from None


def paper_config(values: Optional[Mapping[str, Any]] = None) -> SimConfig:
    """
    Return the paper's resonator (:data:`PAPER_RESONATOR`) with ``values`` laid over it.

    What reproduces the paper (its cases, Figs. 4 and 9, the calibration) builds its
    configuration here, so that it does not depend on the defaults, which are the gyroscope.
    """
    return build_config({**PAPER_RESONATOR, **dict(values or {})})


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
    """
    Return the flat ``{dotted name: value}`` mapping that rebuilds ``config`` (for metadata).

    The configuration as configured: with ``device.seed``, the configured values of the
    parameters the draw changed (:attr:`SimConfig.configured`) and the seed, which draw the
    same device again (``build_config(to_flat(c)) == c``).
    """
    out: Dict[str, Any] = {}
    for spec in PARAMETERS:
        value = getattr(getattr(config, spec.group), spec.attribute)
        out[spec.name] = list(value) if spec.kind in LIST_KINDS else value
    for name, value in config.configured:  # the configured values, not the drawn device's
        out[name] = list(value) if SPECS[name].kind in LIST_KINDS else value
    return out


def device_values(config: SimConfig) -> Dict[str, Any]:
    """
    Return the flat values of the device as simulated (with ``device.seed``: the drawn one).

    :func:`to_flat` gives the configuration (the configured values and the seed, which draw
    the device again); this gives what the groups hold, for the parameters the draw changed.
    """
    out = {}
    for name, _ in config.configured:
        spec = SPECS[name]
        value = getattr(getattr(config, spec.group), spec.attribute)
        out[name] = list(value) if spec.kind in LIST_KINDS else value
    return out


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
