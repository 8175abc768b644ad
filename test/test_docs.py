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

* Every relative link of ``README.md``, ``CONTRIBUTING.md``, ``CHANGELOG.md`` and
  ``doc/*.md`` points to a file or directory that exists (links inside code, absolute URLs
  and pure ``#anchors`` are not files and are left out); a control shows that a broken link
  is reported.
* The README names the command CI runs (``.ci/run``: ``make test-ci``) in a command block.
* ``config/default.yaml`` names every parameter of the table, as the README says it does.
* The repository is self-contained: the README, the other top-level pages, ``doc/``,
  ``config/`` and ``ring_gyro_sim/`` cite no path outside it (``../shared``: the reference
  material beside the repository, which a clone does not have; ``test/test_rosdep_keys.py``
  uses its tools legitimately and is not scanned), and every reference page they or the tests
  name (``physics.md``, ``interface.md``, ``style.md``, ``design.md``) exists in ``doc/``.
* The code carries no history: no date (year-month-day) and no commit hash in the comments
  and docstrings of ``ring_gyro_sim/`` and ``test/`` (the copyright line's year is not a
  date), nor the machine a figure was measured on ("measured on ... host", "measured with
  ... on this machine") or an issue number ("issue N", "issue #N": the tracker is not in the
  repository). A comment's lines are read together, as one text. History goes to
  ``doc/performance.md`` or ``CHANGELOG.md`` (CONTRIBUTING.md).

Each check has a control that shows it reports what it is meant to catch.
"""

import ast
import io
from pathlib import Path
import re
import tokenize

import pytest
from ring_gyro_sim.core.params import PARAMETERS
from ring_gyro_sim.paramfile import load_text

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
README = PACKAGE_ROOT / 'README.md'
DOC_PAGES = sorted((PACKAGE_ROOT / 'doc').glob('*.md'))
TOP_PAGES = [README, PACKAGE_ROOT / 'CONTRIBUTING.md', PACKAGE_ROOT / 'CHANGELOG.md']

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
    # The README points to these pages.
    names = {p.name for p in DOC_PAGES}
    assert {'architecture.md', 'calibration.md', 'numerics.md', 'paper_reproduction.md',
            'performance.md', 'recording.md', 'ros_workspace.md'} <= names


@pytest.mark.parametrize('page', TOP_PAGES + DOC_PAGES,
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
    assert commands == ['make test-ci']
    blocks = re.findall(r'```sh\n(.*?)```', README.read_text(encoding='utf-8'), flags=re.S)
    assert any(re.search(r'^make test-ci(\s|$)', b, flags=re.M) for b in blocks)


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
    # The file's one section, whatever its node key (the wildcard '/**' or a node's name).
    (section,) = load_text(text).values()
    listed = set(_names(section['ros__parameters']))
    assert sorted({p.name for p in PARAMETERS} - listed) == []


# -- self-contained: no path outside the repository, the reference pages in doc/ ----------

_OUTSIDE = re.compile(r'\.\./shared\b|\bshared/(?:docs|paper|tools|rosdistro)\b')
_REFERENCE_PAGE = re.compile(r'(?<![\w-])(physics|interface|style|design)\.md\b')


def _files(*patterns):
    """Return the files of the repository that match the glob ``patterns``, sorted."""
    return sorted({path for pattern in patterns for path in PACKAGE_ROOT.glob(pattern)})


SELF_CONTAINED = [p for p in TOP_PAGES if p.exists()] + _files(
    'doc/**/*.md', 'config/*.yaml', 'ring_gyro_sim/**/*.py')
"""Files that must not cite a path outside the repository."""
NAMING_PAGES = SELF_CONTAINED + [p for p in _files('test/**/*.py')
                                 if p != Path(__file__).resolve()]
"""Files whose names of reference pages must exist in doc/ (this file names them on purpose)."""


def outside_paths(text):
    """Return ``(line, text)`` of every citation of a path outside the repository in ``text``."""
    return [(text.count('\n', 0, m.start()) + 1, m.group()) for m in _OUTSIDE.finditer(text)]


def missing_reference_pages(text, doc_dir):
    """Return the reference pages that ``text`` names and ``doc_dir`` does not hold."""
    return sorted({m.group() for m in _REFERENCE_PAGE.finditer(text)
                   if not (doc_dir / m.group()).is_file()})


def test_nothing_cites_a_path_outside_the_repository():
    found = {str(p.relative_to(PACKAGE_ROOT)): outside_paths(p.read_text(encoding='utf-8'))
             for p in SELF_CONTAINED}
    assert {name: hits for name, hits in found.items() if hits} == {}


def test_the_reference_pages_named_are_in_doc():
    doc_dir = PACKAGE_ROOT / 'doc'
    found = {str(p.relative_to(PACKAGE_ROOT)):
             missing_reference_pages(p.read_text(encoding='utf-8'), doc_dir)
             for p in NAMING_PAGES}
    assert {name: pages for name, pages in found.items() if pages} == {}
    assert (doc_dir / 'physics.md').is_file() and (doc_dir / 'interface.md').is_file()


