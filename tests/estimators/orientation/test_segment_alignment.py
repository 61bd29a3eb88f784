"""Scoring IMU orientation against optical segment poses: mounting and lab heading are recovered."""
from __future__ import annotations

import numpy as np
import pytest

from stridelab.estimators.orientation.evaluation import align_reference, orientation_rmse_deg, segment_alignment
from stridelab.estimators.quaternion import quat_from_axis_angle, quat_from_rotvec, quat_mul
from tests.estimators.orientation.test_dcf import _moving


def _angle_deg(a, b):
    return np.degrees(2 * np.arccos(min(1.0, abs(float(np.dot(a, b))))))


def test_mounting_and_heading_recovered_and_error_scored():
    rng = np.random.default_rng(4)
    _, _, _, q_seg = _moving(n=3000, seed=2)                                 # segment -> lab
    mount = quat_from_axis_angle([0.3, -1.0, 0.4], np.radians(35.0))        # sensor -> segment
    heading = quat_from_axis_angle([0, 0, 1], np.radians(-70.0))             # lab -> ENU
    noise = quat_from_rotvec(rng.normal(0, np.radians(1.0), (3000, 3)))     # 1° per axis estimation error
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), noise)
    h, m = segment_alignment(q_est, q_seg)
    assert _angle_deg(h, heading) < 0.2 and _angle_deg(m, mount) < 0.2
    err = orientation_rmse_deg(q_est, align_reference(q_est, q_seg))
    assert err.total_rmse_deg == pytest.approx(np.sqrt(3) * 1.0, rel=0.1)    # the injected error, not more
    assert abs(h[1]) < 1e-12 and abs(h[2]) < 1e-12                          # heading is a rotation about z only


def test_tilted_lab_is_not_absorbed_into_the_heading():
    """A tilt between the frames cannot be explained by a heading rotation: it stays in the error."""
    _, _, _, q_seg = _moving(n=2000, seed=5)
    tilt = quat_from_axis_angle([1, 0, 0], np.radians(5.0))
    q_est = quat_mul(tilt, q_seg)
    err = orientation_rmse_deg(q_est, align_reference(q_est, q_seg))
    assert err.inclination_rmse_deg > 2.0


@pytest.mark.parametrize("heading_deg", [150.0, -165.0, 95.0])
def test_a_lab_heading_far_from_the_imus_is_found(heading_deg):
    """The alternating fit converges slowly from a far start (the gaitmap walk: ≈150°, 38° error left after 10
    iterations from identity); the multi-start finds it."""
    rng = np.random.default_rng(7)
    _, _, _, q_seg = _moving(n=3000, seed=3)
    mount = quat_from_axis_angle([1.0, 0.2, -0.3], np.radians(100.0))
    heading = quat_from_axis_angle([0, 0, 1], np.radians(heading_deg))
    noise = quat_from_rotvec(rng.normal(0, np.radians(1.0), (3000, 3)))
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), noise)
    h, m = segment_alignment(q_est, q_seg)
    assert _angle_deg(h, heading) < 0.3 and _angle_deg(m, mount) < 0.3
    assert orientation_rmse_deg(q_est, align_reference(q_est, q_seg)).total_rmse_deg < 2.0


def _literal_alternation(q_est, q_ref, h, iterations, tol=1e-12):
    """The alternation written per sample (four quaternion products and a 4x4 scatter per iteration), as
    segment_alignment computed it before its sums were formed once."""
    from stridelab.estimators.quaternion import quat_conj, quat_normalize

    def mean(q):
        q = q[np.all(np.isfinite(q), axis=1)]
        w, v = np.linalg.eigh(q.T @ q)
        m = v[:, -1]
        return m if m[0] >= 0 else -m
    for _ in range(iterations):
        mount = mean(quat_mul(quat_conj(quat_mul(h, q_ref)), q_est))
        g = mean(quat_mul(q_est, quat_conj(quat_mul(q_ref, mount))))
        new = quat_normalize(np.array([g[0], 0.0, 0.0, g[3]]))
        done = 1.0 - abs(float(np.dot(new, h))) < tol
        h = new
        if done:
            break
    mount = mean(quat_mul(quat_conj(quat_mul(h, q_ref)), q_est))
    fit = quat_mul(quat_mul(np.broadcast_to(h, q_ref.shape), q_ref), np.broadcast_to(mount, q_ref.shape))
    ok = np.all(np.isfinite(fit), axis=1) & np.all(np.isfinite(q_est), axis=1)
    return h, mount, float(np.mean(1.0 - np.sum(fit[ok] * q_est[ok], axis=1) ** 2))


