"""Orientation error against a reference (BROAD protocol; Laidig et al. 2021, spec thesis §8 A9-ii).

The error quaternion is taken in the earth frame, ``e = q_est ⊗ q_ref*`` (both sensor→ENU), and split
into a rotation about ENU z (heading) and the rest (inclination):

* total       = 2·acos|e_w|                 (quaternion angle distance)
* heading     = 2·atan(|e_z| / |e_w|)       (angle of the z-twist of e)
* inclination = 2·acos √(e_w² + e_z²)       (angle of the swing of e, i.e. tilt error)

Errors are RMS over a mask (BROAD: ``movement``) in degrees; samples where either quaternion is NaN
are left out. No alignment or heading offset is removed: a 9D estimate is scored against the ENU
reference as it stands.

Lab sessions (optical segment poses, :func:`segment_alignment`): the reference gives the *segment*
(marker cluster) orientation in the *lab* frame, the IMU estimate the *sensor* orientation in ENU. Two
constant rotations separate them — the sensor's mounting on the segment and the lab frame's heading in
ENU (the lab's z axis is vertical) — and both are estimated from the whole trial before scoring, as in
the BROAD paper's evaluation of sensors with an unknown mounting. Inclination errors are unaffected by the
heading offset; total and heading errors are relative to the trial's mean heading offset.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from stridelab.estimators.quaternion import quat_conj, quat_mul, quat_normalize

__all__ = ["OrientationError", "orientation_error_deg", "orientation_rmse_deg", "pooled_rmse", "segment_alignment",
           "align_reference"]


def orientation_error_deg(q_est: np.ndarray, q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample (total, heading, inclination) errors in degrees, each (N,); NaN where an input is NaN."""
    q_est = np.asarray(q_est, dtype=float)
    q_ref = np.asarray(q_ref, dtype=float)
    if q_est.shape != q_ref.shape or q_est.shape[-1] != 4:
        raise ValueError(f"q_est {q_est.shape} and q_ref {q_ref.shape} must both be (N, 4) [w x y z]")
    e = quat_mul(q_est, quat_conj(q_ref))
    e = e / np.linalg.norm(e, axis=-1, keepdims=True)
    w = np.abs(e[..., 0])
    z = np.abs(e[..., 3])
    total = np.degrees(2.0 * np.arccos(np.clip(w, 0.0, 1.0)))
    heading = np.degrees(2.0 * np.arctan2(z, w))
    inclination = np.degrees(2.0 * np.arccos(np.clip(np.sqrt(e[..., 0] ** 2 + e[..., 3] ** 2), 0.0, 1.0)))
    return total, heading, inclination


@dataclass(frozen=True)
class OrientationError:
    """RMS errors in degrees over the scored samples, and how many samples were scored."""
    total_rmse_deg: float
    heading_rmse_deg: float
    inclination_rmse_deg: float
    n_scored: int


def orientation_rmse_deg(q_est: np.ndarray, q_ref: np.ndarray, mask: np.ndarray | None = None) -> OrientationError:
    """RMS (total, heading, inclination) error in degrees over ``mask`` (bool (N,); None = all samples).

    Raises ValueError when no sample is left to score (all masked or NaN).
    """
    total, heading, incl = orientation_error_deg(q_est, q_ref)
    ok = np.isfinite(total)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != total.shape:
            raise ValueError(f"mask {mask.shape} must match the quaternions' sample count {total.shape}")
        ok &= mask
    n = int(ok.sum())
    if n == 0:
        raise ValueError("no sample to score: every sample is masked out or NaN")

    def rms(x):
        return float(np.sqrt(np.mean(x[ok] ** 2)))

    return OrientationError(rms(total), rms(heading), rms(incl), n)


