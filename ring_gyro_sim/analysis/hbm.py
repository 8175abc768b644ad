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
Backbones (Fig. 4) and the forced response (Fig. 9) by harmonic balance, with their plots.

The computation is :mod:`ring_gyro_sim.core.harmonic_balance` (the method, its equations and
its checks are its docstring); this module hands its results on with a ``plot`` method, so that
the core never imports the plotting layer. Every other name is the core's.
"""

from dataclasses import fields

from ring_gyro_sim.analysis import plotting
from ring_gyro_sim.core import harmonic_balance as _hb
from ring_gyro_sim.core.harmonic_balance import (backbone_frequency, DENSE_SAMPLES,
                                                 forced_orbit, forced_orbits_at,
                                                 HarmonicOrbit, monodromy_multipliers,
                                                 time_samples)

__all__ = ['Backbone', 'DENSE_SAMPLES', 'ForcedResponse', 'HarmonicOrbit', 'backbone',
           'backbone_frequency', 'forced_orbit', 'forced_orbits_at', 'frf',
           'monodromy_multipliers', 'time_samples']


def _present(cls, result):
    """Return ``result`` (a core dataclass) as an instance of its subclass ``cls``."""
    return cls(**{f.name: getattr(result, f.name) for f in fields(result)})


class Backbone(_hb.Backbone):
    """:class:`ring_gyro_sim.core.harmonic_balance.Backbone` with a plot."""

    def plot(self, path, **kwargs) -> None:
        """Save a frequency-amplitude plot to ``path`` (see ``plotting.plot_backbone``)."""
        plotting.plot_backbone(self, path, **kwargs)


class ForcedResponse(_hb.ForcedResponse):
    """:class:`ring_gyro_sim.core.harmonic_balance.ForcedResponse` with a plot."""

    def plot(self, path, **kwargs) -> None:
        """Save the FRF plot to ``path`` (see ``plotting.plot_forced_response``)."""
        plotting.plot_forced_response(self, path, **kwargs)


def backbone(*args, **kwargs) -> Backbone:
    """:func:`ring_gyro_sim.core.harmonic_balance.backbone`, the result with a plot."""
    return _present(Backbone, _hb.backbone(*args, **kwargs))


def frf(*args, **kwargs) -> ForcedResponse:
    """:func:`ring_gyro_sim.core.harmonic_balance.frf`, the result with a plot."""
    return _present(ForcedResponse, _hb.frf(*args, **kwargs))
