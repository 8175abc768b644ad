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
The import map of the package (doc/architecture.md, "Layers").

``core`` imports only the standard library, numpy, scipy and numba: never rclpy, a message
package, mcap or matplotlib, nor the layers above it (``ros``, ``recording``, ``analysis``).
Checked twice: at run time in a fresh interpreter, and statically on the source. Above the
core, every import between two parts of the package must be on :data:`LAYERS`, the whole map,
which has no cycle.
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
                'ring_gyro_sim.core.kernels', 'ring_gyro_sim.core.engine.full',
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


# -- the whole map ----------------------------------------------------------------------------

LAYERS = {
    'version': set(),
    'core': set(),
    'progress': set(),
    'outdir': {'core'},
    'extras': {'core'},
    'run': {'core'},
    'paramfile': {'core'},
    'recording': {'core', 'version'},
    'analysis': {'core', 'run', 'progress'},
    'ros': {'core', 'run', 'paramfile', 'recording', 'version'},
    'offline': {'core', 'run', 'paramfile', 'progress', 'recording', 'ros'},
    'replay': {'core', 'recording', 'ros'},
    'sweep': {'core', 'analysis', 'paramfile', 'version', 'outdir', 'progress', 'extras'},
    'rate_record': {'core', 'run', 'analysis', 'offline', 'recording', 'outdir'},
    'characterize': {'core', 'run', 'analysis', 'paramfile', 'progress', 'outdir', 'extras'},
    'report': {'core', 'run', 'analysis', 'sweep', 'outdir', 'extras'},
    'cli': {'core', 'run', 'analysis', 'paramfile', 'recording', 'ros', 'offline', 'replay',
            'sweep', 'rate_record', 'characterize', 'report', 'progress', 'version', 'outdir',
            'extras'},
}
"""
Which parts of the package each part may import (doc/architecture.md), lower layers first:
a part is a sub-package (``core`` with ``core.gyro`` and ``core.kernels``, ``analysis``,
``recording``, ``ros``, ``sweep``) or a top-level module; ``version`` is the package's
``__version__``. Imports inside functions count. A part not listed here fails the test, so a
new module is placed in the map when it is added.
"""


def part_of(module):
    """
    Return the part of the package ``module`` belongs to (None: not a part).

    The package itself (``ring_gyro_sim``, its ``__init__``) is the ``version`` part; a bare
    ``ring_gyro_sim`` of ``from ring_gyro_sim import x`` names no part (``x`` does).
    """
    parts = module.split('.')
    if parts[0] != 'ring_gyro_sim' or len(parts) == 1:
        return None
    return 'version' if parts[1] in ('__version__', '__init__') else parts[1]


def import_edges(package_dir=PACKAGE_DIR):
    """Return ``{(importing part, imported part): [file, ...]}`` over the package's sources."""
    edges = {}
    for path in sorted(package_dir.rglob('*.py')):
        relative = path.relative_to(package_dir.parent).with_suffix('')
        module_name = '.'.join(relative.parts)
        if path.name == '__init__.py':
            module_name += '.__init__'
        own = part_of(module_name if path.parent == package_dir
                      else module_name.replace('.__init__', ''))
        for imported in imported_modules(path.read_text(encoding='utf-8'), module_name):
            other = part_of(imported)
            if other is None or other == own:
                continue
            edges.setdefault((own, other), []).append(str(path.relative_to(package_dir)))
    return edges


def forbidden_edges(edges, layers=LAYERS):
    """Return the edges ``layers`` does not allow, with the files that make them."""
    return {edge: files for edge, files in edges.items()
            if edge[0] not in layers or edge[1] not in layers[edge[0]]}


def test_every_import_between_parts_is_on_the_map():
    edges = import_edges()
    assert ('run', 'core') in edges and ('cli', 'run') in edges  # the scan sees imports
    assert forbidden_edges(edges) == {}
    assert {part for part, _ in edges} | set().union(*LAYERS.values()) <= set(LAYERS)


def test_the_map_has_no_cycle():
    seen, stack = set(), []

    def visit(part):
        assert part not in stack, f'cycle: {" -> ".join(stack + [part])}'
        if part in seen:
            return
        stack.append(part)
        for other in LAYERS[part]:
            visit(other)
        stack.pop()
        seen.add(part)
    for part in LAYERS:
        visit(part)


def test_the_map_check_sees_a_forbidden_import(tmp_path):
    """Control: run.py importing the analysis layer, even inside a function, is reported."""
    package = tmp_path / 'ring_gyro_sim'
    package.mkdir()
    (package / 'run.py').write_text('def f():\n    from ring_gyro_sim.analysis import nnm\n',
                                    encoding='utf-8')
    (package / 'core').mkdir()
    (package / 'core' / '__init__.py').write_text('from ring_gyro_sim import ros\n',
                                                  encoding='utf-8')
    bad = forbidden_edges(import_edges(package))
    assert set(bad) == {('run', 'analysis'), ('core', 'ros')}


