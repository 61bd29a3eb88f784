"""C3D optical markers via ezc3d: a file written by the test reads back in metres."""
import numpy as np
import pytest

ezc3d = pytest.importorskip("ezc3d")

from stridelab.pipeline.formats.c3d import C3DFormatError, cluster_orientation, read_c3d_markers  # noqa: E402


def _write(path, xyz_mm, labels, rate, missing=None):
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, len(labels), xyz_mm.shape[0]))
    pts[:3] = np.transpose(xyz_mm, (2, 1, 0))
    if missing is not None:
        pts[:3, missing[1], missing[0]] = np.nan
    c["data"]["points"] = pts
    c.write(str(path))


def test_roundtrip(tmp_path):
    rng = np.random.default_rng(0)
    n, labels = 250, ("P1", "P2", "P3", "LASI")
    xyz = rng.normal(0, 300, (n, 4, 3))
    _write(tmp_path / "t.c3d", xyz, labels, 100.0, missing=(10, 2))
    m = read_c3d_markers(tmp_path / "t.c3d")
    assert m.labels == labels and m.rate_hz == 100.0 and m.units == "mm"
    assert m.pos_m.shape == (n, 4, 3)
    ok = np.ones((n, 4), bool)
    ok[10, 2] = False
    np.testing.assert_allclose(m.pos_m[ok], xyz[ok] / 1000.0, atol=1e-6)
    assert np.all(np.isnan(m.pos_m[10, 2]))
    np.testing.assert_allclose(m.marker("LASI"), m.pos_m[:, 3])
    assert m.t_s[1] - m.t_s[0] == pytest.approx(0.01)
    R = cluster_orientation(m, ("P1", "P2", "P3"))
    np.testing.assert_allclose(np.einsum("nji,njk->nik", R[ok[:, 2]], R[ok[:, 2]]), np.broadcast_to(np.eye(3), (n - 1, 3, 3)), atol=1e-9)
    with pytest.raises(KeyError, match="not in the file"):
        m.marker("RASI")


def test_bad_files(tmp_path):
    with pytest.raises(C3DFormatError, match="no such file"):
        read_c3d_markers(tmp_path / "nope.c3d")
    (tmp_path / "bad.c3d").write_bytes(b"not a c3d file at all" * 10)
    with pytest.raises(C3DFormatError, match="not a readable C3D"):
        read_c3d_markers(tmp_path / "bad.c3d")
