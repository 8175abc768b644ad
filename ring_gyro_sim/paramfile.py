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
The ``--params-file`` YAML: one check, one verdict for ``ring_gyro_node`` and ``ring_gyro run``.

:func:`check_params_file` reads a file the way rcl's parser (``rcl_yaml_param_parser``) reads
it and refuses, with a :class:`~ring_gyro_sim.core.errors.ParameterError` naming the file, the
parameter and the line, everything that would otherwise run differently in the two:

* a file that is not UTF-8 text (rcl reads a binary file as "no parameters");
* YAML that does not parse, aliases (rcl refuses them) and explicit tags;
* an empty file, or one with no ``ros__parameters`` section that applies to the node
  (``/**``, ``/*``, the node's name or its fully qualified name: rcl ignores the others and
  the node would run silently on its defaults), or whose sections set nothing;
* a value before ``ros__parameters`` (a bare mapping of parameters: rcl refuses it);
* a key given twice in one mapping (rcl and PyYAML both keep the last silently);
* a list mixing types (``[11200, 15800.5]``: rcl refuses it naming only a line), a list of
  lists or of mappings, an empty plain value (``gap:``);
* an unknown parameter name (with the closest known name); ``use_sim_time``,
  ``start_type_description_service`` and ``qos_overrides.*`` belong to ROS and are left out
  of the result.

Scalars are typed as rcl types them (``get_value`` in ``parse.c``): plain ``y/yes/true/on``
(and their capitalised forms) are booleans, then ``strtol(.., 0)`` integers (``0x1F``,
``010`` = 8), then ``strtod`` doubles (``1e-5``, ``2e5``, ``inf``, ``.nan``), else strings
(``~``, ``null``, ``1_000``); quoted scalars are strings. An empty list (``[]``) is "not set"
(``None``). Where PyYAML's YAML 1.1 rules differ (``1e-5`` is a string there, ``~`` is null)
this module follows rcl, so the same file means the same values to both.

``ring_gyro run`` calls :func:`load_yaml` (:func:`check_params_file` then
:func:`~ring_gyro_sim.core.params.build_config`). The node calls :func:`check_node_arguments`
on its command line before ``rclpy.init``: every ``--params-file`` is checked as above for
the node's name and namespace after remapping (``-r __node:=X``, ``-r __ns:=/N``); with
several files, only the "no section for this node" verdict is taken over all of them (a
launch may pass a shared file). Its values then go through the same ``build_config`` when the
node declares them, so for one file the node's verdict is that of ``ring_gyro run``.

This module lives outside ``core`` because ``core`` imports only stdlib, numpy, scipy and numba.
"""

import difflib
import math
import re
import sys
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Tuple

from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import build_config, REPLACED, SimConfig, SPECS
import yaml

DEFAULT_NODE_NAME = 'ring_gyro'
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')
"""Parameters rclpy itself declares on every node (not ours, never refused)."""
PARAMS_KEY = 'ros__parameters'


def is_ros_parameter(name: str) -> bool:
    """Return whether ``name`` is a parameter of ROS itself rather than of ring_gyro_sim."""
    return name in ROS_OWN_PARAMETERS or name.startswith('qos_overrides.')


class RosYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the float forms that rcl's ``strtod`` also accepts."""


# Decimal literals with an exponent that YAML 1.1 leaves as strings: '1e-5', '2e5', '150.0e9',
# '1.5E3', '.5e3'. Integers ('12') keep resolving to int first (rcl: strtol before strtod).
_STRTOD_FLOAT = re.compile(
    r'^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$')
RosYamlLoader.add_implicit_resolver('tag:yaml.org,2002:float', _STRTOD_FLOAT,
                                    list('-+0123456789.'))


def load_text(text: str) -> Any:
    """Parse YAML text with :class:`RosYamlLoader` (no arbitrary objects; recording metadata)."""
    return yaml.load(text, Loader=RosYamlLoader)  # noqa: S506 - a SafeLoader subclass


# -- scalars as rcl types them (rcl_yaml_param_parser/src/parse.c, get_value) ---------------

_TRUE = ('Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON')
_FALSE = ('N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF')
_SPECIAL_DOUBLES = {f'{sign}.{word}': float(f'{"-" if sign == "-" else ""}{word[:3]}')
                    for sign in ('', '+', '-') for word in ('inf', 'Inf', 'INF')}
_SPECIAL_DOUBLES.update({f'.{word}': math.nan for word in ('nan', 'NaN', 'NAN')})
_SPACE = ' \t\n\v\f\r'
_STRTOL = re.compile(r'[+-]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_STRTOD = re.compile(
    r'[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?'
    r'|0[xX](?:[0-9a-fA-F]+\.?[0-9a-fA-F]*|\.[0-9a-fA-F]+)(?:[pP][+-]?[0-9]+)?'
    r'|inf(?:inity)?|nan(?:\([0-9A-Za-z_]*\))?)', re.IGNORECASE)
_INT64 = (-2 ** 63, 2 ** 63 - 1)


def rcl_scalar(text: str, quoted: bool) -> Any:
    """
    Return a YAML scalar typed as rcl types it: bool, int, float or str.

    ``quoted``: single- or double-quoted in the file (always a string).
    """
    if quoted:
        return text
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    body = text.lstrip(_SPACE)
    if _STRTOL.fullmatch(body):
        sign = -1 if body.startswith('-') else 1
        digits = body.lstrip('+-')
        if digits[:2] in ('0x', '0X'):
            value = int(digits[2:], 16)
        elif len(digits) > 1 and digits[0] == '0':
            value = int(digits, 8)
        else:
            value = int(digits)
        value *= sign
        if _INT64[0] <= value <= _INT64[1]:  # else strtol sets ERANGE: try a double
            return value
    if text in _SPECIAL_DOUBLES:
        return _SPECIAL_DOUBLES[text]
    if _STRTOD.fullmatch(body):
        return _strtod(body)
    return text


def _strtod(body: str) -> Any:
    digits = body.lstrip('+-')
    negative = body.startswith('-')
    lower = digits.lower()
    if lower.startswith('inf'):
        return -math.inf if negative else math.inf
    if lower.startswith('nan'):
        return math.nan
    if lower.startswith('0x'):
        value = float.fromhex(('-' if negative else '') + digits)
        mantissa = re.sub(r'p.*$', '', lower[2:])
    else:
        value = float(body)
        mantissa = re.sub(r'e.*$', '', lower)
    nonzero = any(c not in '0.' for c in mantissa)
    if math.isinf(value) or (nonzero and abs(value) < sys.float_info.min):
        return body  # strtod sets ERANGE (overflow or underflow): rcl keeps a string
    return value


# -- structure ------------------------------------------------------------------------------

class _Section(NamedTuple):
    node: str       # '/ns/name' as written, wildcards kept
    line: int
    values: Dict[str, Tuple[Any, int]]   # dotted name -> (value, line)


def _line(node) -> int:
    return node.start_mark.line + 1


def _scalar_key(node, where: str) -> str:
    if not isinstance(node, yaml.ScalarNode) or node.value == '':
        raise ParameterError(f'{where}: line {_line(node)}: a key must be a non-empty name')
    return node.value


def _unique_pairs(mapping, where: str, what) -> List[Tuple[str, Any]]:
    seen: Dict[str, int] = {}
    pairs = []
    for key_node, value_node in mapping.value:
        key = _scalar_key(key_node, where)
        if key in seen:
            raise ParameterError(
                f'{what(key)}: given twice in {where} (lines {seen[key]} and '
                f'{_line(key_node)}): the second would silently replace or merge with the '
                f'first; write it once')
        seen[key] = _line(key_node)
        pairs.append((key, value_node))
    return pairs


_KINDS = {bool: 'bool', int: 'integer', float: 'double', str: 'string'}


def _value(node, name: str, where: str) -> Any:
    if isinstance(node, yaml.ScalarNode):
        quoted = node.style in ('"', "'")
        if node.value == '' and not quoted:
            raise ParameterError(f'{name}: no value ({where}, line {_line(node)}); an empty '
                                 f'list is [], an empty string is ""')
        return rcl_scalar(node.value, quoted)
    if isinstance(node, yaml.SequenceNode):
        items = []
        for item in node.value:
            if not isinstance(item, yaml.ScalarNode):
                raise ParameterError(f'{name}: a list may hold only plain values, line '
                                     f'{_line(item)} has a nested list or mapping ({where})')
            items.append((_value(item, name, where), _line(item)))
        if not items:
            return None  # rcl: not set; the table reads it as an empty list
        first = _KINDS[type(items[0][0])]
        for value, line in items[1:]:
            kind = _KINDS[type(value)]
            if kind != first:
                hint = (' (write every number with a decimal point, e.g. 11200.0)'
                        if {first, kind} == {'integer', 'double'} else '')
                raise ParameterError(
                    f'{name}: a list must hold values of one type, rcl refuses it: line {line} '
                    f'has a {kind} ({value!r}) after {first} values ({where}){hint}')
        return [value for value, _ in items]
    raise ParameterError(f'{name}: unexpected YAML node ({where}, line {_line(node)})')


def _parameters(mapping, prefix: str, where: str, out: Dict[str, Tuple[Any, int]]) -> None:
    if isinstance(mapping, yaml.ScalarNode) and mapping.value == '' and not prefix:
        return  # 'ros__parameters:' with nothing under it
    if not isinstance(mapping, yaml.MappingNode):
        raise ParameterError(f'{where}: line {_line(mapping)}: {PARAMS_KEY} (and every group '
                             f'under it) must be a mapping of names to values')
    for key, node in _unique_pairs(mapping, where, lambda k: f'{prefix}{k}'):
        name = f'{prefix}{key}'
        if isinstance(node, yaml.MappingNode):
            _parameters(node, name + '.', where, out)
        else:
            out[name] = (_value(node, name, where), _line(node))


def _sections(mapping, names: List[str], where: str, out: List[_Section]) -> None:
    for key, node in _unique_pairs(mapping, where,
                                   lambda k: f'node section {"/".join(names + [k])!r}'):
        if key == PARAMS_KEY:
            if not names:
                raise ParameterError(f'{where}: line {_line(node)}: no node name before '
                                     f'{PARAMS_KEY}')
            values: Dict[str, Tuple[Any, int]] = {}
            _parameters(node, '', where, values)
            out.append(_Section('/' + '/'.join(n.strip('/') for n in names), _line(node),
                                values))
        elif isinstance(node, yaml.MappingNode):
            _sections(node, names + [key], where, out)
        else:
            raise ParameterError(
                f'{where}: line {_line(node)}: {key!r} has a value before {PARAMS_KEY} (rcl '
                f'refuses it); a params file is "<node name>: {PARAMS_KEY}: {{name: value}}", '
                f'e.g. "/**: {PARAMS_KEY}: ..." for every node')


def _explicit_tag(event) -> bool:
    if not isinstance(event, (yaml.ScalarEvent, yaml.CollectionStartEvent)) or event.tag is None:
        return False
    implicit = event.implicit
    return not (any(implicit) if isinstance(implicit, tuple) else implicit)


def read_sections(text: str, where: str) -> List[_Section]:
    """Return the ``ros__parameters`` sections of params-file text, in file order."""
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            line = event.start_mark.line + 1
            if isinstance(event, yaml.AliasEvent):
                raise ParameterError(f'{where}: line {line}: YAML aliases (*name) are not '
                                     f'supported by rcl')
            if _explicit_tag(event):
                raise ParameterError(f'{where}: line {line}: explicit YAML tags ({event.tag}) '
                                     f'are not read the same by rcl: quote strings instead')
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        raise ParameterError(f'{where}: not valid YAML ({exc})') from None
    sections: List[_Section] = []
    if root is None:
        return sections
    if not isinstance(root, yaml.MappingNode):
        raise ParameterError(f'{where}: the top level must be a mapping of node names '
                             f'("<node name>: {PARAMS_KEY}: ...")')
    _sections(root, [], where, sections)
    return sections


def _tokens(name: str) -> List[str]:
    return [t for t in name.split('/') if t]


def _matches(pattern: Sequence[str], name: Sequence[str]) -> bool:
    """Match rcl's node-name wildcards: ``*`` one token, ``**`` any number of tokens."""
    if not pattern:
        return not name
    if pattern[0] == '**':
        return any(_matches(pattern[1:], name[i:]) for i in range(len(name) + 1))
    return bool(name) and pattern[0] in ('*', name[0]) and _matches(pattern[1:], name[1:])


def fully_qualified_name(node_name: str, namespace: str = '/') -> str:
    """Return ``/namespace/name``; a ``node_name`` with a ``/`` is taken as qualified already."""
    if '/' in node_name:
        return '/' + '/'.join(_tokens(node_name))
    return '/' + '/'.join(_tokens(namespace) + [node_name])


def section_applies(section_node: str, fqn: str) -> bool:
    """Return whether a section named ``section_node`` applies to the node ``fqn``."""
    return _matches(_tokens(section_node), _tokens(fqn))


def _read_text(path: str) -> str:
    try:
        with open(path, 'rb') as fh:
            data = fh.read()
    except OSError as exc:
        raise ParameterError(f'params file {path!r}: {exc.strerror}') from None
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise ParameterError(
            f'params file {path!r}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset '
            f'{exc.start}); a params file is YAML text') from None


def _unknown(names: Sequence[str]) -> Optional[str]:
    """Return the refusal of unknown names (with the closest known ones), None if none."""
    def hint(name: str) -> str:
        if name in REPLACED:
            return f' ({REPLACED[name]})'
        close = difflib.get_close_matches(name, list(SPECS), n=1, cutoff=0.6)
        return f' (did you mean {close[0]}?)' if close else ''
    if not names:
        return None
    text = f'{names[0]}: unknown parameter of ring_gyro_sim{hint(names[0])}'
    if len(names) > 1:
        text += '; also unknown: ' + ', '.join(name + hint(name) for name in names[1:])
    return text


def unknown_parameter_message(names: Sequence[str]) -> Optional[str]:
    """Return ``'<name>: unknown parameter ... (did you mean ...?)'`` for ``names`` (or None)."""
    return _unknown([n for n in names if n not in SPECS and not is_ros_parameter(n)])


def _select(sections: List[_Section], fqn: str, where: str) -> Tuple[bool, Dict[str, Any]]:
    """Return (a section applies and sets something, merged values: file order, last wins)."""
    applies = False
    merged: Dict[str, Tuple[Any, int]] = {}
    for section in sections:
        if section_applies(section.node, fqn):
            applies = True
            merged.update(section.values)
    unknown = [n for n in merged if n not in SPECS and not is_ros_parameter(n)]
    message = _unknown(unknown)
    if message:
        raise ParameterError(f'{message} ({where}, line {merged[unknown[0]][1]})')
    return applies and bool(merged), {n: v for n, (v, _) in merged.items() if n in SPECS}


def _no_section(where: str, sections: List[_Section], fqn: str) -> ParameterError:
    if not sections:
        return ParameterError(f'{where}: empty: it sets no parameter (a ROS params file is '
                              f'"<node name>: {PARAMS_KEY}: {{name: value}}"; give no file to '
                              f'run on the defaults)')
    names = ', '.join(sorted({s.node for s in sections}))
    return ParameterError(f'{where}: no {PARAMS_KEY} section that sets a parameter of node '
                          f'{fqn!r} (sections: {names}); name the node, or /** for every node')


def check_params_text(text: str, node_name: str = DEFAULT_NODE_NAME, namespace: str = '/',
                      where: str = 'params file') -> Dict[str, Any]:
    """
    Check params-file text for the node ``namespace/node_name``; return its flat parameters.

    The result maps the dotted names of ring_gyro_sim's parameters to their values as rcl
    types them (ROS's own parameters are left out); see the module docstring for what is
    refused.

    Raises
    ------
    ParameterError
        The message names the file (``where``), the parameter and the line.

    """
    fqn = fully_qualified_name(node_name, namespace)
    sections = read_sections(text, where)
    applies, flat = _select(sections, fqn, where)
    if not applies:
        raise _no_section(where, sections, fqn)
    return flat


def check_params_file(path: str, node_name: str = DEFAULT_NODE_NAME,
                      namespace: str = '/') -> Dict[str, Any]:
    """
    Check a ``--params-file`` for the node ``namespace/node_name``; return its flat parameters.

    This is the one validation of ``ring_gyro run`` and ``ring_gyro_node`` (module docstring).

    Raises
    ------
    ParameterError
        Unreadable or not UTF-8, not valid YAML, no section for the node, a duplicate key,
        a mixed list, an unknown name, ...: the message names the file, the parameter and the
        line.

    """
    return check_params_text(_read_text(path), node_name, namespace, f'params file {path!r}')


def parameters_from_yaml_text(text: str, node_name: str = DEFAULT_NODE_NAME) -> Dict[str, Any]:
    """Flat parameters from params-file text (:func:`check_params_text`)."""
    return check_params_text(text, node_name)


def load_yaml(path: str, node_name: str = DEFAULT_NODE_NAME) -> SimConfig:
    """Check (:func:`check_params_file`) and build the :class:`SimConfig` of a params file."""
    return build_config(check_params_file(path, node_name))


# -- the node's command line ----------------------------------------------------------------

class RosArguments(NamedTuple):
    """What the node's ROS arguments say about its parameters."""

    params_files: List[str]
    node_name: str
    namespace: str


_WITH_VALUE = ('-r', '--remap', '-p', '--param', '--params-file', '-e', '--enclave',
               '--log-level', '--log-file-name', '--log-config-file')


def ros_arguments(argv: Sequence[str], node_name: str = DEFAULT_NODE_NAME,
                  namespace: str = '/') -> RosArguments:
    """
    Extract the ``--params-file`` paths and the node name and namespace after remapping.

    Reads the ``--ros-args ... [--]`` sections of ``argv`` as rcl does: ``--params-file F``,
    ``-r/--remap [node:]__node:=X`` (or ``__name``) and ``[node:]__ns:=/N`` (a rule prefixed
    with another node's name is not ours).
    """
    files: List[str] = []
    name, ns = node_name, namespace
    in_ros = False
    args = list(argv)
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--' and in_ros:
            in_ros = False
        elif in_ros and arg in _WITH_VALUE and i + 1 < len(args):
            value = args[i + 1]
            i += 1
            if arg == '--params-file':
                files.append(value)
            elif arg in ('-r', '--remap') and ':=' in value:
                lhs, rhs = value.split(':=', 1)
                target, _, rule = lhs.rpartition(':')
                if target and target != node_name:
                    pass
                elif rule in ('__node', '__name'):
                    name = rhs
                elif rule == '__ns':
                    ns = rhs
        i += 1
    return RosArguments(files, name, ns)


def check_node_arguments(argv: Sequence[str],
                         node_name: str = DEFAULT_NODE_NAME) -> Dict[str, Any]:
    """
    Check every ``--params-file`` of the node's command line; return the merged parameters.

    Each file is checked as :func:`check_params_file` checks it, for the node's name and
    namespace after remapping; "no section for this node" is refused only when no file has
    one (a launch may give the node a file shared with other nodes as well as its own).

    Raises
    ------
    ParameterError
        As :func:`check_params_file`.

    """
    ros = ros_arguments(argv, node_name)
    fqn = fully_qualified_name(ros.node_name, ros.namespace)
    merged: Dict[str, Any] = {}
    found = False
    first: Optional[ParameterError] = None
    for path in ros.params_files:
        where = f'params file {path!r}'
        sections = read_sections(_read_text(path), where)
        applies, flat = _select(sections, fqn, where)
        if applies:
            found = True
            merged.update(flat)
        elif first is None:
            first = _no_section(where, sections, fqn)
    if first is not None and not found:
        raise first
    return merged
