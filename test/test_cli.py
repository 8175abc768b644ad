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
Tests of cli.py (``ring_gyro``): ``run`` with --json, -o and --from, errors, the executable.

``main([...])`` is called in this process; one run and one failing run go through the
installed console script (or ``python -m ring_gyro_sim.cli``) in their own processes.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from ring_gyro_sim import cli
from ring_gyro_sim.core.params import STANDARD_GRAVITY
from ring_gyro_sim.offline import run_offline
from ring_gyro_sim.paramfile import load_yaml

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
NS = '/ring_gyro'
BLOCK_TOPICS = [f'{NS}/modal_displacement', f'{NS}/radial_gap', f'{NS}/sense_electrodes']
SUMMARY_KEYS = {'sim_time_s', 'wall_time_s', 'real_time_factor', 'peak_abs_m', 'final_abs_m',
                'min_gap_m', 'contact'}
SHOCK_10000G = 10_000 * STANDARD_GRAVITY


RESONATOR = {'modes': '{companions: false}', 'gyro': '{enabled: false}',
             'control': '{mode: open_loop}'}
"""The paper's resonator (config/paper.yaml) in YAML flow text, group by group."""


def scenario(path, duration=0.05, **groups):
    """
    Write a params file: the paper's resonator, 10 000 g at t = 0 from rest, plus ``groups``.

    ``groups``: YAML flow mappings by group name, merged into the resonator's.
    """
    lines = ['/**:', '  ros__parameters:',
             '    drive: {amplitude: 0.0, start_on: rest}',
             f'    duration: {duration}',
             f'    scenario: {{shock_times: [0.0], shock_peaks: [{SHOCK_10000G!r}]}}']
    merged = dict(RESONATOR)
    for name, text in groups.items():
        merged[name] = (merged[name][:-1] + ', ' + text[1:]) if name in merged else text
    lines += [f'    {name}: {text}' for name, text in merged.items()]
    path = pathlib.Path(path)
    path.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return path


def block_arrays(path):
    """Return {topic: [(log_time_ns, labels, (K, C) array)]} decoded by mcap_ros2."""
    out = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(topics=BLOCK_TOPICS):
            data = np.array(msg.data, dtype=np.float64).reshape(msg.layout.dim[0].size,
                                                                msg.layout.dim[1].size)
            out.setdefault(channel.topic, []).append(
                (message.log_time, msg.layout.dim[1].label, data))
    return out


def assert_same_outputs(path_a, path_b):
    a, b = block_arrays(path_a), block_arrays(path_b)
    assert sorted(a) == sorted(b) == sorted(BLOCK_TOPICS)
    for topic in BLOCK_TOPICS:
        assert len(a[topic]) == len(b[topic]) > 0
        for (ta, la, xa), (tb, lb, xb) in zip(a[topic], b[topic]):
            assert (ta, la) == (tb, lb)
            assert np.array_equal(xa, xb), f'{topic} at {ta} ns: values differ'


def command():
    """Return the ``ring_gyro`` console script next to this Python, else ``python -m``."""
    exe = pathlib.Path(sys.executable).parent / 'ring_gyro'
    if exe.exists():
        return [str(exe)]
    found = shutil.which('ring_gyro')
    return [found] if found else [sys.executable, '-m', 'ring_gyro_sim.cli']


def run_process(args, cwd, timeout=120):
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    return subprocess.run(command() + args, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False)


def test_run_json_prints_exactly_one_object(tmp_path, capsys):
    path = scenario(tmp_path / 's.yaml')
    assert cli.main(['run', str(path), '--json', '--no-progress']) == 0
    out = capsys.readouterr().out
    assert out.endswith('\n') and out.count('\n') == 1
    summary = json.loads(out)
    assert isinstance(summary, dict)
    assert SUMMARY_KEYS <= set(summary)
    assert summary['sim_time_s'] == pytest.approx(0.05)
    assert summary['contact'] is False
    assert summary['output'] is None
    assert summary['real_time_factor'] == pytest.approx(
        summary['sim_time_s'] / summary['wall_time_s'])
    # The same numbers as the library call on the same file.
    direct = run_offline(load_yaml(str(path)), progress=False)
    assert summary['peak_abs_m'] == direct.peak_abs_m
    assert summary['final_abs_m'] == direct.final_abs_m
    assert summary['min_gap_m'] == direct.min_gap_m
    assert 0.55e-5 < summary['peak_abs_m']['q1'] < 0.60e-5


