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
The import boundary of ``ring_gyro_sim.core`` (doc/architecture.md, "Layers").

``core`` imports only the standard library, numpy, scipy and numba: never rclpy, a message
package, mcap or matplotlib, nor the layers above it (``ros``, ``recording``, ``analysis``).
Checked twice: at run time in a fresh interpreter, and statically on the source.
"""

import ast
import json
from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

PACKAGE_DIR = Path(__file__).resolve().parents[1] / 'ring_gyro_sim'
CORE_DIR = PACKAGE_DIR / 'core'
CORE_MODULES = ['ring_gyro_sim.core.params', 'ring_gyro_sim.core.forces',
                'ring_gyro_sim.core.kernels', 'ring_gyro_sim.core.simulator',
                'ring_gyro_sim.core.structure']
UPPER_LAYERS = ('ring_gyro_sim.ros', 'ring_gyro_sim.recording', 'ring_gyro_sim.analysis')


def is_forbidden(module, upper_layers=UPPER_LAYERS):
    """Tell whether ``module`` is rclpy, *_msgs, mcap*, matplotlib or an upper layer."""
    top = module.split('.')[0]
    if top in ('rclpy', 'matplotlib') or top.startswith('mcap') or top.endswith('_msgs'):
        return True
    return any(module == layer or module.startswith(layer + '.') for layer in upper_layers)


def loaded_after_import(modules):
    """Names in ``sys.modules`` of a fresh interpreter after importing ``modules``."""
    code = textwrap.dedent(f"""
        import importlib, json, sys
        for name in {modules!r}:
            importlib.import_module(name)
        print(json.dumps(sorted(sys.modules)))
    """)
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_core_imports_nothing_from_ros_mcap_or_plotting():
    loaded = loaded_after_import(CORE_MODULES)
    assert set(CORE_MODULES) <= set(loaded)
    assert [m for m in loaded if is_forbidden(m)] == []


def test_analysis_nnm_imports_no_ros_mcap_or_plotting():
    loaded = loaded_after_import(['ring_gyro_sim.analysis.nnm'])
    assert 'ring_gyro_sim.analysis.nnm' in loaded
    bad = [m for m in loaded
           if is_forbidden(m, upper_layers=('ring_gyro_sim.ros', 'ring_gyro_sim.recording'))]
    assert bad == []


def test_the_runtime_check_sees_a_forbidden_import():
    """Control: the subprocess check does report a module that pulls a forbidden one in."""
    loaded = loaded_after_import(['json', 'matplotlib'])
    assert [m for m in loaded if is_forbidden(m)]


def imported_modules(source, module_name):
    """
    Every module that ``source`` (the module ``module_name``) imports, at any depth.

    ``from a import b`` yields both ``a`` and ``a.b`` (b may be a sub-module); relative
    imports are resolved against ``module_name``; ``importlib.import_module('x')`` and
    ``__import__('x')`` with a literal name count as well.
    """
    package = module_name.rsplit('.', 1)[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split('.')
                base = '.'.join(parts[:len(parts) - (node.level - 1)])
                module = f'{base}.{node.module}' if node.module else base
            else:
                module = node.module
            found.append(module)
            found += [f'{module}.{alias.name}' for alias in node.names]
        elif isinstance(node, ast.Call) and node.args:
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, 'id', None)
            arg = node.args[0]
            if name in ('import_module', '__import__') and isinstance(arg, ast.Constant) \
                    and isinstance(arg.value, str):
                found.append(arg.value)
    return found


def core_files():
    files = sorted(CORE_DIR.rglob('*.py'))
    assert len(files) >= 6
    return files


@pytest.mark.parametrize('path', core_files(), ids=lambda p: p.name)
def test_core_source_has_no_forbidden_import(path):
    relative = path.relative_to(PACKAGE_DIR.parent).with_suffix('')
    module_name = '.'.join(relative.parts)
    if path.name == '__init__.py':
        module_name += '.__init__'  # relative imports resolve against the package itself
    bad = [m for m in imported_modules(path.read_text(encoding='utf-8'), module_name)
           if is_forbidden(m)]
    assert bad == [], f'{path}: imports {bad}'


@pytest.mark.parametrize('source, forbidden', [
    ('import rclpy', True),
    ('import rclpy.node as rn', True),
    ('from std_msgs.msg import Float64', True),
    ('import geometry_msgs', True),
    ('def f():\n    import matplotlib.pyplot as plt', True),
    ('from mcap.writer import Writer', True),
    ('import mcap_ros2.decoder', True),
    ('from ring_gyro_sim import ros', True),
    ('from ring_gyro_sim.recording import writer', True),
    ('from .. import analysis', True),
    ('from ..ros.conversions import x', True),
    ('import importlib\nimportlib.import_module("rclpy")', True),
    ('import numpy as np', False),
    ('from scipy.integrate import solve_ivp', False),
    ('from ring_gyro_sim.core import kernels', False),
    ('from . import kernels', False),
    ('from .errors import SimulationError', False),
    ('import ring_gyro_sim.core.params', False),
])
def test_the_static_check_itself(source, forbidden):
    found = imported_modules(source, 'ring_gyro_sim.core.forces')
    assert any(is_forbidden(m) for m in found) is forbidden, found


@pytest.mark.parametrize('path', sorted(PACKAGE_DIR.rglob('*.py')),
                         ids=lambda p: str(p.relative_to(PACKAGE_DIR)))
def test_only_the_plotting_module_imports_matplotlib(path):
    """Matplotlib is imported only in ``analysis/plotting.py`` (doc/architecture.md)."""
    relative = path.relative_to(PACKAGE_DIR.parent).with_suffix('')
    module_name = '.'.join(relative.parts)
    imports = imported_modules(path.read_text(encoding='utf-8'), module_name)
    uses_matplotlib = any(m.split('.')[0] == 'matplotlib' for m in imports)
    assert uses_matplotlib == (module_name == 'ring_gyro_sim.analysis.plotting')


def test_the_node_never_loads_matplotlib_or_the_analysis_plots():
    loaded = loaded_after_import(['ring_gyro_sim.ros.node'])
    assert not [m for m in loaded if m.split('.')[0] == 'matplotlib']
