"""Episodes as a LeRobot dataset (format v3.0, ``dexaug export --format lerobot``).

Why: LeRobot is where today's users train policies; its ``LeRobotDataset`` reads a folder of
this layout (LeRobot's dataset format v3.0, the one its releases since 0.4 write and read):

- ``meta/info.json``: ``codebase_version``, ``fps``, ``features`` (dtype, shape, names),
  ``total_episodes`` / ``total_frames`` / ``total_tasks``, ``splits``, ``chunks_size``, file
  size limits and the ``data_path`` / ``video_path`` templates;
- ``meta/tasks.parquet``: one row per task text, indexed by the text, column ``task_index``;
- ``meta/episodes/chunk-000/file-000.parquet``: one row per episode: its index, ``tasks``,
  ``length``, where its frames are (``data/chunk_index``, ``data/file_index``,
  ``dataset_from_index`` / ``dataset_to_index``) and ``stats/<feature>/<stat>``; dexaug adds
  the source's ``dexaug/...`` columns (a rollout's object, grasp row, validator summary and
  initial MuJoCo state; a session's file and metadata);
- ``meta/stats.json``: the same statistics over every frame (:mod:`.lerobot_stats`);
- ``data/chunk-XXX/file-YYY.parquet``: the frames (:mod:`.lerobot_frames`), many episodes a
  file, a new file past ``data_files_size_in_mb``, a new chunk every ``chunks_size`` files.

The writer takes episodes of any source as
:class:`augment.export.lerobot_episode.LeRobotEpisode` (teleop sessions:
:mod:`.lerobot_sessions`) and rollouts as they come (:class:`sim.episodes.episode.Episode`,
turned into frames by :mod:`.lerobot_frames`): only
successful rollouts are episodes; the failed ones are listed, with their reasons, in
``failed_rollouts.json`` at the dataset's root (LeRobot's reader ignores it; an export of
sessions lists none). Cameras are ``dtype`` ``"image"`` features, PNG in the parquet
(:mod:`.lerobot_images`); no videos (``video_path`` null). The folder is written beside
``out`` and renamed into place, replacing only an empty folder or an earlier LeRobot export.
pyarrow is the optional extra ``lerobot``.
"""

from __future__ import annotations

import importlib
import json
import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from augment.export.lerobot_episode import LeRobotEpisode, same_layout
from augment.export.lerobot_frames import from_rollout
from augment.export.lerobot_images import encode_column
from augment.export.lerobot_stats import STAT_KEYS, aggregate, stats_of, to_json
from sim.episodes.episode import Episode
from sim.errors import DexaugError
from sim.io import replace_folder

__all__ = ["CODEBASE_VERSION", "DATA_PATH", "EPISODES_PATH", "FAILED_FILE", "INDEX_FEATURES",
           "LeRobotExport", "pyarrow_modules", "write_lerobot"]

log = logging.getLogger(__name__)

#: the LeRobot dataset format written (LeRobot's ``CODEBASE_VERSION``)
CODEBASE_VERSION = "v3.0"
#: LeRobot's file templates (info.json carries the first; the reader formats it)
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
#: the failed rollouts, kept apart (dataset root)
FAILED_FILE = "failed_rollouts.json"
#: LeRobot's own per-frame bookkeeping features (dtype, as its reader expects them): the
#: source gives ``timestamp``, the writer the indices
INDEX_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64",
                  "index": "int64", "task_index": "int64"}
#: LeRobot's defaults: files a chunk folder, MB a data file
CHUNKS_SIZE, DATA_FILE_MB, VIDEO_FILE_MB = 1000, 100, 200


def pyarrow_modules() -> tuple[Any, Any]:
    """``(pyarrow, pyarrow.parquet)``, or a one-line error naming the extra that brings them
    (imported by name: pyarrow ships no type information, and its modules are used as Any)."""
    try:
        pa = importlib.import_module("pyarrow")
        pq = importlib.import_module("pyarrow.parquet")
    except ImportError as exc:
        raise DexaugError("the LeRobot export needs pyarrow: pip install 'dexaug[lerobot]'") from exc
    return pa, pq


@dataclass
class LeRobotExport:
    """What :func:`write_lerobot` wrote: episodes and frames, the failed rollouts kept apart,
    the tasks, and the data files (relative to the root)."""

    root: Path
    episodes: int = 0
    frames: int = 0
    failed: int = 0
    tasks: list[str] = field(default_factory=list)
    data_files: list[str] = field(default_factory=list)