def test_run_prints_json_on_stdout_and_the_readable_summary_on_stderr(tmp_path, capsys):
    # Every verb prints one JSON object on stdout, `run` with or without --json; its readable
    # summary goes to stderr, and --json (kept for scripts) leaves that out: JSON only.
    path = scenario(tmp_path / 's.yaml', duration=0.01)
    assert cli.main(['run', str(path), '--no-progress']) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)['sim_time_s'] == pytest.approx(0.01)
    err = captured.err
    assert 'simulated 0.0100 s' in err and 'q1: peak' in err and 'smallest outer gap' in err
    assert 'status finished' in err
    assert cli.main(['run', str(path), '--no-progress', '--json']) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)['sim_time_s'] == pytest.approx(0.01)
    assert captured.err == ''


def test_every_verb_prints_one_json_object(tmp_path, capsys):
    # recover and replay too: their notes go to stderr, the JSON object to stdout
    path = scenario(tmp_path / 's.yaml', duration=0.02)
    recording = tmp_path / 'r.mcap'
    assert cli.main(['run', str(path), '-o', str(recording), '--no-progress']) == 0
    capsys.readouterr()
    assert cli.main(['recover', str(recording)]) == 0
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert printed['output'] == str(tmp_path / 'r.recovered.mcap') and printed['messages'] > 0
    assert 'written to' in captured.err
    assert cli.main(['replay', str(recording), '--rate', '1000', '--topics',
                     f'{NS}/modal_displacement']) == 0
    captured = capsys.readouterr()
    printed = json.loads(captured.out)
    assert printed['published'] == printed['total'] > 0
    assert 'replayed' in captured.err


