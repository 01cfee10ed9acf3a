"""Result writer: one HDF5 file per run, written as the run goes.

The recorder is generic: the run loop declares its per-frame *channels* (dataset path ->
per-frame shape and dtype) and its *statics* (arrays written once), then appends one frame at a
time. The layout is documented in ``docs/results.md``; :mod:`engine.io.results` is the one reader.

:func:`state_channels` and :func:`state_frame` declare and fill the channels that let a file
check its own physics (node velocities and spins, body motion codes, masses and inertias as
statics): ``ResultFile.energy`` / ``angular_momentum`` / ``linear_momentum`` read them.

Killed-run safety (SIGKILL, not power loss)
-------------------------------------------
* The file uses the latest HDF5 format and is switched to SWMR (single-writer/multiple-reader)
  mode at the end of ``__init__``. From then on HDF5 orders its metadata writes so that the file
  on disk is always a valid HDF5 file, whatever moment the writer dies at.
* Root attribute ``n_frames`` is the commit marker. Appended rows wait in memory until a
  commit: every ``flush_every`` frames (None: never by count), once they hold
  ``buffer_bytes``, or ``commit_seconds`` after the last commit (whichever comes first), and
  at ``close``. A commit writes the waiting
  rows (one block per channel), flushes (rows and dataset extents reach the file), then
  rewrites ``n_frames`` in place and flushes again. So ``n_frames`` never counts a row that is
  not on disk; rows past it (a dataset may have been extended before the crash) are never
  shown by the reader, and a kill loses only the rows not yet committed. The run loop commits
  every quarter second of wall time (``RUN_COMMIT_SECONDS``): a live view lags by about that,
  and a frame costs one copy in memory instead of a resize and a write per channel (51
  channels of a detumble scene took 17 ms a frame).
* Chunks are unfiltered (no compression) and bypass the chunk cache, so a row is written to its
  final, fixed place in the file and already-committed bytes are never moved.
* The file is built under a temporary name next to the target (``.<name>.creating``) and
  renamed into place only once it is in SWMR mode, so the result path never shows a
  half-created file (and an older file at that path stays intact until then). A writer killed
  inside ``__init__`` leaves only the temporary file behind.
* File locking is off in the writer and the reader (``locking=False``): SWMR, not locks, keeps
  readers consistent; a reader can open the file while the run writes it, and after the writer
  was killed. Readers open a live or killed file with ``swmr=True`` (see ``engine.io.results``).
* Attribute writes after ``__init__`` (``set_attrs``, ``close``) happen in SWMR mode. Creating
  attributes is outside what SWMR formally guarantees to *concurrent* readers, but it never
  makes the file unopenable. Text attributes are fixed-length (see ``_text``) so that a kill
  while one is replaced cannot leave it dangling; the reader still reads attributes one by one
  and tolerates a bad one.
"""
from __future__ import annotations

import datetime as _dt
import os
import time
import traceback
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from h5py import h5f, h5p, h5s

from engine.jsonable import json_text
from engine.io.output_paths import refuse_special

FORMAT = "brush-studio-result"
FORMAT_VERSION = 1
STATUSES = ("running", "completed", "stopped", "failed", "cancelled")
#: attributes the recorder owns; ``attrs``/``set_attrs`` may not set them
RESERVED_ATTRS = frozenset({"format", "format_version", "scene", "status", "created",
                            "n_frames", "channels", "statics", "summary", "error"})

CHUNK_TARGET_BYTES = 1 << 20   # ~1 MiB chunks for the big per-frame channels
MAX_CHUNK_ROWS = 1024          # scalar series: 8 KiB chunks, not 1 MiB of mostly empty space
_MAX_COMPACT_ATTRS = 1000      # keep root attributes in the root object header (no dense storage)
_MAX_FIXED_TEXT = 32 * 1024    # longest fixed-length text attribute (header messages < 64 KiB)


def _attr_value(name: str, value: Any) -> Any:
    """Python value -> what is stored as an HDF5 attribute: dicts, lists and None become JSON
    text; str, bool, int, float and small numeric arrays are stored as they are."""
    if isinstance(value, (dict, list, tuple)) or value is None:
        return _text(json_text(value))
    if isinstance(value, str):
        return _text(value)
    if isinstance(value, (bool, np.bool_)):
        return np.bool_(value)
    if isinstance(value, (int, np.integer)):
        return np.int64(value)
    if isinstance(value, (float, np.floating)):
        return np.float64(value)
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        return value
    raise TypeError(f"attribute {name!r}: cannot store a {type(value).__name__} "
                    f"(use str, bool, int, float, a numeric array, or a JSON-able dict/list)")


