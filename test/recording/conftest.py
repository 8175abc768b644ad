"""Fixtures of the recording tests."""

import pytest
from recording_samples import sample_messages, write_sample_bag


@pytest.fixture
def sample_bag(tmp_path):
    """Return (path, messages) of a finished sample recording."""
    messages = sample_messages()
    return write_sample_bag(tmp_path / 'run.mcap', messages), messages