def pooled_rmse(parts: list[OrientationError]) -> OrientationError:
    """The RMS errors of several scored pieces (recordings of one session) taken together: the mean squares
    weighted by the scored sample counts, i.e. the figure :func:`orientation_rmse_deg` gives on the pieces
    concatenated."""
    n = sum(p.n_scored for p in parts)
    if n == 0:
        raise ValueError("no sample to score: every piece is empty")

    def pool(k):
        return float(np.sqrt(sum(p.n_scored * getattr(p, k) ** 2 for p in parts) / n))

    return OrientationError(pool("total_rmse_deg"), pool("heading_rmse_deg"), pool("inclination_rmse_deg"), n)


def _top_eigvec(a: np.ndarray) -> np.ndarray:
    """The chordal L2 mean of unit quaternions q from their scatter Σ q qᵀ: its eigenvector with the largest
    eigenvalue, sign chosen with w ≥ 0. ``a`` (4, 4), or a stack (k, 4, 4): NumPy's ``eigh`` calls LAPACK once
    per matrix either way, so a stacked matrix gets the vector it gets alone, bit for bit."""
    w, v = np.linalg.eigh(a)
    if a.ndim == 2:
        m = v[:, -1]
        return m if m[0] >= 0 else -m
    return [m if m[0] >= 0 else -m for m in v[:, :, -1]]


#: ``q * _CONJ`` = ``quat_conj(q)`` without its argument checks (the alternation's inner loop)
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _twist(g: np.ndarray) -> np.ndarray:
    """``quat_normalize([g_w, 0, 0, g_z])``, the twist of ``g`` about the vertical: with two zero components the
    squared norm is g_w² + g_z² in any order of summation, so this equals the general path bit for bit."""
    w, z = float(g[0]), float(g[3])
    n = math.sqrt(w * w + z * z)                # IEEE square root, correctly rounded: np.sqrt's value
    if n == 0.0:
        return quat_normalize(np.array([w, 0.0, 0.0, z]))           # raises: a zero-norm quaternion
    return np.array([w / n, 0.0, 0.0, z / n])


#: entries of L(p) (``_LEFT``) and R(q) (``_RIGHT``): row by row, (component of the quaternion, sign)
_LEFT = (((0, 1), (1, -1), (2, -1), (3, -1)), ((1, 1), (0, 1), (3, -1), (2, 1)),
         ((2, 1), (3, 1), (0, 1), (1, -1)), ((3, 1), (2, -1), (1, 1), (0, 1)))
_RIGHT = (((0, 1), (1, -1), (2, -1), (3, -1)), ((1, 1), (0, 1), (3, 1), (2, -1)),
          ((2, 1), (3, -1), (0, 1), (1, 1)), ((3, 1), (2, 1), (1, -1), (0, 1)))


def _matrices(p: np.ndarray, entries) -> np.ndarray:
    """(N, 4, 4) C-ordered matrices whose entry (r, c) is ± a component of each quaternion of ``p`` (N, 4): each
    entry is a copy or a negation, so the values do not depend on how the array is filled."""
    out = np.empty(p.shape[:-1] + (4, 4))
    for r, row in enumerate(entries):
        for c, (k, sign) in enumerate(row):
            if sign > 0:
                out[..., r, c] = p[..., k]
            else:
                np.negative(p[..., k], out=out[..., r, c])
    return out


def _left(p: np.ndarray) -> np.ndarray:
    """(N, 4, 4) matrices L(p) with ``p ⊗ q = L(p) q`` (Hamilton, [w x y z]); L(p)ᵀ = L(p*)."""
    return _matrices(p, _LEFT)


