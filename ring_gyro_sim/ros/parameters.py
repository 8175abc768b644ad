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
range with the reason for it, choices, read-only where a change needs a restart) and builds
the :class:`~ring_gyro_sim.core.params.SimConfig`; the voltages' ranges are then narrowed to
the configuration's limit (:meth:`~ring_gyro_sim.core.params.SimConfig.voltage_limits`: the
read-only geometry fixes it). An override with a name that is not in the table (``-p`` or a
params file) is refused, naming the closest known name. :func:`updated_config` is what the
node's set-parameters callback uses to validate a run-time change: it rebuilds the
configuration with :func:`~ring_gyro_sim.core.params.build_config`, whose
:class:`~ring_gyro_sim.core.errors.ParameterError` text ('<name>: <reason>') becomes the
refusal reason.

All parameters are dynamically typed: users write ``14000`` for ``14000.0`` (rcl then hands
over an INTEGER) and an empty YAML list arrives as "not set";
:func:`~ring_gyro_sim.core.params.coerce` turns both into the kind the table says, and refuses
anything else by name.

Refusals rclpy makes itself
    rclpy checks a change against the descriptors (read-only, range) and refuses undeclared
    names before the node's on-set callback runs, so the node never sees those; and for an
    undeclared name its reason is ``Invalid access to undeclared parameter(s): []``
    (``Node._check_undeclared_parameters`` consumes its generator in ``any()`` before listing
    it). :class:`CountedParameterRefusals`, a mixin placed before ``rclpy.node.Node``,
    overrides the public ``Node.set_parameters_atomically`` (what both the ``set_parameters``
    and the ``set_parameters_atomically`` services call, see rclpy's
    ``parameter_service.py``) and ``Node.set_parameters``: every refusal, rclpy's and the
    callback's, gets a reason ``'<name>: <reason>'``, is counted by kind (``undeclared``,
    ``read_only``, ``range``, ``invalid``) and passed to :meth:`on_parameter_refusal`, which
    logs it (at most every few seconds per kind and name).
"""

import math
from typing import Any, Dict, Iterable, List, Mapping, Optional, Tuple

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterValueException, ParameterNotDeclaredException
from rclpy.parameter import Parameter

from ring_gyro_sim.core import params
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.paramfile import is_ros_parameter, ROS_OWN_PARAMETERS, \
    unknown_parameter_message
from ring_gyro_sim.ros.throttle import ThrottledWarnings

__all__ = ['CountedParameterRefusals', 'declare_parameters', 'descriptor', 'plain',
           'REFUSAL_KINDS', 'ROS_OWN_PARAMETERS', 'unknown_overrides', 'updated_config']

_INT_LIMIT = 2 ** 63 - 1
_VOLTAGES = ('electrodes.outer_voltage', 'electrodes.inner_voltage')
REFUSAL_KINDS = ('undeclared', 'read_only', 'range', 'invalid')
"""Kinds of refused parameter changes, as counted on /diagnostics."""
REFUSAL_LOG_PERIOD_S = 5.0


def _range(spec: params.ParamSpec,
           config: Optional[params.SimConfig]) -> Tuple[Optional[float], Optional[float]]:
    if config is not None and spec.name in _VOLTAGES:
        limit = config.voltage_limits()[_VOLTAGES.index(spec.name)]
        return -limit, limit
    return spec.minimum, spec.maximum


def descriptor(spec: params.ParamSpec,
               config: Optional[params.SimConfig] = None) -> ParameterDescriptor:
    """
    Return the ParameterDescriptor of one row of the table.

    With ``config`` the voltages' ranges are that configuration's limits (else unbounded:
    they depend on the geometry).
    """
    unit = 'dimensionless' if spec.unit == '-' else spec.unit
    constraints: List[str] = []
    d = ParameterDescriptor(name=spec.name, description=f'{spec.description} [{unit}]',
                            read_only=spec.read_only, dynamic_typing=True)
    low, high = _range(spec, config)
    if spec.kind == 'float' and (low is not None or high is not None):
        d.floating_point_range = [FloatingPointRange(
            from_value=-math.inf if low is None else float(low),
            to_value=math.inf if high is None else float(high), step=0.0)]
    elif spec.kind == 'int':
        d.integer_range = [IntegerRange(
            from_value=-_INT_LIMIT if low is None else int(low),
            to_value=_INT_LIMIT if high is None else int(high), step=1)]
    if spec.kind == 'float':
        constraints.append('a number (integer literals are accepted)')
    elif spec.kind == 'float_list':
        constraints.append('a list of numbers (an empty list means empty)')
    elif spec.kind == 'str_list':
        constraints.append('a list of strings (an empty list means empty)')
    if spec.kind in ('float', 'int', 'float_list') and (low is not None or high is not None):
        left = '(' if spec.open_minimum else '['
        text = (f'{left}{"-inf" if low is None else params.format_number(low)}, '
                f'{"inf" if high is None else params.format_number(high)}]')
        constraints.append(f'range {text}' + ('' if spec.kind != 'float_list' else
                                              ' for every element'))
    if spec.range_note:
        constraints.append(spec.range_note)
    if spec.choices:
        constraints.append('one of ' + ', '.join(spec.choices))
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
        An override that is not a parameter of the table, or a value refused (by a
        descriptor range or by :func:`build_config`); the message starts with the parameter
        name.

    """
    message = unknown_parameter_message(unknown_overrides(node))
    if message:
        raise ParameterError(message)
    for spec in params.PARAMETERS:
        try:
            node.declare_parameter(spec.name, _default(spec), descriptor(spec))
        except InvalidParameterValueException as exc:
            raise ParameterError(_explain(node, spec) or f'{spec.name}: {_reason(exc)}') \
                from None
    values = {spec.name: plain(node.get_parameter(spec.name).value) for spec in params.PARAMETERS}
    config = params.build_config(values)
    for name in _VOLTAGES:
        node.set_descriptor(name, descriptor(params.SPECS[name], config))
    return config


