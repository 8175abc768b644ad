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

matplotlib is optional (the ``plots`` extra). Without it every ``plot_*`` function draws
nothing and returns False (True when it wrote the file), so that the CSVs and summaries of
``ring_gyro backbone``, ``frf`` and ``report`` are still written; :func:`available` tells
beforehand, and :data:`MISSING_MATPLOTLIB` says how to install it (the command line prints it
once, at the start).
"""

import functools
import itertools
import math
from pathlib import Path
from typing import List, Sequence

import numpy as np

MISSING_MATPLOTLIB = ('matplotlib is not installed: the plots will be skipped (the CSV and '
                      'summary files are still written). Install it with '
                      '`pip install matplotlib` (or the plots extra: `pip install '
                      "'ring_gyro_sim[plots]'`; in a ROS workspace: rosdep key "
                      'python3-matplotlib, `apt install python3-matplotlib`).')
"""What to tell a user without matplotlib."""


@functools.lru_cache(maxsize=None)
def available() -> bool:
    """Tell whether matplotlib can be imported (tried once; imports it)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def _pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend (imported on first use), or None."""
    if not available():
        return None
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _save(plt, fig, path) -> None:
    """Lay out, write ``path`` (format from its suffix, 120 dpi) and close ``fig``, always."""
    try:
        fig.tight_layout()
        fig.savefig(path, dpi=120)
    finally:
        plt.close(fig)


def plot_backbone(backbone, path, title=None) -> bool:
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
    if plt is None:
        return False
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
        _save(plt, fig, path)
    finally:
        plt.close(fig)  # also when drawing failed (closing twice is harmless)
    return True


def _runs(mask: np.ndarray):
    """Index ranges ``(start, stop)`` of the runs of equal values in ``mask``."""
    edges = np.flatnonzero(np.diff(mask.astype(np.int8))) + 1
    starts = np.concatenate([[0], edges])
    stops = np.concatenate([edges, [mask.size]])
    return list(zip(starts, stops))


def plot_forced_response(response, path, title=None, marker_hz=None) -> bool:
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
    if plt is None:
        return False
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
        _save(plt, fig, path)
    finally:
        plt.close(fig)  # also when drawing failed (closing twice is harmless)
    return True


def plot_backbones(backbones, path, title='Fig. 4: nonlinear mode q1 for several N_T') -> bool:
    """
    Save several backbones (one per N_T) on one axis (Fig. 4 of the report).

    Parameters
    ----------
    backbones : sequence of ring_gyro_sim.analysis.hbm.Backbone
        The results to draw.
    path : str or path-like
        PNG file.
    title : str
        Plot title.

    """
    plt = _pyplot()
    if plt is None:
        return False
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for b in backbones:
        ax.plot(b.frequency_hz * 1e-3, b.amplitude_m * 1e6, lw=1.0,
                label=f'N_T = {b.taylor_terms}')
    ax.set_xlabel('frequency (kHz)')
    ax.set_ylabel('max |q1| (um)')
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    _save(plt, fig, path)
    return True


# ---------------------------------------------------------------- time-domain cases
# Figs. 5, 7, 10-15 (``analysis/cases.py``, ``report.py``).

def _branch_lines(ax, branches) -> None:
    if branches is None:
        return
    for value, label, style in ((branches.upper_m, 'upper branch', ':'),
                                (branches.lower_m, 'lower branch', '--')):
        if np.isfinite(value):
            ax.axhline(value * 1e6, color='grey', ls=style, lw=0.8, label=label)


def plot_case(result, path, title=None, log=True) -> bool:
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
    if plt is None:
        return False
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
    _save(plt, fig, path)
    return True


def plot_q2_sweep(results, path, title='Case 4: q2 envelope for Q_1 from 5 000 to 180 000'
                  ) -> bool:
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
    if plt is None:
        return False
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
    _save(plt, fig, path)
    return True


def plot_ritz_orders(results, path, channel='w0',
                     title='Fig. 5: radial displacement envelope for N_R = 1..5') -> bool:
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
    if plt is None:
        return False
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for r in results:
        ax.plot(r.envelope.t, r.envelope.channel(channel) * 1e6, lw=0.9,
                label=r.spec.description.split(',')[0])
    ax.set_xlabel('time (s)')
    ax.set_ylabel('radial displacement envelope (um)')
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    _save(plt, fig, path)
    return True


def plot_spectrogram(spec, path, ridge_t=None, ridge_hz=None, f_max_hz=70e3,
                     title='Fig. 7: spectrogram of q1 after a 10 000 g shock') -> bool:
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
    if plt is None:
        return False
    ncols = 2 if ridge_t is not None else 1
    fig, axes = plt.subplots(1, ncols, figsize=(5.5 * ncols, 4.5), squeeze=False)
    ax = axes[0, 0]
    sel = spec.f <= f_max_hz
    db = 10.0 * np.log10(np.maximum(spec.power[sel], 1e-40))
    vmax = float(np.max(db))
    mesh = ax.pcolormesh(spec.t, spec.f[sel] * 1e-3, db, shading='auto', cmap='Greys',
                         vmin=vmax - 80.0, vmax=vmax)
    fig.colorbar(mesh, ax=ax, label='power spectral density (dB re 1 m^2/Hz)')
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
    _save(plt, fig, path)
    return True


# ---------------------------------------------------------------------------- sweep maps
# ``ring_gyro sweep`` (ring_gyro_sim/sweep): the two map axes are the spec's ``plot`` axes;
# every combination of the remaining axes gets its own panel (at most SWEEP_PANELS_PER_FILE
# per file, more go to ``*_part2.png`` ...). Cells are drawn on an index grid, one cell per
# point, labelled with the axis values (linear, log or listed values alike).
# jump_map.png: branch_code (lower / upper / contact / none-or-failed); '?' marks a point whose
# q2 had not settled (the branch is not decided), 'x' a failed point. map_<metric>.png: each
# float metric (m drawn in um); a metric that is nan everywhere is not drawn.
# envelope_<channel>.png (a spec with ``envelopes``): the kept envelope over time, one line per
# point (Fig. 13 for config/sweep_case4.yaml), up to SWEEP_ENVELOPE_LINES points.
# An axis is named for the reader (``Q_1`` for modes.quality_factors[0]: sweep_axis_name), with
# its unit unless it has none; titles wrap to the figure's width; a 1-D metric map has the
# metric's values on its y axis and spans at least MIN_RELATIVE_SPAN of them.
SWEEP_PANELS_PER_FILE = 16
SWEEP_ENVELOPE_LINES = 24
SWEEP_BRANCH_COLOURS = ('#bdbdbd', '#3b6fb6', '#f2b134', '#c0392b')
"""Colours of branch_code -1 (none / failed), 0 (lower), 1 (upper), 2 (contact)."""


SWEEP_NAMES = {'shock.peak_g': 'shock peak', 'shock.phase': 'shock phase',
               'shock.angle_deg': 'shock angle', 'drive.frequency': 'drive frequency',
               'drive.amplitude': 'drive amplitude', 'electrodes.outer_voltage': 'V_o',
               'electrodes.inner_voltage': 'V_i', 'electrodes.gap': 'd_g'}
"""What a sweep axis is called on a plot (the spec's name when it is not here)."""
SWEEP_LIST_NAMES = {'modes.quality_factors': 'Q_{n}', 'modes.frequencies': 'f_{n}',
                    'modes.companion_quality_factors': 'Q_{n}s',
                    'modes.companion_frequencies': 'f_{n}s'}
"""The same for an element ``[i]`` of a list parameter: ``n`` is ``i + 1``, the mode."""
SWEEP_UNITS = {'shock.phase': 'drive periods'}
"""Units to show instead of the table's."""
TITLE_CHARACTERS_PER_INCH = 15
"""Characters of a 9-point title per inch of figure width (titles wrap there)."""


def _sweep_fmt(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f'{value:.6g}'
    return str(value)


def sweep_axis_name(name: str) -> str:
    """Return what a sweep axis is called on a plot: ``Q_1`` for ``modes.quality_factors[0]``."""
    if name in SWEEP_NAMES:
        return SWEEP_NAMES[name]
    base, bracket, index = name.partition('[')
    if bracket and base in SWEEP_LIST_NAMES and index[:-1].isdigit():
        return SWEEP_LIST_NAMES[base].format(n=int(index[:-1]) + 1)
    return name


def sweep_axis_label(name: str, units: str = '') -> str:
    """Return an axis label: the plot name and the unit, none for a dimensionless one."""
    units = SWEEP_UNITS.get(name, units)
    return sweep_axis_name(name) + (f' ({units})' if units not in ('', '-', '1') else '')


def _wrapped(text: str, figure_width_in: float) -> str:
    """Return ``text`` in lines that fit a figure of that width (a title is not cut)."""
    import textwrap
    return textwrap.fill(text, max(20, int(figure_width_in * TITLE_CHARACTERS_PER_INCH)))


def _sweep_panels(ds, plot_axes: Sequence[str]):
    """Yield ``(title, 2-D or 1-D selection dict)`` for each combination of the other axes."""
    others = [d for d in ds[next(iter(ds.data_vars))].dims if d not in plot_axes]
    if not others:
        yield '', {}
        return
    for combo in itertools.product(*(ds[d].values for d in others)):
        sel = dict(zip(others, combo))
        yield ', '.join(f'{sweep_axis_name(k)} = {_sweep_fmt(v)}' for k, v in sel.items()), sel


def _sweep_grid(plt, n: int, width: float = 4.2, height: float = 3.4):
    cols = min(n, 4)
    rows = int(math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols + 0.8, height * rows + 0.6),
                             squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def _sweep_matrix(da, plot_axes: Sequence[str]) -> np.ndarray:
    """Return the values as (rows = y axis, cols = x axis); one row for a 1-D map."""
    if len(plot_axes) == 1:
        return np.asarray(da.values).reshape(1, -1)
    return np.asarray(da.transpose(plot_axes[1], plot_axes[0]).values)


def _sweep_label_axes(ax, ds, plot_axes: Sequence[str], values_on_y: bool = False) -> None:
    """Label the cells with the axis values; ``values_on_y``: a 1-D map whose y is a metric."""
    x = ds[plot_axes[0]]
    ax.set_xticks(range(x.size))
    ax.set_xticklabels([_sweep_fmt(v) for v in x.values], rotation=60, fontsize=7)
    ax.set_xlabel(sweep_axis_label(plot_axes[0], x.attrs.get('units', '')), fontsize=8)
    if len(plot_axes) > 1:
        y = ds[plot_axes[1]]
        ax.set_yticks(range(y.size))
        ax.set_yticklabels([_sweep_fmt(v) for v in y.values], fontsize=7)
        ax.set_ylabel(sweep_axis_label(plot_axes[1], y.attrs.get('units', '')), fontsize=8)
    elif values_on_y:
        ax.ticklabel_format(axis='y', useOffset=False)  # the values, not offsets from one
        ax.tick_params(axis='y', labelsize=7)
    else:
        ax.set_yticks([])


def _sweep_files(stem: Path, panels: List) -> List:
    n = SWEEP_PANELS_PER_FILE
    chunks = [panels[i:i + n] for i in range(0, len(panels), n)]
    out = []
    for i, chunk in enumerate(chunks):
        name = stem.name + ('.png' if i == 0 else f'_part{i + 1}.png')
        out.append((stem.with_name(name), chunk))
    return out


def plot_sweep_jump_map(ds, plot_axes: Sequence[str], path) -> List[str]:
    """Draw ``branch_code`` over the plot axes, a panel per other combination; the files."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch
    plt = _pyplot()
    cmap = ListedColormap(SWEEP_BRANCH_COLOURS)
    norm = BoundaryNorm([-1.5, -0.5, 0.5, 1.5, 2.5], cmap.N)
    written = []
    panel_list = list(_sweep_panels(ds, plot_axes))
    for target, panels in _sweep_files(Path(path).with_suffix(''), panel_list):
        fig, axes = _sweep_grid(plt, len(panels))
        for ax, (title, sel) in zip(axes, panels):
            sub = ds.sel(sel) if sel else ds
            codes = _sweep_matrix(sub['branch_code'], plot_axes)
            ax.imshow(codes, cmap=cmap, norm=norm, origin='lower', aspect='auto',
                      interpolation='nearest')
            settled = _sweep_matrix(sub['settled'], plot_axes) if 'settled' in sub else None
            errors = _sweep_matrix(sub['error'], plot_axes)
            for (r, c), code in np.ndenumerate(codes):
                mark = ''
                if errors[r, c]:
                    mark = 'x'
                elif settled is not None and settled[r, c] == 0 and code != 2:
                    mark = '?'
                if mark:
                    ax.text(c, r, mark, ha='center', va='center', fontsize=8)
            _sweep_label_axes(ax, sub, plot_axes)
            ax.set_title(title or 'final branch of q2', fontsize=8)
        handles = [Patch(color=SWEEP_BRANCH_COLOURS[i + 1], label=n)
                   for i, n in enumerate(('lower', 'upper', 'contact'))]
        handles.append(Patch(color=SWEEP_BRANCH_COLOURS[0], label='none / failed (x)'))
        axes[-1].legend(handles=handles, loc='upper left', bbox_to_anchor=(1.02, 1.0),
                        fontsize=7, frameon=False)
        fig.suptitle(_wrapped('Jump map: final branch of the 2theta drive (? = not settled)',
                              fig.get_figwidth()), fontsize=9, x=0.02, ha='left')
        _save(plt, fig, target)
        written.append(str(target))
    return written


MIN_RELATIVE_SPAN = 0.01
"""A 1-D metric map spans at least this fraction of its largest value: 1.2037 and
1.2066 um (0.24 %) are drawn as the near-equal values they are, not as a jump across the
panel."""


def _minimum_span(ax, values) -> None:
    """Widen the y range of a 1-D map to :data:`MIN_RELATIVE_SPAN` of its values' size."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return
    low, high = float(finite.min()), float(finite.max())
    span = MIN_RELATIVE_SPAN * max(abs(low), abs(high))
    if 0.0 < high - low < span:
        middle = 0.5 * (low + high)
        ax.set_ylim(middle - 0.6 * span, middle + 0.6 * span)


def plot_sweep_metric_maps(ds, plot_axes: Sequence[str], metrics: Sequence[str],
                           out_dir) -> List[str]:
    """Draw each float metric of ``metrics`` (um for ``*_m``); the files written."""
    plt = _pyplot()
    written = []
    for name in metrics:
        if name not in ds or ds[name].dtype.kind != 'f':
            continue
        values = ds[name].values
        if not np.any(np.isfinite(values)):
            continue
        scale, unit = (1e6, 'um') if name.endswith('_m') else (1.0, ds[name].attrs.get(
            'units', ''))
        finite = values[np.isfinite(values)] * scale
        vmin, vmax = float(finite.min()), float(finite.max())
        stem = Path(out_dir) / f'map_{name}'
        for target, panels in _sweep_files(stem, list(_sweep_panels(ds, plot_axes))):
            fig, axes = _sweep_grid(plt, len(panels))
            for ax, (title, sel) in zip(axes, panels):
                sub = ds.sel(sel) if sel else ds
                m = _sweep_matrix(sub[name], plot_axes) * scale
                if len(plot_axes) == 1:
                    x = np.arange(m.shape[1])
                    ax.plot(x, m[0], 'o-', ms=4)
                    ax.set_ylabel(f'{name} ({unit})', fontsize=8)
                    ax.grid(True, alpha=0.3)
                    _sweep_label_axes(ax, sub, plot_axes, values_on_y=True)
                    _minimum_span(ax, m[0])
                else:
                    im = ax.imshow(m, origin='lower', aspect='auto', interpolation='nearest',
                                   vmin=vmin, vmax=vmax, cmap='viridis')
                    fig.colorbar(im, ax=ax, label=f'{unit}')
                    _sweep_label_axes(ax, sub, plot_axes)
                ax.set_title(title or name, fontsize=8)
            fig.suptitle(_wrapped(f'{name}: {ds[name].attrs.get("long_name", "")}',
                                  fig.get_figwidth()), fontsize=9, x=0.02, ha='left')
            _save(plt, fig, target)
            written.append(str(target))
    return written


def plot_sweep_envelopes(ds, out_dir) -> List[str]:
    """Draw each kept ``envelope_<channel>_m`` over time, a line per point; the files."""
    plt = _pyplot()
    written = []
    names = [n for n in ds.data_vars if n.startswith('envelope_') and 'time' in ds[n].dims]
    for name in names:
        da = ds[name]
        axes = [d for d in da.dims if d != 'time']
        combos = list(itertools.product(*(ds[d].values for d in axes)))
        if not combos or len(combos) > SWEEP_ENVELOPE_LINES:
            continue
        channel = name[len('envelope_'):-len('_m')]
        fig, ax = plt.subplots(figsize=(8, 4.5))
        t = ds['time'].values
        for combo in combos:
            y = da.sel(dict(zip(axes, combo))).values * 1e6
            label = ', '.join(f'{sweep_axis_name(k)} = {_sweep_fmt(v)}'
                              for k, v in zip(axes, combo))
            ax.plot(t, np.where(y > 0.0, y, np.nan), lw=0.9, label=label)
        ax.set_yscale('log')
        ax.set_xlabel('time (s)')
        ax.set_ylabel(f'{channel} positive envelope (um)')
        ax.set_title(f'{channel} envelope per point', fontsize=10)
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=7, loc='best')
        target = Path(out_dir) / f'envelope_{channel}.png'
        _save(plt, fig, target)
        written.append(str(target))
    return written


def plot_sweep(ds, plot_axes: Sequence[str], metrics: Sequence[str], out_dir) -> List[str]:
    """
    Write the jump map (when ``final_branch`` was kept) and the metric maps of a sweep.

    Parameters
    ----------
    ds : xarray.Dataset
        Results of :mod:`ring_gyro_sim.sweep.results` (dims = sweep axes).
    plot_axes : sequence of str
        x (and y) axis of the maps; a panel per combination of the other axes.
    metrics : sequence of str
        Metrics to draw (float variables only; nan everywhere: skipped).
    out_dir : str or path-like
        Directory of ``jump_map.png``, ``map_<metric>.png`` and ``envelope_<channel>.png``
        (kept envelopes, :func:`plot_sweep_envelopes`).

    Returns
    -------
    list of str
        The files written (none without matplotlib).

    """
    written = []
    if not available():
        return written
    if 'branch_code' in ds:
        written += plot_sweep_jump_map(ds, plot_axes, Path(out_dir) / 'jump_map.png')
    written += plot_sweep_metric_maps(ds, plot_axes, metrics, out_dir)
    written += plot_sweep_envelopes(ds, out_dir)
    return written


def plot_population(ds, sheet, path) -> List[str]:
    """
    Draw the histogram of each datasheet figure of a device population; the files written.

    Parameters
    ----------
    ds : xarray.Dataset
        Results of a ``kind: gyroscope`` sweep (``sweep.results``).
    sheet : mapping
        Its datasheet (``sweep.results.population_datasheet``): the figures drawn, their
        display units and statistics.
    path : str or Path
        PNG file to write.

    """
    plt = _pyplot()
    figures = sheet['figures']
    if plt is None or not figures:
        return []
    from matplotlib.ticker import MaxNLocator
    columns = 3
    rows = int(math.ceil(len(figures) / columns))
    fig, axes = plt.subplots(rows, columns, figsize=(4.0 * columns, 3.2 * rows + 0.6),
                             squeeze=False)
    for ax, (name, f) in zip(axes.ravel(), figures.items()):
        scale = f['display_scale']
        v = ds[name].values.ravel().astype(float)
        v = v[np.isfinite(v)] * scale
        ax.hist(v, bins=max(5, int(math.ceil(math.sqrt(v.size)))), color='tab:blue',
                alpha=0.75, edgecolor='white')
        ax.axvline(f['median'] * scale, color='k', lw=1.2, label='median')
        for key, label in (('mean_minus_3_sigma', 'mean -+ 3 sigma'),
                           ('mean_plus_3_sigma', None)):
            ax.axvline(f[key] * scale, color='tab:red', lw=1.0, ls='--', label=label)
        for key, label in (('min', 'min / max'), ('max', None)):
            ax.axvline(f[key] * scale, color='tab:grey', lw=0.9, ls=':', label=label)
        ax.set_xlabel(f'{f["label"]} ({f["display_units"]})', fontsize=8)
        ax.set_ylabel('devices', fontsize=8)
        ax.set_title(_wrapped(f'{name}: {f["long_name"]}', 3.6), fontsize=7)
        ax.ticklabel_format(axis='x', style='sci', scilimits=(-2, 4), useOffset=False)
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
    for ax in axes.ravel()[len(figures):]:
        ax.set_visible(False)
    axes.ravel()[0].legend(fontsize=6, loc='upper left', frameon=False)
    axes_text = ', '.join(f'{sweep_axis_name(k)} {v[0]}-{v[1]}' for k, v in sheet['axes'].items())
    fig.suptitle(_wrapped(f'Device population: {sheet["devices"] - sheet["failed"]} devices '
                          f'({axes_text}); datasheet figures from the factory rate tables',
                          fig.get_figwidth()), fontsize=9, x=0.02, ha='left')
    _save(plt, fig, path)
    return [str(path)]


def plot_rate(traces, path, title='Rate output', shock_s=None, drive=None,
              band=0.01, recovery_s=None) -> bool:
    """
    Save the rate output against the applied rate, its error and the drive (against time).

    Parameters
    ----------
    traces : sequence of (label, t, rate, applied)
        One or more rate records: times (s), the rate output and the applied rate (rad/s),
        e.g. open and closed loop.
    path : str or Path
        PNG file to write.
    title : str
        Title of the figure.
    shock_s : float, optional
        Start of the shock, s (marked).
    drive : sequence of (label, t, ratio), optional
        The drive pick-off over its value at the operating point (a third panel).
    band : float
        Relative band drawn on the error panel (the recovery band, 1 %).
    recovery_s : float, optional
        After the shock, when the rate was back within its band for good, s from the shock's
        start (``core.gyro.stats``: ``rate_recovery_s``); marked. With ``shock_s`` and no
        recovery, the error panel says it was not back by the end.

    """
    plt = _pyplot()
    if plt is None:
        return False
    rows = 3 if drive else 2
    fig, axes = plt.subplots(rows, 1, figsize=(8.0, 2.6 * rows + 0.6), sharex=True)
    top, middle = axes[0], axes[1]
    for label, t, rate, applied in traces:
        prefix = f'{label}: ' if label else ''
        top.plot(t, np.degrees(rate), lw=0.7, label=f'{prefix}~/rate')
        top.plot(t, np.degrees(applied), lw=0.9, ls='--', label=f'{prefix}applied')
        err = np.abs(np.asarray(rate) - np.asarray(applied))
        middle.semilogy(t, np.degrees(np.maximum(err, 1e-12)), lw=0.7, label=label or None)
        middle.semilogy(t, np.degrees(band * np.abs(applied)), lw=0.8, ls=':', color='k')
    if drive:
        for label, t, ratio in drive:
            axes[2].semilogy(t, np.maximum(ratio, 1e-6), lw=0.8, label=label or None)
        axes[2].set_ylabel('drive pick-off / nominal')
    for ax in axes:
        if shock_s is not None:
            ax.axvline(shock_s, color='k', lw=0.6, ls=':',
                       label='shock' if ax is middle else None)
        if shock_s is not None and recovery_s is not None:
            ax.axvline(shock_s + recovery_s, color='tab:green', lw=1.0, ls='--',
                       label=(f'back within the band {recovery_s:.4g} s after the shock'
                              if ax is middle else None))
        ax.grid(True, lw=0.3)
    if shock_s is not None and recovery_s is None:
        middle.text(0.99, 0.95, 'not back within the band by the end', color='tab:red',
                    ha='right', va='top', fontsize=8, transform=middle.transAxes)
    top.set_ylabel('rate (deg/s)')
    middle.set_ylabel(f'|error| (deg/s); {100 * band:g} % band')
    axes[-1].set_xlabel('t (s)')
    if shock_s is not None:
        middle.legend(fontsize=7, loc='lower right')
    top.legend(fontsize=7)
    top.set_title(title)
    _save(plt, fig, path)
    return True


def plot_allan(tau_s, adev, err, path, model=None, arw_deg_per_h=None,
               predicted_arw_deg_per_h=None, fit_tau_s=None, floor=None,
               slope_only=None, long_record=None) -> bool:
    """
    Save an Allan-deviation plot with the ARW line and the bias-instability floor marked.

    Parameters
    ----------
    tau_s, adev, err : sequence of float
        Averaging times (s), Allan deviation and its standard error (deg/h).
    path : str or Path
        PNG file to write.
    model : sequence of float, optional
        The fitted noise model's deviation at ``tau_s``, deg/h.
    arw_deg_per_h, predicted_arw_deg_per_h : float, optional
        Level of the -1/2 line at tau = 1 s, deg/h (measured, predicted): ``N / sqrt(tau)``.
    fit_tau_s : (float, float), optional
        The tau range of the fit (shaded).
    floor : (float, float), optional
        ``(tau_s, deg/h)`` of the curve's minimum (the bias-instability read).
    slope_only : ((float, float), float), optional
        The plain -1/2 fit: its tau range (s) and level at 1 s (deg/h).
    long_record : (tau_s, adev, err, label, floor), optional
        A second, longer record's curve (deg/h) with its label, and its minimum
        ``(tau_s, deg/h)`` or None; the tau axis and the -1/2 lines extend to it.

    """
    plt = _pyplot()
    if plt is None:
        return False
    tau = np.asarray(tau_s, dtype=float)
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    try:
        ax.errorbar(tau, adev, yerr=err, fmt='o', ms=3, lw=0.8, label='measured (oadev)')
        line_tau = np.array([tau[0], tau[-1]])
        if long_record is not None:
            l_tau, l_adev, l_err, l_label, l_floor = long_record
            l_tau = np.asarray(l_tau, dtype=float)
            ax.errorbar(l_tau, l_adev, yerr=l_err, fmt='s', ms=2.5, lw=0.8, alpha=0.8,
                        color='tab:purple', label=l_label)
            if l_floor is not None:
                ax.plot([l_floor[0]], [l_floor[1]], 's', color='tab:purple', ms=8, mfc='none',
                        label=f'its minimum {l_floor[1]:.3g} deg/h at {l_floor[0]:.3g} s: '
                              f'BI = {l_floor[1] / 0.6643:.3g} deg/h')
            line_tau = np.array([min(tau[0], l_tau[0]), max(tau[-1], l_tau[-1])])
        if fit_tau_s is not None:
            ax.axvspan(fit_tau_s[0], fit_tau_s[1], color='0.9', zorder=0, label='fit range')
        if model is not None:
            ax.loglog(tau, model, '-', lw=1.0, label='fitted noise model')
        if arw_deg_per_h is not None:
            ax.loglog(line_tau, arw_deg_per_h / np.sqrt(line_tau), '--', lw=1.0,
                      label=f'-1/2 slope: ARW = {arw_deg_per_h / 60.0:.4g} deg/sqrt(h)')
            ax.plot([1.0], [arw_deg_per_h], 'k*', ms=9)
        if predicted_arw_deg_per_h is not None:
            ax.loglog(line_tau, predicted_arw_deg_per_h / np.sqrt(line_tau), ':', lw=1.0,
                      color='k', label=f'model ARW {predicted_arw_deg_per_h / 60.0:.4g} '
                                       f'deg/sqrt(h)')
        if slope_only is not None:
            (lo, hi), level = slope_only
            seg = np.array([lo, hi])
            ax.loglog(seg, level / np.sqrt(seg), '-', lw=3, alpha=0.6,
                      label=f'plain -1/2 fit ({lo:.3g}-{hi:.3g} s): '
                            f'{level / 60.0:.4g} deg/sqrt(h)')
        if floor is not None:
            ax.axhline(floor[1], color='tab:red', lw=0.8, ls='-.',
                       label=f'minimum {floor[1]:.3g} deg/h at {floor[0]:.3g} s: '
                             f'BI = {floor[1] / 0.6643:.3g} deg/h')
            ax.plot([floor[0]], [floor[1]], 'o', color='tab:red', ms=7, mfc='none')
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_xlabel('tau (s)')
        ax.set_ylabel('Allan deviation (deg/h)')
        ax.set_title('Allan deviation of the zero-rate output')
        ax.grid(True, which='both', lw=0.3)
        ax.legend(fontsize=7)
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True


def plot_scale_factor(rate_dps, residual_ppm, error_ppm, predicted_ppm, path,
                      nonlinearity_ppm=None) -> bool:
    """
    Save the scale-factor error against the rate (residuals from the least-squares line).

    Parameters
    ----------
    rate_dps : sequence of float
        Rates of the table, deg/s.
    residual_ppm, error_ppm, predicted_ppm : sequence of float
        Measured residuals, their standard errors and the model's residuals, ppm of the
        full-scale output.
    path : str or Path
        PNG file to write.
    nonlinearity_ppm : float, optional
        The nonlinearity figure (in the title).

    """
    plt = _pyplot()
    if plt is None:
        return False
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    try:
        ax.errorbar(rate_dps, residual_ppm, yerr=2.0 * np.asarray(error_ppm), fmt='o-', ms=4,
                    lw=0.8, capsize=3, label='measured (+- 2 standard errors)')
        ax.plot(rate_dps, predicted_ppm, 's--', ms=3, lw=0.8, label='model')
        ax.axhline(0.0, color='k', lw=0.5)
        ax.set_xlabel('rate (deg/s)')
        ax.set_ylabel('residual from the line (ppm of full scale)')
        title = 'Scale-factor error'
        if nonlinearity_ppm is not None:
            title += f': nonlinearity {nonlinearity_ppm:.3g} ppm FS'
        ax.set_title(title)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8)
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True


