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
The ``--params-file`` YAML, read as the node reads it, for the command line and the tests.

The node gets its parameters from rcl's YAML parser (``rcl_yaml_param_parser``), which
types a plain scalar as bool, integer or, through ``strtod``, double. PyYAML's safe loader
follows YAML 1.1, where ``150.0e9``, ``1e-5`` and ``2e5`` are *strings* (a float needs a dot
and a signed exponent); :data:`RosYamlLoader` adds the exponent forms that ``strtod`` reads so
that one file means the same numbers in both. Quoted scalars stay strings in both.

This module lives outside ``core`` because ``core`` imports only stdlib, numpy, scipy and numba.
"""

import re
from typing import Any, Dict, Mapping

from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import build_config, flatten, SimConfig
import yaml


class RosYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the float forms that rcl's ``strtod`` also accepts."""


# Decimal literals with an exponent that YAML 1.1 leaves as strings: '1e-5', '2e5', '150.0e9',
# '1.5E3', '.5e3'. Integers ('12') keep resolving to int first (rcl: strtol before strtod).
_STRTOD_FLOAT = re.compile(
    r'^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$')
RosYamlLoader.add_implicit_resolver('tag:yaml.org,2002:float', _STRTOD_FLOAT,
                                    list('-+0123456789.'))


def load_text(text: str) -> Any:
    """Parse YAML text with :class:`RosYamlLoader` (no arbitrary objects)."""
    return yaml.load(text, Loader=RosYamlLoader)  # noqa: S506 - a SafeLoader subclass


def parameters_from_yaml_text(text: str, node_name: str = 'ring_gyro') -> Dict[str, Any]:
    """
    Flat parameters from the text of a ROS 2 ``--params-file`` YAML.

    Accepts the ROS layout (``<node>: ros__parameters: ...``, ``/**:`` or the fully
    qualified node name) and, for convenience, a bare mapping of parameters.
    """
    try:
        tree = load_text(text) or {}
    except yaml.YAMLError as exc:
        raise ParameterError(f'params file: not valid YAML ({exc})') from None
    if not isinstance(tree, Mapping):
        raise ParameterError('params file: the top level must be a mapping')
    sections = []
    for key, value in tree.items():
        if isinstance(value, Mapping) and 'ros__parameters' in value:
            bare = str(key).lstrip('/').split('/')[-1]
            if key in ('/**', '**') or bare == node_name or bare == '*':
                sections.append(value['ros__parameters'] or {})
    if not sections:
        if any(isinstance(v, Mapping) and 'ros__parameters' in v for v in tree.values()):
            raise ParameterError(f'params file: no ros__parameters section for node '
                                 f'{node_name!r} or /**')
        sections = [tree]
    flat: Dict[str, Any] = {}
    for section in sections:
        flat.update(flatten(section))
    return flat


def load_yaml(path: str, node_name: str = 'ring_gyro') -> SimConfig:
    """Load and validate a :class:`SimConfig` from a ``--params-file`` YAML file."""
    try:
        with open(path, 'r', encoding='utf-8') as fh:
            text = fh.read()
    except OSError as exc:
        raise ParameterError(f'params file {path!r}: {exc.strerror}') from None
    return build_config(parameters_from_yaml_text(text, node_name))
