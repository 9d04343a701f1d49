"""Per-feature statistics as LeRobot keeps them (meta/episodes ``stats/...``, meta/stats.json).

Why: LeRobot's policies normalise inputs and outputs with these (mean/std, min/max, or
quantiles), read from meta/stats.json; per-episode stats let a subset be re-aggregated. Each
statistic is taken per column over the frames (axis 0), shaped like the feature (a (1,)
feature gives 1-element lists), ``count`` the number of frames; std is the population one
(ddof 0), as LeRobot's. An episode's quantiles ``q01``…``q99`` are exact (LeRobot's own
writer estimates them from histograms). The dataset's stats are pooled from the episodes'
(:func:`aggregate`, so an export holds one episode's frames at a time, not all): min, max,
count, mean and std exactly (std from the pooled second moment), quantiles as LeRobot
aggregates them, the count-weighted mean of the episodes'. Booleans count as 0/1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["QUANTILES", "STAT_KEYS", "aggregate", "feature_stats", "image_stats", "stats_of",
           "to_json"]

#: quantile levels LeRobot's stats carry, and their keys
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
#: the statistics of each feature, in the order they are written
STAT_KEYS = ("min", "max", "mean", "std", "count", *QUANTILES)


def feature_stats(values: np.ndarray) -> dict[str, np.ndarray]:
    """:data:`STAT_KEYS` of one feature's frames ``values`` ((n,) or (n, d), n ≥ 1)."""
    x = np.asarray(values, dtype=np.float64)
    x = x.reshape(len(x), -1)
    out = {"min": x.min(axis=0), "max": x.max(axis=0), "mean": x.mean(axis=0),
           "std": x.std(axis=0), "count": np.array([len(x)], dtype=np.int64)}
    out.update({k: np.quantile(x, q, axis=0) for k, q in QUANTILES.items()})
    return out


def image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """LeRobot's statistics of one camera's frames ((n, h, w, 3) uint8), as its
    ``compute_episode_stats`` makes them: per colour channel over every pixel of every frame
    (LeRobot samples frames; here all are used), divided by 255, each shaped (3, 1, 1);
    ``count`` the number of frames."""
    x = np.asarray(frames, dtype=np.float64).reshape(-1, 3) / 255.0
    out = {"min": x.min(axis=0), "max": x.max(axis=0), "mean": x.mean(axis=0),
           "std": x.std(axis=0)}
    out.update({k: np.quantile(x, q, axis=0) for k, q in QUANTILES.items()})
    shaped = {k: v.reshape(3, 1, 1) for k, v in out.items()}
    shaped["count"] = np.array([len(frames)], dtype=np.int64)
    return shaped


def stats_of(columns: Mapping[str, np.ndarray],
             image_keys: frozenset[str] = frozenset()) -> dict[str, dict[str, np.ndarray]]:
    """:func:`feature_stats` of every column; the camera columns ``image_keys`` per colour
    channel as LeRobot keeps a camera's (:func:`image_stats`)."""
    return {k: image_stats(v) if k in image_keys else feature_stats(v)
            for k, v in columns.items()}


def aggregate(parts: Sequence[Mapping[str, Mapping[str, np.ndarray]]]
              ) -> dict[str, dict[str, np.ndarray]]:
    """The stats of the frames of all ``parts`` (each :func:`stats_of` one episode) pooled
    (module docstring)."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for k in parts[0]:
        per = [p[k] for p in parts]
        counts = np.array([p["count"][0] for p in per], dtype=np.float64)
        n = counts.reshape(-1, *[1] * np.ndim(per[0]["mean"]))   # broadcast over the stat's shape
        means = np.stack([p["mean"] for p in per])
        mean = (n * means).sum(axis=0) / n.sum()
        second = (n * (np.stack([p["std"] for p in per]) ** 2 + means ** 2)).sum(axis=0) / n.sum()
        out[k] = {"min": np.min([p["min"] for p in per], axis=0),
                  "max": np.max([p["max"] for p in per], axis=0), "mean": mean,
                  "std": np.sqrt(np.maximum(second - mean ** 2, 0.0)),
                  "count": np.array([int(n.sum())], dtype=np.int64)}
        out[k].update({q: (n * np.stack([p[q] for p in per])).sum(axis=0) / n.sum()
                       for q in QUANTILES})
    return out


def to_json(stats: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, dict[str, list]]:
    """Stats as plain lists (meta/stats.json)."""
    return {k: {s: v.tolist() for s, v in per.items()} for k, per in stats.items()}
