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
Where results go, checked before anything is computed: ``--out DIR`` and ``-o FILE``.

A verb that computes for minutes and then cannot write its results loses them all
(``ring_gyro characterize`` into a read-only directory: 20 minutes). Each verb therefore
checks its output location first: :func:`prepare_directory` creates ``--out`` (with its
parents), refuses an existing file there, and writes and removes a probe file in it, which
is the one test that holds on a read-only file system, for root, on network file systems and
under ACLs (``os.access`` says yes to root on a read-only mount's directory);
:func:`check_file` does the same for the directory of a ``-o`` file and refuses a directory
given as the file. The errors are :class:`OutputPathError`, one line naming the option, the
path and the reason.
"""

import os
from pathlib import Path
import tempfile
from typing import Union

from ring_gyro_sim.core.errors import RingGyroError

__all__ = ['OutputPathError', 'check_file', 'prepare_directory']

PROBE_PREFIX = '.ring_gyro-write-test-'


class OutputPathError(RingGyroError, OSError):
    """An output location cannot be used; the message names the option, the path and why."""


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _where(directory: Path, path) -> str:
    """Name ``directory`` in a message about ``path``: 'it' when it is the path itself."""
    return 'it' if os.fspath(directory) == os.fspath(path) else repr(str(directory))


def _probe(directory: Path, option: str, path) -> None:
    """Write and remove a file in ``directory``; raise :class:`OutputPathError` if it fails."""
    try:
        fd, name = tempfile.mkstemp(prefix=PROBE_PREFIX, dir=directory)
    except OSError as exc:
        raise OutputPathError(f'{option} {path}: cannot write in {_where(directory, path)}: '
                              f'{_reason(exc)}') from None
    os.close(fd)
    os.unlink(name)


def _make_directory(directory: Path, option: str, path) -> None:
    if directory.exists() and not directory.is_dir():
        where = 'exists' if _where(directory, path) == 'it' else f'{str(directory)!r} exists'
        raise OutputPathError(f'{option} {path}: {where} and is not a directory')
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        what = 'the directory' if _where(directory, path) == 'it' else repr(str(directory))
        raise OutputPathError(f'{option} {path}: cannot create {what}: '
                              f'{_reason(exc)}') from None


def prepare_directory(path: Union[str, os.PathLike], option: str = '--out') -> Path:
    """
    Create an output directory (and its parents) and check that files can be written in it.

    Raises
    ------
    OutputPathError
        ``path`` is an existing file, cannot be created, or nothing can be written in it.

    """
    directory = Path(path)
    _make_directory(directory, option, path)
    _probe(directory, option, path)
    return directory


def check_file(path: Union[str, os.PathLike], option: str = '-o') -> Path:
    """
    Check that the file ``path`` can be written: its directory created and writable.

    The file itself is not created; an existing file is left to the caller's rule (replaced,
    or refused without ``--overwrite``).

    Raises
    ------
    OutputPathError
        ``path`` is a directory, or its directory cannot be created or written in.

    """
    target = Path(path)
    if target.is_dir():
        raise OutputPathError(f'{option} {path}: is a directory (give a file name)')
    directory = target.parent
    _make_directory(directory, option, path)
    _probe(directory, option, path)
    return target
