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
Sweeps at scale on ``dask.distributed``: shock-survival and jump maps (``ring_gyro sweep``).

A point is (parameter set) -> metrics (:func:`point.evaluate`, one pure function over the one
run path, through :func:`ring_gyro_sim.analysis.cases.run_case`); a spec (:mod:`.spec`)
says which points; :func:`engine.run_sweep` computes the missing ones on a Dask cluster,
stores each as it finishes (:mod:`.store`) and writes the results as an ``xarray.Dataset``
(:mod:`.results`) with PNG maps (``analysis.plotting.plot_sweep``). User guide: ``doc/sweeps.md``.

Why a package of its own, above ``analysis``: it needs ``dask.distributed``, ``xarray`` and
``netCDF4`` (the ``sweep`` extra of setup.py), which the node never imports; ``analysis``
stays free of them. One exception: ``ring_gyro report`` runs its Case 4 through this package
(:func:`ring_gyro_sim.report.run_case4`, which imports it inside the function, when
the plan has Case 4). Importing this package imports none of them either: they load when a
sweep runs or its results are built.
"""

from ring_gyro_sim.sweep.spec import load_spec, parse_spec, Point, SweepSpec, SweepSpecError

__all__ = ['Point', 'SweepSpec', 'SweepSpecError', 'load_spec', 'parse_spec', 'run_sweep']


def run_sweep(*args, **kwargs):
    """Run a sweep: :func:`ring_gyro_sim.sweep.engine.run_sweep` (dask loads here)."""
    from ring_gyro_sim.sweep.engine import run_sweep as _run
    return _run(*args, **kwargs)