def module_graph(package_dir=PACKAGE_DIR):
    """
    Return ``{module: {module it imports, ...}}`` over the package's own modules.

    Imports inside functions count. ``from a import b`` with ``a.b`` a module is an import
    of ``a.b`` only: importing a sub-module runs its package's ``__init__`` first, which is
    the order Python gives and no circle; ``from a import name`` is an import of ``a``.
    """
    modules = {}
    for path in sorted(package_dir.rglob('*.py')):
        parts = path.relative_to(package_dir.parent).with_suffix('').parts
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        modules[name] = path
    graph = {}
    for name, path in modules.items():
        package = name if path.name == '__init__.py' else name.rsplit('.', 1)[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                edges.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                module = node.module or ''
                if node.level:
                    base = package.split('.')[:len(package.split('.')) - (node.level - 1)]
                    module = '.'.join(base + ([module] if module else []))
                subs = [f'{module}.{alias.name}' for alias in node.names]
                modules_named = [s for s in subs if s in modules]
                edges.update(modules_named)
                if len(modules_named) < len(subs):
                    edges.add(module)
        graph[name] = {m for m in edges if m in modules and m != name}
    return graph


def import_circles(graph):
    """Return the circles of ``graph``: its strongly connected parts of two or more modules."""
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            part = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                part.append(other)
                if other == node:
                    break
            if len(part) > 1:
                circles.append(sorted(part))
    for node in sorted(graph):
        if node not in index:
            visit(node)
    return circles


def test_no_module_imports_itself_through_others():
    graph = module_graph()
    assert 'ring_gyro_sim.core.engine.full' in graph['ring_gyro_sim.run']  # the scan works
    assert import_circles(graph) == []


def test_the_circle_check_sees_a_circle_inside_a_function(tmp_path):
    """Control: a -> b at the top, b -> a inside a function, is a circle; a -> pkg.c is not."""
    package = tmp_path / 'ring_gyro_sim'
    (package / 'pkg').mkdir(parents=True)
    (package / '__init__.py').write_text('', encoding='utf-8')
    (package / 'a.py').write_text('from ring_gyro_sim import b\nfrom ring_gyro_sim.pkg import c\n',
                                  encoding='utf-8')
    (package / 'b.py').write_text('def f():\n    from ring_gyro_sim import a\n', encoding='utf-8')
    (package / 'pkg' / '__init__.py').write_text('from ring_gyro_sim.pkg.c import X\n',
                                                 encoding='utf-8')
    (package / 'pkg' / 'c.py').write_text('X = 1\n', encoding='utf-8')
    assert import_circles(module_graph(package)) == [['ring_gyro_sim.a', 'ring_gyro_sim.b']]


PUBLIC_UNDERSCORES = {'_replace', '_asdict', '_fields', '_make'}
"""Names with an underscore that are public by their type's own API (named tuples)."""
FOREIGN_PRIVATE_READS = {('core/kernels/cache.py', '_cache'),
                         ('core/kernels/cache.py', '_cache_file'),
                         ('core/kernels/cache.py', '_load_index')}
"""numba's own dispatcher cache, read where the kernels' cache is checked (not ours)."""


def private_reads(package_dir=PACKAGE_DIR):
    """
    Return ``[(file, line, expression)]``: an underscore name read off another module's object.

    ``obj._name`` is allowed on ``self`` and ``cls``, and where the module itself defines
    ``_name`` (a class of the module reading another instance of itself); not elsewhere.
    """
    found = []
    for path in sorted(package_dir.rglob('*.py')):
        relative = str(path.relative_to(package_dir))
        tree = ast.parse(path.read_text(encoding='utf-8'))
        own = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                own.add(node.name)
            elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                  and node.value.id in ('self', 'cls')):
                own.add(node.attr)
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and node.attr.startswith('_')
                    and not node.attr.startswith('__')):
                continue
            if isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls'):
                continue
            if (node.attr in PUBLIC_UNDERSCORES or node.attr in own
                    or (relative, node.attr) in FOREIGN_PRIVATE_READS):
                continue
            found.append((relative, node.lineno, ast.unparse(node)))
    return found


def test_no_module_reads_another_modules_private_names():
    assert private_reads() == []


def test_the_private_read_check_sees_one(tmp_path):
    """Control: reading another module's object's ``_field`` is found, one's own is not."""
    package = tmp_path / 'ring_gyro_sim'
    package.mkdir()
    (package / 'a.py').write_text(
        'class A:\n    def __init__(self):\n        self._x = 1\n\n'
        '    def copy(self, other):\n        self._x = other._x\n', encoding='utf-8')
    (package / 'b.py').write_text('def f(a):\n    return a._x, a._replace()\n',
                                  encoding='utf-8')
    assert private_reads(package) == [('b.py', 2, 'a._x')]
