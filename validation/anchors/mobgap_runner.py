"""Run mobgap's Mobilise-D pipelines on recordings given as one .npz; print JSON results.

Runs INSIDE the isolated mobgap environment (``make .venv-mobgap``), never imported by StrideLab:
``.venv-mobgap/bin/python validation/anchors/mobgap_runner.py IN.npz OUT.json``. Standard library, NumPy, pandas and
mobgap only.

Input arrays per recording ``k`` (``names`` lists them): ``{k}/acc`` (N, 3) m/s² and ``{k}/gyr`` (N, 3) deg/s in
mobgap's sensor frame (x up, y medio-lateral, z anterior, right-handed, as the Mobilise-D McRoberts sensor),
``{k}/meta`` = [fs_hz, height_m, sensor_height_m]. Output JSON: ``{name: {pipeline: {...}}}`` for pipelines
``healthy`` (MobilisedPipelineHealthy: GsdIluz) and ``impaired`` (MobilisedPipelineImpaired: GsdIonescu), each with
``ic_s`` and ``ic_side`` (contacts inside the pipeline's walking bouts), ``wb_start_s``, ``wb_end_s``,
``cadence_spm``, ``stride_length_m``, ``walking_speed_m_s`` per walking bout, ``cpu_s``, or ``error``.
"""
from __future__ import annotations

import json
import sys
import time
import warnings


def _run_one(pipe_cls, acc, gyr, fs, height_m, sensor_height_m):
    import numpy as np
    import pandas as pd
    from mobgap.data import GaitDatasetFromData

    df = pd.DataFrame({"acc_x": acc[:, 0], "acc_y": acc[:, 1], "acc_z": acc[:, 2],
                       "gyr_x": gyr[:, 0], "gyr_y": gyr[:, 1], "gyr_z": gyr[:, 2]})
    meta = {"height_m": height_m, "sensor_height_m": sensor_height_m, "cohort": "HA", "foot_length_cm": None,
            "weight_kg": None, "sensor_type": "McRoberts", "indip_data_used": None, "sensor_attachment_su": None}
    rec = {"measurement_condition": "laboratory"}
    ds = GaitDatasetFromData({("rec",): {"LowerBack": df}}, fs, {("rec",): meta}, {("rec",): rec})
    t0 = time.process_time()
    p = pipe_cls(dmo_thresholds=None, dmo_aggregation=None).run(ds[0])
    cpu = time.process_time() - t0
    wb = p.per_wb_parameters_
    ics = p.raw_ic_list_.reset_index(drop=True)
    starts = wb["start"].to_numpy(float) if len(wb) else np.empty(0)
    ends = wb["end"].to_numpy(float) if len(wb) else np.empty(0)
    ic = ics["ic"].to_numpy(float) if len(ics) else np.empty(0)
    side = ics["lr_label"].astype(str).to_numpy() if len(ics) else np.empty(0, str)
    inside = np.zeros(len(ic), bool)
    for s, e in zip(starts, ends):
        inside |= (ic >= s) & (ic <= e)

    def col(name):
        return [None if not np.isfinite(v) else float(v) for v in wb[name].to_numpy(float)] if name in wb else \
            [None] * len(wb)
    return {"ic_s": (ic[inside] / fs).tolist(), "ic_side": side[inside].tolist(),
            "wb_start_s": (starts / fs).tolist(), "wb_end_s": (ends / fs).tolist(),
            "cadence_spm": col("cadence_spm"), "stride_length_m": col("stride_length_m"),
            "walking_speed_m_s": col("walking_speed_mps"), "cpu_s": cpu}


def main(argv: list[str]) -> int:
    import numpy as np
    from mobgap import __version__
    from mobgap.pipeline import MobilisedPipelineHealthy, MobilisedPipelineImpaired

    src, dst = argv[1], argv[2]
    z = np.load(src, allow_pickle=False)
    names = [str(n) for n in z["names"]]
    out = {"_mobgap_version": __version__}
    for i, name in enumerate(names):
        acc, gyr, meta = z[f"{name}/acc"], z[f"{name}/gyr"], z[f"{name}/meta"]
        out[name] = {}
        for label, cls in (("healthy", MobilisedPipelineHealthy), ("impaired", MobilisedPipelineImpaired)):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    out[name][label] = _run_one(cls, acc, gyr, float(meta[0]), float(meta[1]), float(meta[2]))
            except Exception as e:  # noqa: BLE001 - one recording's failure is reported, the others still run
                out[name][label] = {"error": f"{type(e).__name__}: {e}"[:300]}
        print(f"mobgap {i + 1}/{len(names)} {name}", file=sys.stderr, flush=True)
    with open(dst, "w") as f:
        json.dump(out, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