def write_lerobot(out: Path | str, episodes: Iterable[Episode | LeRobotEpisode], *,
                  robot_type: str | None = None, source: str = "dexaug",
                  data_file_mb: float = DATA_FILE_MB, chunks_size: int = CHUNKS_SIZE,
                  progress: Callable[[int], None] | None = None) -> LeRobotExport:
    """Write ``episodes`` as a LeRobot v3.0 dataset at ``out`` (module docstring): every
    :class:`LeRobotEpisode`, and the successful rollouts (failed ones listed in
    :data:`FAILED_FILE`); ``robot_type`` defaults to the first episode's,
    ``progress(n_seen)`` after each episode. All written episodes must share one layout
    (features) and frame rate."""
    out = Path(out)
    writer = _Writer(out, data_file_mb, chunks_size)

    def fill(tmp: Path) -> None:
        writer.root = tmp
        for seen, ep in enumerate(episodes, start=1):
            writer.add(ep)
            if progress is not None:
                progress(seen)
        writer.finish(robot_type, source)

    replace_folder(out, fill, marker="meta/info.json", what="LeRobot export")
    done = writer.done
    done.root = out
    log.debug("wrote %d episodes (%d frames) to %s; %d failed rollouts kept apart",
              done.episodes, done.frames, out, done.failed)
    return done


class _Writer:
    """The dataset as the episodes come: frames gathered into data files of at most
    ``data_file_mb``, one meta/episodes row each, failed rollouts set aside."""

    def __init__(self, out: Path, data_file_mb: float, chunks_size: int) -> None:
        self.pa, self.pq = pyarrow_modules()
        self.root = out
        self.data_file_mb, self.chunks_size = data_file_mb, chunks_size
        self.done = LeRobotExport(out)
        self.failed: list[dict[str, Any]] = []
        self.rows: list[dict[str, Any]] = []
        self.pending: list[dict[str, np.ndarray]] = []
        self.stats: list[dict[str, dict[str, np.ndarray]]] = []   # per episode
        self.first: LeRobotEpisode | None = None
        self.features: dict[str, dict[str, Any]] = {}
        self.images: frozenset[str] = frozenset()
        self.file_at = [0, 0]   # chunk, file of the data file being filled

    def add(self, item: Episode | LeRobotEpisode) -> None:
        """One episode; a rollout only if it succeeded, else a line of the failures."""
        done = self.done
        if isinstance(item, Episode):
            if not item.success or not len(item):
                self.failed.append({"grasp_index": item.grasp_index, "object": item.object,
                                    "hand": item.hand, "failure": item.failure,
                                    "steps": len(item)})
                done.failed += 1
                return
            item = from_rollout(item)
        if self.first is None:
            self.first = item
            self.features = {**item.features, **{k: {"dtype": t, "shape": [1], "names": None}
                                                 for k, t in INDEX_FEATURES.items()}}
            self.images = frozenset(k for k, f in item.features.items() if f["dtype"] == "image")
        _check_fits(self.first, item)
        if item.task not in done.tasks:
            done.tasks.append(item.task)
        cols = {**item.columns, **_index_columns(len(item), done.episodes, done.frames,
                                                 done.tasks.index(item.task))}
        size = sum(v.nbytes for p in (*self.pending, cols) for v in p.values())
        if self.pending and size > self.data_file_mb * 2**20:
            self._flush()
        self.stats.append(stats_of(cols, self.images))
        self.rows.append(_episode_row(item, done.episodes, self.stats[-1], self.file_at,
                                      done.frames))
        self.pending.append(cols)
        done.episodes += 1
        done.frames += len(item)

    def _flush(self) -> None:
        if not self.pending:
            return
        rel = DATA_PATH.format(chunk_index=self.file_at[0], file_index=self.file_at[1])
        _write_parquet(self.pa, self.pq, self.root / rel, _concat(self.pending), self.features)
        self.done.data_files.append(rel)
        self.pending.clear()
        self.file_at[1] += 1
        if self.file_at[1] >= self.chunks_size:
            self.file_at = [self.file_at[0] + 1, 0]

    def finish(self, robot_type: str | None, source: str) -> None:
        """The last data file, the meta and the failures."""
        if self.first is None:
            raise DexaugError(f"{self.done.root}: no successful episode to write "
                              f"({len(self.failed)} failed rollouts); nothing written")
        self._flush()
        _write_meta(self.pa, self.pq, self.root, self.first, self.features, self.done,
                    self.rows, self.stats, robot_type, self.data_file_mb, self.chunks_size)
        (self.root / FAILED_FILE).write_text(json.dumps(
            {"source": source, "failed": self.failed}, indent=1) + "\n")


