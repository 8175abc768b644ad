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
Ctrl-C and SIGTERM early in the life of ``ring_gyro_node``.

The real node process gets the signal at several moments of its start-up: the imports (rclpy,
numpy, numba: about 0.5 s here), ``rclpy.init``, the start state. Every time it must end with
exit code 0 and without a traceback. A signal that lands before the package installed its
handlers is Python's to handle, not the package's: while the interpreter itself starts (its
frozen start-up modules, ``site``), or in the few statements of ours before the first lines of
``ring_gyro_sim/ros/__init__.py`` install them. Such a traceback names no frame of ours past
that point (SIGINT), or the process ends by the signal with nothing written (SIGTERM's default
action), and is told apart (it needs a start-up slower than the first moment, 50 ms). The
handlers once went in after ``import signal`` (1 ms idle, more under load): a CI run's Ctrl-C
landed in it; ``_signal`` now installs them, with nothing to import.
"""

import re
import signal
import subprocess
import time

from node_harness import node_command, node_env, params_yaml, REPO_ROOT
import pytest

MOMENTS_S = (0.05, 0.1, 0.2, 0.3, 0.4, 0.6, 0.8, 1.0)
"""When the signal is sent after the process started, s: across the imports (tracebacks
came in the first ~0.4 s, and up to 0.9 s under load, before the early handlers), rclpy.init
and the start state."""
EXIT_TIMEOUT_S = 60.0
"""The imports go on after a noted signal (then the process ends at once), generously."""


def run_and_signal(params_file, sig, delay_s):
    """Start the node, send ``sig`` after ``delay_s``; return (exit code, stderr text)."""
    proc = subprocess.Popen(node_command(params_file), cwd=REPO_ROOT, env=node_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(delay_s)
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=EXIT_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail(f'the node did not end within {EXIT_TIMEOUT_S} s of {sig.name}')
    return proc.returncode, err.decode(errors='replace')


def before_our_handlers(code, stderr, sig):
    """
    Tell whether the signal came before the package could install its handlers.

    That is while Python itself started (its frozen start-up modules, ``site`` and the ``.pth``
    files it runs: the editable install's finder imports pathlib), or in the few statements of
    ours that run before ``ring_gyro_sim/ros/__init__.py`` installs them (see
    :func:`_before_the_handlers`). SIGINT then gives a traceback with no frame of ours past
    that point; SIGTERM, whose default action is to end the process, an exit by the signal
    with nothing written.
    """
    if code == -sig and not stderr.strip():
        return True
    frames = [(f, int(n)) for f, n in re.findall(r'File "([^"]+)", line (\d+)', stderr)]
    if not frames:
        return False
    ours = [(f, n) for f, n in frames if _ours(f)]
    if ours:
        return all(_before_the_handlers(f, n) for f, n in ours)
    frozen = all(f.startswith('<frozen ') for f, _ in frames)
    return frozen or 'init_import_site' in stderr


def _ours(path):
    """Tell whether a traceback's file is the package's (or its console script)."""
    return ('/ring_gyro_sim/' in path and 'site-packages' not in path
            or path.endswith('ring_gyro_node'))


INSTALL_LINE = next(
    number for number, text in enumerate(
        (REPO_ROOT / 'ring_gyro_sim' / 'ros' / '__init__.py').read_text().splitlines(), 1)
    if '_signal.signal(' in text)
"""The line of ``ring_gyro_sim/ros/__init__.py`` that installs the early handlers."""


def _before_the_handlers(path, line):
    """
    Tell whether a frame of ours runs before the early handlers are installed.

    The console script's frame is its import line (a frame past it is in ``node.py``), the
    package's ``__init__.py`` holds a docstring and two names, and ``ros/__init__.py`` installs
    the handlers at :data:`INSTALL_LINE`, after only a few statements (a Ctrl-C there needs a
    start-up exactly as slow as the first moment, to the tens of microseconds).
    """
    if path.endswith('ring_gyro_node') or path.endswith('/ring_gyro_sim/__init__.py'):
        return True
    return path.endswith('/ring_gyro_sim/ros/__init__.py') and line <= INSTALL_LINE


@pytest.fixture(scope='module')
def params_file(tmp_path_factory):
    # From rest: the start state costs nothing, so the later moments reach the running node.
    path = tmp_path_factory.mktemp('signals') / 'params.yaml'
    path.write_text(params_yaml({'drive.start_on': 'rest', 'duration': 0.0}))
    return path


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_an_early_signal_ends_the_node_cleanly(params_file, sig):
    outcomes = []
    for delay in MOMENTS_S:
        code, err = run_and_signal(params_file, sig, delay)
        outcomes.append((delay, code, err))
        print(f'{sig.name} at {delay:.2f} s: exit code {code}, '
              f'{err.strip().splitlines()[-1] if err.strip() else "(no output)"}')
    ours = [(d, c, e) for d, c, e in outcomes if not before_our_handlers(c, e, sig)]
    # Only the first moment may come before the package installed its handlers.
    assert len(ours) >= len(MOMENTS_S) - 1
    for delay, code, err in ours:
        assert 'Traceback' not in err, f'{sig.name} at {delay} s:\n{err}'
        assert code == 0, f'{sig.name} at {delay} s: exit code {code}\n{err}'
