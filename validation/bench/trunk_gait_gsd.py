"""Gait-sequence detection's slow-walking rule (``TrunkGaitParams.gsd_slow_min_std_m_s2`` / ``gsd_slow_min_autocorr``)
chosen by leave-one-group-out, and what it costs in non-walking (issue 42, point 3: slow and pathological walking).

``stridelab bench trunk-gait-gsd [--voisard DIR] [--mobilised DIR] [--uci DIR] [--json]``

Real data and what counts as walking / non-walking (each recording's whole length is analysed end to end by
``analyse_trunk_gait``; only the gait-sequence constants change between candidates):

* Voisard (L5, 9 subjects, 52 trials): walking = the reference heel strikes' span; non-walking = the standing
  before and after it, more than 1 s away. Contacts scored as ``validation/bench/trunk_gait.py`` scores them.
* Mobilise-D HA-001 (L5, 3 trials): walking = INDIP MicroWB bouts (contacts scored inside them, as the bench);
  non-walking = more than 1 s away from any INDIP or Stereophoto walking bout (Stereophoto has a walk at 131-134 s
  of Test11 that INDIP leaves out).
* UCI chest (chest, 8 participants, about 5 h; ``stridelab.pipeline.formats.uci_chest``): non-walking = the samples
  labelled 1 (working at a computer, seated) more than 1 s from any other label; walking = label 4, whose coverage
  by detected bouts is reported (labels are coarse: no contact reference). The standing labels (3 standing, 7
  talking while standing) are not used as non-walking: the detector before this round already finds walking bouts
  in 24 % of the time labelled 7 and 25 % of label 3 (their SD of the acceleration norm reaches walking values:
  the participants move about), so they measure the labels more than the detector; their figures are printed as
  ``uci_standing_labels``.

Per recording and candidate: contacts (TP / FP / FN, timing) inside the reference walking; **false detections**:
detected contacts and detected walking-bout time inside non-walking time. Groups: the 9 Voisard subjects, HA-001,
the 8 UCI participants (18 groups).

Choice rule (constrained, fixed before looking at the data): the candidates are ordered from most permissive (the
lowest amplitude floor, then the lowest autocorrelation) to off (floor = inf, the detector before this round). In
each fold the most permissive candidate is chosen whose **training** groups show (a) no more false-detection contacts
in non-walking time and (b) no larger contact loss inside reference walking (``trunk_gait.ic_loss``, group mean)
than the detector without the rule. Real slow walking too weak for the strong rule is not in these data (the
slowest real walks, HA-001 at 0.41-0.51 m/s, pass the strong rule), so nothing here rewards sensitivity: the rule
is allowed as far as it costs nothing measurable. The held-out group's figures under its fold's choice are the
cross-validated result. Hand-made slow walks (0.3 m/s, walking aid) from their own model are the check that the
chosen rule finds what the real data cannot show (tests/estimators/trunk_gait/test_gsd_slow.py).
"""
from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

import click

from stridelab.pipeline.console import emit_json, err_console
from stridelab.validation.bench.trunk_gait import (DEFAULT_VOISARD, PROJECT_ROOT, Det, Rec, ic_loss, load_mobilised,
                                                   load_voisard, score)

DEFAULT_MOBILISED = PROJECT_ROOT.parent / "shared" / "data" / "mobilised_lab"
DEFAULT_UCI = PROJECT_ROOT.parent / "shared" / "data" / "uci_chest"
FLOORS = (0.05, 0.06, 0.08, 0.10, 0.12, 0.15)
AUTOCORRS = (0.5, 0.6, 0.7, 0.8)
#: most permissive first, off (the detector before the slow rule) last
CANDIDATES = tuple((f, r) for f in FLOORS for r in AUTOCORRS) + ((float("inf"), 0.6),)
NON_WALK_MARGIN_S = 1.0
UCI_NON_WALKING = (1,)
UCI_STANDING = (3, 7)
UCI_WALKING = 4