def plot_rectification(amplitudes_g, bias_deg_per_h, path, slope=None, coefficient=None,
                       title='Vibration rectification') -> bool:
    """
    Save the rectified bias against the vibration amplitude, log-log, with its power law.

    Parameters
    ----------
    amplitudes_g : sequence of float
        Peak amplitudes, g.
    bias_deg_per_h : sequence of float
        Rectified bias at each, deg/h (its magnitude is drawn; the sign is in the legend).
    path : str or Path
        PNG file to write.
    slope, coefficient : float, optional
        The fitted ``|bias| = coefficient A^slope`` (deg/h, A in g), drawn dashed.
    title : str
        The plot's title (the frequency and direction).

    """
    plt = _pyplot()
    if plt is None:
        return False
    a = np.asarray(amplitudes_g, dtype=float)
    y = np.asarray(bias_deg_per_h, dtype=float)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    try:
        sign = 'negative' if np.all(y < 0) else 'positive' if np.all(y > 0) else 'mixed'
        shown = np.where(np.abs(y) > 0.0, np.abs(y), np.nan)
        ax.loglog(a, shown, 'o', label=f'|rectified bias| (measured, {sign})')
        if slope is not None and coefficient is not None:
            fine = np.geomspace(a.min(), a.max(), 50)
            ax.loglog(fine, abs(coefficient) * fine ** slope, '--', lw=1.0,
                      label=f'fit: {abs(coefficient):.4g} deg/h x (A / 1 g)^{slope:.4f}')
        ax.set_xlabel('vibration amplitude A (g, peak)')
        ax.set_ylabel('|rectified bias| (deg/h)')
        ax.set_title(title)
        ax.grid(True, which='both', lw=0.3)
        ax.legend(fontsize=8)
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True


