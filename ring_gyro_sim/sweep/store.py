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
The point store of a sweep: one small JSON file per finished point, written atomically.

``DIR/points/<key>.json`` holds a computed point (metrics, wall time, worker),
``DIR/failed/<key>.json`` one that raised or whose worker died: failures are retried by
``--resume``, computed points never are. A file is written to a temporary name in the same
directory, flushed to disk (``fsync``) and renamed with ``os.replace``: a reader (or a
resumed sweep) sees the whole record or none, whatever was killed when. Both the worker
that computed a point (when it sees the directory) and the client (on receipt) store it;
the two records are the same point, so whichever lands last is as good. A file that does not
hold a whole record (truncated by a full disk or a copy) is named by :meth:`PointStore.check`
and set aside by the engine, which computes the point again.

Non-finite floats are written as ``null`` (strict JSON) and read back as nan.

One sweep at a time writes into a directory: :meth:`PointStore.lock` takes an exclusive
``flock`` on ``DIR/.sweep.lock`` (which names the holder), held until :meth:`PointStore.unlock`
or the process ends (the kernel drops it then: a killed sweep leaves no stale lock). Two sweeps
started together into one directory would otherwise both decide what to compute from the same
empty store and replace each other's results. On a file system without locks the sweep goes
on unprotected.
"""

import errno
import fcntl
import json
import math
import os
from pathlib import Path
import socket
import tempfile
from typing import Any, Dict, Iterator, Optional

__all__ = ['LOCK_NAME', 'PointStore']

LOCK_NAME = '.sweep.lock'
"""The lock file of a sweep's directory."""
_NO_LOCKS = (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL)
"""What flock reports on a file system that has no locks."""


def _strict(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


class PointStore:
    """
    The ``points/`` and ``failed/`` directories of one sweep output directory.

    Parameters
    ----------
    root : str or path-like
        The sweep's ``--out`` directory.
    create : bool
        Create the directories (the client); False: use them only if they are there.

    """

    def __init__(self, root, create: bool = True) -> None:
        self.root = Path(root)
        self.points = self.root / 'points'
        self.failed = self.root / 'failed'
        self._lock_fd: Optional[int] = None
        if create:
            self.points.mkdir(parents=True, exist_ok=True)
            self.failed.mkdir(parents=True, exist_ok=True)

    def lock(self) -> Optional[str]:
        """
        Take the directory's exclusive sweep lock; None, or who holds it already.

        Returns
        -------
        str or None
            None: this store holds the lock now (or the file system has no locks); else
            the holder as its lock file names it (``pid N on HOST``).

        """
        if self._lock_fd is not None:
            return None
        path = self.root / LOCK_NAME
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode('utf-8', 'replace').strip()
            os.close(fd)
            return holder or 'another process'
        except OSError as exc:
            if exc.errno not in _NO_LOCKS:
                os.close(fd)
                raise
        os.ftruncate(fd, 0)
        os.pwrite(fd, f'pid {os.getpid()} on {socket.gethostname()}\n'.encode(), 0)
        self._lock_fd = fd
        return None

    def unlock(self) -> None:
        """Release the lock :meth:`lock` took (the lock file stays)."""
        fd, self._lock_fd = self._lock_fd, None
        if fd is not None:
            os.close(fd)

    @staticmethod
    def reachable(root) -> bool:
        """Tell whether ``root`` holds a point store (a worker on another machine: no)."""
        return os.path.isdir(os.path.join(root, 'points'))

    def path(self, key: str, failed: bool = False) -> Path:
        """Return the file of point ``key``."""
        return (self.failed if failed else self.points) / f'{key}.json'

    def write(self, record: Dict[str, Any]) -> Path:
        """Store ``record`` atomically (a failure under ``failed/``); return its path."""
        failed = record.get('error') is not None
        target = self.path(record['key'], failed)
        text = json.dumps(_strict(record), sort_keys=True, allow_nan=False)
        fd, tmp = tempfile.mkstemp(prefix=f'.{record["key"]}.', suffix='.tmp',
                                   dir=target.parent)
        try:
            with os.fdopen(fd, 'w', encoding='utf-8') as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
        if not failed:
            try:
                self.path(record['key'], failed=True).unlink()
            except FileNotFoundError:
                pass
        return target

    def read(self, key: str) -> Optional[Dict[str, Any]]:
        """Return the computed record of ``key`` (None: not computed, or unreadable)."""
        record, _ = self._load(key)
        return record

    def check(self, key: str) -> Optional[str]:
        """Return why the stored file of ``key`` holds no computed record (None: it does)."""
        return self._load(key)[1]

    def _load(self, key: str):
        """Return ``(record, None)`` or ``(None, why not)`` for the file of ``key``."""
        try:
            text = self.path(key).read_text(encoding='utf-8')
        except FileNotFoundError:
            return None, 'no file'
        except (OSError, UnicodeDecodeError) as exc:
            return None, f'unreadable: {exc}'
        try:
            record = json.loads(text)
        except ValueError as exc:
            return None, f'not a whole JSON record ({len(text)} bytes; {exc})'
        if not isinstance(record, dict) or record.get('key') != key:
            return None, 'not the record of this point (its key differs)'
        if record.get('metrics') is None:
            return None, 'holds no metrics'
        return record, None

    def set_aside(self, key: str) -> Path:
        """Rename the damaged file of ``key`` to ``<key>.json.damaged`` (kept); its path."""
        target = self.path(key).with_name(f'{key}.json.damaged')
        os.replace(self.path(key), target)
        return target

    def has(self, key: str) -> bool:
        """Tell whether point ``key`` is computed (its file exists)."""
        return self.path(key).is_file()

    def keys(self) -> Iterator[str]:
        """Yield the keys of the computed points."""
        for p in self.points.glob('*.json'):
            yield p.stem

    def read_failure(self, key: str) -> Optional[Dict[str, Any]]:
        """Return the failure record of ``key`` (None: none)."""
        try:
            return json.loads(self.path(key, failed=True).read_text(encoding='utf-8'))
        except (OSError, ValueError):
            return None
