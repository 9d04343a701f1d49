"""LeRobot's side of ``benchmarks/bench_export_lerobot.py``: run by the interpreter of a venv
with LeRobot (``--lerobot-python``), never by the project's. It imports nothing of dexaug, so
its dependencies (lerobot, torch) are that venv's and none of the project's extras
(tests/test_packaging.py leaves ``benchmarks/outside/`` out of its scan for that reason).

Usage: ``PY benchmarks/outside/lerobot_reader.py ROOT EXPECTED``: prints one JSON object.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np


def check_lerobot(root: Path, expected: Path) -> dict[str, Any]:
    """In LeRobot's venv: ``LeRobotDataset`` on ``root``, its frames against ``expected``
    (an .npz of the episodes' ``observation.state``, ``action``, ``episode_index`` rows, and
    per camera its (frames, h, w, 3) uint8 images where the export has one). Its table holds
    float64 exactly; its items are torch tensors (float32 of the same; images (3, h, w) in
    [0, 1], what LeRobot makes of a PNG). The fps must be an int (LeRobot types it so): its
    type is reported, and every frame's stored ``timestamp`` against ``frame_index / fps``
    within the dataset's ``tolerance_s`` (the sync LeRobot's timestamps promise)."""
    import importlib.metadata

    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    t0 = time.perf_counter()
    ds = LeRobotDataset("dexaug/bench", root=root)
    load_s = time.perf_counter() - t0
    want = np.load(expected)
    table = ds.hf_dataset.with_format("arrow")[:]   # the frames LeRobot loaded, as stored
    out: dict[str, Any] = {"lerobot": importlib.metadata.version("lerobot"),
                           "torch": importlib.metadata.version("torch"),
                           "codebase_version": ds.meta.info["codebase_version"],
                           "episodes": ds.num_episodes, "frames": len(ds), "fps": ds.fps,
                           "load_s": load_s}
    out["fps_is_int"] = type(ds.fps) is int
    lag_s = np.abs(table["timestamp"].to_numpy().astype(np.float64)
                   - table["frame_index"].to_numpy() / ds.fps)
    out["timestamp_max_error_s"] = float(lag_s.max())
    out["timestamps_within_tolerance"] = bool(lag_s.max() <= ds.tolerance_s)
    for k in ("observation.state", "action", "episode_index"):
        col = table[k].combine_chunks()
        got = (col.to_numpy() if k == "episode_index"
               else col.flatten().to_numpy().reshape(len(col), -1))
        out[f"{k}_table_equal"] = bool(got.shape == want[k].shape and np.array_equal(got, want[k]))
    step = max(len(ds) // 50, 1)
    items = range(0, len(ds), step)
    out["items_checked"] = len(items)
    out["items_equal_float32"] = all(
        np.array_equal(ds[i]["action"].numpy(), want["action"][i].astype(np.float32))
        and np.array_equal(ds[i]["observation.state"].numpy(),
                           want["observation.state"][i].astype(np.float32))
        and int(ds[i]["episode_index"]) == int(want["episode_index"][i]) for i in items)
    out["task"] = ds[0]["task"]
    out["camera_keys"] = list(ds.meta.camera_keys)
    for cam in ds.meta.camera_keys:   # LeRobot's items: (3, h, w) float32 in [0, 1]
        if cam in want.files:
            want_img = want[cam].transpose(0, 3, 1, 2).astype(np.float32) / 255.0
            out[f"{cam}_item_shape"] = list(ds[0][cam].shape)
            out[f"{cam}_items_equal"] = all(
                np.array_equal(ds[i][cam].numpy(), want_img[i]) for i in items)
            out[f"{cam}_stats_mean"] = np.asarray(ds.meta.stats[cam]["mean"]).ravel().tolist()
    # as a policy is trained: chunks of the next actions (LeRobot checks the timestamps
    # against fps for this), through a torch DataLoader
    import torch

    dt = 1.0 / ds.fps
    chunked = LeRobotDataset("dexaug/bench", root=root,
                             delta_timestamps={"action": [0.0, dt, 2 * dt, 3 * dt]})
    batch = next(iter(torch.utils.data.DataLoader(chunked, batch_size=8, shuffle=False)))
    out["action_chunk_shape"] = list(batch["action"].shape)
    out["action_chunk_equal_float32"] = bool(np.array_equal(
        batch["action"][0].numpy(), want["action"][:4].astype(np.float32)))
    out["stats_keys"] = sorted(ds.meta.stats["action"])
    return out


if __name__ == "__main__":
    print(json.dumps(check_lerobot(Path(sys.argv[1]), Path(sys.argv[2]))))