@dataclasses.dataclass
class Item:
    name: str
    group: str
    dataset: str               # voisard | mobilised | uci
    acc: np.ndarray
    gyr: np.ndarray
    fs: float
    height_m: float | None
    placement: str
    non_walking: np.ndarray    # (N,) bool per sample
    walking: np.ndarray | None = None   # UCI: label-4 samples
    standing: np.ndarray | None = None  # UCI: labels 3 and 7 (reported, not used)
    rec: Rec | None = None     # Voisard / Mobilise-D: the bench record (contact reference)


def _mask_outside(n: int, fs: float, spans: list[tuple[float, float]]) -> np.ndarray:
    m = np.ones(n, bool)
    for a, b in spans:
        m[max(0, int((a - NON_WALK_MARGIN_S) * fs)):max(0, int(np.ceil((b + NON_WALK_MARGIN_S) * fs)))] = False
    return m


def load_items(voisard: Path | None, mobilised: Path | None, uci: Path | None) -> tuple[list[Item], list]:
    failed: list = []
    items: list[Item] = []
    if voisard is not None and voisard.is_dir():
        for r in load_voisard(voisard, failed, None, foot_reference=False):
            items.append(Item(r.name, r.group, "voisard", r.acc, r.gyr, r.fs, r.height_m, "lower_back",
                              _mask_outside(len(r.acc), r.fs, [(r.ref_ic_s[0], r.ref_ic_s[-1])]), rec=r))
    if mobilised is not None and mobilised.exists():
        from stridelab.pipeline.formats.mobilised import find_mobilised_files, read_mobilised
        stereo = {}
        for f in find_mobilised_files(mobilised):
            for t in read_mobilised(f):
                s = t.reference("Stereophoto", "MicroWB")
                stereo[t.name] = [] if s is None else list(zip(s.start_s, s.end_s))
        for r in load_mobilised(mobilised, failed):
            spans = list(zip(r.ref_bouts["start_s"], r.ref_bouts["end_s"])) + stereo.get(r.trial_group, [])
            items.append(Item(r.name, r.group, "mobilised", r.acc, r.gyr, r.fs, r.height_m, "lower_back",
                              _mask_outside(len(r.acc), r.fs, spans), rec=r))
    if uci is not None and uci.is_dir():
        from stridelab.pipeline.formats.uci_chest import load_uci_chest
        for p in load_uci_chest(uci):
            fs = p.sampling_rate_hz
            other = np.flatnonzero(~np.isin(p.labels, UCI_NON_WALKING))
            spans = [(i / fs, (i + 1) / fs) for i in other]
            non = _mask_outside(len(p.acc), fs, spans) if len(other) else np.ones(len(p.acc), bool)
            items.append(Item(f"uci:{p.participant}", f"uci:{p.participant}", "uci", p.acc, np.zeros_like(p.acc),
                              fs, None, "chest", non, walking=p.labels == UCI_WALKING,
                              standing=np.isin(p.labels, UCI_STANDING)))
    return items, failed


def run_item(it: Item, params) -> dict:
    from stridelab.estimators.trunk_gait import analyse_trunk_gait
    res = analyse_trunk_gait(it.acc, it.gyr, it.fs, placement=it.placement, height_m=it.height_m,
                             leg_length_m=it.rec.leg_length_m if it.rec is not None else None, params=params)
    n = len(it.acc)
    ic_idx = np.clip(np.rint(res.initial_contacts_s * it.fs).astype(np.int64), 0, n - 1)
    in_bout = np.zeros(n, bool)
    for a, b in zip(res.bouts.start_s, res.bouts.end_s):
        in_bout[int(a * it.fs):int(np.ceil(b * it.fs)) + 1] = True
    seq = np.zeros(n, bool)
    for a, b in res.gait_sequences_s:
        seq[int(a * it.fs):int(b * it.fs)] = True
    out = {"fd_contacts": int(it.non_walking[ic_idx].sum()),
           "fd_bout_s": float((in_bout & it.non_walking).sum() / it.fs),
           "fd_sequence_s": float((seq & it.non_walking).sum() / it.fs),
           "non_walking_s": float(it.non_walking.sum() / it.fs), "n_bouts": len(res.bouts)}
    if it.walking is not None:
        out["walking_s"] = float(it.walking.sum() / it.fs)
        out["walking_in_bouts_s"] = float((in_bout & it.walking).sum() / it.fs)
    if it.standing is not None:
        out["standing_s"] = float(it.standing.sum() / it.fs)
        out["standing_in_bouts_s"] = float((in_bout & it.standing).sum() / it.fs)
        out["standing_contacts"] = int(it.standing[ic_idx].sum())
    if it.rec is not None:
        b = res.bouts
        out["det"] = Det(ic_s=res.initial_contacts_s, bouts={"start_s": b.start_s, "end_s": b.end_s,
                                                           "cadence_spm": b.cadence_spm,
                                                           "stride_length_m": b.stride_length_m,
                                                           "walking_speed_m_s": b.walking_speed_m_s})
    return out