@pytest.mark.parametrize("heading_deg, iterations", [(-70.0, 5), (150.0, 5), (150.0, 200), (20.0, 3)])
def test_sums_formed_once_equal_the_per_sample_alternation(heading_deg, iterations):
    """Same heading, mounting and residual as the alternation computed sample by sample, with NaN rows in
    either input and a 5° error that leaves a residual, from a start far from the answer."""
    from stridelab.estimators.orientation.evaluation import _alternate, _Scatter
    rng = np.random.default_rng(11)
    _, _, _, q_seg = _moving(n=2500, seed=4)
    mount = quat_from_axis_angle([0.5, 1.0, -0.2], np.radians(60.0))
    heading = quat_from_axis_angle([0, 0, 1], np.radians(heading_deg))
    noise = quat_from_rotvec(rng.normal(0, np.radians(5.0), (2500, 3)))
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), noise)
    q_est[rng.choice(2500, 200, replace=False)] = np.nan
    q_seg = q_seg.copy()
    q_seg[rng.choice(2500, 150, replace=False), 2] = np.nan
    start = np.array([1.0, 0.0, 0.0, 0.0])
    h0, m0, c0 = _literal_alternation(q_est, q_seg, start, iterations)
    h1, m1, c1 = _alternate(_Scatter(q_est, q_seg), start, iterations)
    assert np.allclose(h1, h0, atol=1e-9) and np.allclose(m1, m0, atol=1e-9)
    assert c1 == pytest.approx(c0, rel=1e-9, abs=1e-12) and c0 > 1e-4


def test_no_finite_pair_is_refused():
    q = np.full((10, 4), np.nan)
    with pytest.raises(ValueError, match="no finite quaternion"):
        segment_alignment(q, np.tile([1.0, 0, 0, 0], (10, 1)))


def _scatter_case(seed: int, n: int = 400):
    from stridelab.estimators.orientation.evaluation import _Scatter
    rng = np.random.default_rng(seed)
    _, _, _, q_seg = _moving(n=n, seed=seed)
    mount = quat_from_axis_angle(rng.normal(size=3), rng.uniform(0, np.pi))
    heading = quat_from_axis_angle([0, 0, 1], rng.uniform(-np.pi, np.pi))
    q_est = quat_mul(quat_mul(quat_mul(heading, q_seg), mount), quat_from_rotvec(rng.normal(0, 0.05, (n, 3))))
    q_est[rng.choice(n, 10, replace=False)] = np.nan
    return _Scatter(q_est, q_seg), rng


def test_the_contraction_kernel_is_einsum_bit_for_bit():
    """``_contract`` replaces ``np.einsum("ajbk,j,k->ab", ...)`` in the alternation's inner loop: identical values
    and layout (Fortran order, as einsum returns it) on the tensors ``_Scatter`` forms."""
    from stridelab.estimators.orientation.evaluation import _contract
    for seed in range(8):
        sc, rng = _scatter_case(seed)
        assert sc._kernel
        for t in (sc._tm, sc._tp):
            for c in [rng.normal(size=4) for _ in range(25)] + [np.array([0.6, -0.0, -0.0, -0.8])]:
                ref = np.einsum("ajbk,j,k->ab", t, c, c)
                out = _contract(t, c)
                assert np.array_equal(out, ref) and out.strides == ref.strides


def test_stacked_starts_equal_one_alternation_each_bit_for_bit():
    """``segment_alignment`` runs its 12 starts together (one stacked ``eigh`` per step); each start's heading,
    mounting and cost are those of its own ``_alternate``, to the last bit, including starts that stop early."""
    from stridelab.estimators.orientation.evaluation import _alternate, _alternate_many
    for seed in range(6):
        sc, _ = _scatter_case(seed)
        starts = [np.array([np.cos(a), 0.0, 0.0, np.sin(a)]) for a in np.pi * np.arange(12) / 12]
        together = _alternate_many(sc, starts, 40)
        for start, (h, m, c) in zip(starts, together):
            h1, m1, c1 = _alternate(sc, start, 40)
            assert np.array_equal(h, h1) and np.array_equal(m, m1) and c == c1


def test_product_matrices_are_the_hamilton_product():
    """``_left(p) q = p ⊗ q`` and ``_right(q) p = p ⊗ q``; L(p)ᵀ = L(p*) exactly (every entry is ± a component)."""
    from stridelab.estimators.orientation.evaluation import _left, _right
    from stridelab.estimators.quaternion import quat_conj
    rng = np.random.default_rng(9)
    p, q = rng.normal(size=(50, 4)), rng.normal(size=(50, 4))
    ref = quat_mul(p, q)
    assert np.allclose(np.einsum("nij,nj->ni", _left(p), q), ref, rtol=0, atol=1e-12)
    assert np.allclose(np.einsum("nij,nj->ni", _right(q), p), ref, rtol=0, atol=1e-12)
    assert np.array_equal(np.swapaxes(_left(p), 1, 2), _left(quat_conj(p)))
    assert np.array_equal(np.swapaxes(_right(q), 1, 2), _right(quat_conj(q)))
