"""``stridelab simulate``: the simulator of ``studies/`` writes its recordings as MCAP files."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from pipeline.formats.mcap_write import write_recording


def simulate_to_dir(directory: Path, *, manifest=None, seed: int | None = None, participants: int | None = None,
                    hours: float | None = None, on_file: Callable[[Path], None] = lambda p: None) -> list[Path]:
    """Simulate a study (default: the demo manifest) into ``directory``; returns the files written."""
    from studies.manifest import DEFAULT_MANIFEST, load_manifest
    from studies.simulator import simulate_study
    m = load_manifest(manifest or DEFAULT_MANIFEST)
    if hours is not None:
        m = m.with_free_living_hours(hours)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    for rec in simulate_study(m, seed=seed, participants=participants):
        p = write_recording(rec, directory / f"{rec.name}.mcap")
        on_file(p)
        out.append(p)
    return out