def group_figures(items: list[Item], runs: list[dict], idx: list[int]) -> dict:
    fd_c = sum(runs[i]["fd_contacts"] for i in idx)
    fd_b = sum(runs[i]["fd_bout_s"] for i in idx)
    fd_s = sum(runs[i]["fd_sequence_s"] for i in idx)
    non = sum(runs[i]["non_walking_s"] for i in idx)
    out = {"fd_contacts": fd_c, "fd_bout_s": round(fd_b, 2), "fd_sequence_s": round(fd_s, 2),
           "non_walking_h": round(non / 3600, 3)}
    ref = [i for i in idx if items[i].rec is not None]
    if ref:
        s = score([items[i].rec for i in ref], [runs[i]["det"] for i in ref])
        out.update({k: s[k] for k in ("ic_sensitivity", "ic_precision", "ic_timing_mae_ms", "ic_tp", "ic_fp",
                                      "ic_fn", "cadence_mape_pct", "bouts_reference", "bouts_matched")})
        out["ic_loss_ms"] = round(ic_loss(s), 3)
    w = [i for i in idx if items[i].walking is not None]
    if w:
        ws = sum(runs[i]["walking_s"] for i in w)
        out["walking_label_in_bouts"] = round(sum(runs[i]["walking_in_bouts_s"] for i in w) / ws, 4) if ws else None
        ss = sum(runs[i]["standing_s"] for i in w)
        out["uci_standing_labels"] = {"h": round(ss / 3600, 3),
                                      "in_bouts": round(sum(runs[i]["standing_in_bouts_s"] for i in w) / ss, 4),
                                      "contacts": sum(runs[i]["standing_contacts"] for i in w)}
    return out


def choose(groups: list[str], fig: dict) -> dict:
    """Leave-one-group-out with the constrained rule of the module docstring. ``fig[(g, c)]``: group figures."""
    off = len(CANDIDATES) - 1
    ug = sorted(set(groups))

    def admissible(c: int, train: list[str]) -> bool:
        fd = sum(fig[(g, c)]["fd_contacts"] for g in train)
        fd0 = sum(fig[(g, off)]["fd_contacts"] for g in train)
        lg = [g for g in train if "ic_loss_ms" in fig[(g, c)]]
        loss = np.mean([fig[(g, c)]["ic_loss_ms"] for g in lg]) if lg else 0.0
        loss0 = np.mean([fig[(g, off)]["ic_loss_ms"] for g in lg]) if lg else 0.0
        return fd <= fd0 and loss <= loss0 + 1e-9

    held = {}
    for g in ug:
        train = [x for x in ug if x != g] or [g]
        held[g] = next(c for c in range(len(CANDIDATES)) if admissible(c, train))
    ins = next(c for c in range(len(CANDIDATES)) if admissible(c, ug))
    return {"held_out_choice": held, "in_sample_choice": ins}


def _cand(c: int) -> dict:
    f, r = CANDIDATES[c]
    return {"gsd_slow_min_std_m_s2": f if np.isfinite(f) else "inf (off)", "gsd_slow_min_autocorr": r}