def plot_step(t_s, response, gain, time_constant_s, path,
              predicted_time_constant_s=None) -> bool:
    """
    Save a rate-step response (over the step) with its first-order fit.

    Parameters
    ----------
    t_s : sequence of float
        Time since the step, s.
    response : sequence of float
        Output over the step size (0 before, ~1 after).
    gain, time_constant_s : float
        The fit ``gain (1 - exp(-t / tau))``.
    path : str or Path
        PNG file to write.
    predicted_time_constant_s : float, optional
        The model's time constant (drawn dotted).

    """
    plt = _pyplot()
    if plt is None:
        return False
    t = np.asarray(t_s, dtype=float)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    try:
        ax.plot(t, response, lw=0.6, label='~/rate / step')
        after = np.maximum(t, 0.0)
        ax.plot(t, gain * (1.0 - np.exp(-after / time_constant_s)), '--', lw=1.0,
                label=f'first-order fit: tau = {time_constant_s:.4g} s, '
                      f'f_3dB = {1.0 / (2.0 * math.pi * time_constant_s):.4g} Hz')
        if predicted_time_constant_s is not None:
            ax.plot(t, 1.0 - np.exp(-after / predicted_time_constant_s), ':', color='k',
                    lw=1.0, label=f'model: tau = {predicted_time_constant_s:.4g} s')
        ax.axhline(gain * (1.0 - math.exp(-1.0)), color='0.5', lw=0.5)
        ax.axvline(time_constant_s, color='0.5', lw=0.5)
        ax.set_xlabel('time since the step (s)')
        ax.set_ylabel('output / step')
        ax.set_title('Rate step response (bandwidth)')
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8)
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True


