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
Tests of analysis/plotting.py: what the figures say.

Each figure is taken as matplotlib drew it, just before it is written and closed (``_save``
is wrapped), so that its titles, labels, ticks and colour bars can be read back.
"""

import numpy as np
import pytest
from ring_gyro_sim.analysis import plotting

pytest.importorskip('matplotlib')  # an extra (setup.py 'plots')


@pytest.fixture
def drawn(monkeypatch):
    """Return the list of figures drawn, each as it was when it was saved."""
    figures = []
    save = plotting._save

    def keep(plt, fig, path):
        fig.canvas.draw()
        figures.append({'suptitle': fig._suptitle.get_text() if fig._suptitle else '',
                        'width_in': fig.get_figwidth(),
                        'axes': [{'xlabel': ax.get_xlabel(), 'ylabel': ax.get_ylabel(),
                                  'title': ax.get_title(), 'ylim': ax.get_ylim(),
                                  'yticks': [t.get_text() for t in ax.get_yticklabels()],
                                  'lines': [line.get_label() for line in ax.get_lines()],
                                  'texts': [text.get_text() for text in ax.texts]}
                                 for ax in fig.axes]})
        save(plt, fig, path)
    monkeypatch.setattr(plotting, '_save', keep)
    return figures


def one_axis_sweep():
    xr = pytest.importorskip('xarray')
    q1 = xr.Variable('modes.quality_factors[0]', np.array([5000.0, 40000.0, 180000.0]),
                     attrs={'units': '-', 'spacing': 'log'})
    long = 'time q2 is back above the branch threshold for good (nan: never left it, or ends ' \
        'lower)'
    return xr.Dataset(
        {'final_q2_m': (['modes.quality_factors[0]'], np.array([1.2037e-6, 1.2066e-6, 1.205e-6]),
                        {'units': 'm', 'long_name': 'mean q2 envelope over the last 0.2 s'}),
         'return_time_s': (['modes.quality_factors[0]'], np.array([np.nan, 4.2, 7.3]),
                           {'units': 's', 'long_name': long})},
        coords={'modes.quality_factors[0]': q1})


def test_a_one_axis_sweep_map_has_its_values_on_y_and_its_whole_title(tmp_path, drawn):
    ds = one_axis_sweep()
    written = plotting.plot_sweep_metric_maps(ds, ['modes.quality_factors[0]'],
                                              ['final_q2_m', 'return_time_s'], tmp_path)
    assert len(written) == 2 and len(drawn) == 2
    q2, back = drawn
    axis = q2['axes'][0]
    assert axis['xlabel'] == 'Q_1'  # not 'modes.quality_factors[0] (-)'
    numbers = [t for t in axis['yticks'] if t]
    assert len(numbers) >= 3 and all(float(t.replace('\u2212', '-')) for t in numbers), numbers
    low, high = axis['ylim']
    assert high - low >= 0.01 * 1.2066  # 0.24 % apart: not drawn as a jump across the panel
    title = back['suptitle']
    assert title.replace('\n', ' ') == 'return_time_s: ' + ds['return_time_s'].attrs['long_name']
    width = int(back['width_in'] * plotting.TITLE_CHARACTERS_PER_INCH)
    assert max(len(line) for line in title.splitlines()) <= width


def test_sweep_axis_names_are_the_readers():
    assert plotting.sweep_axis_name('modes.quality_factors[0]') == 'Q_1'
    assert plotting.sweep_axis_name('modes.frequencies[2]') == 'f_3'
    assert plotting.sweep_axis_label('modes.quality_factors[1]', '-') == 'Q_2'
    assert plotting.sweep_axis_label('shock.peak_g', 'g') == 'shock peak (g)'
    assert plotting.sweep_axis_label('shock.phase', '1') == 'shock phase (drive periods)'
    assert plotting.sweep_axis_label('ring.radius', 'm') == 'ring.radius (m)'


def test_the_spectrogram_has_a_colour_bar(tmp_path, drawn):
    # fig07's grey levels need a scale
    from ring_gyro_sim.analysis import envelope as env
    rate = 200e3
    t = np.arange(int(0.05 * rate)) / rate
    spec = env.spectrogram(1e-6 * np.sin(2 * np.pi * 10.6e3 * t), rate, segment_s=5e-3,
                           overlap=0.5)
    assert plotting.plot_spectrogram(spec, tmp_path / 'fig07.png')
    labels = [ax['ylabel'] for ax in drawn[0]['axes']]
    assert 'power spectral density (dB re 1 m^2/Hz)' in labels, labels


@pytest.mark.parametrize('recovery_s', [1.25, None])
def test_the_rate_plot_marks_the_recovery(tmp_path, drawn, recovery_s):
    # rate.png marks when the rate was back (or that it was not), not only the shock
    t = np.linspace(0.0, 3.0, 301)
    applied = np.full_like(t, 0.1745)
    rate = applied + np.where(t > 0.5, 0.5 * np.exp(-(t - 0.5) / 0.2), 0.0)
    assert plotting.plot_rate([('', t, rate, applied)], tmp_path / 'rate.png', shock_s=0.5,
                              recovery_s=recovery_s)
    error = drawn[0]['axes'][1]
    marks = [label for label in error['lines'] if label.startswith('back within the band')]
    if recovery_s is None:
        assert marks == [] and 'not back within the band by the end' in error['texts']
    else:
        assert marks == ['back within the band 1.25 s after the shock'], error['lines']
