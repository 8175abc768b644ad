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
PNG maps of a sweep's Dataset: the jump map and one map per numeric metric.

The two map axes are the spec's ``plot`` axes (default: the first two axes); every
combination of the remaining axes gets its own panel (at most :data:`PANELS_PER_FILE` per
file; more go to ``*_part2.png`` ...). Cells are drawn on an index grid, one cell per point,
labelled with the axis values (linear, log or listed values alike).

* ``jump_map.png``: ``branch_code`` (lower / upper / contact / none-or-failed); ``?`` marks a
  point whose q2 had not settled at the end (``settled`` 0: the branch is not decided) and
  ``x`` a failed point.
* ``map_<metric>.png`` for each float metric kept (m shown in um); a metric that is nan
  everywhere (e.g. ``contact_time_s`` without contact) is not drawn.

matplotlib comes from :func:`ring_gyro_sim.analysis.plotting._pyplot` (Agg, imported on
first use), the package's one entry to it.
"""

import itertools
import math
from pathlib import Path
from typing import List, Sequence

import numpy as np

__all__ = ['PANELS_PER_FILE', 'plot_jump_map', 'plot_metric_maps', 'plot_all']

PANELS_PER_FILE = 16
BRANCH_COLOURS = ('#bdbdbd', '#3b6fb6', '#f2b134', '#c0392b')
"""Colours of branch_code -1 (none / failed), 0 (lower), 1 (upper), 2 (contact)."""


def _fmt(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f'{value:.4g}'
    return str(value)


def _panels(ds, plot_axes: Sequence[str]):
    """Yield ``(title, 2-D or 1-D selection dict)`` for each combination of the other axes."""
    others = [d for d in ds[next(iter(ds.data_vars))].dims if d not in plot_axes]
    if not others:
        yield '', {}
        return
    for combo in itertools.product(*(ds[d].values for d in others)):
        sel = dict(zip(others, combo))
        yield ', '.join(f'{k} = {_fmt(v)}' for k, v in sel.items()), sel


def _grid(plt, n: int, width: float = 4.2, height: float = 3.4):
    cols = min(n, 4)
    rows = int(math.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols + 0.8, height * rows + 0.6),
                             squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def _matrix(da, plot_axes: Sequence[str]) -> np.ndarray:
    """Return the values as (rows = y axis, cols = x axis); one row for a 1-D map."""
    if len(plot_axes) == 1:
        return np.asarray(da.values).reshape(1, -1)
    return np.asarray(da.transpose(plot_axes[1], plot_axes[0]).values)


def _label_axes(ax, ds, plot_axes: Sequence[str]) -> None:
    x = ds[plot_axes[0]]
    ax.set_xticks(range(x.size))
    ax.set_xticklabels([_fmt(v) for v in x.values], rotation=60, fontsize=7)
    ax.set_xlabel(f'{plot_axes[0]} ({x.attrs.get("units", "")})', fontsize=8)
    if len(plot_axes) > 1:
        y = ds[plot_axes[1]]
        ax.set_yticks(range(y.size))
        ax.set_yticklabels([_fmt(v) for v in y.values], fontsize=7)
        ax.set_ylabel(f'{plot_axes[1]} ({y.attrs.get("units", "")})', fontsize=8)
    else:
        ax.set_yticks([])


def _files(stem: Path, panels: List) -> List:
    chunks = [panels[i:i + PANELS_PER_FILE] for i in range(0, len(panels), PANELS_PER_FILE)]
    out = []
    for i, chunk in enumerate(chunks):
        name = stem.name + ('.png' if i == 0 else f'_part{i + 1}.png')
        out.append((stem.with_name(name), chunk))
    return out


def plot_jump_map(ds, plot_axes: Sequence[str], path) -> List[str]:
    """Draw ``branch_code`` over the plot axes, a panel per other combination; the files."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch
    from ring_gyro_sim.analysis.plotting import _pyplot, _save
    plt = _pyplot()
    cmap = ListedColormap(BRANCH_COLOURS)
    norm = BoundaryNorm([-1.5, -0.5, 0.5, 1.5, 2.5], cmap.N)
    written = []
    for target, panels in _files(Path(path).with_suffix(''), list(_panels(ds, plot_axes))):
        fig, axes = _grid(plt, len(panels))
        for ax, (title, sel) in zip(axes, panels):
            sub = ds.sel(sel) if sel else ds
            codes = _matrix(sub['branch_code'], plot_axes)
            ax.imshow(codes, cmap=cmap, norm=norm, origin='lower', aspect='auto',
                      interpolation='nearest')
            settled = _matrix(sub['settled'], plot_axes) if 'settled' in sub else None
            errors = _matrix(sub['error'], plot_axes)
            for (r, c), code in np.ndenumerate(codes):
                mark = ''
                if errors[r, c]:
                    mark = 'x'
                elif settled is not None and settled[r, c] == 0 and code != 2:
                    mark = '?'
                if mark:
                    ax.text(c, r, mark, ha='center', va='center', fontsize=8)
            _label_axes(ax, sub, plot_axes)
            ax.set_title(title or 'final branch of q2', fontsize=8)
        handles = [Patch(color=BRANCH_COLOURS[i + 1], label=n)
                   for i, n in enumerate(('lower', 'upper', 'contact'))]
        handles.append(Patch(color=BRANCH_COLOURS[0], label='none / failed (x)'))
        fig.legend(handles=handles, loc='upper right', fontsize=7, ncol=4)
        fig.suptitle('Jump map: final branch of the 2theta drive (? = not settled)',
                     fontsize=9, x=0.02, ha='left')
        _save(plt, fig, target)
        written.append(str(target))
    return written


def plot_metric_maps(ds, plot_axes: Sequence[str], metrics: Sequence[str], out_dir
                     ) -> List[str]:
    """Draw each float metric of ``metrics`` (um for ``*_m``); the files written."""
    from ring_gyro_sim.analysis.plotting import _pyplot, _save
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
        for target, panels in _files(stem, list(_panels(ds, plot_axes))):
            fig, axes = _grid(plt, len(panels))
            for ax, (title, sel) in zip(axes, panels):
                sub = ds.sel(sel) if sel else ds
                m = _matrix(sub[name], plot_axes) * scale
                if len(plot_axes) == 1:
                    x = np.arange(m.shape[1])
                    ax.plot(x, m[0], 'o-', ms=4)
                    ax.set_ylabel(f'{name} ({unit})', fontsize=8)
                    ax.grid(True, alpha=0.3)
                    _label_axes(ax, sub, plot_axes)
                else:
                    im = ax.imshow(m, origin='lower', aspect='auto', interpolation='nearest',
                                   vmin=vmin, vmax=vmax, cmap='viridis')
                    fig.colorbar(im, ax=ax, label=f'{unit}')
                    _label_axes(ax, sub, plot_axes)
                ax.set_title(title or name, fontsize=8)
            fig.suptitle(f'{name}: {ds[name].attrs.get("long_name", "")}', fontsize=9,
                         x=0.02, ha='left')
            _save(plt, fig, target)
            written.append(str(target))
    return written


def plot_all(ds, plot_axes: Sequence[str], metrics: Sequence[str], out_dir) -> List[str]:
    """Write the jump map (when ``final_branch`` was kept) and the metric maps."""
    written = []
    if 'branch_code' in ds:
        written += plot_jump_map(ds, plot_axes, Path(out_dir) / 'jump_map.png')
    written += plot_metric_maps(ds, plot_axes, metrics, out_dir)
    return written
