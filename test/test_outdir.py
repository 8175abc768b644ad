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

"""Tests of outdir.py: output locations checked before anything is computed."""

import os

import pytest
from ring_gyro_sim.core.errors import RingGyroError
from ring_gyro_sim.outdir import check_file, OutputPathError, prepare_directory


def test_a_directory_is_created_with_its_parents_and_left_empty(tmp_path):
    made = prepare_directory(tmp_path / 'a' / 'b')
    assert made.is_dir() and list(made.iterdir()) == []
    assert prepare_directory(made) == made  # an existing directory is fine


def test_a_file_where_a_directory_goes_is_refused(tmp_path):
    (tmp_path / 'f').write_text('keep')
    with pytest.raises(OutputPathError, match=r'^--out .*f: exists and is not a directory$'):
        prepare_directory(tmp_path / 'f')
    with pytest.raises(OutputPathError, match='cannot create the directory: Not a directory'):
        prepare_directory(tmp_path / 'f' / 'sub')
    assert (tmp_path / 'f').read_text() == 'keep'


def test_a_directory_nothing_can_be_written_in_is_refused(tmp_path):
    try:  # /sys refuses new files to root as well; chmod would not stop root
        os.close(os.open('/sys/ring_gyro_probe', os.O_WRONLY | os.O_CREAT | os.O_EXCL))
    except OSError:
        pass
    else:
        os.unlink('/sys/ring_gyro_probe')
        pytest.skip('/sys is writable here')
    with pytest.raises(OutputPathError, match=r'^--out /sys: cannot write in it: '):
        prepare_directory('/sys')
    with pytest.raises(OutputPathError, match=r"^-o /sys/x.csv: cannot write in '/sys': "):
        check_file('/sys/x.csv')


def test_a_file_output_is_checked_but_not_created(tmp_path):
    target = check_file(tmp_path / 'new' / 'x.csv')
    assert target.parent.is_dir() and not target.exists()
    with pytest.raises(OutputPathError, match='is a directory'):
        check_file(tmp_path)


def test_the_error_is_both_the_package_error_and_an_os_error():
    assert issubclass(OutputPathError, RingGyroError) and issubclass(OutputPathError, OSError)
