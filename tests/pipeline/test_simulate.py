"""``stridelab simulate``: parallel participants write the same bytes as a serial run."""
from __future__ import annotations

import hashlib

import pytest

from stridelab.validation.simulate import simulate_to_dir


def _digests(files):
    return [(f.name, hashlib.sha256(f.read_bytes()).hexdigest()) for f in files]


@pytest.mark.slow
def test_parallel_simulation_is_byte_identical_to_serial(tmp_path):
    # one visit each (the demo's second visit is the same kinds of file again); passing visits also checks that the
    # workers get the override (the parallel run would write the manifest's two visits otherwise)
    serial = simulate_to_dir(tmp_path / "a", participants=2, hours=0.02, jobs=1, visits=1)
    parallel = simulate_to_dir(tmp_path / "b", participants=2, hours=0.02, jobs=2, visits=1)
    assert len(serial) == len(parallel) > 2
    assert _digests(serial) == _digests(parallel)
