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
The metrics of a sweep point: the tables of what each kind of point measures.

Each entry is ``name: (type, unit, description)``. The spec checks what a sweep asks for
against them (``sweep.spec``), a point fills them (``sweep.point``), the results label
their variables with them (``sweep.results``).
"""

from collections import OrderedDict
from typing import Dict

__all__ = ['DEVICE_FIELDS', 'ENVIRONMENT_METRICS', 'FIGURES', 'GYRO_METRICS', 'METRICS',
           'metric_table']


METRICS: Dict[str, tuple] = OrderedDict([
    ('final_branch', ('str', '', "branch q2 ends on: 'upper', 'lower', 'contact' ('none': "
                                 'no drive)')),
    ('final_q2_m', ('float', 'm', 'mean q2 envelope over the last 0.2 s')),
    ('min_q2_m', ('float', 'm', 'smallest q2 envelope (1 ms windows)')),
    ('min_q2_time_s', ('float', 's', 'time of the smallest q2 envelope')),
    ('q2_after_shock_m', ('float', 'm', 'largest q2 envelope in the first 10 ms')),
    ('min_gap_m', ('float', 'm', 'smallest outer gap over the run (0 at contact)')),
    ('min_gap_fraction', ('float', '1', 'min_gap_m / d_g')),
    ('contact', ('bool', '', 'the ring touched an electrode (the run stopped there)')),
    ('contact_time_s', ('float', 's', 'time of the contact (nan: none)')),
    ('contact_theta_deg', ('float', 'deg', 'where the ring touched, from x (nan: none)')),
    ('return_time_s', ('float', 's', 'time q2 is back above the branch threshold for good '
                                     '(nan: never left it, or ends lower)')),
    ('settled', ('bool', '', 'q2 envelope within 5 % over the last 0.2 s (branch decided)')),
    ('settle_time_s', ('float', 's', 'last time q2 was more than 5 % off its final value')),
    ('peak_q1_m', ('float', 'm', 'largest q1 envelope')),
    ('final_q1_m', ('float', 'm', 'mean q1 envelope over the last 0.2 s')),
    ('status', ('str', '', "simulator status at the end ('running', 'contact', 'failed')")),
])
"""Metrics of a point: name -> (kind, unit, meaning); every record holds all of them."""


FIGURES: Dict[str, tuple] = OrderedDict([
    ('bias_rad_s', ('float', 'rad/s', 'zero-rate output b = r(0) / S of the factory rate table '
                                      'at the reference temperature (K2)')),
    ('quadrature_rad_s', ('float', 'rad/s', 'quadrature r_q(0) / S at zero rate, at the '
                                            'reference temperature (K1)')),
    ('scale_factor', ('float', 'readout/(rad/s)', 'S of the factory rate table (K2): m/s^2 '
                                                  'per rad/s with force-to-rebalance, V open '
                                                  'loop')),
    ('scale_factor_error_ppm', ('float', 'ppm', 'S / S_nominal - 1, S_nominal the nominal '
                                                "device's (device.seed 0)")),
    ('bias_tc_rad_s_k', ('float', 'rad/s/K', 'b_1 of the K3 fit: the bias change per K at '
                                             'the reference (nan: no temperature points)')),
    ('scale_factor_tc_ppm_k', ('float', 'ppm/K', 's_1 of the K3 fit: the relative scale '
                                                 'factor change per K at the reference')),
    ('quadrature_tc_rad_s_k', ('float', 'rad/s/K', "the K3 fit of the quadrature's change: "
                                                   'per K at the reference')),
])
"""A device's datasheet figures (:func:`gyroscope_figures`): name -> (kind, unit, meaning)."""


DEVICE_FIELDS: Dict[str, tuple] = OrderedDict([
    ('split_hz', ('float', 'Hz', '2theta pair: principal frequency f_x - f_y (companion)')),
    ('frequency_axis_deg', ('float', 'deg', '2theta pair: ring angle of the axis of f_x')),
    ('q_mismatch', ('float', '1', '2theta pair: Q_y / Q_x - 1 of its principal Q')),
    ('damping_axis_deg', ('float', 'deg', '2theta pair: ring angle of the axis of Q_x')),
    ('sense_misalignment_deg', ('float', 'deg', 'gyro.sense_misalignment of the device')),
    ('phase_error_rad', ('float', 'rad', 'gyro.phase_error of the device')),
    ('pickoff_gain_mismatch', ('float', '1', 'gyro.pickoff_gain_mismatch of the device')),
])
"""The imperfections of a point's device as simulated (drawn with ``device.seed``)."""


GYRO_METRICS: Dict[str, tuple] = OrderedDict(list(FIGURES.items()) + list(DEVICE_FIELDS.items()))
"""Metrics of a gyroscope point (``kind: gyroscope``): its figures and its device."""


ENVIRONMENT_METRICS: Dict[str, tuple] = OrderedDict([
    ('rectified_bias_rad_s', ('float', 'rad/s', 'mean ~/rate over the last average s less the '
                                                "same device's without the environment")),
    ('rectified_bias_deg_per_h', ('float', 'deg/h', 'the rectified bias in deg/h')),
    ('rectified_quadrature_rad_s', ('float', 'rad/s', 'the same of the quadrature channel')),
    ('rate_rad_s', ('float', 'rad/s', 'mean ~/rate over the last average s (noise off)')),
    ('reference_rate_rad_s', ('float', 'rad/s', 'the same without the environment')),
    ('q1_amplitude_m', ('float', 'm', "closed-form amplitude of the 1theta mode's answer to "
                                      'the sine, A / (omega_1^2 - omega^2) (0: none)')),
    ('contact', ('bool', '', 'the ring touched an electrode (the run stopped: no means)')),
])
"""Metrics of an environment point (``kind: environment``)."""


def metric_table(kind: str) -> Dict[str, tuple]:
    """Return the metrics of a point of ``kind`` (``case``: :data:`METRICS`)."""
    return {'gyroscope': GYRO_METRICS, 'environment': ENVIRONMENT_METRICS}.get(kind, METRICS)
