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
The README and the ``doc/`` pages hold together.

* Every relative link of ``README.md`` and ``doc/*.md`` points to a file or directory that
  exists (links inside code, absolute URLs and pure ``#anchors`` are not files and are left
  out); a control shows that a broken link is reported.
* The README names the command CI runs (``.ci/run``: ``make test``).
* ``config/default.yaml`` names every parameter of the table, as the README says it does.
"""

from pathlib import Path
import re

import pytest
from ring_gyro_sim.core.params import PARAMETERS
from ring_gyro_sim.paramfile import load_text

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
README = PACKAGE_ROOT / 'README.md'
DOC_PAGES = sorted((PACKAGE_ROOT / 'doc').glob('*.md'))

_FENCE = re.compile(r'^(```|~~~).*?^\1[^\n]*$', re.MULTILINE | re.DOTALL)
_CODE_SPAN = re.compile(r'(`+)(?:(?!\1).)+?\1', re.DOTALL)
_LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]*)>?(?:\s+"[^"]*")?\s*\)')
_REFERENCE = re.compile(r'^\s*\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$', re.MULTILINE)
_SCHEME = re.compile(r'^[a-zA-Z][a-zA-Z0-9+.-]*:')


def link_targets(text):
    """Return the targets of the inline and reference links of Markdown ``text``, not in code."""
    prose = _CODE_SPAN.sub('', _FENCE.sub('', text))
    return _LINK.findall(prose) + _REFERENCE.findall(prose)


def broken_links(page: Path):
    """Return the relative link targets of ``page`` that do not name an existing path."""
    broken = []
    for target in link_targets(page.read_text(encoding='utf-8')):
        if not target or target.startswith('#') or _SCHEME.match(target):
            continue  # an anchor in the page or a URL (http:, mailto:): not a file
        path = target.split('#', 1)[0]
        if not (page.parent / path).exists():
            broken.append(target)
    return broken


def test_there_are_doc_pages():
    # The README points to these pages (the split of issue 9).
    names = {p.name for p in DOC_PAGES}
    assert {'architecture.md', 'calibration.md', 'numerics.md', 'paper_reproduction.md',
            'performance.md', 'recording.md', 'ros_workspace.md'} <= names


@pytest.mark.parametrize('page', [README] + DOC_PAGES,
                         ids=lambda p: str(p.relative_to(PACKAGE_ROOT)))
def test_relative_links_resolve(page):
    assert broken_links(page) == []


def test_the_readme_links_every_doc_page():
    targets = {Path(t.split('#', 1)[0]).name for t in link_targets(README.read_text('utf-8'))}
    assert [p.name for p in DOC_PAGES if p.name not in targets] == []


def test_the_link_check_reports_a_broken_link(tmp_path):
    """Control: a missing target is reported; code, URLs and anchors are not links to files."""
    (tmp_path / 'there.md').write_text('x', encoding='utf-8')
    page = tmp_path / 'page.md'
    page.write_text(
        '[ok](there.md) [ok too](there.md#part) [gone](missing.md) ![img](gone.png)\n'
        '[web](https://example.org/x.md) [anchor](#top) `[code](nope.md)`\n'
        '```\n[fenced](nope2.md)\n```\n'
        '[ref]: also_missing.md\n', encoding='utf-8')
    assert broken_links(page) == ['missing.md', 'gone.png', 'also_missing.md']


def test_the_readme_names_the_ci_command():
    ci = (PACKAGE_ROOT / '.ci' / 'run').read_text(encoding='utf-8')
    commands = [line.strip() for line in ci.splitlines()
                if line.strip() and not line.lstrip().startswith(('#', 'set ', 'cd '))]
    assert commands == ['make test']
    assert 'make test' in README.read_text(encoding='utf-8')


def _names(mapping, prefix=''):
    for key, value in mapping.items():
        if isinstance(value, dict):
            yield from _names(value, f'{prefix}{key}.')
        else:
            yield prefix + key


def test_default_yaml_names_every_parameter():
    # README "Parameters": config/default.yaml lists every parameter (its values are checked
    # against the table's defaults in test/core/test_params.py).
    text = (PACKAGE_ROOT / 'config' / 'default.yaml').read_text(encoding='utf-8')
    listed = set(_names(load_text(text)['ring_gyro']['ros__parameters']))
    assert sorted({p.name for p in PARAMETERS} - listed) == []