def _index_columns(n: int, episode_index: int, first_index: int,
                   task_index: int) -> dict[str, np.ndarray]:
    """LeRobot's bookkeeping of an episode's ``n`` frames; ``first_index``: the dataset-wide
    ``index`` of its first frame."""
    return {"frame_index": np.arange(n, dtype=np.int64),
            "episode_index": np.full(n, episode_index, dtype=np.int64),
            "index": np.arange(first_index, first_index + n, dtype=np.int64),
            "task_index": np.full(n, task_index, dtype=np.int64)}


def _check_fits(first: LeRobotEpisode, ep: LeRobotEpisode) -> None:
    if not same_layout(first, ep):
        raise DexaugError(f"episode of {ep.robot_type} ({ep.task!r}, {ep.fps} fps): its "
                          f"features or frame rate differ from the first episode's "
                          f"({first.robot_type}, {first.fps} fps); one LeRobot dataset holds "
                          "one layout")


def _concat(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _arrow_column(pa: Any, values: np.ndarray, ft: dict[str, Any]) -> Any:
    """One feature as an Arrow column: a scalar for shape (1,), a PNG struct for an image,
    else a fixed-size list (what LeRobot's ``datasets`` features, ``Sequence(length=n)``,
    are)."""
    if ft["dtype"] == "image":
        return encode_column(pa, values)
    if list(ft["shape"]) == [1]:
        return pa.array(values.reshape(-1))
    flat = pa.array(np.ascontiguousarray(values).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(flat, int(ft["shape"][0]))


def _write_parquet(pa: Any, pq: Any, path: Path, cols: dict[str, np.ndarray],
                   features: dict[str, dict[str, Any]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.table({k: _arrow_column(pa, cols[k], features[k]) for k in features})
    pq.write_table(table, path, compression="snappy")


def _stat_columns(stats: dict[str, dict[str, np.ndarray]]) -> dict[str, Any]:
    return {f"stats/{k}/{s}": per[s].tolist() for k, per in stats.items() for s in STAT_KEYS}


def _episode_row(ep: LeRobotEpisode, index: int, stats: dict[str, dict[str, np.ndarray]],
                 file_at: list[int], first_frame: int) -> dict[str, Any]:
    """One row of meta/episodes (module docstring)."""
    return {"episode_index": index, "tasks": [ep.task], "length": len(ep),
            "data/chunk_index": file_at[0], "data/file_index": file_at[1],
            "dataset_from_index": first_frame, "dataset_to_index": first_frame + len(ep),
            "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0,
            **_stat_columns(stats), **ep.meta}


def _write_meta(pa: Any, pq: Any, root: Path, first: LeRobotEpisode, features: dict[str, Any],
                done: LeRobotExport, ep_rows: list[dict[str, Any]],
                stats: list[dict[str, dict[str, np.ndarray]]], robot_type: str | None,
                data_file_mb: float, chunks_size: int) -> None:
    """info.json, tasks, episodes and stats.json."""
    meta = root / "meta"
    (meta / "episodes" / "chunk-000").mkdir(parents=True, exist_ok=True)
    info = {"codebase_version": CODEBASE_VERSION, "robot_type": robot_type or first.robot_type,
            "total_episodes": done.episodes, "total_frames": done.frames,
            "total_tasks": len(done.tasks), "chunks_size": chunks_size,
            "data_files_size_in_mb": data_file_mb, "video_files_size_in_mb": VIDEO_FILE_MB,
            "fps": first.fps, "splits": {"train": f"0:{done.episodes}"},
            "data_path": DATA_PATH, "video_path": None, "features": features}
    (meta / "info.json").write_text(json.dumps(info, indent=4) + "\n")
    (meta / "stats.json").write_text(json.dumps(to_json(aggregate(stats)), indent=4) + "\n")
    pq.write_table(pa.Table.from_pylist(ep_rows),
                   root / EPISODES_PATH.format(chunk_index=0, file_index=0))
    _write_tasks(pa, pq, meta / "tasks.parquet", done.tasks)


def _write_tasks(pa: Any, pq: Any, path: Path, tasks: list[str]) -> None:
    """meta/tasks.parquet as pandas writes a frame indexed by the task text (LeRobot reads
    it with ``pandas.read_parquet`` and looks tasks up by that index): the pandas schema
    metadata names the ``task`` column as the index, so no pandas is needed here."""
    pandas_meta = {
        "index_columns": ["task"], "column_indexes": [],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
                     "numpy_type": "int64", "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode",
                     "numpy_type": "object", "metadata": None}],
        "creator": {"library": "dexaug", "version": "1"}, "pandas_version": "2.0.0"}
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()),
                      "task": pa.array(tasks, pa.string())})
    table = table.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})
    pq.write_table(table, path)

