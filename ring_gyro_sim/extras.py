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
The libraries some verbs need beyond the node's, checked before those verbs compute anything.

``pip install ring_gyro_sim`` brings allantools, and the ``sweep`` extra dask, distributed,
xarray and netCDF4; in a ROS workspace rosdep brings only what has a rosdep key (netCDF4 and
pandas do, the others not: doc/ros_workspace.md). A verb that found one missing half-way
ended in an ImportError traceback (``characterize`` after its first runs, ``sweep`` at once).
:func:`require` names every missing module of a verb at its start, with the pip command and,
where there is one, the rosdep key: one :class:`MissingDependencyError`. Nothing is
imported to find out (``importlib.util.find_spec``).
"""

import importlib.util
from typing import Dict, List, Optional, Sequence, Tuple

from ring_gyro_sim.core.errors import RingGyroError

__all__ = ['MODULES', 'MissingDependencyError', 'SWEEP', 'missing', 'require']

MODULES: Dict[str, Tuple[str, Optional[str]]] = {
    'allantools': ('allantools', None),
    'dask': ('dask[distributed]', None),
    'distributed': ('dask[distributed]', None),
    'xarray': ('xarray', None),
    'netCDF4': ('netCDF4', 'python3-netcdf4'),
    'pandas': ('pandas', 'python3-pandas'),
}
"""Module -> (its pip requirement, its rosdep key or None: no key in the Jazzy rosdistro)."""
SWEEP = ('dask', 'distributed', 'xarray', 'netCDF4', 'pandas')
"""What a sweep imports (setup.py extra ``sweep``; pandas comes with xarray)."""


class MissingDependencyError(RingGyroError, ImportError):
    """A verb's libraries are not installed; the message names them and how to install them."""


def missing(modules: Sequence[str]) -> List[str]:
    """Return the modules of ``modules`` that cannot be imported here (none is imported)."""
    out = []
    for name in modules:
        try:
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # a finder that refuses it, a broken package
            found = False
        if not found:
            out.append(name)
    return out


def require(modules: Sequence[str], what: str) -> None:
    """
    Raise :class:`MissingDependencyError` if any of ``modules`` is missing.

    Parameters
    ----------
    modules : sequence of str
        Keys of :data:`MODULES`.
    what : str
        What needs them, to start the message (``'characterize (the Allan deviation)'``).

    """
    absent = missing(modules)
    if not absent:
        return
    pip = list(dict.fromkeys(MODULES[m][0] for m in absent))
    keys = [MODULES[m][1] for m in absent if MODULES[m][1]]
    without = [m for m in absent if not MODULES[m][1]]
    ros = []
    if keys:
        ros.append(f'rosdep keys {", ".join(keys)}')
    if without:
        ros.append(f'no rosdep key for {", ".join(without)}')
    pip_text = ' '.join(f'"{r}"' if '[' in r else r for r in pip)
    raise MissingDependencyError(
        f'{what} needs {", ".join(absent)}, not installed: pip install {pip_text} (in a ROS '
        f'workspace: {"; ".join(ros)}: doc/ros_workspace.md)')
