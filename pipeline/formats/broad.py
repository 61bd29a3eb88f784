"""Reader for BROAD HDF5 trials (Laidig et al., *Data* 6(7):72, 2021; data README ``../shared/data``).

Each trial holds ``imu_gyr`` (N, 3) rad/s, ``imu_acc`` (N, 3) m/s², ``imu_mag`` (N, 3) µT, ``opt_quat``
(N, 4) [w x y z] sensor→ENU optical reference (NaN where the markers were occluded), ``opt_pos`` (N, 3) m,
``movement`` (N,) bool (samples to score) and the attribute ``sampling_rate`` (Hz). These are already
StrideLab's conventions, so the reader converts nothing.

Discovery: any number of trials with any names. ``load_broad(path)`` accepts a directory (every
``*.hdf5``/``*.h5`` file in it, sorted by name), a single file, and, inside a file, either the datasets at
the root (one trial per file, the public release) or one HDF5 group per trial (any group that holds
``imu_gyr``, found recursively). ``trials.json`` beside the files, when present, adds a description and
the group labels (``undisturbed``, ``rotation``, ...); trials missing from it still load.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["BroadTrial", "load_broad", "find_broad_files"]

_REQUIRED = ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement")


@dataclass(frozen=True)
class BroadTrial:
    """One BROAD trial in SI units, sensor→ENU reference.

    name: trial name (file stem, or ``stem/group`` for multi-trial files).
    gyr, acc, mag: (N, 3) rad/s, m/s² (specific force), µT.
    quat_ref: (N, 4) [w x y z] optical reference, sensor→ENU; NaN rows where not tracked.
    pos_ref: (N, 3) m or None.
    movement: (N,) bool, samples to score.
    sampling_rate_hz: float.
    description, groups: from ``trials.json`` when available.
    """
    name: str
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_ref: np.ndarray
    pos_ref: np.ndarray | None
    movement: np.ndarray
    sampling_rate_hz: float
    description: str = ""
    groups: tuple[str, ...] = field(default_factory=tuple)

    @property
    def disturbed(self) -> bool:
        return "disturbed" in self.groups or "_disturbed_" in f"_{self.name}_"


def find_broad_files(path: str | Path) -> list[Path]:
    """HDF5 files of a BROAD folder (sorted), or ``[path]`` for a single file. Raises ValueError if none."""
    p = Path(path)
    if p.is_file():
        return [p]
    if not p.is_dir():
        raise ValueError(f"BROAD path {p} does not exist (expected a folder of *.hdf5 trials or one file)")
    files = sorted([*p.glob("*.hdf5"), *p.glob("*.h5")])
    if not files:
        raise ValueError(f"no *.hdf5 / *.h5 files in {p}: is this the BROAD data folder?")
    return files


def _read_group(g, name: str, meta: dict) -> BroadTrial:
    missing = [k for k in _REQUIRED if k not in g]
    if missing:
        raise ValueError(f"BROAD trial {name}: missing dataset(s) {', '.join(missing)}")
    rate = g.attrs.get("sampling_rate", None)
    if rate is None and "sampling_rate" in g:
        rate = np.asarray(g["sampling_rate"][()]).ravel()[0]
    if rate is None:
        raise ValueError(f"BROAD trial {name}: no 'sampling_rate' attribute")
    info = meta.get(name.split("/")[-1], {}) or meta.get(name, {})
    return BroadTrial(
        name=name,
        gyr=np.ascontiguousarray(g["imu_gyr"][()], dtype=np.float64),
        acc=np.ascontiguousarray(g["imu_acc"][()], dtype=np.float64),
        mag=np.ascontiguousarray(g["imu_mag"][()], dtype=np.float64),
        quat_ref=np.ascontiguousarray(g["opt_quat"][()], dtype=np.float64),
        pos_ref=np.ascontiguousarray(g["opt_pos"][()], dtype=np.float64) if "opt_pos" in g else None,
        movement=np.asarray(g["movement"][()], dtype=bool).ravel(),
        sampling_rate_hz=float(np.asarray(rate).ravel()[0]),
        description=str(info.get("description", "")),
        groups=tuple(info.get("groups", ())),
    )


def load_broad(path: str | Path, names: list[str] | None = None) -> list[BroadTrial]:
    """All trials under ``path`` (see module doc); ``names`` keeps only trials whose name contains one of them."""
    import h5py

    files = find_broad_files(path)
    meta_file = (Path(path) if Path(path).is_dir() else Path(path).parent) / "trials.json"
    meta = {}
    if meta_file.is_file():
        try:
            meta = json.loads(meta_file.read_text()).get("trials", {})
        except (ValueError, AttributeError):
            meta = {}
    trials: list[BroadTrial] = []
    for f in files:
        try:
            h = h5py.File(f, "r")
        except OSError as e:
            raise ValueError(f"cannot read {f} as HDF5: {e}") from e
        with h:
            if "imu_gyr" in h:
                trials.append(_read_group(h, f.stem, meta))
            else:
                found = []
                h.visititems(lambda n, o: found.append(n) if hasattr(o, "keys") and "imu_gyr" in o else None)
                for n in sorted(found):
                    trials.append(_read_group(h[n], f"{f.stem}/{n}", {k: v for k, v in meta.items()} |
                                              {f"{f.stem}/{n}": meta.get(n.split('/')[-1], {})}))
    if names:
        trials = [t for t in trials if any(n in t.name for n in names)]
    if not trials:
        raise ValueError(f"no BROAD trials found under {path}")
    return trials
