"""Shared set-up of the stage tests: a simulated lab session as MCAP files, the runner with a chosen stage
registry, and snapshot queries."""
from __future__ import annotations

from dataclasses import replace

from stridelab.pipeline import runner, stages
from stridelab.warehouse.read import connect_snapshot


def write_lab_session(directory, *, distance_sensors: bool, optical_reference: bool, participant: int = 0,
                      walking_trials: int = 1):
    """A demo-manifest participant (default the first; 2 = the hemiparetic P003): calibration trial + walking
    trials of 30 s, written as MCAP files into ``directory``. Returns (files, truths) in recording order."""
    from stridelab.pipeline.formats.mcap_write import write_recording
    from stridelab.studies.manifest import DEFAULT_MANIFEST, load_manifest
    from stridelab.validation.simulator import simulate_lab_session, study_participants
    m = load_manifest(DEFAULT_MANIFEST)
    m = replace(m, lab=replace(m.lab, walking_trials=walking_trials, distance_sensors=distance_sensors,
                               optical_reference=optical_reference))
    files, truths = [], []
    for rec, truth in simulate_lab_session(m, study_participants(m, participant + 1)[participant], 0):
        files.append(write_recording(rec, directory / f"{rec.name}.mcap"))
        truths.append(truth)
    return files, truths


def use_registry(mp, reg):
    """Make the runner (and ``stages.registry``) see only the stages ``reg`` (a list) on the monkeypatch ``mp``."""
    mp.setattr(runner, "registry", lambda: reg)
    mp.setattr(stages, "registry", lambda: reg)


def run_with(mp, root, files, reg):
    """``runner.run`` over ``files`` into ``root`` with only the stages ``reg``; asserts nothing failed."""
    use_registry(mp, reg)
    summary = runner.run(root, None, files=files)
    assert not summary.failed, summary.failed
    return summary


def df(root, sql, params=()):
    """Query a read-only snapshot of the warehouse at ``root`` into a DataFrame."""
    con = connect_snapshot(root)
    try:
        return con.execute(sql, list(params)).df()
    finally:
        con.close()
