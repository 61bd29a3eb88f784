"""Reader for C3D files of optical markers (ezc3d), the accepted alternative to MCAP reference poses.

Returns marker trajectories in metres with NaN for occluded samples (C3D residual < 0 or all-zero
coordinates), the frame rate and the labels. Units are taken from ``POINT:UNITS`` (mm, cm, m).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

_UNIT_TO_M = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "dm": 0.1, "in": 0.0254}


class C3DFormatError(ValueError):
    """The file is not a readable C3D file of markers (one-line reason)."""


@dataclass(frozen=True)
class MarkerData:
    """Optical markers of one C3D file.

    labels: marker names; pos_m: (N, M, 3) positions in metres in the lab frame (NaN = missing);
    rate_hz: frame rate; first_frame: index of the first frame in the capture; units: the unit
    stated in the file (converted to metres in ``pos_m``).
    """
    labels: tuple[str, ...]
    pos_m: np.ndarray
    rate_hz: float
    first_frame: int
    units: str

    @property
    def t_s(self) -> np.ndarray:
        """(N,) frame times in seconds from the first frame of the capture."""
        return (self.first_frame + np.arange(self.pos_m.shape[0])) / self.rate_hz

    def marker(self, label: str) -> np.ndarray:
        """(N, 3) trajectory of one marker by label."""
        try:
            return self.pos_m[:, self.labels.index(label)]
        except ValueError:
            raise KeyError(f"marker {label!r} not in the file; labels: {', '.join(self.labels)}") from None


def read_c3d_markers(path: str | Path) -> MarkerData:
    """Read the markers of a C3D file (ezc3d); raises :class:`C3DFormatError` on unreadable files."""
    import ezc3d
    path = Path(path)
    if not path.is_file():
        raise C3DFormatError(f"{path}: no such file")
    try:
        c = ezc3d.c3d(str(path))
    except Exception as e:  # ezc3d raises RuntimeError/IOError with long messages
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise C3DFormatError(f"{path.name}: not a readable C3D file ({first})") from None
    point = c["parameters"]["POINT"]
    labels = tuple(str(s).strip() for s in point["LABELS"]["value"])
    units = str(point["UNITS"]["value"][0]).strip().lower() if "UNITS" in point and len(point["UNITS"]["value"]) else "mm"
    if units not in _UNIT_TO_M:
        raise C3DFormatError(f"{path.name}: unknown POINT:UNITS {units!r} (expected mm, cm or m)")
    rate = float(np.ravel(point["RATE"]["value"])[0]) if "RATE" in point else float(c["header"]["points"]["frame_rate"])
    if not rate > 0:
        raise C3DFormatError(f"{path.name}: point rate is {rate}, expected > 0")
    pts = np.asarray(c["data"]["points"], float)            # (4, M, N)
    xyz = np.transpose(pts[:3], (2, 1, 0)) * _UNIT_TO_M[units]
    missing = np.all(pts[:3] == 0, axis=0).T
    meta = c["data"].get("meta_points", {})
    if "residuals" in meta and np.size(meta["residuals"]):
        missing |= (np.asarray(meta["residuals"])[0].T < 0)
    xyz[missing] = np.nan
    return MarkerData(labels=labels[: xyz.shape[1]], pos_m=xyz, rate_hz=rate,
                      first_frame=int(c["header"]["points"]["first_frame"]), units=units)


def cluster_orientation(markers: MarkerData, labels: tuple[str, str, str]) -> np.ndarray:
    """(N, 3, 3) orientation of a rigid 3-marker cluster (plate frame, thesis §3 validation):
    x = m1→m2, z = x × (m1→m3), y = z × x (columns, lab frame)."""
    a, b, c = (markers.marker(lb) for lb in labels)
    x = b - a
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z = np.cross(x, c - a)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)
