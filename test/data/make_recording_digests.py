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
Digests of short recordings of the shipped configurations, and of their re-simulations.

Each case is ``ring_gyro run CONFIG --duration D -o run.mcap`` of a file of ``config/`` (or
of one of them with a few values laid over it, :data:`CASES`), then ``ring_gyro run --from
run.mcap -o again.mcap``. Both recordings are read back with the ``mcap`` library (not the
package's reader) and digested per topic: the SHA-256 of every message's log time, publish
time and serialised bytes in file order. ``/diagnostics`` is digested without the values that
depend on the wall clock (:data:`WALL_CLOCK_KEYS`); the metadata records without
``git_revision`` (the tree's, not the run's).

Used two ways:

* ``python test/data/make_recording_digests.py OUT.json`` writes the digests, with the
  library versions and the CPU they were made with (``test/data/recording_digests.json``
  is what the tree of a behaviour-preserving change must reproduce);
* ``test/test_recording_digests.py`` computes them again and compares.

Run it with the tree to be digested first on ``PYTHONPATH`` to digest another checkout.
"""

import hashlib
import importlib.util
import json
import os
import pathlib
import subprocess
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parent


def _repo() -> pathlib.Path:
    """Return the checkout whose package is imported (its ``config/`` is digested)."""
    spec = importlib.util.find_spec('ring_gyro_sim')
    return pathlib.Path(spec.origin).resolve().parents[1]


DURATION_S = {'default': 0.3, 'demo': 0.62, 'gyro': 0.2, 'gyro_case3': 0.62,
              'gyro_shock': 1.05, 'paper': 0.1}
"""Simulated seconds of each shipped configuration (past its first shock where it has one)."""

EXTRA = {
    'default_seeded_warm': ('default', {'device': {'seed': 7},
                                        'scenario': {'temperature_times': [0.0, 0.2],
                                                     'temperature_values': [298.15, 318.15]}},
                            0.3),
    'default_vibration': ('default', {'scenario': {'vibration_frequency': 1000.0,
                                                   'vibration_amplitude': 98.0665}}, 0.1),
}
"""Cases of a shipped file with values laid over it: (base, overrides, duration s)."""

WALL_CLOCK_KEYS = frozenset(('real_time_factor_achieved', 'real_time_factor_average', 'lag_s'))
"""``/diagnostics`` values that depend on how fast the host ran (offline runs: the wall)."""


def cases():
    """Return ``{name: (params file text, duration s)}`` of every case."""
    out = {}
    repo = _repo()
    for name, duration in DURATION_S.items():
        out[name] = ((repo / 'config' / f'{name}.yaml').read_text(encoding='utf-8'), duration)
    import yaml
    for name, (base, overrides, duration) in EXTRA.items():
        tree = yaml.safe_load((repo / 'config' / f'{base}.yaml').read_text(encoding='utf-8'))
        params = next(iter(tree.values()))['ros__parameters']
        for group, values in overrides.items():
            params.setdefault(group, {}).update(values)
        out[name] = (yaml.safe_dump(tree, sort_keys=True), duration)
    return out


def _diagnostics_bytes(decoded) -> bytes:
    """Return a canonical text of a decoded ``/diagnostics`` message without the wall clock."""
    parts = [f'{decoded.header.stamp.sec}.{decoded.header.stamp.nanosec:09d}']
    for status in decoded.status:
        parts.append(f'{status.level}|{status.name}|{status.message}|{status.hardware_id}')
        parts.extend(f'{kv.key}={kv.value}' for kv in status.values
                     if kv.key not in WALL_CLOCK_KEYS)
    return '\n'.join(parts).encode()


def digest_recording(path) -> dict:
    """Return ``{topic: sha256}`` and ``{metadata name: sha256}`` of one recording."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    decoder = DecoderFactory()
    topics = {}
    counts = {}
    with open(path, 'rb') as fh:
        reader = make_reader(fh, decoder_factories=[decoder])
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            h = topics.setdefault(channel.topic, hashlib.sha256())
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            data = (_diagnostics_bytes(decoded) if channel.topic == '/diagnostics'
                    else message.data)
            h.update(f'{message.log_time},{message.publish_time},{len(data)};'.encode())
            h.update(data)
        fh.seek(0)
        reader = make_reader(fh)
        metadata = {}
        for record in reader.iter_metadata():
            values = {k: v for k, v in record.metadata.items() if k != 'git_revision'}
            name = record.name
            index = sum(1 for k in metadata if k.split('#')[0] == name)
            text = json.dumps(values, sort_keys=True)
            metadata[f'{name}#{index}'] = hashlib.sha256(text.encode()).hexdigest()
    return {'topics': {t: f'{counts[t]}:{h.hexdigest()}' for t, h in sorted(topics.items())},
            'metadata': dict(sorted(metadata.items()))}


def _ring_gyro(*args, cwd):
    """Run ``ring_gyro`` of the tree first on the path; raise with its stderr on failure."""
    code = 'import sys; from ring_gyro_sim.cli import main; sys.exit(main(sys.argv[1:]))'
    done = subprocess.run([sys.executable, '-c', code, *args], cwd=cwd,
                          capture_output=True, text=True, env=dict(os.environ))
    if done.returncode != 0:
        raise RuntimeError(f'ring_gyro {" ".join(args)}: exit {done.returncode}\n'
                           f'{done.stderr[-3000:]}')
    return json.loads(done.stdout)


def compute(names=None) -> dict:
    """Return the digests of every case (or of ``names``): recorded and re-simulated."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for name, (text, duration) in cases().items():
            if names is not None and name not in names:
                continue
            params = tmp / f'{name}.yaml'
            params.write_text(text, encoding='utf-8')
            first, again = tmp / f'{name}.mcap', tmp / f'{name}.again.mcap'
            _ring_gyro('run', str(params), '--duration', repr(duration), '--no-progress',
                       '--json', '-o', str(first), cwd=tmp)
            _ring_gyro('run', '--from', str(first), '--no-progress', '--json',
                       '-o', str(again), cwd=tmp)
            out[name] = {'run': digest_recording(first), 'from': digest_recording(again)}
    return out


def versions_and_machine() -> str:
    """Return the library versions and the CPU, as ``test/data/make_demo_reference.py``."""
    spec = importlib.util.spec_from_file_location('make_demo_reference',
                                                  HERE / 'make_demo_reference.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return f'{module.versions()};{module.machine()}'


def main(argv) -> int:
    """Write the digests of every case to ``argv[0]``."""
    if len(argv) != 1:
        print('usage: make_recording_digests.py OUT.json', file=sys.stderr)
        return 2
    result = {'made_with': versions_and_machine(), 'cases': compute()}
    pathlib.Path(argv[0]).write_text(json.dumps(result, indent=1, sort_keys=True) + '\n',
                                     encoding='utf-8')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
