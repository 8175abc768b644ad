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
What rosbag2 (Jazzy) stores besides the messages: QoS profiles and the bag metadata.

Layouts follow rosbag2_storage (Jazzy, metadata version 9): ``qos.cpp``
(``convert<rclcpp::QoS>::encode``, ``serialize_rclcpp_qos_vector``) and ``yaml.hpp``
(``convert<BagMetadata>::encode``), emitted the way yaml-cpp's ``YAML::Dump`` does: block style,
2-space indentation, sequences indented under their key, no trailing newline.
"""

import functools
import re

import yaml

#: Metadata version written by rosbag2 Jazzy (QoS policies as strings, QoS as a YAML sequence).
METADATA_VERSION = 9

# RMW_DURATION_INFINITE as rmw_time_t, which is what rmw_fastrtps reports for the deadline,
# lifespan and liveliness lease of a publisher with default QoS, hence what rosbag2 records.
_INFINITE_TIME = {'sec': 9223372036, 'nsec': 854775807}

_RELIABILITY = {True: 'reliable', False: 'best_effort'}
DURABILITIES = ('volatile', 'transient_local')

_PLAIN = re.compile(r'[A-Za-z0-9_./][A-Za-z0-9_./+\-]*')


@functools.lru_cache(maxsize=1024)
def _plain(value: str) -> bool:
    """Tell whether ``value`` can be written unquoted (it reads back as the same string)."""
    return bool(_PLAIN.fullmatch(value)) and yaml.safe_load(value) == value


def qos_profile(*, reliable: bool, durability: str, depth: int) -> dict:
    """Return one offered QoS profile in rosbag2's key order and string encodings."""
    return {
        'history': 'keep_last',
        'depth': depth,
        'reliability': _RELIABILITY[bool(reliable)],
        'durability': durability,
        'deadline': dict(_INFINITE_TIME),
        'lifespan': dict(_INFINITE_TIME),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(_INFINITE_TIME),
        'avoid_ros_namespace_conventions': False,
    }


def bag_metadata(*, file_name, topics, message_count, start_ns, end_ns, custom_data,
                 ros_distro) -> dict:
    """
    Return the BagMetadata mapping of a single-file bag in rosbag2's key order.

    ``topics`` holds (name, type, qos_profile, type_hash, message_count) tuples, qos_profile
    one profile or a list of them; times are integer ns (0 for an empty bag).
    """
    duration = {'nanoseconds': end_ns - start_ns}
    starting_time = {'nanoseconds_since_epoch': start_ns}
    return {
        'version': METADATA_VERSION,
        'storage_identifier': 'mcap',
        'duration': duration,
        'starting_time': starting_time,
        'message_count': message_count,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': name,
                    'type': type_name,
                    'serialization_format': 'cdr',
                    'offered_qos_profiles': profile if isinstance(profile, list) else [profile],
                    'type_description_hash': type_hash,
                },
                'message_count': count,
            }
            for name, type_name, profile, type_hash, count in topics
        ],
        # rosbag2_compression's file/message compression, not MCAP chunk compression.
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [file_name],
        'files': [{
            'path': file_name,
            'starting_time': dict(starting_time),
            'duration': dict(duration),
            'message_count': message_count,
        }],
        # yaml-cpp encodes an empty map as a null node.
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ros_distro,
    }


def _scalar(value):
    if value is None:
        return '~'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        if _plain(value):
            return value
        # JSON escapes are valid in YAML double-quoted scalars.
        return '"' + (value.replace('\\', '\\\\').replace('"', '\\"')
                      .replace('\n', '\\n').replace('\t', '\\t').replace('\r', '\\r')) + '"'
    raise TypeError(f'cannot emit {type(value).__name__} as YAML scalar')


def _emit(node, indent, lines):
    pad = ' ' * indent
    if isinstance(node, dict) and node:
        for name, value in node.items():
            key = _scalar(name)
            if isinstance(value, (dict, list)) and value:
                lines.append(f'{pad}{key}:')
                _emit(value, indent + 2, lines)
            elif isinstance(value, (dict, list)):
                # yaml-cpp puts an empty flow collection on its own line.
                lines.append(f'{pad}{key}:')
                lines.append(f'{pad}  ' + ('{}' if isinstance(value, dict) else '[]'))
            else:
                lines.append(f'{pad}{key}: {_scalar(value)}')
    elif isinstance(node, list) and node:
        for item in node:
            if isinstance(item, (dict, list)) and item:
                first = len(lines)
                _emit(item, indent + 2, lines)
                lines[first] = f'{pad}- ' + lines[first][indent + 2:]
            elif isinstance(item, (dict, list)):
                lines.append(f'{pad}- ' + ('{}' if isinstance(item, dict) else '[]'))
            else:
                lines.append(f'{pad}- {_scalar(item)}')
    elif isinstance(node, (dict, list)):
        lines.append(pad + ('{}' if isinstance(node, dict) else '[]'))
    else:
        lines.append(pad + _scalar(node))


def dump(node) -> str:
    """Return ``node`` (dicts, lists, str, int, bool, None) as yaml-cpp's YAML::Dump would."""
    lines = []
    _emit(node, 0, lines)
    return '\n'.join(lines)
