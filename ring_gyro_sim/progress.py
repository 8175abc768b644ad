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
One progress reporter for long offline runs (``ring_gyro run``, the paper cases, ``report``).

A thin layer over ``tqdm`` (the field's progress bar, not a hand-written one): :class:`Progress`
in simulated seconds, :class:`Counter` in things done (a sweep's points). It appears only once
a run has taken :data:`DELAY_S` of wall time, refreshes about twice a second on a terminal and,
when stderr is not a terminal (a log file, CI), writes one plain line every
:data:`PIPE_INTERVAL_S` instead of carriage-return updates.
"""

import sys
from typing import Optional, TextIO

from tqdm import tqdm

__all__ = ['Counter', 'DELAY_S', 'PIPE_INTERVAL_S', 'Progress']

DELAY_S = 2.0
"""Wall seconds before the bar appears (short runs show nothing)."""
PIPE_INTERVAL_S = 5.0
"""Wall seconds between lines when stderr is not a terminal."""


class _Lines:
    """A file wrapper that turns tqdm's carriage-return refreshes into whole lines."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace('\r', '').replace('\x1b[A', '')
        if text.strip():
            self.stream.write(text.rstrip('\n') + '\n')

    def flush(self) -> None:
        self.stream.flush()


class Progress:
    """
    A progress bar over ``total_s`` simulated seconds on stderr.

    Parameters
    ----------
    total_s : float
        Simulated seconds of the whole run.
    enabled : bool
        False shows nothing.
    name : str, optional
        Prefix of the bar (e.g. the case name).

    """

    def __init__(self, total_s: float, enabled: bool = True, name: Optional[str] = None) -> None:
        self.total_s = float(total_s)
        self._done_s = 0.0
        self._bar = None
        if not enabled:
            return
        stream = sys.stderr
        tty = bool(getattr(stream, 'isatty', lambda: False)())
        self._bar = tqdm(
            total=self.total_s, desc=name, unit='sim s', unit_scale=False, delay=DELAY_S,
            file=stream if tty else _Lines(stream), mininterval=0.5 if tty else PIPE_INTERVAL_S,
            dynamic_ncols=tty, ncols=None if tty else 100, leave=True,
            bar_format='{desc}{percentage:5.1f}% |{bar}| {n:.3f}/{total:.3f} sim s '
                       '[{elapsed}<{remaining}, x{rate_noinv_fmt}]'.replace(
                           '{desc}', '{desc}: ' if name else ''))

    def note(self, text: str) -> None:
        """Write one line on stderr now (above the bar when there is one), shown or not."""
        if self._bar is not None:
            self._bar.write(text, file=self._bar.fp)
        else:
            sys.stderr.write(text + '\n')
            sys.stderr.flush()

    def update(self, sim_s: float, note: str = '') -> None:
        """Report that ``sim_s`` simulated seconds are done (``note``: a short postfix)."""
        if self._bar is None:
            return
        step = max(0.0, min(sim_s, self.total_s) - self._done_s)
        self._done_s += step
        if note:
            self._bar.set_postfix_str(note, refresh=False)
        self._bar.update(step)

    def close(self) -> None:
        """Finish the bar (a final line when it was shown)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class Counter:
    """
    A progress bar over ``total`` things (a sweep's points) on ``stream`` (stderr).

    Parameters
    ----------
    total : int
        Things in all.
    initial : int
        Already done (stored points of a resumed sweep).
    unit : str
        What is counted.
    enabled : bool
        False shows no bar (:meth:`write` still writes).
    name : str, optional
        Prefix of the bar.
    stream : file, optional
        Where the bar goes (default: ``sys.stderr`` at the time of the call).

    """

    def __init__(self, total: int, initial: int = 0, unit: str = 'point',
                 enabled: bool = True, name: Optional[str] = None,
                 stream: Optional[TextIO] = None) -> None:
        stream = sys.stderr if stream is None else stream
        self.stream = stream
        tty = bool(getattr(stream, 'isatty', lambda: False)())
        self._bar = None
        if enabled:
            self._bar = tqdm(total=total, initial=initial, unit=unit, desc=name,
                             file=stream if tty else _Lines(stream), delay=DELAY_S,
                             mininterval=0.5 if tty else PIPE_INTERVAL_S,
                             dynamic_ncols=tty, ncols=None if tty else 100)

    def update(self, count: int = 1) -> None:
        """Count ``count`` more done."""
        if self._bar is not None:
            self._bar.update(count)

    def write(self, text: str, file: Optional[TextIO] = None) -> None:
        """Write one line on ``file`` (default: the bar's stream), above the bar if shown."""
        target = self.stream if file is None else file
        if self._bar is not None and target is self.stream:
            self._bar.write(text, file=self._bar.fp)
        else:
            target.write(text + '\n')
            target.flush()

    def close(self) -> None:
        """Finish the bar (a final line when it was shown)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
