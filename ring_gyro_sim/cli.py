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
``ring_gyro``: the offline command line (run, replay, calibrate, ...).

Every verb prints one JSON object on stdout (its numbers and files) and writes what a person
reads (progress, notes, the run's summary) on stderr; an error is one line on stderr,
``ring_gyro VERB: error: ...``, exit 1 (2 for a usage error: argparse's).

``main()`` only parses arguments; the work is done by importable functions
(``ring_gyro_sim.offline``, ``ring_gyro_sim.replay``, ``ring_gyro_sim.analysis``). Each verb
imports its modules when it runs, on purpose: ``ring_gyro --help`` and argument errors answer
at once, without loading rclpy, numba or scipy (about a second).
"""

import argparse
import json
import sys
from typing import List, Optional

from ring_gyro_sim import __version__
from ring_gyro_sim.core.errors import RingGyroError

FILE_OPTION = ('-o', '--out', '--output')
DIR_OPTION = ('-o', '--out')
"""Where a verb writes, one spelling for all: ``-o`` / ``--out``, a file or a directory as the
verb writes one (``FILE``, ``DIR`` in its help); ``--output``, the former spelling of the file
verbs, stays accepted for the scripts that use it."""
OLD_SPELLING = ' (--output: the former spelling, still accepted)'


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='ring_gyro',
        description='Offline tools of ring_gyro_sim (a MEMS ring gyroscope under shock).')
    p.add_argument('--version', action='version', version=f'ring_gyro {__version__}',
                   help='print the package version and exit')
    sub = p.add_subparsers(dest='verb', metavar='VERB')

    run = sub.add_parser('run', help='run a scenario file offline, as fast as possible')
    run.add_argument('scenario', nargs='?', help='params YAML (same file as the node takes)')
    run.add_argument(*FILE_OPTION, dest='output', metavar='FILE.mcap',
                     help='record the run to this MCAP file' + OLD_SPELLING)
    run.add_argument('--from', dest='source', metavar='FILE.mcap',
                     help='re-simulate a recording from its parameters and inputs')
    run.add_argument('--duration', type=float, help='simulated time, s (overrides duration)')
    run.add_argument('--decimation', type=int, metavar='N',
                     help='record every N-th sample of the block topics (overrides '
                          'record.decimation; with --from, 1 gives every sample again)')
    run.add_argument('--overwrite', action='store_true',
                     help='replace an existing recording (record.overwrite: true; never the '
                          'scenario or the source recording itself)')
    run.add_argument('--json', action='store_true',
                     help='the JSON object on stdout only: no readable summary on stderr '
                          '(the JSON is printed either way)')
    run.add_argument('--no-progress', action='store_true', help='no progress bar')
    run.add_argument('--node-name', default='ring_gyro',
                     help='node name whose ros__parameters to read (default ring_gyro)')

    rep = sub.add_parser('replay', help='publish a recording into ROS topics with its timing')
    rep.add_argument('recording', help='MCAP file')
    rep.add_argument('--rate', type=float, default=1.0, help='playback speed factor')
    rep.add_argument('--clock', action='store_true', help='publish /clock from the log times')
    rep.add_argument('--topics', nargs='+', help='only these topics')
    rep.add_argument('--max-gap', type=float, default=None, metavar='SECONDS',
                     help='shorten longer gaps between log times to this, with a warning '
                          '(default 1 s; inf keeps them)')
    rep.add_argument('--wait-for-subscribers', type=float, default=0.0, metavar='S',
                     help='start once every topic has a subscriber (at most S s) '
                          'instead of after a fixed discovery wait')

    rec = sub.add_parser('recover', help='write a complete copy of a killed recording that '
                                         'every MCAP reader opens')
    rec.add_argument('recording', help='MCAP file (e.g. of a killed run: no summary)')
    rec.add_argument(*FILE_OPTION, dest='output', metavar='FILE.mcap',
                     help='the copy (default FILE.recovered.mcap; an existing file is '
                          'refused)' + OLD_SPELLING)

    cal = sub.add_parser('calibrate', help='outer voltage that puts the 1theta backbone '
                                           'through a target point (Fig. 4)')
    cal.add_argument('params', nargs='?',
                     help="params YAML (default: the paper's resonator, config/paper.yaml)")
    cal.add_argument('--target-hz', type=float, default=10.6e3,
                     help='backbone frequency to reach at --amplitude, Hz (default 10600, '
                          "the paper's Fig. 4)")
    cal.add_argument('--amplitude', type=float, default=6e-6,
                     help='amplitude of q1 where the frequency is matched, m (default 6e-6)')
    cal.add_argument('--low', type=float, default=40.0, help='voltage bracket low, V')
    cal.add_argument('--high', type=float, default=120.0, help='voltage bracket high, V')
    _add_harmonic_balance_verbs(sub)
    rt = sub.add_parser('rate', help='the rate output of a gyroscope recording against the '
                        'applied rate: rate.png, rate.csv and its figures (JSON)')
    rt.add_argument('recording', help='MCAP of a run with gyro.enabled')
    rt.add_argument(*DIR_OPTION, required=True, metavar='DIR',
                    help='directory for rate.png and rate.csv (created)')

    rpt = sub.add_parser('report', help='regenerate the paper figures (PNG) and summary.json '
                                        "/ summary.md with our numbers beside the paper's")
    rpt.add_argument(*DIR_OPTION, required=True, metavar='DIR',
                     help='output directory (created)')
    rpt.add_argument('--quick', action='store_true',
                     help='short runs (a few minutes; branches not decided)')
    rpt.add_argument('--workers', type=int, default=2,
                     help="worker processes of the job pool and of Case 4's local Dask "
                          'cluster (default 2)')
    _add_sweep_verb(sub)
    _add_characterize_verb(sub)
    return p


def _add_characterize_verb(sub) -> None:
    ch = sub.add_parser('characterize', help="the gyroscope's datasheet measured as IEEE Std "
                                             '1431 measures one: datasheet.md, datasheet.json '
                                             'and PNGs (doc/datasheet.md)')
    ch.add_argument('params', help='params YAML of a gyroscope (gyro.enabled: true), as '
                                   '`ring_gyro run` takes it')
    ch.add_argument(*DIR_OPTION, required=True, metavar='DIR',
                    help='output directory (created)')
    ch.add_argument('--quick', action='store_true',
                    help='short records (~20 simulated s; the figures are rough)')
    ch.add_argument('--loops', help='loop modes of the shock table, comma-separated: open '
                                    '(the fixed drive), closed (PLL + AGC), rebalance (closed '
                                    'loop + force-to-rebalance) (default: every one this '
                                    'build has)')
    ch.add_argument('--shock-g', help='shock amplitudes, g, comma-separated (default 1000,'
                                      '3000,10000; --quick 1000,10000)')
    ch.add_argument('--workers', type=int,
                    help='processes that run the tests (default: the cores; the datasheet '
                         'is the same for any number)')
    ch.add_argument('--no-progress', action='store_true', help='no progress bar')
    ch.add_argument('--node-name', default='ring_gyro',
                    help='node name whose ros__parameters to read (default ring_gyro)')


def _add_sweep_verb(sub) -> None:
    sw = sub.add_parser('sweep', help='a parameter sweep on Dask (jump maps): results.nc, '
                                      'results.csv and PNG maps (doc/sweeps.md)')
    sw.add_argument('spec', help='sweep spec YAML (base params file, axes, duration, metrics)')
    sw.add_argument(*DIR_OPTION, required=True, metavar='DIR',
                    help='output directory (created; points/ stored as they finish)')
    sw.add_argument('--scheduler', metavar='ADDRESS',
                    help='a running Dask scheduler (tcp://host:port); default: a local '
                         'cluster')
    sw.add_argument('--workers', type=int,
                    help='processes of the local cluster (default: the cores)')
    sw.add_argument('--resume', action='store_true',
                    help='keep the points stored in --out and compute the rest')
    sw.add_argument('--no-progress', action='store_true', help='no progress bar')
    sw.add_argument('--no-plots', action='store_true', help='no PNG maps')
    sw.add_argument('--dashboard-address', default=':8787',
                    help="local cluster's dashboard (default :8787; '' none)")


def _add_harmonic_balance_verbs(sub) -> None:
    bb = sub.add_parser('backbone', help='backbone of a nonlinear mode by harmonic balance '
                                         '(Fig. 4); writes CSV and PNG')
    bb.add_argument('params', nargs='?',
                    help="params YAML (default: the paper's resonator, config/paper.yaml)")
    bb.add_argument('--mode', type=int, default=1, help='n of the n-theta mode (default 1)')
    bb.add_argument('--taylor-terms', type=int, help='N_T (default: from the params; 0 = '
                                                     'untruncated)')
    bb.add_argument('--max-amplitude', type=float, default=6.5e-6,
                    help='continue up to this max |q_mode|, m (default 6.5e-6)')
    bb.add_argument('--harmonics', type=int, default=12, help='N_h (default 12)')
    bb.add_argument(*FILE_OPTION, dest='output', default='backbone.csv', metavar='FILE.csv',
                    help='CSV file (amplitude_m,frequency_hz); the plot goes beside it (.png)'
                         + OLD_SPELLING)
    bb.add_argument('--node-name', default='ring_gyro',
                    help='node name whose ros__parameters to read (default ring_gyro)')

    fr = sub.add_parser('frf', help='forced response to the 2theta drive by harmonic balance '
                                    'and continuation (Fig. 9); writes CSV and PNG')
    fr.add_argument('params', nargs='?',
                    help="params YAML (default: the paper's resonator, config/paper.yaml)")
    fr.add_argument('--mode', type=int, default=2,
                    help='n of the coordinate whose amplitude is reported (default 2)')
    fr.add_argument('--f-range', type=float, nargs=2, default=(15.70e3, 15.85e3),
                    metavar=('LOW', 'HIGH'), help='drive frequencies, Hz '
                                                  '(default 15700 15850)')
    fr.add_argument('--drive-amplitude', type=float,
                    help='A_e, m/s^2 (default: drive.amplitude of the params)')
    fr.add_argument('--taylor-terms', type=int, help='N_T (default: from the params)')
    fr.add_argument('--harmonics', type=int, default=3, help='N_h (default 3)')
    fr.add_argument('--stability', choices=('hill', 'monodromy'), default='hill',
                    help="Floquet multipliers by Hill's method or the monodromy matrix")
    fr.add_argument(*FILE_OPTION, dest='output', default='frf.csv', metavar='FILE.csv',
                    help='CSV file (frequency_hz,amplitude_m,stable); the plot goes beside '
                         'it (.png)' + OLD_SPELLING)
    fr.add_argument('--node-name', default='ring_gyro',
                    help='node name whose ros__parameters to read (default ring_gyro)')


def _load(path: Optional[str], node_name: str = 'ring_gyro'):
    """Return the configuration of a params file; none: the paper's resonator."""
    from ring_gyro_sim.core.params import paper_config
    from ring_gyro_sim.paramfile import load_yaml
    return load_yaml(path, node_name) if path else paper_config()


def _note(verb: str):
    """Return a function that writes one line ``ring_gyro VERB: ...`` on stderr at once."""
    def note(text: str) -> None:
        print(f'ring_gyro {verb}: {text}', file=sys.stderr, flush=True)
    return note


def _say_if_compiling(note, who: str = 'the kernels') -> None:
    """Say, before anything runs, that the kernels compile (numba's cache is cold)."""
    from ring_gyro_sim.core.kernels import cache
    if cache.cold_kernels():
        note(f'compiling {who} (first run of this version on this machine, '
             f'~{cache.COMPILE_CPU_S:.0f} s of CPU; the next runs load them)...')


def cmd_run(args) -> int:
    """``ring_gyro run``."""
    from ring_gyro_sim import offline
    from ring_gyro_sim.ros.recorder import check_output_path
    from ring_gyro_sim.run import format_number
    _say_if_compiling(_note('run'))
    if args.source:
        check_output_path(args.output, [args.source])
        summary = offline.resimulate(args.source, args.output, progress=not args.no_progress,
                                     overwrite=args.overwrite or None,
                                     decimation=args.decimation)
    else:
        if not args.scenario:
            raise RingGyroError('run: give a scenario file (or --from FILE.mcap)')
        config = offline.with_record_decimation(_load(args.scenario, args.node_name),
                                                args.decimation)
        output = args.output or config.run.record_path or None
        check_output_path(output, [args.scenario])
        summary = offline.run_offline(config, args.duration, output=output,
                                      progress=not args.no_progress,
                                      overwrite=args.overwrite or None, log=_note('run'))
    if not args.json:
        lines = [f'simulated {summary.sim_time_s:.4f} s in {summary.wall_time_s:.2f} s '
                 f'(x{summary.real_time_factor:.1f} real time), status {summary.status}']
        for name, peak in summary.peak_abs_m.items():
            lines.append(f'  {name}: peak {format_number(peak * 1e6)} um, last 10 ms '
                         f'{format_number(summary.final_abs_m[name] * 1e6)} um')
        lines.append(f'  smallest outer gap {format_number(summary.min_gap_m * 1e6)} um')
        if summary.message:
            lines.append(f'  {summary.message}')
        if summary.output:
            lines.append(f'  recorded to {summary.output}')
        print('\n'.join(lines), file=sys.stderr)
    print(summary.to_json())
    return 0


def cmd_replay(args) -> int:
    """``ring_gyro replay``."""
    from ring_gyro_sim.replay import MAX_GAP_S, replay
    result = replay(args.recording, rate=args.rate, clock=args.clock, topics=args.topics,
                    max_gap_s=MAX_GAP_S if args.max_gap is None else args.max_gap,
                    wait_for_subscribers_s=args.wait_for_subscribers)
    print(f'ring_gyro replay: {result.describe()}', file=sys.stderr)
    from dataclasses import asdict
    print(json.dumps(dict(asdict(result), recording=args.recording), sort_keys=True))
    return 0  # also when SIGINT / SIGTERM stopped it (the note says so)


def cmd_recover(args) -> int:
    """``ring_gyro recover``."""
    from ring_gyro_sim.recording.recover import recover
    result = recover(args.recording, args.output)
    print(f'ring_gyro recover: {result.describe()}', file=sys.stderr)
    print(json.dumps({'source': str(result.source), 'output': str(result.output),
                      'messages': result.message_count, 'topics': result.topics,
                      'chunks': result.chunk_count, 'metadata_records': result.metadata_count,
                      'was_complete': result.was_complete, 'stopped_at': result.stopped_at,
                      'reason': result.reason, 'source_size': result.source_size},
                     sort_keys=True))
    return 0


def cmd_calibrate(args) -> int:
    """``ring_gyro calibrate``."""
    import time
    from ring_gyro_sim.analysis.nnm import calibrate_outer_voltage, frequency_at_amplitude
    note = _note('calibrate')
    config = _load(args.params)
    started = time.monotonic()
    note(f'the outer voltage that puts the 1theta backbone through {args.target_hz:g} Hz at '
         f"{args.amplitude * 1e6:g} um, by Brent's method over {args.low:g}-{args.high:g} V: "
         f'~10 backbones by shooting, seconds each')

    def step(count: int, volts: float, frequency_hz: float) -> None:
        note(f'{count}: V_o = {volts:.4f} V -> {frequency_hz:.2f} Hz at '
             f'{args.amplitude * 1e6:g} um ({frequency_hz - args.target_hz:+.2f} Hz; '
             f'{time.monotonic() - started:.0f} s)')
    volts = calibrate_outer_voltage(config, args.target_hz, args.amplitude,
                                    (args.low, args.high), progress=step)
    note(f"V_o = {volts:.4f} V; the backbone at the file's "
         f'{config.electrodes.outer_voltage:g} V for comparison...')
    at_default = frequency_at_amplitude(config, args.amplitude)
    note(f'done in {time.monotonic() - started:.0f} s')
    print(json.dumps({'outer_voltage_v': volts, 'target_hz': args.target_hz,
                      'amplitude_m': args.amplitude,
                      'frequency_at_default_hz': at_default,
                      'default_outer_voltage_v': config.electrodes.outer_voltage}))
    return 0


def _cores() -> int:
    """Return the cores this process may run on (its affinity where the OS says it)."""
    import os
    affinity = getattr(os, 'sched_getaffinity', None)
    return len(affinity(0)) if affinity else (os.cpu_count() or 1)


def _plots_available(verb: str) -> bool:
    """Tell whether matplotlib is there; if not, say so once (before computing) and how."""
    from ring_gyro_sim.analysis import plotting
    if plotting.available():
        return True
    print(f'ring_gyro {verb}: {plotting.MISSING_MATPLOTLIB}', file=sys.stderr)
    return False


def _check_csv_output(output: str) -> None:
    """Refuse a ``-o`` CSV path that cannot be written, before computing anything."""
    from pathlib import Path
    from ring_gyro_sim.outdir import check_file
    if Path(output).suffix.lower() == '.png':
        raise RingGyroError(f'-o {output}: give the CSV file; the PNG is written beside it')
    check_file(output, '-o')


def _write_result(result, output: str, plots: bool, **plot_options) -> Optional[str]:
    """Write ``result`` to the CSV ``output`` and its plot beside it; return the PNG path."""
    from pathlib import Path
    csv = Path(output)
    png = csv.with_suffix('.png')
    result.to_csv(csv)
    if not plots:
        print(f'wrote {csv}; plot skipped (no matplotlib)', file=sys.stderr)
        return None
    result.plot(png, **plot_options)
    return str(png)


def _ended(result) -> dict:
    """Return ``status`` / ``message`` of a continuation: finished, or stopped and why."""
    return {'status': 'stopped' if result.status else 'finished', 'message': result.status}


def cmd_backbone(args) -> int:
    """``ring_gyro backbone``."""
    from ring_gyro_sim.analysis import hbm
    plots = _plots_available('backbone')
    _check_csv_output(args.output)
    config = _load(args.params, args.node_name)
    result = hbm.backbone(config, mode=args.mode, taylor_terms=args.taylor_terms,
                          max_amplitude_m=args.max_amplitude, harmonics=args.harmonics)
    png = _write_result(result, args.output, plots)
    print(json.dumps({'csv': args.output, 'png': png, 'points': int(result.amplitude_m.size),
                      'taylor_terms': result.taylor_terms, 'harmonics': result.harmonics,
                      'amplitude_m': float(result.amplitude_m[-1]),
                      'frequency_hz': float(result.frequency_hz[-1]),
                      **_ended(result)}))
    return 0


def cmd_frf(args) -> int:
    """``ring_gyro frf``."""
    from ring_gyro_sim.analysis import hbm
    plots = _plots_available('frf')
    _check_csv_output(args.output)
    config = _load(args.params, args.node_name)
    result = hbm.frf(config, mode=args.mode, f_range_hz=tuple(args.f_range),
                     drive_amplitude=args.drive_amplitude, harmonics=args.harmonics,
                     taylor_terms=args.taylor_terms, stability=args.stability)
    png = _write_result(result, args.output, plots, marker_hz=config.drive.frequency)
    print(json.dumps({'csv': args.output, 'png': png, 'points': int(result.frequency_hz.size),
                      'drive_amplitude': result.drive_amplitude,
                      'fold_frequencies_hz': list(result.fold_frequencies_hz),
                      'max_amplitude_m': float(result.amplitude_m.max()),
                      **_ended(result)}))
    return 0


def cmd_rate(args) -> int:
    """``ring_gyro rate``."""
    from ring_gyro_sim.rate_record import rate_report
    print(json.dumps(rate_report(args.recording, args.out), sort_keys=True))
    return 0


def cmd_report(args) -> int:
    """``ring_gyro report``."""
    from ring_gyro_sim import extras
    extras.require(extras.SWEEP, 'report (its Case 4 runs through the sweep engine)')
    from ring_gyro_sim.report import build_report
    plots = _plots_available('report')
    _say_if_compiling(_note('report'), 'the kernels in each worker')
    summary = build_report(args.out, quick=args.quick, workers=args.workers)
    if not plots:
        print(f'ring_gyro report: figures skipped (no matplotlib); CSVs and summary in '
              f'{args.out}', file=sys.stderr)
    print(json.dumps({'out': args.out, 'quick': args.quick,
                      'wall_time_s': summary['wall_time_s'],
                      'cases': {c['name']: c.get('final_branch') for c in summary['cases']}}))
    return 0


def cmd_characterize(args) -> int:
    """``ring_gyro characterize``."""
    from pathlib import Path
    from ring_gyro_sim import extras
    from ring_gyro_sim.characterize import characterize, NEEDS, parse_loops
    extras.require(NEEDS, 'characterize (the Allan deviation)')
    loops = parse_loops(args.loops)
    peaks = None
    if args.shock_g is not None:
        try:
            peaks = [float(v) for v in args.shock_g.split(',') if v.strip()]
        except ValueError:
            raise RingGyroError(f'--shock-g: not numbers: {args.shock_g!r}') from None
    _plots_available('characterize')
    _say_if_compiling(_note('characterize'))
    sheet = characterize(args.params, args.out, quick=args.quick, loops=loops,
                         progress=not args.no_progress, node_name=args.node_name,
                         shock_peaks_g=peaks,
                         workers=_cores() if args.workers is None else args.workers)
    print(json.dumps({
        'out': args.out, 'quick': args.quick, 'loops': sheet['loops'],
        'scale_factor_v_per_rad_s': sheet['scale_factor'],
        'scale_factor_nonlinearity_ppm': sheet['scale_factor_nonlinearity_ppm'],
        'bias_deg_per_h': sheet['bias_deg_per_h'],
        'arw_deg_per_sqrt_h': sheet['arw_deg_per_sqrt_h'],
        'bias_instability_deg_per_h': sheet['bias_instability_deg_per_h'],
        'bandwidth_hz': sheet['bandwidth_hz'], 'shock_entries': len(sheet['shock']),
        'drift_model': sheet['drift_model'],
        'long_record_tau_max_s': sheet['long_record'].get('tau_max_s'),
        'agreement': sheet['agreement'], 'wall_time_s': sheet['wall_time_s'],
        'files': [str(Path(args.out) / name) for name in sheet['files']]}, sort_keys=True))
    return 0


def cmd_sweep(args) -> int:
    """``ring_gyro sweep``: exit 0, or 3 when some points failed (results written)."""
    from ring_gyro_sim import extras
    extras.require(extras.SWEEP, 'sweep')  # at the start, before the spec is even read
    from ring_gyro_sim.sweep import load_spec, run_sweep
    spec = load_spec(args.spec)
    if not args.scheduler:  # a cluster elsewhere has its own cache
        _say_if_compiling(_note('sweep'), 'the kernels in each worker')
    outcome = run_sweep(spec, args.out, scheduler=args.scheduler,
                        workers=args.workers, resume=args.resume,
                        progress=not args.no_progress, plots=not args.no_plots,
                        dashboard_address=args.dashboard_address or None)
    print(json.dumps(outcome.summary()))
    return 3 if outcome.failures else 0


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``ring_gyro``."""
    parser = _parser()
    args = parser.parse_args(argv)
    if not args.verb:
        parser.print_help()
        return 2
    handler = {'run': cmd_run, 'replay': cmd_replay, 'recover': cmd_recover, 'rate': cmd_rate,
               'calibrate': cmd_calibrate,
               'backbone': cmd_backbone, 'frf': cmd_frf,
               'report': cmd_report, 'sweep': cmd_sweep,
               'characterize': cmd_characterize}[args.verb]
    try:
        return handler(args)
    except RingGyroError as exc:
        print(f'ring_gyro {args.verb}: error: {exc}', file=sys.stderr)
        return 1
    except OSError as exc:  # a file the verb reads or writes, after the checks at its start
        where = f'{exc.filename}: ' if exc.filename else ''
        print(f'ring_gyro {args.verb}: error: {where}{exc.strerror or exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