def unknown_overrides(node) -> List[str]:
    """Return the names given to the node (params file, ``-p``) that are not in the table."""
    # rclpy has no public accessor for the overrides it was started with.
    overrides: Mapping[str, Any] = getattr(node, '_parameter_overrides', {}) or {}
    return sorted(name for name in overrides
                  if name not in params.SPECS and not is_ros_parameter(name))


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
        if is_ros_parameter(p.name):
            continue
        if p.name not in params.SPECS:
            raise ParameterError(unknown_parameter_message([p.name]))
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


def _descriptor_refusal(node, param: Parameter) -> Optional[Tuple[str, str]]:
    """Return (kind, reason) if rclpy's descriptor check refuses ``param``, else None."""
    d = node.describe_parameter(param.name)
    if d.read_only:
        return 'read_only', (f'{param.name}: read-only, set it in the params file (a change '
                             f'needs a restart)')
    value = param.value
    ranges = (d.floating_point_range if param.type_ == Parameter.Type.DOUBLE
              else d.integer_range if param.type_ == Parameter.Type.INTEGER else [])
    if ranges:
        r = ranges[0]
        low, high = min(r.from_value, r.to_value), max(r.from_value, r.to_value)
        edge = any(math.isclose(value, x, rel_tol=node.PARAM_REL_TOL) for x in (low, high))
        if not edge and not low < value < high:
            spec = params.SPECS.get(param.name)
            note = f' ({spec.range_note})' if spec is not None and spec.range_note else ''
            return 'range', (f'{param.name}: must be between {low:.6g} and {high:.6g}{note}, '
                             f'got {value!r}')
    return None


class CountedParameterRefusals:
    """
    Mixin for an ``rclpy.node.Node``: every refused parameter change counted and explained.

    Put it before ``Node`` in the bases. See the module docstring for the rclpy hooks used.
    :attr:`parameter_refusals` counts by kind (:data:`REFUSAL_KINDS`); override
    :meth:`on_parameter_refusal` to act on each refusal (the default logs it).
    """

    def __init__(self, *args, **kwargs) -> None:
        self.parameter_refusals: Dict[str, int] = {kind: 0 for kind in REFUSAL_KINDS}
        self._refusal_log = ThrottledWarnings(lambda text: self.get_logger().warn(text),
                                              REFUSAL_LOG_PERIOD_S)
        super().__init__(*args, **kwargs)

    def set_parameters_atomically(self, parameter_list: List[Parameter]) -> SetParametersResult:
        """Set as ``Node.set_parameters_atomically``; a refusal is counted, named and logged."""
        undeclared = [p.name for p in parameter_list if not self.has_parameter(p.name)]
        if undeclared and not getattr(self, '_allow_undeclared_parameters', False):
            reason = (unknown_parameter_message(undeclared)
                      or f'{undeclared[0]}: not a declared parameter')
            return self._refuse('undeclared', undeclared[0], reason)
        for param in parameter_list:
            found = _descriptor_refusal(self, param)
            if found is not None:
                # rclpy refuses it too (its check runs first); its reason is ours now.
                result = super().set_parameters_atomically(parameter_list)
                if result.successful:  # rclpy's edge tolerance let it through
                    return result
                return self._refuse(found[0], param.name, found[1])
        try:
            result = super().set_parameters_atomically(parameter_list)
        except ParameterNotDeclaredException:  # declared meanwhile by another thread
            return self._refuse('undeclared', undeclared[0] if undeclared else '?',
                                'not a declared parameter')
        if not result.successful:
            name = result.reason.split(':', 1)[0] if ':' in result.reason else \
                (parameter_list[0].name if parameter_list else '?')
            return self._refuse('invalid', name, result.reason)
        return result

    def set_parameters(self, parameter_list: List[Parameter]) -> List[SetParametersResult]:
        """Set one by one as ``Node.set_parameters``, each through the counted path."""
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def parameter_refusal_counts(self) -> Dict[str, int]:
        """Return ``rejected_parameter_changes`` (total) and one key per kind, for diagnostics."""
        counts = {'rejected_parameter_changes': sum(self.parameter_refusals.values())}
        counts.update({f'rejected_parameter_{kind}': n
                       for kind, n in self.parameter_refusals.items()})
        return counts

    def on_parameter_refusal(self, kind: str, name: str, reason: str) -> None:
        """Log a refusal, at most every REFUSAL_LOG_PERIOD_S per kind and name."""
        self._refusal_log((kind, name), f'parameter change refused ({kind}): {reason}')

    def _refuse(self, kind: str, name: str, reason: str) -> SetParametersResult:
        self.parameter_refusals[kind] += 1
        self.on_parameter_refusal(kind, name, reason)
        return SetParametersResult(successful=False, reason=reason)
