"""Reader for "Activity Recognition from a Single Chest-Mounted Accelerometer" (UCI; Casale et al. 2011/2012).

One CSV per participant (``<n>.csv``), no header, columns ``seq, x, y, z, label``; x/y/z are **uncalibrated**
12-bit ADC counts (0..4095) at 52 Hz; labels 1 working at computer (sitting), 2 standing up / walking / stairs
(mixed), 3 standing, 4 walking, 5 up/down stairs, 6 walking and talking, 7 talking while standing, 0 unlabelled.

Conversion to StrideLab units (m/s²): ``(counts − 2048) × k`` with the ADC mid-scale as the nominal zero-g
level and ``k`` chosen so that the median norm over still seconds is 1 g. The estimators' auto-calibration
refines gain and offset when the still orientations allow it. Axes stay as stored (y reads ≈ +1 g upright).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["UciParticipant", "load_uci_participant", "load_uci_chest", "counts_to_m_s2", "SAMPLING_RATE_HZ", "LABEL_TO_CLASS"]

SAMPLING_RATE_HZ = 52.0
#: UCI label code -> index of stridelab.estimators.activity.evaluation.SCORED_CLASSES (sitting, standing, walking, stairs);
#: 2 (mixed standing up / walking / stairs) and 0 (unlabelled) are not scored
LABEL_TO_CLASS = {1: 0, 3: 1, 7: 1, 4: 2, 6: 2, 5: 3}
ADC_MIDSCALE = 2048.0
G = 9.80665


@dataclass(frozen=True)
class UciParticipant:
    """One participant file: ``acc`` (N, 3) m/s² (converted), ``counts`` (N, 3) raw ADC counts, ``labels`` (N,)
    int, ``counts_per_g`` the conversion used, ``participant`` the file stem."""
    participant: str
    acc: np.ndarray
    counts: np.ndarray
    labels: np.ndarray
    counts_per_g: float
    sampling_rate_hz: float = SAMPLING_RATE_HZ


def counts_to_m_s2(counts: np.ndarray, fs: float = SAMPLING_RATE_HZ, midscale: float = ADC_MIDSCALE) -> tuple[np.ndarray, float]:
    """(acc m/s², counts per g): zero-g at ``midscale``, scale from the median norm of still 1-s windows."""
    c = np.asarray(counts, dtype=np.float64) - midscale
    w = max(1, int(fs))
    nw = c.shape[0] // w
    if nw == 0:
        raise ValueError("UCI chest file too short (less than one second of samples)")
    blk = c[: nw * w].reshape(nw, w, 3)
    sd = blk.std(axis=1).max(axis=1)
    norm = np.linalg.norm(blk.mean(axis=1), axis=1)
    still = sd <= np.percentile(sd, 30)
    cpg = float(np.median(norm[still]))
    if not np.isfinite(cpg) or cpg <= 0:
        raise ValueError("cannot scale the UCI counts: no still second with a non-zero mean")
    return c * (G / cpg), cpg


def load_uci_participant(path: Path | str) -> UciParticipant:
    """Read one ``<n>.csv``; raises ``ValueError`` naming the file when it is not in the UCI format."""
    p = Path(path)
    try:
        d = np.loadtxt(p, delimiter=",", ndmin=2)
    except (OSError, ValueError) as e:
        raise ValueError(f"{p}: not a UCI chest CSV (expected 'seq,x,y,z,label' numeric rows): {e}") from e
    if d.ndim != 2 or d.shape[1] != 5 or d.shape[0] < 2:
        raise ValueError(f"{p}: expected 5 columns 'seq,x,y,z,label', got shape {d.shape}")
    counts = d[:, 1:4]
    if not np.isfinite(d).all():
        raise ValueError(f"{p}: non-numeric or non-finite values (nan/inf); every row must be 'seq,x,y,z,label'")
    if counts.min() < 0 or counts.max() > 4095:
        raise ValueError(f"{p}: x/y/z outside the 12-bit ADC range 0..4095 (not UCI counts?)")
    acc, cpg = counts_to_m_s2(counts)
    return UciParticipant(participant=p.stem, acc=acc, counts=counts, labels=d[:, 4].astype(np.int64),
                          counts_per_g=cpg)


def load_uci_chest(directory: Path | str) -> list[UciParticipant]:
    """Every ``*.csv`` in ``directory`` sorted by participant number; ``ValueError`` if there is none."""
    d = Path(directory)
    files = sorted(d.glob("*.csv"), key=lambda f: (0, int(f.stem)) if f.stem.isdigit() else (1, f.stem))
    if not files:
        raise ValueError(f"no UCI chest CSV files (*.csv) in {d}")
    return [load_uci_participant(f) for f in files]
