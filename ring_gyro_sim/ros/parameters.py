# Copyright 2025 ring_gyro_sim developers
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
ROS parameters of the node, declared from the one table ``core.params.PARAMETERS``.

:func:`declare_parameters` declares every row with a descriptor (description with the unit,
range, read-only where a change needs a restart) and builds the
:class:`~ring_gyro_sim.core.params.SimConfig`; :func:`updated_config` is what the node's
set-parameters callback uses to validate a run-time change: it rebuilds the configuration
with :func:`~ring_gyro_sim.core.params.build_config`, whose
:class:`~ring_gyro_sim.core.errors.ParameterError` text ('<name>: <reason>') becomes the
refusal reason.

All parameters are dynamically typed: users write ``14000`` for ``14000.0`` (rcl then hands
over an INTEGER) and an empty YAML list arrives as "not set";
:func:`~ring_gyro_sim.core.params.coerce` turns both into the kind the table says, and refuses
anything else by name.
"""

import math
from typing import Any, Dict, Iterable, List, Mapping, Tuple

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter

from ring_gyro_sim.core import params
from ring_gyro_sim.core.errors import ParameterError

_INT_LIMIT = 2 ** 63 - 1
_CHOICES = {'drive.start_on': params.DRIVE_START_CHOICES,
            'integrator.method': params.INTEGRATOR_METHODS,
            'record.compression': params.RECORD_COMPRESSIONS}
# Parameters rclpy itself declares on every node (not ours, never refused here).
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def descriptor(spec: params.ParamSpec) -> ParameterDescriptor:
    """Return the ParameterDescriptor of one row of the table."""
    unit = 'dimensionless' if spec.unit == '-' else spec.unit
    constraints: List[str] = []
    d = ParameterDescriptor(name=spec.name, description=f'{spec.description} [{unit}]',
                            read_only=spec.read_only, dynamic_typing=True)
    if spec.kind == 'float' and (spec.minimum is not None or spec.maximum is not None):
        d.floating_point_range = [FloatingPointRange(
            from_value=-math.inf if spec.minimum is None else float(spec.minimum),
            to_value=math.inf if spec.maximum is None else float(spec.maximum), step=0.0)]
    elif spec.kind == 'int':
        d.integer_range = [IntegerRange(
            from_value=-_INT_LIMIT if spec.minimum is None else int(spec.minimum),
            to_value=_INT_LIMIT if spec.maximum is None else int(spec.maximum), step=1)]
    if spec.kind == 'float':
        constraints.append('a number (integer literals are accepted)')
    elif spec.kind == 'float_list':
        constraints.append('a list of numbers (an empty list means empty)')
    elif spec.kind == 'str_list':
        constraints.append('a list of strings (an empty list means empty)')
    if spec.name in _CHOICES:
        constraints.append('one of ' + ', '.join(_CHOICES[spec.name]))
    if spec.read_only:
        constraints.append('read-only: set it in the params file (a change needs a restart)')
    d.additional_constraints = '; '.join(constraints)
    return d


def _default(spec: params.ParamSpec) -> Any:
    # rclpy types an empty list as a BYTE_ARRAY; "not set" is what rcl makes of [] anyway.
    if spec.kind == 'float_list':
        return [float(x) for x in spec.default] or None
    if spec.kind == 'str_list':
        return [str(x) for x in spec.default] or None
    return spec.default


def declare_parameters(node) -> params.SimConfig:
    """
    Declare every parameter of the table on ``node`` and build the validated SimConfig.

    Values come from the node's overrides (``--ros-args --params-file F``, ``-p``) or the
    table's defaults.

    Raises
    ------
    ParameterError
        A value is refused (by a descriptor range or by :func:`build_config`); the message
        starts with the parameter name.

    """
    for spec in params.PARAMETERS:
        try:
            node.declare_parameter(spec.name, _default(spec), descriptor(spec))
        except InvalidParameterValueException as exc:
            raise ParameterError(_explain(node, spec) or f'{spec.name}: {_reason(exc)}') \
                from None
    values = {spec.name: plain(node.get_parameter(spec.name).value) for spec in params.PARAMETERS}
    return params.build_config(values)


def unknown_overrides(node) -> List[str]:
    """Return the names given to the node (params file, ``-p``) that are not in the table."""
    # rclpy has no public accessor for the overrides it was started with.
    overrides: Mapping[str, Any] = getattr(node, '_parameter_overrides', {}) or {}
    return sorted(name for name in overrides
                  if name not in params.SPECS and name not in ROS_OWN_PARAMETERS
                  and not name.startswith('qos_overrides.'))


def plain(value: Any) -> Any:
    """Return a parameter value as plain Python (array.array -> list)."""
    if value is not None and not isinstance(value, (bool, int, float, str)):
        return list(value)
    return value


def updated_config(current: params.SimConfig,
                   changes: Iterable[Parameter]) -> Tuple[params.SimConfig, Dict[str, Any]]:
    """
    Return the configuration ``current`` with ``changes`` applied, validated.

    Parameters that are not ours (``use_sim_time``) are left out.

    Returns
    -------
    (SimConfig, dict)
        The new configuration and the changed parameters as ``{name: coerced value}`` (what
        the recorder stores).

    Raises
    ------
    ParameterError
        The message names the parameter and the reason (the set-parameters refusal reason).

    """
    flat = params.to_flat(current)
    changed: Dict[str, Any] = {}
    for p in changes:
        if p.name in ROS_OWN_PARAMETERS:
            continue
        if p.name not in params.SPECS:
            raise ParameterError(f'{p.name}: unknown parameter')
        value = plain(p.value)
        if value is None and params.SPECS[p.name].kind not in ('float_list', 'str_list'):
            raise ParameterError(f'{p.name}: cannot be unset at run time')
        changed[p.name] = params.coerce(p.name, value)
    flat.update(changed)
    return params.build_config(flat), changed


def _explain(node, spec: params.ParamSpec) -> str:
    """Return the table's message for an override that a descriptor refused ('' if none)."""
    override = (getattr(node, '_parameter_overrides', {}) or {}).get(spec.name)
    if override is None:
        return ''
    try:
        params.build_config({spec.name: plain(override.value)})
    except ParameterError as exc:
        return str(exc)
    return ''


def _reason(exc: InvalidParameterValueException) -> str:
    text = str(exc.args[0]) if exc.args else str(exc)
    return text.split('Reason: ', 1)[-1]
