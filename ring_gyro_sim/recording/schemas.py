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
ROS 2 message definitions and type hashes, as rosbag2 (Jazzy) stores them in a bag.

The schema text reproduces ``rosbag2_cpp::LocalMessageDefinitionSource::get_full_text`` for the
``ros2msg`` encoding: the type's own ``.msg`` file verbatim (comments included), then every
dependency once, depth first, each dependency's direct dependencies in sorted order. Each
dependency is preceded by an empty line, a line of 80 ``=`` and ``MSG: pkg/Type``, where
``pkg/Type`` is the name as written in the referring ``.msg`` file (``std_msgs/Header``), a bare
name being qualified with the referring package (``MultiArrayLayout`` in std_msgs is
``std_msgs/MultiArrayLayout``). Nested types such as ``builtin_interfaces/Time`` are included.

The ``.msg`` files are found through the ament index. The PyPI Jazzy wheels install them under
``<sys.prefix>/share/<pkg>`` without setting ``AMENT_PREFIX_PATH``, so that prefix is searched
as well.
"""

import functools
import importlib
import json
import os
import re
import sys

from ament_index_python.packages import get_package_share_directory

from ring_gyro_sim.recording.errors import RecordingError

#: The line that separates the definitions of a ``ros2msg`` schema (80 ``=``).
DELIMITER = '=' * 80

# rosbag2's limit, ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH.
_MAX_RECURSION_DEPTH = 50

# The same field-type pattern rosbag2 applies to the whole .msg text: the first word of every line
# that does not start with '#', with an optional array suffix.
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')

# rosbag2's list, plus wstring (which rosbag2 would wrongly look up as a message type).
_PRIMITIVE_TYPES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring',
})

_ROS_NAME = r'[a-zA-Z][a-zA-Z0-9_]*'
_TYPE_NAME = re.compile(rf'({_ROS_NAME})/(?:({_ROS_NAME})/)?({_ROS_NAME})')


def _split_type_name(type_name):
    """Split 'pkg/msg/Type' or 'pkg/Type' into (package, namespace, name)."""
    match = _TYPE_NAME.fullmatch(type_name) if isinstance(type_name, str) else None
    if match is None:
        raise RecordingError(
            f"invalid message type name {type_name!r}: expected 'pkg/msg/Type' or 'pkg/Type'")
    package, namespace, name = match.groups()
    return package, namespace or 'msg', name


def normalize_type_name(type_name: str) -> str:
    """Return the rosbag2 schema name 'pkg/msg/Type' of 'pkg/msg/Type' or 'pkg/Type'."""
    package, namespace, name = _split_type_name(type_name)
    return f'{package}/{namespace}/{name}'


@functools.lru_cache(maxsize=None)
def _share_directory(package):
    """Return the share directory of an installed ROS package, or None if it is not found."""
    try:
        return get_package_share_directory(package)
    except (KeyError, OSError):
        # KeyError: PackageNotFoundError; OSError: AMENT_PREFIX_PATH unset (the PyPI wheels
        # never set it).
        pass
    candidate = os.path.join(sys.prefix, 'share', package)
    return candidate if os.path.isdir(candidate) else None


def _interface_file(package, namespace, name, extension):
    share = _share_directory(package)
    if share is None:
        return None
    path = os.path.join(share, namespace, name + extension)
    return path if os.path.isfile(path) else None


@functools.lru_cache(maxsize=None)
def _msg_spec(type_name):
    """Return (text, dependencies) of one .msg file, dependencies sorted as rosbag2 does."""
    package, namespace, name = _split_type_name(type_name)
    path = _interface_file(package, namespace, name, '.msg')
    if path is None:
        where = _share_directory(package)
        reason = (f'package {package!r} is not installed' if where is None
                  else f'{namespace}/{name}.msg not found in {where}')
        raise RecordingError(f'unknown message type {type_name!r}: {reason}')
    # newline='' keeps the file byte for byte, as rosbag2 reads it.
    with open(path, encoding='utf-8', newline='') as stream:
        text = stream.read()
    dependencies = set()
    for field_type in _MSG_FIELD_TYPE.findall(text):
        if field_type in _PRIMITIVE_TYPES:
            continue
        dependencies.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return text, tuple(sorted(dependencies))


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    r"""
    Return the full ``ros2msg`` schema text of a message type, as rosbag2 Jazzy writes it.

    Parameters
    ----------
    type_name : str
        'pkg/msg/Type' (or 'pkg/Type'), e.g. 'std_msgs/msg/Float64MultiArray'.

    Returns
    -------
    str
        The type's .msg text, then each dependency once after ``'\n' + DELIMITER + '\n'`` and
        ``'MSG: pkg/Type\n'``.

    Raises
    ------
    RecordingError
        If the type or one of its dependencies is not installed.

    """
    seen = set()

    def append_recursive(name, depth):
        if depth <= 0:
            raise RecordingError(
                f'reached the maximum recursion depth resolving the definition of {type_name!r}')
        text, dependencies = _msg_spec(name)
        parts = [text]
        for dependency in dependencies:
            if dependency not in seen:
                seen.add(dependency)
                parts.append(f'\n{DELIMITER}\nMSG: {dependency}\n')
                parts.append(append_recursive(dependency, depth - 1))
        return ''.join(parts)

    _msg_spec(type_name)  # an unknown root type is reported as such
    try:
        return append_recursive(type_name, _MAX_RECURSION_DEPTH)
    except RecordingError as exc:
        raise RecordingError(f'cannot resolve the definition of {type_name!r}: {exc}') from exc


@functools.lru_cache(maxsize=None)
def type_description_hash(type_name: str) -> str:
    """
    Return the REP-2011 type hash ('RIHS01_<64 hex>') of a message type, '' if unavailable.

    The hash is read from ``share/<pkg>/msg/<Type>.json``, the type description that
    rosidl_generator_type_description installs and from which the hash compiled into the type
    support (the one rclpy reports as ``TopicEndpointInfo.topic_type_hash``) is computed. Jazzy
    rclpy message classes do not expose it directly.

    Parameters
    ----------
    type_name : str
        'pkg/msg/Type' (or 'pkg/Type').

    """
    package, namespace, name = _split_type_name(type_name)
    path = _interface_file(package, namespace, name, '.json')
    if path is None:
        return ''
    try:
        with open(path, encoding='utf-8') as stream:
            hashes = json.load(stream).get('type_hashes', [])
    except (OSError, ValueError, AttributeError):
        return ''
    full_name = f'{package}/{namespace}/{name}'
    for entry in hashes:
        if isinstance(entry, dict) and entry.get('type_name') == full_name:
            value = entry.get('hash_string', '')
            return value if isinstance(value, str) and value.startswith('RIHS') else ''
    return ''


def message_type_name(message_or_class) -> str:
    """
    Return 'pkg/msg/Type' of an rclpy message instance or class.

    Raises
    ------
    TypeError
        If the argument is not a generated ROS 2 message (instance or class).

    """
    cls = message_or_class if isinstance(message_or_class, type) else type(message_or_class)
    parts = getattr(cls, '__module__', '').split('.')
    if (len(parts) < 3 or parts[1] != 'msg'
            or not callable(getattr(cls, 'get_fields_and_field_types', None))):
        raise TypeError(f'{cls.__module__}.{cls.__qualname__} is not a ROS 2 message type')
    return f'{parts[0]}/msg/{cls.__name__}'


@functools.lru_cache(maxsize=None)
def message_class(type_name: str) -> type:
    """
    Return the rclpy message class of 'pkg/msg/Type' (or 'pkg/Type').

    Raises
    ------
    RecordingError
        If the Python module of the type cannot be imported.

    """
    package, namespace, name = _split_type_name(type_name)
    try:
        module = importlib.import_module(f'{package}.{namespace}')
        return getattr(module, name)
    except (ImportError, AttributeError) as exc:
        raise RecordingError(
            f'cannot import message type {type_name!r}: {exc}') from exc