def _right(q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) matrices R(q) with ``p ⊗ q = R(q) p``."""
    return _matrices(q, _RIGHT)


#: byte strides (a, j, b, k) of the (4, 4, 4, 4) float64 sums ``_Scatter`` forms: j fastest, then a, k, b
_CONTRACT_STRIDES = (32, 8, 512, 128)


@njit(cache=True)
def _contract(t, c):
    """``np.einsum("ajbk,j,k->ab", t, c, c)`` for ``t`` laid out as :data:`_CONTRACT_STRIDES`, bit for bit:
    einsum walks the reduction in the operand's memory order, j inside k, each j-run summed from 0 in its own
    accumulator ((t·c_j)·c_k) and added to the output (NumPy 2.2; checked against np.einsum by the tests). One
    call costs ~1 µs against einsum's ~3.6 µs: the alternation makes two per iteration. The result is in
    Fortran order, as einsum's: the scatter is symmetric only to rounding, and BLAS reads ``m @ a @ m`` in
    memory order, so a C-ordered copy gave residual costs differing in the last bit (and another start won)."""
    out = np.empty((4, 4))                   # out[b, a]: returned transposed, i.e. Fortran order
    for a in range(4):
        for b in range(4):
            s = 0.0
            for k in range(4):
                acc = 0.0
                for j in range(4):
                    acc += t[a, j, b, k] * c[j] * c[k]
                s = s + acc
            out[b, a] = s
    return out.T


class _Scatter:
    """The alternation's two scatter matrices as quadratic forms, summed over the samples once.

    With ``e`` = q_est and ``r`` = q_ref (rows where both are finite, n of them):
    ``(h ⊗ r)* ⊗ e = L(r*) R(e) h* = M h*`` and ``e ⊗ (r ⊗ m)* = L(e) R(r*) m* = P m*``, so the matrices whose
    top eigenvectors are the chordal means, Σ (M c)(M c)ᵀ and Σ (P d)(P d)ᵀ, are the 4-index sums
    Σ M[a,j] M[b,k] (and the same for P) contracted with c ⊗ c: 16 numbers per sample summed once instead of
    four quaternion products per sample in every iteration. The residual is a quadratic form too:
    ⟨h ⊗ r ⊗ m, e⟩ = ⟨m, (h ⊗ r)* ⊗ e⟩ (L(p)ᵀ = L(p*)), so Σ ⟨fit, e⟩² = mᵀ A(h) m."""

    def __init__(self, q_est: np.ndarray, q_ref: np.ndarray):
        ok = np.all(np.isfinite(q_est), axis=1) & np.all(np.isfinite(q_ref), axis=1)
        e, r = q_est[ok], q_ref[ok]
        self.n = len(e)
        if self.n == 0:
            raise ValueError("no finite quaternion to average")
        rc = quat_conj(r)
        m = _left(rc) @ _right(e)
        p = _left(e) @ _right(rc)
        self._tm = np.einsum("iaj,ibk->ajbk", m, m, optimize=True)
        self._tp = np.einsum("iaj,ibk->ajbk", p, p, optimize=True)

        # the sums as einsum laid them out (optimize=True: a transposed tensordot): :func:`_contract` adds in
        # the order np.einsum uses for that layout; any other layout keeps np.einsum
        self._kernel = self._tm.strides == self._tp.strides == _CONTRACT_STRIDES

    def _form(self, t: np.ndarray, c: np.ndarray) -> np.ndarray:
        return _contract(t, c) if self._kernel else np.einsum("ajbk,j,k->ab", t, c, c)

    def mount_scatter(self, h: np.ndarray) -> np.ndarray:
        return self._form(self._tm, h * _CONJ)

    def heading_scatter(self, mount: np.ndarray) -> np.ndarray:
        return self._form(self._tp, mount * _CONJ)

    def mount(self, h: np.ndarray) -> np.ndarray:
        return _top_eigvec(self.mount_scatter(h))

    def heading(self, mount: np.ndarray) -> np.ndarray:
        return _top_eigvec(self.heading_scatter(mount))


def _alternate(sc: _Scatter, h: np.ndarray, iterations: int,
               tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray, float]:
    """Alternating chordal-mean least squares from the heading ``h``; returns (h, mount, cost), cost = mean
    chordal residual 1 − ⟨q_est, h ⊗ q_ref ⊗ mount⟩² (0 = exact fit)."""
    h = np.asarray(h, float)
    for _ in range(iterations):         # :func:`_alternate_many`'s steps for one start, without its bookkeeping
        new = _twist(sc.heading(sc.mount(h)))
        done = 1.0 - abs(float(np.dot(new, h))) < tol
        h = new
        if done:
            break
    a = sc.mount_scatter(h)
    mount = _top_eigvec(a)
    return h, mount, float(1.0 - mount @ a @ mount / sc.n)


def _alternate_many(sc: _Scatter, starts: list[np.ndarray], iterations: int,
                    tol: float = 1e-12) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """:func:`_alternate` from each of ``starts``, each start stopping on its own; the starts' 4×4 eigenproblems
    of a step go to LAPACK in one stacked call (the same vectors as one call each: :func:`_top_eigvec`)."""
    hs = [np.asarray(h, float) for h in starts]
    active = list(range(len(hs)))
    for _ in range(iterations):
        if not active:
            break
        mounts = _top_eigvecs([sc.mount_scatter(hs[i]) for i in active])
        still = []
        for i, g in zip(active, _top_eigvecs([sc.heading_scatter(m) for m in mounts])):
            new = _twist(g)                                           # its twist about the vertical
            if not 1.0 - abs(float(np.dot(new, hs[i]))) < tol:
                still.append(i)
            hs[i] = new
        active = still
    scatters = [sc.mount_scatter(h) for h in hs]
    return [(h, mount, float(1.0 - mount @ a @ mount / sc.n))
            for h, a, mount in zip(hs, scatters, _top_eigvecs(scatters))]


def _top_eigvecs(scatters: list[np.ndarray]) -> list[np.ndarray]:
    """:func:`_top_eigvec` of each matrix: one LAPACK batch for several, the plain call for one."""
    return [_top_eigvec(scatters[0])] if len(scatters) == 1 else _top_eigvec(np.stack(scatters))


def segment_alignment(q_est: np.ndarray, q_ref: np.ndarray, *, iterations: int = 200,
                      starts: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """The two constant rotations between an IMU estimate and an optical segment reference.

    q_est (N, 4): sensor→ENU; q_ref (N, 4): segment→lab (both [w x y z], NaN rows ignored). Model
    ``q_est ≈ q_heading ⊗ q_ref ⊗ q_mount`` with ``q_heading`` a rotation about the vertical (lab→ENU) and
    ``q_mount`` the sensor's orientation on the segment (sensor→segment). Alternating chordal-mean least
    squares. The alternation converges slowly when the lab's heading is far from the start (on the gaitmap walk,
    lab x vs the IMU's ENU heading ≈ 150°: 38° total error left after 10 iterations from identity, 3.0° at
    convergence), so it starts from ``starts`` headings evenly spaced over 360°, keeps the one with the lowest
    residual after 5 iterations and iterates it to convergence (at most ``iterations``). The per-sample sums
    are formed once (:class:`_Scatter`), so an iteration costs the same for any trial length. Returns
    ``(q_heading, q_mount)``.
    """
    q_est = np.asarray(q_est, float)
    q_ref = np.asarray(q_ref, float)
    if q_est.shape != q_ref.shape or q_est.shape[-1] != 4:
        raise ValueError(f"q_est {q_est.shape} and q_ref {q_ref.shape} must both be (N, 4) [w x y z]")
    sc = _Scatter(q_est, q_ref)
    best = None
    halves = [np.pi * k / max(1, starts) for k in range(max(1, starts))]   # half the heading angle
    for h, _, cost in _alternate_many(sc, [np.array([np.cos(a), 0.0, 0.0, np.sin(a)]) for a in halves], 5):
        if best is None or cost < best[1]:
            best = (h, cost)
    h, mount, _ = _alternate(sc, best[0], iterations)
    return h, mount


def align_reference(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """The reference mapped onto the estimate's frames (sensor→ENU), ready for :func:`orientation_rmse_deg`."""
    h, mount = segment_alignment(q_est, q_ref)
    return quat_mul(quat_mul(np.broadcast_to(h, q_ref.shape), q_ref), np.broadcast_to(mount, q_ref.shape))