def test_the_self_containment_checks_report_what_they_must(tmp_path):
    """Control: outside paths and reference pages missing from doc/ are reported."""
    text = ('See ../shared/docs/physics.md and\nthe paper in `../shared/paper/`; ../sharedx '
            'and shared/docsx are not paths. Also style.md, doc/interface.md, '
            'my-physics.md and design.mdx.\n')
    assert outside_paths(text) == [(1, '../shared'), (2, '../shared')]
    (tmp_path / 'interface.md').write_text('x', encoding='utf-8')
    assert missing_reference_pages(text, tmp_path) == ['physics.md', 'style.md']
    assert SELF_CONTAINED and len(NAMING_PAGES) > len(SELF_CONTAINED)


# -- no history in the code: dates, hashes, hosts and issues in comments and docstrings ----

_DATE = re.compile(r'\b(?:19|20)\d\d-[01]\d-[0-3]\d\b')
_COMMIT = re.compile(r'\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b')
_COPYRIGHT = re.compile(r'#\s*Copyright\b')
_MEASURED_ON_HOST = re.compile(
    r'\bmeasured\s+(?:on|with)\b(?:[^.;]|\.\d){0,120}?\b(?:host|machine)\b', re.IGNORECASE)
"""A measurement's host named: "measured on ..." or "with ...", the host or machine in the
sentence."""
_ISSUE = re.compile(r'\bissues?[\s-]*#?\d+', re.IGNORECASE)
"""An issue number: "issue N", "Issue #N", "issue-N", "issues N, M and K" (N a number)."""


def comments_and_docstrings(source):
    """
    Yield ``(line, text)`` of every comment and docstring of Python ``source``.

    Comments on consecutive lines are one text, their lines joined without the ``#``, so that
    a phrase broken across them is found. Docstrings are the string-literal statements: those
    of modules, classes and functions and the attribute docstrings that follow an assignment.
    """
    block = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT and not _COPYRIGHT.match(token.string):
            if block and token.start[0] != block[-1][0] + 1:
                yield block[0][0], '\n'.join(text for _, text in block)
                block = []
            block.append((token.start[0], token.string.lstrip('#')))
    if block:
        yield block[0][0], '\n'.join(text for _, text in block)
    for node in ast.walk(ast.parse(source)):
        if (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
                and isinstance(node.value.value, str)):
            yield node.lineno, node.value.value


def pattern_marks(source, patterns):
    """Return ``(line, mark)`` of every match of ``patterns`` in the comments and docstrings."""
    return sorted((line + text.count('\n', 0, m.start()), ' '.join(m.group().split()))
                  for line, text in comments_and_docstrings(source)
                  for pattern in patterns for m in pattern.finditer(text))


def history_marks(source):
    """Return ``(line, mark)`` of every date or commit hash in the comments and docstrings."""
    return pattern_marks(source, (_DATE, _COMMIT))


def provenance_marks(source):
    """Return ``(line, mark)`` of every host of a measurement or issue number in them."""
    return pattern_marks(source, (_MEASURED_ON_HOST, _ISSUE))


HISTORY_FREE = _files('ring_gyro_sim/**/*.py', 'test/**/*.py')


def test_no_date_or_commit_hash_in_comments_or_docstrings():
    found = {str(p.relative_to(PACKAGE_ROOT)): history_marks(p.read_text(encoding='utf-8'))
             for p in HISTORY_FREE}
    assert {name: marks for name, marks in found.items() if marks} == {}


def test_the_history_check_reports_dates_and_hashes():
    """Control: a date or a hash in a comment or a docstring is found; code and years are not."""
    day, commit = '-'.join(('2026', '12', '03')), 'f6652' + '7b'
    source = (f'# Copyright {day[:4]} ring_gyro_sim developers\n'
              f'"""Module, measured on {day}."""\n'
              f'X = 1  # see {commit}^ for the old way\n'
              f'"""Attribute docstring of X, made with {commit}."""\n'
              f'LABEL = "{day} {commit}"  # a string in code is data, not history\n'
              'def f():\n'
              f'    """Return 2000000 (deadbeef and cafe are words; 1e-12 is a number)."""\n'
              '    return 2000000\n')
    assert history_marks(source) == [(2, day), (3, commit), (4, commit)]


def test_no_host_of_a_measurement_or_issue_number_in_comments_or_docstrings():
    found = {str(p.relative_to(PACKAGE_ROOT)): provenance_marks(p.read_text(encoding='utf-8'))
             for p in HISTORY_FREE}
    assert {name: marks for name, marks in found.items() if marks} == {}


def test_the_history_check_reports_hosts_and_issue_numbers():
    """Control: a measurement's host or an issue number is found, across a comment's lines."""
    source = ('"""Module: a take costs 6 us (measured with rclpy\'s take on this\n'
              'project\'s host)."""\n'
              '# Measured on this machine (2-core, numpy 2.4): 37 ns per normal.\n'
              'X = 1  # the bound of Issue 22, item 8\n'
              '# as issue #25 asks; the\n'
              '# issue-11 budget\n'
              'LABEL = "measured on the host, issue 9"  # a string in code is data\n'
              'def f():\n'
              '    """Return the measured rate (with the host\'s clock, ros2/rclpy#1371)."""\n'
              '    # Measured on 0.4 s means. The host is shared; tissue 3 is no issue.\n'
              '    return 1\n')
    assert provenance_marks(source) == [
        (1, "measured with rclpy's take on this project's host"),
        (3, 'Measured on this machine'), (4, 'Issue 22'), (5, 'issue #25'), (6, 'issue-11')]