def run(voisard: Path | None, mobilised: Path | None, uci: Path | None, show: bool = True) -> dict:
    from stridelab.estimators.trunk_gait import TrunkGaitParams
    items, failed = load_items(voisard, mobilised, uci)
    shipped = TrunkGaitParams()
    runs = {}
    for c, (f, r) in enumerate(CANDIDATES):
        p = dataclasses.replace(shipped, gsd_slow_min_std_m_s2=f, gsd_slow_min_autocorr=r)
        runs[c] = [run_item(it, p) for it in items]
        if show:
            err_console.print(f"  candidate {c + 1}/{len(CANDIDATES)}: {_cand(c)}", highlight=False)
    groups = [it.group for it in items]
    ug = sorted(set(groups))
    fig = {(g, c): group_figures(items, runs[c], [i for i, it in enumerate(items) if it.group == g])
           for g in ug for c in runs}
    ch = choose(groups, fig)
    off = len(CANDIDATES) - 1
    ship_c = next((c for c, (f, r) in enumerate(CANDIDATES)
                   if f == shipped.gsd_slow_min_std_m_s2 and r == shipped.gsd_slow_min_autocorr), None)

    def block(pick) -> dict:
        out = {}
        for ds in ("voisard", "mobilised", "uci"):
            idx = [i for i, it in enumerate(items) if it.dataset == ds]
            if not idx:
                continue
            # pool each group's recordings under its own candidate
            pooled_runs = [runs[pick(items[i].group)][i] for i in range(len(items))]
            out[ds] = group_figures(items, pooled_runs, idx)
        return out

    res = {
        "scheme": "leave-one-group-out over 18 groups (9 Voisard subjects, Mobilise-D HA-001, 8 UCI chest "
                  "participants); per fold the most permissive candidate (lowest floor, then lowest "
                  "autocorrelation) whose training groups have no more false-detection contacts in non-walking "
                  "time and no larger contact loss in reference walking than the rule off",
        "candidates": [_cand(c) for c in range(len(CANDIDATES))],
        "off": block(lambda g: off),
        "cross_validated": block(lambda g: ch["held_out_choice"][g]),
        "in_sample_choice": _cand(ch["in_sample_choice"]),
        "held_out_choice_by_group": {g: _cand(c) for g, c in ch["held_out_choice"].items()},
        "fold_counts": {json.dumps(_cand(c)): sum(1 for v in ch["held_out_choice"].values() if v == c)
                        for c in sorted(set(ch["held_out_choice"].values()))},
        "per_candidate_overall": {json.dumps(_cand(c)): {
            "fd_contacts": sum(fig[(g, c)]["fd_contacts"] for g in ug),
            "fd_bout_s": round(sum(fig[(g, c)]["fd_bout_s"] for g in ug), 2),
            "fd_sequence_s": round(sum(fig[(g, c)]["fd_sequence_s"] for g in ug), 2),
            "ic_loss_ms_group_mean": round(float(np.mean([fig[(g, c)]["ic_loss_ms"] for g in ug
                                                          if "ic_loss_ms" in fig[(g, c)]])), 3)}
            for c in range(len(CANDIDATES))},
        "failed_files": failed,
    }
    if ship_c is not None:
        res["shipped_defaults"] = block(lambda g: ship_c)
    return res


@click.command("trunk-gait-gsd")
@click.option("--voisard", type=click.Path(path_type=Path), default=DEFAULT_VOISARD, show_default=True,
              help="Voisard et al. 2023 folder (N-M.json + N-M_lb.txt)")
@click.option("--mobilised", type=click.Path(path_type=Path), default=DEFAULT_MOBILISED, show_default=True,
              help="Mobilise-D standardized data folder or one data.mat")
@click.option("--uci", type=click.Path(path_type=Path), default=DEFAULT_UCI, show_default=True,
              help="UCI chest-accelerometer folder (<n>.csv)")
@click.option("--json", "as_json", is_flag=True, help="print the result as JSON on stdout")
def command(voisard: Path, mobilised: Path, uci: Path, as_json: bool) -> None:
    """Trunk-gait gait-sequence detection: the slow-walking rule's constants by leave-one-group-out, false
    detections in non-walking (standing, sitting) and contacts in reference walking, per data set.

    \b
    Example:
      stridelab bench trunk-gait-gsd --json
    """
    res = run(voisard, mobilised, uci)
    if as_json:
        emit_json(res)
    else:
        for blk in ("off", "shipped_defaults", "cross_validated"):
            if blk in res:
                click.echo(f"{blk}: " + json.dumps(res[blk], default=float))
        click.echo("in-sample choice: " + json.dumps(res["in_sample_choice"]))


if __name__ == "__main__":  # pragma: no cover
    command(sys.argv[1:])
