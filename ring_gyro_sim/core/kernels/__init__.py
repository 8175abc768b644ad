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
Compiled kernels: the electrostatic force, the time stepper and the output channels.

A package of modules by job; every public name is re-exported here, so that callers write
``from ring_gyro_sim.core import kernels`` and ``kernels.run_samples(...)``:

- :mod:`~ring_gyro_sim.core.kernels.status`: the status codes a kernel stops with, their text;
- :mod:`~ring_gyro_sim.core.kernels.splitting`: the splitting's coefficients and
  :class:`Method`;
- :mod:`~ring_gyro_sim.core.kernels.drift`: the drift (A), the exact linear flow and its
  propagators;
- :mod:`~ring_gyro_sim.core.kernels.force`: the electrostatic force (:class:`Force`,
  :func:`nl_accel`);
- :mod:`~ring_gyro_sim.core.kernels.forcing`: the external forcing of a stage (:class:`Drive`,
  :class:`Forcing`);
- :mod:`~ring_gyro_sim.core.kernels.stops`: the mechanical stops' contact force
  (:class:`Stops`, :func:`stop_accel`);
- :mod:`~ring_gyro_sim.core.kernels.step`: the kicks, the splitting step and
  :func:`run_samples` (:class:`Scratch`);
- :mod:`~ring_gyro_sim.core.kernels.channels`: the output channels (:func:`output_channels`);
- :mod:`~ring_gyro_sim.core.kernels.readout`: the read-out electronics' kernels
  (:func:`pickoff_volts`, :func:`iq_fit`);
- :mod:`~ring_gyro_sim.core.kernels.envelope`: the averaged model's closed-loop slow flow
  (:class:`EnvelopeModel`, :func:`run_periods`, :func:`force_harmonic`,
  :func:`pickoff_harmonic`).

Method
------
The equations of motion (eq. 28) are ``x'' = L(x, x') + a_nl(x) + a_ext(t)`` with
``L = -(omega/Q) x' - omega^2 x`` linear and per coordinate. They are split into

* **A**, the damped linear oscillators, propagated *exactly* (closed-form 2x2 flow per
  coordinate: no phase error, no numerical damping whatever the step; ``drift.py``);
* **B**, the kick ``v += tau * (a_nl(x) + a_ext(t))`` by the electrostatic force (which
  depends on positions only; ``force.py``) and the external forcing (shock, base
  acceleration, drive; ``forcing.py``).

Because the B-flow depends on positions only and A is at most linear in velocities,
``[B, [B, [B, A]]] = 0``: the splitting has the Runge-Kutta-Nystrom structure, so the
optimised symmetric RKN splittings of Blanes & Moan (2002, J. Comput. Appl. Math. 142,
313-330) apply, in BAB form with the last kick's force reused as the next step's first
(FSAL): ``bm6`` = SRKN_11^b (order 6, 11 force evaluations per step), ``bm4`` = SRKN_6^b
(order 4, 6 evaluations), ``strang`` (order 2, 1 evaluation). Undamped, the method is
symplectic: the energy error stays bounded (no drift), which the tests check.

In a rotating sensor frame (``gyro.enabled`` with a rate) B also holds the Coriolis term,
linear in the velocities, and is integrated exactly as well (``step._kick_rotating``); the
commutator identity above then no longer holds exactly, so the RKN order is not guaranteed
for the rotation's part. It is small (``2 kappa Omega / omega`` ~ 1e-5 of the oscillators'
rates at 300 deg/s) and measured: ``test/core/test_rotation.py`` holds the 1e-4 budget
against DOP853 while the frame spins up to 50 rad/s.