def plot_shock_recovery(panels, path, band=0.01) -> bool:
    """
    Save the rate error after a shock, one panel per loop mode side by side.

    Parameters
    ----------
    panels : sequence of (title, curves, available)
        Per loop mode: its title, ``[(label, t_since_shock_s, error_deg_s, applied_deg_s)]``
        (one per shock amplitude; none: the panel says it was not measured) and whether the
        build has that mode.
    path : str or Path
        PNG file to write.
    band : float
        Relative band drawn (the recovery band, 1 % of the rate).

    """
    plt = _pyplot()
    if plt is None:
        return False
    fig, axes = plt.subplots(1, len(panels), figsize=(5.0 * len(panels), 4.4), sharey=True,
                             squeeze=False)
    try:
        for ax, (title, curves, available) in zip(axes[0], panels):
            for label, t, err, applied in curves:
                ax.semilogy(t, np.maximum(np.abs(err), 1e-9), lw=0.6, label=label)
            if curves:
                applied = np.abs(curves[0][3])
                ax.semilogy(curves[0][1], band * applied, 'k:', lw=0.8,
                            label=f'{100 * band:g} % of the rate')
                ax.legend(fontsize=7)
            else:
                ax.text(0.5, 0.5, 'not measured' + (
                    '' if available else '\n(not available in this build)'),
                    ha='center', va='center', transform=ax.transAxes)
            ax.axvline(0.0, color='k', lw=0.5)
            ax.set_title(title)
            ax.set_xlabel('time since the shock (s)')
            ax.grid(True, which='both', lw=0.3)
        axes[0][0].set_ylabel('|rate error| (deg/s)')
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True


