"""The mobgap anchor runner on one real Mobilise-D trial, in the isolated environment (``make anchors-mobgap``);
skipped with the reason when that environment or the data is absent."""
from __future__ import annotations

import pytest

from tests.conftest import PROJECT_ROOT, shared_data

pytestmark = [pytest.mark.realdata, pytest.mark.slow]


def test_mobgap_runner_finds_the_straight_walk(tmp_path):
    from stridelab.validation.bench.trunk_gait import DEFAULT_MOBGAP_PY, load_mobilised, run_mobgap, score
    if not DEFAULT_MOBGAP_PY.is_file():
        pytest.skip(f"mobgap environment absent ({DEFAULT_MOBGAP_PY}); run `make anchors-mobgap`")
    recs = [r for r in load_mobilised(shared_data("mobilised_lab"), []) if r.name.endswith("Test5_Trial1")]
    assert len(recs) == 1
    mg, reason = run_mobgap(recs, DEFAULT_MOBGAP_PY, show=False)
    assert reason is None and mg["_version"] == "1.2.0", reason
    for variant in ("as_worn", "aligned"):
        s = score(recs, mg[variant]["healthy"])
        assert s["ic_sensitivity"] >= 0.8 and s["bouts_matched"] == 1, (variant, s)
    assert PROJECT_ROOT.joinpath("validation", "anchors", "mobgap-requirements.txt").is_file()
