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
Plots of the time-domain cases (Figs. 5, 7, 10-15).

matplotlib is imported lazily, inside the functions, with the non-interactive Agg backend:
importing this module costs nothing and needs no display. Amplitudes are drawn in um,
frequencies in kHz; the data stay in SI units.
"""

import numpy as np


def _pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend (imported on first use)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _branch_lines(ax, branches) -> None:
    if branches is None:
        return
    for value, label, style in ((branches.upper_m, 'upper branch', ':'),
                                (branches.lower_m, 'lower branch', '--')):
        if np.isfinite(value):
            ax.axhline(value * 1e6, color='grey', ls=style, lw=0.8, label=label)


def plot_case(result, path, title=None, log=True) -> None:
    """
    Save the positive envelopes of the modal displacements of one case (Figs. 10-12, 14-15).

    Parameters
    ----------
    result : ring_gyro_sim.analysis.cases.CaseResult
        The run.
    path : str or path-like
        PNG file.
    title : str, optional
        Plot title (default: the case description).
    log : bool
        Logarithmic amplitude axis (the branches differ by a factor of about 14).

    """
    plt = _pyplot()
    e = result.envelope
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for name in e.names:
        if name.startswith('q'):
            ax.plot(e.t, e.channel(name) * 1e6, lw=0.9, label=name)
    _branch_lines(ax, result.branches)
    if log:
        ax.set_yscale('log')
    ax.set_xlabel('time (s)')
    ax.set_ylabel('positive envelope (um)')
    ax.set_title(title or result.spec.description, fontsize=10)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8, loc='best')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_q2_sweep(results, path, title='Case 4: q2 envelope for Q_1 from 5 000 to 180 000'
                  ) -> None:
    """
    Save the q2 envelopes of a Q_1 sweep on one axis (Fig. 13).

    Parameters
    ----------
    results : sequence of CaseResult
        One run per Q_1.
    path : str or path-like
        PNG file.
    title : str
        Plot title.

    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for r in results:
        ax.plot(r.envelope.t, r.envelope.channel('q2') * 1e6, lw=0.9,
                label=f'Q_1 = {r.spec.q1_quality:g}')
    if results:
        _branch_lines(ax, results[0].branches)
    ax.set_yscale('log')
    ax.set_xlabel('time (s)')
    ax.set_ylabel('q2 positive envelope (um)')
    ax.set_title(title, fontsize=10)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8, loc='best')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_ritz_orders(results, path, channel='w0',
                     title='Fig. 5: radial displacement envelope for N_R = 1..5') -> None:
    """
    Save the envelope of the radial displacement for several Ritz orders (Fig. 5).

    Parameters
    ----------
    results : sequence of CaseResult
        One run per N_R.
    path : str or path-like
        PNG file.
    channel : str
        Envelope channel: 'w0' (w at theta = 0, m) or 'wmax' (max over theta, m).
    title : str
        Plot title.

    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for r in results:
        ax.plot(r.envelope.t, r.envelope.channel(channel) * 1e6, lw=0.9,
                label=r.spec.description.split(',')[0])
    ax.set_xlabel('time (s)')
    ax.set_ylabel('radial displacement envelope (um)')
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_spectrogram(spec, path, ridge_t=None, ridge_hz=None, f_max_hz=70e3,
                     title='Fig. 7: spectrogram of q1 after a 10 000 g shock') -> None:
    """
    Save a spectrogram (Fig. 7) with an optional ridge of the 1theta line.

    Parameters
    ----------
    spec : ring_gyro_sim.analysis.envelope.Spectrogram
        Spectrogram (power in m^2/Hz).
    path : str or path-like
        PNG file.
    ridge_t, ridge_hz : array_like, optional
        Times (s) and frequencies (Hz) of the 1theta ridge, drawn in a zoom panel.
    f_max_hz : float
        Upper frequency shown, Hz.
    title : str
        Plot title.

    """
    plt = _pyplot()
    ncols = 2 if ridge_t is not None else 1
    fig, axes = plt.subplots(1, ncols, figsize=(5.5 * ncols, 4.5), squeeze=False)
    ax = axes[0, 0]
    sel = spec.f <= f_max_hz
    db = 10.0 * np.log10(np.maximum(spec.power[sel], 1e-40))
    vmax = float(np.max(db))
    ax.pcolormesh(spec.t, spec.f[sel] * 1e-3, db, shading='auto', cmap='Greys',
                  vmin=vmax - 80.0, vmax=vmax)
    ax.set_xlabel('time (s)')
    ax.set_ylabel('frequency (kHz)')
    ax.set_title(title, fontsize=9)
    if ridge_t is not None:
        ax2 = axes[0, 1]
        ax2.plot(ridge_t, np.asarray(ridge_hz) * 1e-3, lw=1.0)
        ax2.set_xlabel('time (s)')
        ax2.set_ylabel('1theta frequency (kHz)')
        ax2.set_title('zoom: 1theta line (ridge)', fontsize=9)
        ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
