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
Plots of the analysis results: the only module of the package that imports matplotlib.

matplotlib is imported lazily, inside the functions, with the non-interactive Agg backend,
so importing this module (or the analysis layer) costs nothing and needs no display.
Results are drawn in micrometres and kilohertz; the data stay in SI units.
"""

import numpy as np


def _pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend (imported on first use)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def plot_backbone(backbone, path, title=None) -> None:
    """
    Save the backbone of a nonlinear mode (frequency against amplitude, as Fig. 4).

    Parameters
    ----------
    backbone : ring_gyro_sim.analysis.hbm.Backbone
        The result to draw (``frequency_hz`` in Hz, ``amplitude_m`` in m).
    path : str or path-like
        Output image file (the format follows the suffix, e.g. ``.png``).
    title : str or None
        Figure title (default: mode, N_T and N_h).

    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.5))
    try:
        label = f'N_T = {backbone.taylor_terms}' if backbone.taylor_terms else 'untruncated'
        ax.plot(backbone.frequency_hz * 1e-3, backbone.amplitude_m * 1e6, '-', label=label)
        ax.set_xlabel('frequency (kHz)')
        ax.set_ylabel(f'max |q{backbone.mode}| (um)')
        ax.set_title(title or f'Backbone of the {backbone.mode}theta mode '
                              f'(harmonic balance, N_h = {backbone.harmonics})')
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(path, dpi=120)
    finally:
        plt.close(fig)


def _runs(mask: np.ndarray):
    """Index ranges ``(start, stop)`` of the runs of equal values in ``mask``."""
    edges = np.flatnonzero(np.diff(mask.astype(np.int8))) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [mask.size]])
    return list(zip(starts, stops))


def plot_forced_response(response, path, title=None, marker_hz=None) -> None:
    """
    Save the forced response (amplitude against drive frequency, as Fig. 9).

    Stable parts are drawn solid, unstable parts dashed; folds are marked.

    Parameters
    ----------
    response : ring_gyro_sim.analysis.hbm.ForcedResponse
        The result to draw (``frequency_hz`` in Hz, ``amplitude_m`` in m).
    path : str or path-like
        Output image file.
    title : str or None
        Figure title.
    marker_hz : float or None
        A drive frequency (Hz) to mark with a vertical line (e.g. 15798.3 Hz).

    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11.0, 4.5))
    try:
        f = response.frequency_hz * 1e-3
        a = response.amplitude_m * 1e6
        stable = np.asarray(response.stable, dtype=bool)
        # right panel: the resonance itself (where the response exceeds 5 % of its peak)
        near = f[a >= 0.05 * a.max()]
        pad = 0.15 * max(near.max() - near.min(), 1e-6)
        for ax, zoom in zip(axes, (False, True)):
            labelled = set()
            for start, stop in _runs(stable):
                sl = slice(max(start - 1, 0), stop)   # overlap one point: pieces join
                kind = 'stable' if stable[start] else 'unstable'
                ax.plot(f[sl], a[sl], '-' if stable[start] else '--',
                        color='C0' if stable[start] else 'C3',
                        label=None if kind in labelled else kind)
                labelled.add(kind)
            for fold in response.fold_frequencies_hz:
                ax.axvline(fold * 1e-3, color='0.6', lw=0.8, ls=':')
            if marker_hz is not None:
                ax.axvline(marker_hz * 1e-3, color='C2', lw=0.8, label=f'{marker_hz:.1f} Hz')
            if zoom:
                ax.set_xlim(near.min() - pad, near.max() + pad)
                ax.set_title('resonance (folds dotted)')
            else:
                ax.set_title(title or f'Forced response, A_e = {response.drive_amplitude:g} '
                                      f'm/s^2 (HB, N_h = {response.harmonics})')
            ax.set_xlabel('drive frequency (kHz)')
            ax.set_ylabel(f'max |q{response.mode}| (um)')
            ax.ticklabel_format(axis='x', useOffset=False)
            ax.grid(True, alpha=0.3)
            ax.legend()
        fig.tight_layout()
        fig.savefig(path, dpi=120)
    finally:
        plt.close(fig)