Error budget (measured in ``test/core/test_simulator.py`` and ``benchmarks/``): the error is
proportional to the nonlinear force (the linear part is exact) times ``(omega h)^p``. At the
default step (see ``simulator.default_max_step``) the paper configuration stays within 1e-4 of
the peak q1 of a DOP853 reference at rtol 1e-10 over 20 ms after a 10 000 g shock.
Steps that overlap a shock pulse are cut into sub-steps of at most ``T_s / 16`` so the
half-sine (whose derivative jumps at both ends) is resolved. With mechanical stops, a step that
may touch one is cut into sub-steps of ``pi / (16 omega_c)``, the stiffest contact's
half-period, and a full step that touched one is taken again so (``stops.py``, S4); the stops'
force joins the electrostatic one in B (its loading or unloading stiffness is chosen by the
sign of the penetration's rate, the only use of the velocities outside the rotating kick).

Everything is float64 and SI. Kernels take arrays and scalars grouped by what they are, in
named tuples (:class:`Force`, :class:`Drive`, :class:`Forcing`, :class:`Method`,
:class:`Scratch` for :func:`run_samples`; :class:`OutputGeometry` and :class:`Channels` for
:func:`output_channels`; inside the step, ``step.Span`` and ``forcing.DrivePhasors``), so
that a call reads like its meaning and two arrays cannot be swapped silently (a tuple in the
wrong place does not compile); a kernel's other arguments are its state, counts and outputs.
``core/engine/full.py`` builds the tuples (once per configuration where they do not change),
validates inputs, calls the kernels, and checks the result. A state that leaves the model's
range stops the kernel with a status code and the index of the angle (never NaN).
The two entry points (``run_samples``, ``output_channels``) release the GIL, so that a
recorder thread can serialise and compress while they run.

numba's disk cache
------------------
The kernels are compiled with ``cache=True``: the first use compiles them and writes the
machine code next to the modules (``__pycache__``, or the user's cache directory when the
package is read-only); later processes load it. The cache of a function is invalidated when
*its own* source file changes, not when a function it inlines or calls from another module
does: ``run_samples`` (``step.py``) carries the force (``force.py``), the drift (``drift.py``)
and the forcing (``forcing.py``) compiled into it, and ``output_channels`` (``channels.py``)
the angle values of ``force.py``. After changing any module of this package, delete the
cache before running or measuring anything::

    find ring_gyro_sim -name __pycache__ -exec rm -rf {} +

(or point ``NUMBA_CACHE_DIR`` at an empty directory); otherwise a process may run the old code
of a callee inside a cached caller.

Design
------
Strict IEEE arithmetic throughout (no fast-math: no FMA contraction, no reassociated sums), so
that results do not depend on the vector width or the CPU, and every sum runs in a fixed order.
The stages of a step form one chain of dependent operations (each force needs the previous
drift, each drift the previous kick), so the latency of that chain, not the number of
operations, sets the cost: the code is shaped to shorten it and to let the loops over the
angles vectorise. The measured costs, and what was tried and not kept, are in
``doc/performance.md`` ("The kernels' costs, measured").

* numba's reference counting: a function that takes arrays and has branches increments and
  decrements every array argument atomically on every call unless its pruning pass can prove
  the pairs redundant. ``run_samples`` is compiled with ``_nrt=False`` (it allocates
  nothing); :func:`output_channels` copies each sample's coordinates instead of taking a
  (reference-counted) view per sample;
* the force's common case (``force._force``) has no branch that stores, returns early or
  calls out (such a branch makes the inlined path much slower); ``force._force_any`` decides
  between it and the out-of-line ``force._force_general`` before either runs, so that a state
  with excited companions (sine content) does not evaluate the common case first for nothing;
* floating-point min, max and sum reductions do not vectorise without fast-math (each is a
  chain of dependent operations): the range check counts the angles outside (-1, 1) as
  integers (``force._all_inside``), the smallest gap's grid maximum is found in independent
  lanes (``channels._first_argmax``; the maximum is exact in any order), and the projections
  sum each coordinate in a register, the coordinates as independent chains;
* the series is evaluated by Estrin's scheme written out for 4, 8, 12 or 16 coefficients
  (``force._series_values``), one loop over the angles with the coefficients in registers
  (Horner's rule is one multiply and add per degree on the chain); longer series take
  Horner's rule three degrees per pass (``force._horner``);
* the angle values take six or three coordinates per pass (``force._angle_values``), so that
  they are not stored and reloaded on the chain once per coordinate; the range check over the
  angles runs only when ``sum |q_n|`` reaches the gap (``force._REACH_INSIDE``);
* the pieces of a step (``step._cut_step``, ``step._step``, ``drift._kick_drift``,
  ``forcing._external``, ``force._force``) are ``inline='always'``: inlined, they cost what
  the loop written out would; called, a step would pass ~20 array structures every step.
  ``force._force_general`` stays out of line (the rare path; inlining it does not pay);
* named tuples cost nothing inside a kernel, but numba's dispatcher types each one on every
  call from Python (about a microsecond each): negligible on a 10 ms block, noticeable only
  for very short calls;
* loops over the angles run innermost on coordinate-major arrays (``(n, angles)``) so that
  they vectorise; ``fe`` is zeroed once per call, since a loop that only zeroes a short array
  compiles to a ``memset`` call.
"""

from ring_gyro_sim.core.kernels.channels import (Channels, output_channels, OutputGeometry,
                                                 RING_MAX_MARGIN)
from ring_gyro_sim.core.kernels.drift import (linear_propagators, pair_propagators,
                                              pair_system)
from ring_gyro_sim.core.kernels.envelope import (EnvelopeModel, force_harmonic,
                                                 pickoff_harmonic, run_periods)
from ring_gyro_sim.core.kernels.force import (estrin_layout, ESTRIN_MAX_SLOTS, Force,
                                              member_basis, NEEDS_GENERAL, nl_accel,
                                              orbit_angle)
from ring_gyro_sim.core.kernels.forcing import Drive, drive_phasor, Forcing
from ring_gyro_sim.core.kernels.readout import iq_fit, pickoff_volts
from ring_gyro_sim.core.kernels.splitting import Method, splitting_coefficients
from ring_gyro_sim.core.kernels.status import (describe_status, STATUS_INNER_CONTACT,
                                               STATUS_NONFINITE, STATUS_OK,
                                               STATUS_OUTER_CONTACT, STATUS_SERIES_RANGE)
from ring_gyro_sim.core.kernels.step import run_samples, Scratch
from ring_gyro_sim.core.kernels.stops import (IMPACTS as STOP_IMPACTS,
                                              IN_CONTACT as STOP_IN_CONTACT,
                                              LAST_CONTACT as STOP_LAST_CONTACT, stop_accel,
                                              stop_angles, stop_max_substep, Stops,
                                              SUBSTEPS as STOP_SUBSTEPS)

__all__ = ['STATUS_OK', 'STATUS_OUTER_CONTACT', 'STATUS_INNER_CONTACT', 'STATUS_SERIES_RANGE',
           'STATUS_NONFINITE', 'NEEDS_GENERAL', 'Force', 'Drive', 'Forcing', 'Method', 'Scratch',
           'ESTRIN_MAX_SLOTS', 'estrin_layout', 'orbit_angle', 'describe_status',
           'splitting_coefficients', 'linear_propagators', 'pair_propagators', 'pair_system',
           'member_basis', 'nl_accel', 'drive_phasor', 'run_samples', 'OutputGeometry',
           'Channels', 'output_channels', 'RING_MAX_MARGIN',
           'pickoff_volts', 'iq_fit', 'Stops', 'stop_accel', 'stop_angles',
           'stop_max_substep', 'STOP_IMPACTS', 'STOP_IN_CONTACT', 'STOP_LAST_CONTACT',
           'STOP_SUBSTEPS', 'EnvelopeModel', 'force_harmonic', 'pickoff_harmonic',
           'run_periods']