def _text(text: str):
    """Strings are stored as fixed-length UTF-8 attributes, held entirely in the root object
    header. Variable-length strings live in HDF5's global heap, which SWMR does not order
    against the header: a writer killed while replacing one can leave that attribute
    unreadable (seen in stress tests); a fixed-length one is rewritten with its header. Texts
    too long for an object header message fall back to variable length."""
    data = text.encode("utf-8")
    if len(data) > _MAX_FIXED_TEXT:
        return text
    return np.array(data, dtype=h5py.string_dtype("utf-8", max(1, len(data))))


def _chunk_rows(row_shape: tuple[int, ...], dtype: np.dtype) -> int:
    row_bytes = max(1, int(np.prod(row_shape, dtype=np.int64)) * dtype.itemsize)
    return int(min(MAX_CHUNK_ROWS, max(1, CHUNK_TARGET_BYTES // row_bytes)))


def _open_for_writing(path: Path) -> h5py.File:
    fapl = h5p.create(h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5f.LIBVER_LATEST, h5f.LIBVER_LATEST)  # SWMR needs the v110+ format
    fapl.set_file_locking(False, True)  # readers use locking=False too (must match in-process)
    fcpl = h5p.create(h5p.FILE_CREATE)
    fcpl.set_attr_phase_change(_MAX_COMPACT_ATTRS, _MAX_COMPACT_ATTRS - 1)
    fid = h5f.create(os.fsencode(path), h5f.ACC_TRUNC, fapl=fapl, fcpl=fcpl)
    return h5py.File(fid)


#: the run loop's commit interval (wall seconds): about what a live view lags and a kill loses
RUN_COMMIT_SECONDS = 0.25


def _append_block(ds, i0: int, block: np.ndarray) -> None:
    """Extend dataset ``ds`` to ``i0 + len(block)`` rows and write ``block`` (its dtype, C
    order) at row ``i0``, through h5py's low-level calls: the high-level resize and slice
    assignment build a selection in Python each time, about 0.2 ms a channel, which made a
    commit of the detumble's 51 channels cost some 17 ms."""
    shape = block.shape
    ds.id.set_extent((i0 + shape[0],) + shape[1:])
    if block.size == 0:    # a channel of empty rows (no bodies, ...): nothing to write
        return
    file_space = ds.id.get_space()
    file_space.select_hyperslab((i0,) + (0,) * (len(shape) - 1), shape)
    ds.id.write(h5s.create_simple(shape), file_space, np.ascontiguousarray(block))


class Recorder:
    """Writes one run's result file. See the module docstring and ``docs/results.md``."""

    def __init__(self, path, scene_json: str,
                 channels: dict[str, tuple[tuple[int, ...], str]],
                 static: dict[str, np.ndarray], attrs: dict | None = None,
                 flush_every: int | None = 1, commit_seconds: float | None = None,
                 buffer_bytes: int = 32 << 20):
        self.path = Path(path)
        if flush_every is not None and int(flush_every) < 1:
            raise ValueError(f"flush_every must be >= 1 or None, got {flush_every!r}")
        if commit_seconds is not None and not commit_seconds > 0:
            raise ValueError(f"commit_seconds must be > 0 or None, got {commit_seconds!r}")
        self.flush_every = None if flush_every is None else int(flush_every)
        self.commit_seconds = commit_seconds
        self.buffer_bytes = int(buffer_bytes)
        self._pending: list[dict[str, np.ndarray]] = []  # appended rows not yet written
        self._pending_bytes = 0
        self._last_commit = time.monotonic()
        if not isinstance(scene_json, str):
            raise TypeError("scene_json must be the scene's JSON text (str)")
        if not channels:
            raise ValueError("a result needs at least one channel")
        self._channels: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
        for name, spec in channels.items():
            try:
                shape, dtype = spec
                shape = tuple(int(n) for n in shape)
                dtype = np.dtype(dtype)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"channel {name!r}: expected ((per-frame shape), dtype), "
                                 f"got {spec!r} ({exc})") from None
            if any(n < 0 for n in shape) or dtype.kind not in "biuf":
                raise ValueError(f"channel {name!r}: shape {shape} / dtype {dtype} not allowed "
                                 f"(non-negative sizes, numeric or bool dtype)")
            self._channels[name] = (shape, dtype)
        overlap = set(self._channels) & set(static)
        if overlap:
            raise ValueError(f"names used both as channel and static: {sorted(overlap)}")
        extra = dict(attrs or {})
        bad = RESERVED_ATTRS & set(extra)
        if bad:
            raise ValueError(f"attributes {sorted(bad)} are written by the recorder itself")

        self._n_written = 0     # rows written to every channel
        self._n_committed = 0   # rows counted by the n_frames attribute
        self._closed = False
        creating = self.path.with_name(f".{self.path.name}.creating")
        # never a device, a named pipe or a folder: the file is renamed onto the path
        refuse_special(self.path, "result file")
        refuse_special(creating, "result file's temporary file")
        self._file = _open_for_writing(creating)
        try:
            f = self._file
            f.attrs["format"] = _text(FORMAT)
            f.attrs["format_version"] = np.int64(FORMAT_VERSION)
            f.attrs["scene"] = _text(scene_json)
            f.attrs["status"] = _text("running")
            f.attrs["created"] = _text(
                _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"))
            f.attrs["n_frames"] = np.int64(0)
            f.attrs["channels"] = _text(json_text(list(self._channels)))
            f.attrs["statics"] = _text(json_text(list(static)))
            for key, value in extra.items():
                f.attrs[key] = _attr_value(key, value)
            self._datasets = {}
            for name, (shape, dtype) in self._channels.items():
                try:
                    self._datasets[name] = f.create_dataset(
                        name, shape=(0, *shape), maxshape=(None, *shape), dtype=dtype,
                        chunks=(_chunk_rows(shape, dtype), *shape) if all(shape) else None,
                        rdcc_nbytes=0)  # no chunk cache: rows go straight to their place
                except (ValueError, TypeError) as exc:
                    raise ValueError(f"channel {name!r}: cannot create dataset ({exc})") from None
            for name, value in static.items():
                arr = np.asarray(value)
                if arr.dtype.kind == "U":
                    arr = arr.astype(object)
                    f.create_dataset(name, data=arr, dtype=h5py.string_dtype())
                elif arr.dtype.kind in "biuf":
                    f.create_dataset(name, data=arr)
                else:
                    raise ValueError(f"static {name!r}: dtype {arr.dtype} not allowed "
                                     f"(numeric, bool or str)")
            f.flush()
            f.swmr_mode = True  # from here on the file on disk is always readable
            refuse_special(self.path, "result file")  # (again: it may have appeared since)
            os.replace(creating, self.path)  # the open handle follows the inode
        except BaseException:
            self._file.close()
            self._closed = True
            creating.unlink(missing_ok=True)
            raise

    # ---------------------------------------------------------------- writing
    @property
    def n_frames(self) -> int:
        """Frames appended so far (committed or not)."""
        return self._n_written

    @property
    def closed(self) -> bool:
        return self._closed

    def append(self, frame: dict[str, Any]) -> None:
        """Append one row to every channel. Every channel must be present, with exactly its
        per-frame shape and a dtype that casts safely (same kind) to the channel's; nothing is
        written unless the whole frame is valid."""
        if self._closed:
            raise ValueError(f"recorder for {self.path} is closed")
        missing = [n for n in self._channels if n not in frame]
        unknown = [n for n in frame if n not in self._channels]
        if missing or unknown:
            raise ValueError(f"frame {self._n_written}: missing channels {missing}, "
                             f"unknown channels {unknown}")
        rows = {}
        for name, (shape, dtype) in self._channels.items():
            value = np.asarray(frame[name])
            if value.shape != shape:
                raise ValueError(f"channel {name!r}: frame {self._n_written} has shape "
                                 f"{value.shape}, expected {shape}")
            if not np.can_cast(value.dtype, dtype, casting="same_kind"):
                raise ValueError(f"channel {name!r}: frame {self._n_written} has dtype "
                                 f"{value.dtype}, which does not cast safely to {dtype}")
            # a copy: the row waits in memory until the commit, and the caller may reuse
            # its arrays (``np.array`` keeps a 0-d row 0-d, ``ascontiguousarray`` does not)
            rows[name] = np.array(value, dtype=dtype, order="C", copy=True)
        self._pending.append(rows)
        self._pending_bytes += sum(row.nbytes for row in rows.values())
        self._n_written += 1
        if ((self.flush_every is not None
             and self._n_written - self._n_committed >= self.flush_every)
                or self._pending_bytes >= self.buffer_bytes
                or (self.commit_seconds is not None
                    and time.monotonic() - self._last_commit >= self.commit_seconds)):
            self.flush()

    def flush(self) -> None:
        """Make every appended frame durable and visible: flush rows, then bump n_frames."""
        if self._closed:
            return
        f = self._file
        if self._pending:
            i0 = self._n_committed
            for name, ds in self._datasets.items():
                _append_block(ds, i0, np.stack([rows[name] for rows in self._pending]))
            self._pending = []
            self._pending_bytes = 0
        self._last_commit = time.monotonic()
        f.flush()                       # rows and extents are in the file ...
        if self._n_committed != self._n_written:
            f.attrs.modify("n_frames", np.int64(self._n_written))
            f.flush()                   # ... before n_frames counts them
            self._n_committed = self._n_written

    def set_attrs(self, **attrs) -> None:
        """Set root attributes (dicts/lists become JSON text). Flushed at once."""
        if self._closed:
            raise ValueError(f"recorder for {self.path} is closed")
        bad = RESERVED_ATTRS & set(attrs)
        if bad:
            raise ValueError(f"attributes {sorted(bad)} are written by the recorder itself")
        values = {k: _attr_value(k, v) for k, v in attrs.items()}
        for key, value in values.items():
            self._file.attrs[key] = value
        self._file.flush()

    def close(self, status: str, summary: dict | None = None, error: dict | None = None) -> None:
        """Commit every frame, write ``status`` (and ``summary``/``error`` as JSON text) and
        close the file. Calling it again does nothing."""
        if self._closed:
            return
        if status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
        try:
            self.flush()
            f = self._file
            if summary is not None:
                f.attrs["summary"] = _text(json_text(summary))
            if error is not None:
                f.attrs["error"] = _text(json_text(error))
            f.attrs["status"] = _text(status)
            f.flush()
        finally:
            self._closed = True
            self._file.close()
        try:  # the ParaView/VisIt description beside it (docs/results.md); never fatal
            from engine.io.xdmf import write_xdmf
            write_xdmf(self.path)
        except Exception:
            pass

    # ---------------------------------------------------------------- context manager
    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is None:
            self.close("completed")
            return False
        from engine.errors import RunCancelled  # local: keep the recorder importable on its own
        cancelled = isinstance(exc, (RunCancelled, KeyboardInterrupt))
        self.close("cancelled" if cancelled else "failed", error=error_dict(exc))
        return False

    def __del__(self):
        # A recorder dropped without close() leaves status "running" (= interrupted), but
        # commits the frames it has and closes the file cleanly.
        try:
            if not self._closed:
                self.flush()
                self._closed = True
                self._file.close()
        except Exception:
            pass


# ----------------------------------------------------------------------------- state channels
#: body motion codes of engine.kernels.bodies, by code: the static ``bodies/motion_names``
#: stores them so that a reader needs no engine import to tell free bodies from fixed ones
BODY_MOTION_NAMES = ("fixed", "kinematic", "hinge", "free")


def state_channels(system) -> tuple[dict, dict]:
    """Channels and statics (beyond the run loop's own) that make a file's momentum and
    kinetic / gravity energy computable: channel group ``node_velocities`` (off by default)
    and, with group ``bodies``, each body's motion code per frame plus its mass properties.
    ``system`` is an ``engine.assembly.system.System``."""
    want = set(system.scene.run.channels)
    ch: dict[str, tuple] = {}
    static: dict[str, np.ndarray] = {}
    nd, bd = system.nodes, system.bodies
    n_nodes = nd.x.shape[0]
    if "node_velocities" in want and n_nodes:
        ch["nodes/velocities"] = ((n_nodes, 3), "f8")
        ch["nodes/angular_velocities"] = ((n_nodes, 3), "f8")
        static["nodes/mass"] = nd.mass
        static["nodes/rotational_inertia"] = nd.inertia
        static["nodes/free"] = nd.inv_mass > 0
        static["nodes/initial_positions"] = nd.x0
    if "bodies" in want and system.body_names:
        static["bodies/motion_names"] = np.array(BODY_MOTION_NAMES)
        for k, name in enumerate(system.body_names):
            ch[f"bodies/{name}/motion"] = ((), "i1")
            static[f"bodies/{name}/mass"] = np.float64(bd.mass[k])
            static[f"bodies/{name}/principal_inertia"] = bd.Ip[k]
            static[f"bodies/{name}/initial_position"] = bd.pos0[k]
            static[f"bodies/{name}/hinge_axis"] = bd.hinge_axis[k]
            static[f"bodies/{name}/hinge_inertia"] = np.float64(bd.hinge_inertia[k])
    if static:
        static["gravity"] = np.asarray(system.tables.gravity, float)
    return ch, static


def state_frame(system, channels) -> dict:
    """This frame's rows of the channels :func:`state_channels` declared."""
    fr: dict[str, Any] = {}
    if "nodes/velocities" in channels:
        fr["nodes/velocities"] = system.nodes.v
        fr["nodes/angular_velocities"] = system.nodes.w
    motion = system.bodies.motion
    for k, name in enumerate(system.body_names):
        key = f"bodies/{name}/motion"
        if key in channels:
            fr[key] = np.int8(motion[k])
    return fr


def error_dict(exc: BaseException) -> dict:
    """The ``error`` attribute for an exception: type, message, traceback, and the
    exception's own ``as_dict()`` fields when it has them (InstabilityError)."""
    out: dict[str, Any] = {"type": type(exc).__name__, "message": str(exc)}
    as_dict = getattr(exc, "as_dict", None)
    if callable(as_dict):
        try:
            out.update(as_dict())
        except Exception:
            pass
    as_dicts = getattr(exc, "as_dicts", None)
    if callable(as_dicts):
        try:
            out["problems"] = as_dicts()
        except Exception:
            pass
    out["traceback"] = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return out
