"""Leave-one-group-out choice of a configuration from a small grid (issue 15, point 4).

``loss[g, c]`` = the loss of configuration c on group g (a trial, a subject, a walk). For each group g the
configuration minimising ``aggregate`` of the *other* groups' losses is chosen and its loss on g is the held-out
(cross-validated) loss; the in-sample choice minimises over all groups. NaN losses count as ``nan_loss``.
"""
from __future__ import annotations

import numpy as np

__all__ = ["logo_choose"]


def logo_choose(loss: np.ndarray, *, aggregate=np.mean, nan_loss: float = np.inf) -> dict:
    """``{"held_out_choice": (G,) int, "held_out_loss": (G,), "in_sample_choice": int}`` (see module docstring)."""
    L = np.where(np.isfinite(loss), loss, nan_loss).astype(float)
    G, C = L.shape
    choice = np.empty(G, np.int64)
    held = np.empty(G)
    for g in range(G):
        rest = np.delete(L, g, axis=0)
        score = np.array([aggregate(rest[:, c]) for c in range(C)]) if G > 1 else L[g]
        choice[g] = int(np.argmin(score))
        held[g] = loss[g, choice[g]]
    ins = int(np.argmin([aggregate(L[:, c]) for c in range(C)]))
    return {"held_out_choice": choice, "held_out_loss": held, "in_sample_choice": ins}