def plot_temperature_series(temperature_c, bias_deg_h, bias_compensated_deg_h, scale_ppm,
                            scale_compensated_ppm, fit_points_c, path) -> bool:
    """
    Save the bias and scale-factor error over a temperature series, with and without K3.

    Parameters
    ----------
    temperature_c : sequence of float
        The die temperatures of the series, degrees Celsius.
    bias_deg_h, bias_compensated_deg_h : sequence of float
        Zero-rate output with the calibration held, without and with the compensation, deg/h.
    scale_ppm, scale_compensated_ppm : sequence of float
        Scale-factor error against the calibration's, without and with it, ppm.
    fit_points_c : sequence of float
        Where the compensation was fitted (with the reference), degrees Celsius.
    path : str or Path
        PNG file to write.

    """
    plt = _pyplot()
    if plt is None:
        return False
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True)
    try:
        for ax, raw, comp, unit in ((top, bias_deg_h, bias_compensated_deg_h, 'deg/h'),
                                    (bottom, scale_ppm, scale_compensated_ppm, 'ppm')):
            ax.plot(temperature_c, raw, 'o-', ms=4, lw=0.8, label='calibration held')
            ax.plot(temperature_c, comp, 's--', ms=4, lw=0.8, label='with the compensation')
            for t in fit_points_c:
                ax.axvline(t, color='0.6', lw=0.6, ls=':')
            ax.axhline(0.0, color='k', lw=0.5)
            ax.grid(True, lw=0.3)
            ax.set_ylabel(f'{"bias" if ax is top else "scale-factor error"} ({unit})')
        top.legend(fontsize=8)
        bottom.set_xlabel('die temperature (deg C); dotted: where the compensation was fitted')
        top.set_title('Temperature series (IEEE Std 1431): bias and scale factor')
        _save(plt, fig, path)
    finally:
        plt.close(fig)
    return True
