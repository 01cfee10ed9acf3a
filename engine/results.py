"""The one reader of Brush Studio result files (layout: ``docs/results.md``).

Used by plots, tests, the studio and the API. It opens finished files, files a run is still
writing, and files whose writer was killed; it only ever returns the first ``n_frames`` rows.

    with open_result("run.h5") as r:
        t = r.time
        f = r.series("brushes/main/root_force")   # (n_frames, 3)
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .errors import BrushStudioError
from .recorder import FORMAT, FORMAT_VERSION


def open_result(path) -> "ResultFile":
    """Open a result file for reading; BrushStudioError if it is missing, not a Brush Studio
    result, or written by a newer Brush Studio."""
    return ResultFile(path)


def _open_h5(path: Path) -> h5py.File:
    """Open read-only. A finished file opens plainly; a file being written (or whose writer
    died) is marked open-for-SWMR-writing and opens with swmr=True. Locking is off, as in the
    writer (HDF5 requires the same locking setting for two handles in one process)."""
    if not path.exists():
        raise BrushStudioError(f"result file {path} does not exist")
    if not path.is_file():
        raise BrushStudioError(f"result file {path} is not a file")
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as plain_exc:
        try:
            return h5py.File(path, "r", swmr=True, locking=False)
        except OSError:
            pass
        msg = str(plain_exc)
        if "already open for write" in msg:
            raise BrushStudioError(
                f"{path} is marked open-for-writing by a writer that died outside SWMR mode, "
                f"so HDF5 refuses to open it (`h5clear -s` removes the mark). The recorder "
                f"never leaves a result in this state; it may be a '.creating' file of a run "
                f"killed while its file was being set up, which holds no frames") from None
        raise BrushStudioError(f"{path} is not a readable HDF5 file: {msg}") from None


def _decode(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


class ResultFile:
    """A result file opened for reading. Context manager; ``close()`` without ``with``."""

    def __init__(self, path):
        self.path = Path(path)
        self._file: h5py.File | None = None
        self._scene = None
        self._load()

    # ---------------------------------------------------------------- opening
    def _load(self) -> None:
        f = _open_h5(self.path)
        try:
            attrs: dict[str, Any] = {}
            self.unreadable_attrs: list[str] = []
            for key in f.attrs:  # one by one: one bad attribute must not hide the frames
                try:
                    attrs[key] = _decode(f.attrs[key])
                except Exception:
                    self.unreadable_attrs.append(key)
            if attrs.get("format") != FORMAT:
                raise BrushStudioError(
                    f"{self.path} is not a Brush Studio result (root attribute format = "
                    f"{attrs.get('format')!r}, expected {FORMAT!r})")
            version = attrs.get("format_version")
            if not isinstance(version, int):
                raise BrushStudioError(f"{self.path}: format_version {version!r} is not an "
                                       f"integer")
            if version > FORMAT_VERSION:
                raise BrushStudioError(
                    f"{self.path} has format_version {version}; this Brush Studio reads "
                    f"version {FORMAT_VERSION} and older: update Brush Studio")
            try:
                channel_names = json.loads(attrs["channels"])
                static_names = json.loads(attrs["statics"])
                n_attr = int(attrs["n_frames"])
            except (KeyError, TypeError, ValueError) as exc:
                raise BrushStudioError(f"{self.path}: damaged root attributes ({exc!r})") \
                    from None
            lengths = []
            for name in channel_names:
                if name not in f or not isinstance(f[name], h5py.Dataset):
                    raise BrushStudioError(f"{self.path}: channel {name!r} is listed but "
                                           f"missing")
                lengths.append(f[name].shape[0])
        except BaseException:
            f.close()
            raise
        if self._file is not None:
            self._file.close()
        self._file = f
        self.attrs = attrs
        self._channel_names = list(channel_names)
        self._static_names = list(static_names)
        # n_frames is the writer's commit marker; the extents guard against a damaged marker
        self.n_frames = max(0, min([n_attr, *lengths]))
        self._time = None

    def refresh(self) -> None:
        """Re-open the file to see frames (and attributes) written since it was opened.

        The old handle is closed first: HDF5 hands a second open of a file that is still open
        in this process the same underlying file, with its stale view. For the same reason,
        close other handles to a file being written before opening it again."""
        self._require_open()
        self.close()
        self._load()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> "ResultFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"ResultFile({str(self.path)!r}, status={self.status!r}, "
                f"n_frames={self.n_frames})")

    def _require_open(self) -> h5py.File:
        if self._file is None:
            raise BrushStudioError(f"result file {self.path} is closed")
        return self._file

    # ---------------------------------------------------------------- metadata
    @property
    def status(self) -> str:
        return str(self.attrs.get("status", "running"))

    @property
    def interrupted(self) -> bool:
        """True while the run is still being written, or if its writer died (status never left
        "running"). The reader cannot tell the two apart; the job layer can."""
        return self.status == "running"

    @property
    def scene_json(self) -> str:
        return str(self.attrs.get("scene", ""))

    @property
    def scene(self):
        """The run's scene (engine.spec.Scene), parsed on first use."""
        if self._scene is None:
            from .spec import parse_scene
            self._scene = parse_scene(self.scene_json)
        return self._scene

    def json_attr(self, name: str, default: Any = None) -> Any:
        """A root attribute stored as JSON text (summary, error, stages, brush_names...)."""
        text = self.attrs.get(name)
        if text is None:
            return default
        try:
            return json.loads(text)
        except (TypeError, ValueError):
            raise BrushStudioError(f"{self.path}: attribute {name!r} is not JSON text") \
                from None

    @property
    def summary(self) -> dict | None:
        return self.json_attr("summary")

    @property
    def error(self) -> dict | None:
        return self.json_attr("error")

    # ---------------------------------------------------------------- data
    def channels(self) -> list[str]:
        """Per-frame dataset paths, in the order the writer declared them."""
        return list(self._channel_names)

    def statics(self) -> list[str]:
        return list(self._static_names)

    def _channel(self, name: str) -> h5py.Dataset:
        f = self._require_open()
        if name not in self._channel_names:
            raise BrushStudioError(f"{self.path} has no channel {name!r}; it has "
                                   f"{self._channel_names}")
        return f[name]

    @property
    def time(self) -> np.ndarray:
        """Simulated time of each frame, s, shape (n_frames,)."""
        if self._time is None:
            if "time" not in self._channel_names:
                raise BrushStudioError(f"{self.path} has no 'time' channel")
            self._time = self.series("time")
        return self._time

    def series(self, name: str, frames=slice(None)) -> np.ndarray:
        """Rows of channel ``name`` for ``frames`` (a slice, an int, or a sequence of ints
        indexing the first n_frames rows). Never returns rows at or past n_frames."""
        ds = self._channel(name)
        n = self.n_frames
        if isinstance(frames, (int, np.integer)):
            return self.frame(name, int(frames))
        if isinstance(frames, slice):
            start, stop, step = frames.indices(n)
            if step > 0:
                if start >= stop:
                    return np.empty((0, *ds.shape[1:]), dtype=ds.dtype)
                return ds[start:stop:step]
            idx = np.arange(start, stop, step)
        else:
            idx = np.asarray(frames)
            if idx.dtype.kind not in "iu":
                raise TypeError(f"frames must be a slice, an int or integers, got {frames!r}")
            idx = idx.astype(np.int64).ravel()
            if idx.size and (idx.min() < -n or idx.max() >= n):
                raise IndexError(f"frame index out of range for {n} frames")
            idx = np.where(idx < 0, idx + n, idx)
        if idx.size == 0:
            return np.empty((0, *ds.shape[1:]), dtype=ds.dtype)
        lo, hi = int(idx.min()), int(idx.max()) + 1
        return ds[lo:hi][idx - lo]

    def frame(self, name: str, i: int) -> np.ndarray:
        """Row ``i`` of channel ``name`` (negative i counts from n_frames)."""
        ds = self._channel(name)
        n = self.n_frames
        if not -n <= i < n:
            raise IndexError(f"frame {i} out of range: {self.path} has {n} frames")
        return ds[i % n]

    def static(self, name: str) -> np.ndarray:
        f = self._require_open()
        if name not in self._static_names:
            raise BrushStudioError(f"{self.path} has no static {name!r}; it has "
                                   f"{self._static_names}")
        ds = f[name]
        if h5py.check_string_dtype(ds.dtype) is not None:
            return np.asarray(ds.asstr()[()], dtype=object)
        return ds[()]
