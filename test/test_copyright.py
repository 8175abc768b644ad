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
The copyright test of `ros2 pkg create --build-type ament_python`, runnable without ROS.

It calls ``ament_copyright.main.main`` as the generated test does when ament_copyright is
installed (a ROS installation; it is not on PyPI), else applies its rule for Python files: a
``# Copyright <year> <holder>`` line followed by the Apache License 2.0 file header.
"""

from pathlib import Path
import re

import pytest

try:
    from ament_copyright.main import main
except ImportError:  # not installed (not on PyPI): the rule below
    main = None

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
LINTED = ('ring_gyro_sim', 'test', 'setup.py', 'benchmarks')

# ament_copyright's file header of the apache2 license (template/apache2_header.txt); it
# compares with the whitespace collapsed.
APACHE2_HEADER = """
Licensed under the Apache License, Version 2.0 (the "License");
you may not use this file except in compliance with the License.
You may obtain a copy of the License at

    http://www.apache.org/licenses/LICENSE-2.0

Unless required by applicable law or agreed to in writing, software
distributed under the License is distributed on an "AS IS" BASIS,
WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
See the License for the specific language governing permissions and
limitations under the License.
"""
# ament_copyright's regex: 'Copyright [(c)] YEAR[-YEAR][, YEAR...] NAME'.
COPYRIGHT_LINE = re.compile(r'^#\s*copyright(?:\s+\(c\))?\s+\d{4}(?:-\d{4})?'
                            r'(?:,\s*\d{4}(?:-\d{4})?)*,?\s+\S.*$', re.IGNORECASE)


def python_files():
    files = []
    for name in LINTED:
        path = PACKAGE_ROOT / name
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            files += [p for p in sorted(path.rglob('*.py'))
                      if not any(part.startswith(('.', '__pycache__'))
                                 for part in p.relative_to(PACKAGE_ROOT).parts[:-1])]
    return files


def header_problem(text):
    """None if ``text`` starts with an ament-style copyright + Apache-2.0 header, else why."""
    if not text.strip():
        return None  # ament_copyright skips empty files
    lines = text.splitlines()
    while lines and lines[0].startswith('#') and (
            lines[0].startswith('#!') or 'coding:' in lines[0] or 'coding=' in lines[0]):
        lines.pop(0)
    while lines and not lines[0].strip():
        lines.pop(0)
    block = []
    for line in lines:
        if not line.startswith('#'):
            break
        block.append(line)
    if not block or not COPYRIGHT_LINE.match(block[0]):
        return 'does not start with a "# Copyright <year> <holder>" line'
    body = ' '.join(' '.join(line[1:] for line in block[1:]).split())
    if ' '.join(APACHE2_HEADER.split()) not in body:
        return 'has no Apache License 2.0 header after the copyright line'
    return None


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright():
    if main is not None:
        rc = main(argv=[str(PACKAGE_ROOT / p) for p in LINTED if (PACKAGE_ROOT / p).exists()])
        assert rc == 0, 'Found errors'
        return
    files = python_files()
    assert files
    problems = []
    for path in files:
        why = header_problem(path.read_text(encoding='utf-8'))
        if why:
            problems.append(f'{path.relative_to(PACKAGE_ROOT)}: {why}')
    assert not problems, f'{len(problems)} files without a copyright header:\n' + \
        '\n'.join(problems)


GOOD = '# Copyright 2025 ring_gyro_sim developers\n#\n' + \
    ''.join(f'#{" " if line else ""}{line}\n' for line in APACHE2_HEADER.strip().splitlines()) + \
    '\n"""Docstring."""\n'


@pytest.mark.copyright
@pytest.mark.linter
@pytest.mark.parametrize('text, ok', [
    (GOOD, True),
    ('#!/usr/bin/env python3\n' + GOOD, True),
    ('', True),
    ('"""Docstring."""\n', False),
    ('# Copyright ring_gyro_sim developers\n' + GOOD.split('\n', 1)[1], False),  # no year
    ('# Copyright 2025 ring_gyro_sim developers\n# SPDX: MIT\n', False),
    (GOOD.replace('AS IS', 'AS-IS'), False),
])
def test_header_rule(text, ok):
    assert (header_problem(text) is None) is ok, header_problem(text)