def test_duration_option_overrides_the_file(tmp_path, capsys):
    path = scenario(tmp_path / 's.yaml', duration=1.0)
    assert cli.main(['run', str(path), '--json', '--duration', '0.004', '--no-progress']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['sim_time_s'] == pytest.approx(0.004)
    assert summary['samples'] == 800


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    """``ring_gyro run s.yaml -o run.mcap --json`` (in process): (path, summary)."""
    work = tmp_path_factory.mktemp('cli')
    path = scenario(work / 's.yaml', duration=0.03, record='{decimation: 1}')  # every sample
    out = work / 'run.mcap'
    capture = _Capture()
    with capture:
        rc = cli.main(['run', str(path), '-o', str(out), '--json', '--no-progress'])
    assert rc == 0, capture.err
    return out, json.loads(capture.out)


class _Capture:
    """Capture sys.stdout / sys.stderr of a module-scoped call (capsys is function-scoped)."""

    def __enter__(self):
        import io
        self._saved = sys.stdout, sys.stderr
        sys.stdout, sys.stderr = io.StringIO(), io.StringIO()
        return self

    def __exit__(self, *exc):
        self.out, self.err = sys.stdout.getvalue(), sys.stderr.getvalue()
        sys.stdout, sys.stderr = self._saved


def test_output_option_writes_a_recording(recorded):
    path, summary = recorded
    assert summary['output'] == str(path)
    assert path.stat().st_size > 0
    blocks = block_arrays(path)
    # 0.03 s at 200 kHz in blocks of 10 ms.
    assert [len(b) for b in blocks.values()] == [3, 3, 3]
    data = np.concatenate([a for _, _, a in blocks[f'{NS}/modal_displacement']])
    assert data.shape == (6000, 4)
    assert np.max(np.abs(data[:, 1])) == summary['peak_abs_m']['q1']
    with open(path, 'rb') as stream:
        assert make_reader(stream).get_header().profile == 'ros2'


def test_from_recording_resimulates_bit_identically(recorded, tmp_path, capsys):
    path, summary = recorded
    again = tmp_path / 'again.mcap'
    assert cli.main(['run', '--from', str(path), '-o', str(again), '--json',
                     '--no-progress']) == 0
    resumed = json.loads(capsys.readouterr().out)
    assert resumed['output'] == str(again)
    assert resumed['peak_abs_m'] == summary['peak_abs_m']
    assert_same_outputs(path, again)


def test_decimation_option_and_every_sample_again_from_a_decimated_recording(
        tmp_path, capsys):
    from ring_gyro_sim.recording.reader import read_block_topic, read_metadata
    path = scenario(tmp_path / 's.yaml', duration=0.03, record='{decimation: 1}')
    thinned = tmp_path / 'thinned.mcap'
    assert cli.main(['run', str(path), '-o', str(thinned), '--decimation', '7',
                     '--no-progress']) == 0
    assert read_metadata(thinned, 'ring_gyro_sim')['record_decimation'] == '7'
    again, full = tmp_path / 'again.mcap', tmp_path / 'full.mcap'
    assert cli.main(['run', '--from', str(thinned), '-o', str(again), '--no-progress']) == 0
    assert cli.main(['run', '--from', str(thinned), '-o', str(full), '--decimation', '1',
                     '--no-progress']) == 0
    capsys.readouterr()
    assert read_metadata(again, 'ring_gyro_sim')['record_decimation'] == '7'
    assert_same_outputs(thinned, again)
    for name in ('modal_displacement', 'radial_gap', 'sense_electrodes'):
        kept, every = read_block_topic(thinned, name), read_block_topic(full, name)
        assert every.end_ns == kept.end_ns
        assert len(every.data) == 6000  # 30 ms at 200 kHz: every sample again
        index = np.rint(every.data[:, 0] * 200_000).astype(int)
        assert np.array_equal(kept.data, every.data[index % 7 == 0]), name  # bit for bit
    assert cli.main(['run', str(path), '--decimation', '0', '--no-progress']) != 0
    assert 'record.decimation' in capsys.readouterr().err


def test_from_a_file_that_is_not_a_recording(tmp_path, capsys):
    path = scenario(tmp_path / 's.yaml')
    assert cli.main(['run', '--from', str(path), '--no-progress']) != 0
    err = capsys.readouterr().err
    assert 's.yaml' in err and 'MCAP' in err


@pytest.mark.parametrize('groups, field', [
    ({'modes': '{quality_factors: [-5.0, 64700.0, 170000.0]}'}, 'modes.quality_factors'),
    ({'electrodes': '{outer_voltag: 70.0}'}, 'electrodes.outer_voltag'),
    ({'electrodes': '{outer_voltage: abc}'}, 'electrodes.outer_voltage'),
])
def test_invalid_field_exits_nonzero_naming_it(tmp_path, capsys, groups, field):
    path = scenario(tmp_path / 'bad.yaml', **groups)
    rc = cli.main(['run', str(path), '--json', '--no-progress'])
    captured = capsys.readouterr()
    assert rc != 0
    assert field in captured.err
    assert captured.out == ''


def test_zero_duration_is_refused(tmp_path, capsys):
    path = scenario(tmp_path / 's.yaml', duration=0.0)
    assert cli.main(['run', str(path), '--no-progress']) != 0
    assert 'duration' in capsys.readouterr().err


@pytest.mark.parametrize('where', ['under_a_file', 'directory'])
def test_unwritable_output_fails_at_start(tmp_path, capsys, where):
    # 100 s of simulation if it started: the failure must come before the run. (Missing
    # parent directories are created; a path through a regular file cannot be.)
    path = scenario(tmp_path / 's.yaml', duration=100.0)
    (tmp_path / 'no').write_text('a file, not a directory')
    target = tmp_path / 'no' / 'such' / 'dir' / 'x.mcap' if where == 'under_a_file' else tmp_path
    start = time.perf_counter()
    rc = cli.main(['run', str(path), '-o', str(target), '--no-progress'])
    elapsed = time.perf_counter() - start
    err = capsys.readouterr().err
    assert rc != 0
    assert elapsed < 10.0
    assert str(target) in err and 'error' in err
    assert (tmp_path / 'no').read_text() == 'a file, not a directory'


def test_help_lists_the_verbs(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(['--help'])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for verb in ('run', 'replay', 'calibrate'):
        assert verb in out
    assert cli.main([]) == 2


def test_console_script_in_its_own_process(tmp_path):
    path = scenario(tmp_path / 's.yaml', duration=0.02)
    result = run_process(['run', str(path), '-o', 'p.mcap', '--json'], cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 1
    summary = json.loads(lines[0])
    assert SUMMARY_KEYS <= set(summary)
    assert (tmp_path / 'p.mcap').stat().st_size > 0
    # A short run shows no progress bar.
    assert result.stderr == ''
    bad = scenario(tmp_path / 'bad.yaml', modes='{quality_factors: [1.0, 2.0]}')
    result = run_process(['run', str(bad)], cwd=tmp_path)
    assert result.returncode != 0
    assert 'modes.quality_factors' in result.stderr
    assert 'Traceback' not in result.stderr


# ----------------------------------------------------- where the results go
def unwritable_directory():
    """Return an existing directory nothing can be created in (root included), or skip."""
    try:
        probe = os.open('/sys/ring_gyro_probe', os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except OSError:
        return '/sys'
    os.close(probe)
    os.unlink('/sys/ring_gyro_probe')
    pytest.skip('/sys is writable here')


def one_error_line(err, verb):
    line = err.strip()
    assert '\n' not in line and 'Traceback' not in err, err
    assert line.startswith(f'ring_gyro {verb}: error: '), line
    return line


@pytest.fixture
def boom(monkeypatch):
    """Make every computation of the verbs below fail the test: the check comes first."""
    from ring_gyro_sim import characterize, rate_record, report
    from ring_gyro_sim.analysis import hbm

    def computing(*args, **kwargs):
        raise AssertionError('computing before the output location was checked')
    monkeypatch.setattr(characterize, 'load_device', lambda *a, **k: {})
    monkeypatch.setattr(characterize, '_drift_and_step', computing)
    monkeypatch.setattr(report, 'run_case4', computing)
    monkeypatch.setattr(report, 'run_jobs', computing)
    monkeypatch.setattr(hbm, 'backbone', computing)
    monkeypatch.setattr(rate_record, 'applied_rate', computing)


@pytest.mark.parametrize('verb, args, where, reason', [
    ('rate', ['REC', '--out', 'FILE'], 'FILE', 'exists and is not a directory'),
    ('rate', ['REC', '--out', 'RO/out'], 'RO/out', 'cannot create the directory'),
    ('sweep', ['SPEC', '--out', 'FILE'], 'FILE', 'exists and is not a directory'),
    ('sweep', ['SPEC', '--out', 'RO'], 'RO', 'cannot write in it'),
    ('characterize', ['config/default.yaml', '--out', 'FILE'], 'FILE', 'exists and is not'),
    ('characterize', ['config/default.yaml', '--out', 'RO/sheet'], 'RO/sheet',
     'cannot create the directory'),
    ('characterize', ['config/default.yaml', '--out', 'RO'], 'RO', 'cannot write in it'),
    ('report', ['--out', 'FILE/sub', '--quick'], 'FILE/sub',
     'cannot create the directory: Not a directory'),
    ('backbone', ['-o', 'RO/b.csv'], 'RO/b.csv', "cannot write in 'RO'"),
])
def test_an_unusable_output_is_one_line_before_any_work(tmp_path, capsys, boom, verb, args,
                                                        where, reason):
    # One line, not a traceback, and before any work: characterize into a read-only
    # directory would otherwise compute for 13 s (20 minutes for the full sheet) and lose it.
    ro = unwritable_directory()
    (tmp_path / 'FILE').write_text('a file')
    (tmp_path / 'REC').write_bytes(b'\x89MCAP0\r\n')
    (tmp_path / 'SPEC').write_text('duration: 0.01\naxes: {shock.peak_g: [1000.0]}\n')

    def fill(text):
        text = text.replace('RO', ro).replace('FILE', str(tmp_path / 'FILE'))
        text = text.replace('REC', str(tmp_path / 'REC')).replace('SPEC', str(tmp_path / 'SPEC'))
        return str(REPO_ROOT / text) if text.startswith('config/') else text
    assert cli.main([verb] + [fill(a) for a in args]) == 1
    line = one_error_line(capsys.readouterr().err, verb)
    assert f'{fill(where)}: {fill(reason)}' in line, line
    assert (tmp_path / 'FILE').read_text() == 'a file'


@pytest.mark.parametrize('args, message', [
    (['--scheduler', 'not an address'], "--scheduler 'not an address': not a scheduler "
                                        'address (tcp://HOST:PORT)'),
    (['--dashboard-address', 'garbage:xx'], "--dashboard-address 'garbage:xx': expected "
                                            '[HOST]:PORT'),
])
def test_a_bad_dask_address_is_one_line(tmp_path, capsys, args, message):
    # One line, not distributed's ValueError or RuntimeError traceback
    spec = tmp_path / 'spec.yaml'
    spec.write_text('duration: 0.01\naxes: {shock.peak_g: [1000.0]}\n')
    assert cli.main(['sweep', str(spec), '--out', str(tmp_path / 'o')] + args) == 1
    assert message in one_error_line(capsys.readouterr().err, 'sweep')
    assert not (tmp_path / 'o').exists()


def test_an_os_error_late_in_a_verb_is_one_line(tmp_path, capsys, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(28, 'No space left on device', str(tmp_path / 'rate.csv'))
    monkeypatch.setattr(cli, 'cmd_rate', full)
    assert cli.main(['rate', 'x.mcap', '--out', str(tmp_path)]) == 1
    line = one_error_line(capsys.readouterr().err, 'rate')
    assert line.endswith(f'{tmp_path / "rate.csv"}: No space left on device')


def read_only_mount_shell(directory):
    """Return an argv prefix that runs a shell with a read-only tmpfs on ``directory``."""
    unshare = shutil.which('unshare')
    if unshare is None:
        pytest.skip('no unshare')
    argv = [unshare, '-m', 'sh', '-c']
    probe = subprocess.run(argv + [f'mount -t tmpfs -o ro tmpfs {directory}'],
                           capture_output=True, timeout=30, check=False)
    if probe.returncode != 0:
        pytest.skip(f'cannot mount a read-only file system here: {probe.stderr!r}')
    return argv


def test_a_read_only_file_system_is_one_line_per_verb(tmp_path):
    # `recover -o`, `rate --out`, `sweep --out` and `characterize --out` on a read-only file
    # system (EROFS, which root meets too).
    ro = tmp_path / 'ro'
    ro.mkdir()
    shell = read_only_mount_shell(ro)
    recording = tmp_path / 'r.mcap'
    assert cli.main(['run', str(scenario(tmp_path / 's.yaml', duration=0.01)), '-o',
                     str(recording), '--no-progress']) == 0
    spec = tmp_path / 'spec.yaml'
    spec.write_text('duration: 0.01\naxes: {shock.peak_g: [1000.0]}\n')
    python = f'PYTHONPATH={REPO_ROOT} {sys.executable} -m ring_gyro_sim.cli'
    verbs = {'recover': f'recover {recording} -o {ro}/x.mcap',
             'rate': f'rate {recording} --out {ro}/rate',
             'sweep': f'sweep {spec} --out {ro}',
             'characterize': f'characterize {REPO_ROOT}/config/default.yaml --out {ro} --quick'}
    script = f'mount -t tmpfs -o ro tmpfs {ro} && ' + ' ; '.join(
        f'{python} {args} 2> {tmp_path}/{verb}.err; echo $? > {tmp_path}/{verb}.rc'
        for verb, args in verbs.items())
    subprocess.run(shell + [script], timeout=600, check=True)
    for verb in verbs:
        err = (tmp_path / f'{verb}.err').read_text()
        assert (tmp_path / f'{verb}.rc').read_text().strip() == '1', err
        assert one_error_line(err, verb).endswith('Read-only file system'), err


def test_version_prints_the_package_version(capsys):
    from ring_gyro_sim import __version__
    with pytest.raises(SystemExit) as exc:
        cli.main(['--version'])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f'ring_gyro {__version__}\n'


def subparsers():
    """Return ``{verb: its ArgumentParser}`` of ``ring_gyro``."""
    import argparse
    action = next(a for a in cli._parser()._actions
                  if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_every_option_of_every_verb_has_help():
    missing = [f'{verb} {act.option_strings or act.dest}'
               for verb, parser in subparsers().items() for act in parser._actions
               if not act.help]
    assert missing == []


def test_the_loops_help_names_every_loop_mode():
    from ring_gyro_sim.characterize import LOOP_MODES
    loops = next(a for a in subparsers()['characterize']._actions if a.dest == 'loops')
    assert [m for m in LOOP_MODES if m not in loops.help] == []


@pytest.mark.parametrize('peak_g, status', [(10_000, 'finished'), (40_000, 'contact')])
def test_the_json_status_says_how_the_run_ended(tmp_path, capsys, peak_g, status):
    # "running" is not a status a finished run may report
    path = scenario(tmp_path / 's.yaml', duration=0.01)
    path.write_text(path.read_text().replace(repr(SHOCK_10000G),
                                             repr(peak_g * STANDARD_GRAVITY)))
    assert cli.main(['run', str(path), '--json', '--no-progress']) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary['status'], summary['contact']) == (status, status == 'contact')
    assert bool(summary['message']) == (status == 'contact')


@pytest.mark.parametrize('verb', ['backbone', 'frf'])
@pytest.mark.parametrize('why, status', [('', 'finished'),
                                         ('the amplitude turned back at 6e-06 m', 'stopped')])
def test_the_continuations_say_finished_or_stopped(tmp_path, capsys, monkeypatch, verb, why,
                                                   status):
    # "finished" or "stopped", never an empty status
    from ring_gyro_sim.analysis import hbm

    class Result:
        amplitude_m = frequency_hz = np.array([1e-6, 2e-6])
        taylor_terms, harmonics, drive_amplitude, fold_frequencies_hz = 4, 3, 0.065, ()

        def __init__(self, *args, **kwargs):
            self.status = why

        def to_csv(self, path):
            pathlib.Path(path).write_text('x\n')

        def plot(self, path, **kwargs):
            pathlib.Path(path).write_bytes(b'')
    monkeypatch.setattr(hbm, verb, Result)
    assert cli.main([verb, '-o', str(tmp_path / 'r.csv')]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert (printed['status'], printed['message']) == (status, why)


WRITES = {'run': 'FILE.mcap', 'recover': 'FILE.mcap', 'backbone': 'FILE.csv',
          'frf': 'FILE.csv', 'rate': 'DIR', 'report': 'DIR', 'sweep': 'DIR',
          'characterize': 'DIR'}
"""Verbs that write: what ``-o`` / ``--out`` names for each."""


def test_every_verb_that_writes_takes_o_and_out():
    # One spelling for every verb: `-o` / `--out`
    parsers = subparsers()
    for verb, metavar in WRITES.items():
        where = [a for a in parsers[verb]._actions if '--out' in a.option_strings]
        assert len(where) == 1, verb
        assert where[0].option_strings[:2] == ['-o', '--out'] and where[0].metavar == metavar
        if metavar != 'DIR':  # the file verbs' former spelling stays for scripts
            assert '--output' in where[0].option_strings
    others = [verb for verb, parser in parsers.items() if verb not in WRITES
              for a in parser._actions if {'-o', '--out', '--output'} & set(a.option_strings)]
    assert others == []


def test_the_three_spellings_reach_the_same_option(tmp_path, capsys):
    path = scenario(tmp_path / 's.yaml', duration=0.002)
    for i, flag in enumerate(('-o', '--out', '--output')):
        assert cli.main(['run', str(path), flag, str(tmp_path / f'{i}.mcap'), '--json']) == 0
        assert json.loads(capsys.readouterr().out)['output'] == str(tmp_path / f'{i}.mcap')


def test_run_says_when_it_computes_the_start_state(tmp_path, capsys, monkeypatch):
    # The start state takes up to 30 s (config/paper.yaml): the user is told before
    from collections import OrderedDict
    from ring_gyro_sim.core.gyro import operating_point
    monkeypatch.setattr(operating_point, '_MEMO', OrderedDict())
    monkeypatch.setattr(operating_point, 'drive_orbit', lambda config: None)  # the 30 s
    path = scenario(tmp_path / 's.yaml', duration=0.002)
    path.write_text(path.read_text().replace('drive: {amplitude: 0.0, start_on: rest}',
                                             'drive: {amplitude: 0.065, start_on: upper_branch}'))
    assert cli.main(['run', str(path), '--json', '--no-progress']) == 0
    err = capsys.readouterr().err
    assert err.startswith('ring_gyro run: computing the start state (upper_branch of the drive '
                          'at 15798.6 Hz, 0.065 m/s^2): a few seconds\n'), err


@pytest.mark.parametrize('cold, said', [(['run_samples'], True), ([], False), (None, False)])
def test_run_says_it_compiles_when_the_cache_is_cold(tmp_path, capsys, monkeypatch, cold,
                                                     said):
    # The first compile takes tens of seconds (cache.COMPILE_CPU_S): the user is told before
    from ring_gyro_sim.core.kernels import cache
    monkeypatch.setattr(cache, 'cold_kernels', lambda: cold)
    path = scenario(tmp_path / 's.yaml', duration=0.002)
    assert cli.main(['run', str(path), '--json', '--no-progress']) == 0
    err = capsys.readouterr().err
    assert ('ring_gyro run: compiling the kernels' in err) == said, err


def test_calibrate_shows_each_evaluation_as_it_goes(capsys, monkeypatch):
    # A calibration takes about a minute: it says each evaluation as it goes. The backbone
    # (seconds each) is replaced by a line in V_o here: what is tested is what the verb
    # says, not the shooting.
    from ring_gyro_sim.analysis import nnm

    def backbone_at(config, amplitude_m, mode=1):
        return 10.0e3 + 10.0 * (config.electrodes.outer_voltage - 40.0)
    monkeypatch.setattr(nnm, 'frequency_at_amplitude', backbone_at)
    assert cli.main(['calibrate', '--target-hz', '10500']) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)['outer_voltage_v'] == pytest.approx(90.0, abs=1e-3)
    lines = captured.err.splitlines()
    assert lines[0].startswith('ring_gyro calibrate: the outer voltage that puts the 1theta '
                               'backbone through 10500 Hz at 6 um')
    steps = [line for line in lines if line.startswith('ring_gyro calibrate: 1: ')
             or line.startswith('ring_gyro calibrate: 2: ')]
    assert steps[0].startswith('ring_gyro calibrate: 1: V_o = 40.0000 V -> 10000.00 Hz at 6 um '
                               '(-500.00 Hz;'), steps
    assert lines[-1].startswith('ring_gyro calibrate: done in ')
