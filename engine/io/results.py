"""The one reader of Brush Studio result files (layout: ``docs/results.md``).

Used by plots, tests, the studio and the API. It opens finished files, files a run is still
writing, and files whose writer was killed; it only ever returns the first ``n_frames`` rows.

    with open_result("run.h5") as r:
        t = r.time
        f = r.series("brushes/main/root_force")   # (n_frames, 3)
        L = r.angular_momentum(about=(0, 0, 0))  # (n_frames, 3), needs "node_velocities"

Physics from a file (``energy``, ``kinetic_energy``, ``angular_momentum``, ``linear_momentum``)
follows ``engine.energies`` / ``engine.angular_momentum`` / ``engine.linear_momentum`` of the
live system term by term; see "Physics from a file" in ``docs/results.md``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from engine.errors import BrushStudioError
from engine.model.layout import quat_to_matrix
from engine.io.recorder import FORMAT, FORMAT_VERSION

ENERGY_KEYS = ("kinetic", "bond", "contact", "gravity", "dissipated", "external_work", "total")


class MissingChannelError(BrushStudioError, LookupError):
    """A quantity needs a channel group the file does not have. ``group`` is the name to add
    to the scene's ``run.channels``; ``dataset`` the missing dataset path."""

    def __init__(self, path, quantity: str, group: str, dataset: str):
        self.group = group
        self.dataset = dataset
        self.quantity = quantity
        super().__init__(
            f"{path}: {quantity} needs channel group {group!r} (dataset {dataset!r}), which "
            f"this file does not have: add \"{group}\" to the scene's run.channels and run "
            f"it again")


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
        """The run's scene (engine.model.spec.Scene), parsed on first use."""
        if self._scene is None:
            from engine.model.spec import parse_scene
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

    # ---------------------------------------------------------------- physics
    # Same terms, same selections (free nodes, free / hinge bodies) as engine.energies,
    # engine.angular_momentum and engine.linear_momentum of the live System.
    def kinetic_energy(self, frame=None):
        """Translational + rotational kinetic energy of free nodes and free / hinge bodies, J:
        a float for frame ``i``, an (n_frames,) array for ``frame=None``. Needs channel
        groups ``node_velocities`` (if the scene has brushes) and ``bodies`` (if it has
        bodies)."""
        sel, one = self._frames(frame)
        total = np.zeros(self._n_selected(sel))
        nodes = self._node_state(sel, "kinetic energy", positions=False)
        if nodes is not None:
            v, w = nodes["velocity"], nodes["angular_velocity"]
            total += 0.5 * np.einsum("n,fni,fni->f", nodes["mass"], v, v)
            total += 0.5 * np.einsum("n,fni,fni->f", nodes["inertia"], w, w)
        for body in self._body_states(sel, "kinetic energy"):
            free, hinge = body["free"], body["hinge"]
            v, w = body["velocity"], body["angular_velocity"]
            L = _body_angular_momentum(body)
            total += np.where(free, 0.5 * body["mass"] * np.einsum("fi,fi->f", v, v)
                              + 0.5 * np.einsum("fi,fi->f", w, L), 0.0)
            om = w @ body["hinge_axis"]
            total += np.where(hinge, 0.5 * body["hinge_inertia"] * om * om, 0.0)
        return float(total[0]) if one else total

    def energy(self, frame=None) -> dict:
        """The breakdown of ``engine.energies(system)`` at frame ``i`` (floats) or at every
        frame (``frame=None``: (n_frames,) arrays), J.

        ``kinetic`` and ``gravity`` are computed from the recorded state (node velocities and
        spins, positions, masses; body velocities, orientations, mass properties): channel
        groups ``node_velocities``, ``nodes`` and ``bodies``. ``bond``, ``contact``,
        ``dissipated`` and ``external_work`` cannot be computed from positions (they need the
        bonds' rest geometry and stiffnesses, the contacts' tangential springs and the run's
        history) and are the values the run loop recorded in channel group ``energy``.
        ``total`` is ``kinetic + bond + contact + gravity`` as in ``engine.energies``."""
        sel, one = self._frames(frame)
        out = {"kinetic": self.kinetic_energy(frame)}
        for key in ("bond", "contact", "dissipated", "external_work"):
            name = f"energy/{key}"
            if name not in self._channel_names:
                raise MissingChannelError(self.path, f"the {key} energy", "energy", name)
            out[key] = self.series(name, sel) if not one else float(self.frame(name, frame))
        gravity = np.zeros(self._n_selected(sel))
        nodes = self._node_state(sel, "the gravity energy", velocities=False)
        if nodes is not None:
            gravity -= np.einsum("n,fni,i->f", nodes["mass"],
                                 nodes["position"] - nodes["initial_position"],
                                 nodes["gravity"])
        for body in self._body_states(sel, "the gravity energy"):
            moving = body["free"] | body["hinge"]
            gravity -= np.where(moving, body["mass"] * ((body["position"]
                                                         - body["initial_position"])
                                                        @ body["gravity"]), 0.0)
        gravity = gravity + self._orbit_energy(
            nodes, self._body_states(sel, "the gravity energy"), len(gravity))
        out["gravity"] = float(gravity[0]) if one else gravity
        out["total"] = out["kinetic"] + out["bond"] + out["contact"] + out["gravity"]
        return {key: out[key] for key in ENERGY_KEYS}

    def angular_momentum(self, about=(0.0, 0.0, 0.0), frame=None) -> np.ndarray:
        """Total angular momentum of free nodes (orbital + spin) and free bodies about the
        point ``about`` (m, world frame), kg m^2/s: (3,) for frame ``i``, (n_frames, 3) for
        ``frame=None``. Hinge bodies are left out, as in ``engine.angular_momentum`` (their
        axle takes up angular momentum). Needs channel groups ``nodes`` and
        ``node_velocities`` (if the scene has brushes) and ``bodies`` (if it has bodies)."""
        sel, one = self._frames(frame)
        o = np.asarray(about, float).reshape(3)
        total = np.zeros((self._n_selected(sel), 3))
        nodes = self._node_state(sel, "angular momentum")
        if nodes is not None:
            p = nodes["mass"][None, :, None] * nodes["velocity"]
            total += np.cross(nodes["position"] - o, p).sum(axis=1)
            total += np.einsum("n,fni->fi", nodes["inertia"], nodes["angular_velocity"])
        for body in self._body_states(sel, "angular momentum"):
            own = np.cross(body["position"] - o, body["mass"] * body["velocity"])
            own += _body_angular_momentum(body)
            total += np.where(body["free"][:, None], own, 0.0)
        return total[0] if one else total

    def body_angular_momentum(self, name: str, frame=None) -> np.ndarray:
        """Spin angular momentum of body ``name`` about its centre of mass (inertial, world
        components; the engine's ``L``), kg m^2/s: (3,) for frame ``i``, (n_frames, 3) for
        ``frame=None``. Needs channel group ``bodies``."""
        sel, one = self._frames(frame)
        names = list(self.json_attr("body_names", []))
        if name not in names:
            raise KeyError(f"{self.path} has no body {name!r}; bodies: {names}")
        L = _body_angular_momentum(self._body_states(sel, "angular momentum")[names.index(name)])
        return L[0] if one else L

    def linear_momentum(self, frame=None) -> np.ndarray:
        """Total linear momentum of free nodes and free bodies, kg m/s: (3,) for frame ``i``,
        (n_frames, 3) for ``frame=None``. Needs ``node_velocities`` / ``bodies`` as
        ``kinetic_energy`` does."""
        sel, one = self._frames(frame)
        total = np.zeros((self._n_selected(sel), 3))
        nodes = self._node_state(sel, "linear momentum", positions=False)
        if nodes is not None:
            total += np.einsum("n,fni->fi", nodes["mass"], nodes["velocity"])
        for body in self._body_states(sel, "linear momentum"):
            total += np.where(body["free"][:, None], body["mass"] * body["velocity"], 0.0)
        return total[0] if one else total

    def _frames(self, frame):
        """(selection for ``series``, whether one frame was asked for)."""
        if frame is None:
            return slice(None), False
        if isinstance(frame, slice):
            return frame, False
        i = int(frame)
        n = self.n_frames
        if not -n <= i < n:
            raise IndexError(f"frame {frame} out of range: {self.path} has {n} frames")
        return [i % n], True

    def _n_selected(self, sel) -> int:
        return len(self.series("time", sel))

    def _need(self, name: str, group: str, quantity: str) -> None:
        if name not in self._channel_names:
            raise MissingChannelError(self.path, quantity, group, name)

    def _node_state(self, sel, quantity: str, positions=True, velocities=True):
        """The free nodes' statics (``mass``, ``inertia``, ``initial_position``,
        ``gravity``) and, over the selected frames, ``position`` and / or ``velocity`` and
        ``angular_velocity`` as asked; None if the scene has no nodes."""
        if not self.json_attr("brush_names", []):
            return None
        # the statics come with the velocities (channel group node_velocities)
        self._need("nodes/velocities", "node_velocities", quantity)
        if positions:
            self._need("nodes/positions", "nodes", quantity)
        free = np.asarray(self.static("nodes/free"), bool)
        out = {"mass": self.static("nodes/mass")[free],
               "inertia": self.static("nodes/rotational_inertia")[free],
               "initial_position": self.static("nodes/initial_positions")[free],
               "gravity": np.asarray(self.static("gravity"), float)}
        if positions:
            out["position"] = self.series("nodes/positions", sel)[:, free]
        if velocities:
            out["velocity"] = self.series("nodes/velocities", sel)[:, free]
            out["angular_velocity"] = self.series("nodes/angular_velocities", sel)[:, free]
        return out

    def _body_states(self, sel, quantity: str) -> list[dict]:
        """Per body: its recorded state over the selected frames, its mass properties, and
        boolean (frames,) masks ``free`` / ``hinge`` from its motion code at each frame."""
        out = []
        for name in self.json_attr("body_names", []):
            self._need(f"bodies/{name}/position", "bodies", quantity)
            self._need(f"bodies/{name}/motion", "bodies", quantity)
            motion_names = [str(n) for n in self.static("bodies/motion_names")]
            code = self.series(f"bodies/{name}/motion", sel)
            body = {key: self.series(f"bodies/{name}/{key}", sel) for key in (
                "position", "orientation", "velocity", "angular_velocity")}
            for key in ("mass", "principal_inertia", "initial_position", "hinge_axis",
                        "hinge_inertia"):
                body[key] = np.asarray(self.static(f"bodies/{name}/{key}"), float)
            body["gravity"] = np.asarray(self.static("gravity"), float)
            body["frame_rate"] = self._frame_rate()
            body["free"] = code == motion_names.index("free")
            body["hinge"] = code == motion_names.index("hinge")
            out.append(body)
        return out


    def _orbit_energy(self, nodes, bodies, n_frames: int) -> np.ndarray | float:
        """The orbital part of the Jacobi integral (``engine.kernels.orbit.orbit_energy_terms``,
        the same function as the live ``engine.energies``): 0 without an orbit."""
        orbit = self.scene.environment.orbit
        if orbit is None or orbit.n == 0.0:
            return 0.0
        from engine.kernels.orbit import orbit_energy_terms
        if nodes is not None:
            node_mass, node_x = nodes["mass"], nodes["position"]
        else:
            node_mass, node_x = np.zeros(0), np.zeros((n_frames, 0, 3))
        if not bodies:
            F = n_frames
            return orbit_energy_terms(orbit.n, orbit.gravity_gradient, node_mass, node_x,
                                      np.zeros((F, 0)), np.zeros(0), np.zeros((F, 0, 3)),
                                      np.zeros((F, 0, 3, 3)), np.zeros((0, 3)),
                                      np.zeros((F, 0, 3)))
        stack = lambda key: np.stack([b[key] for b in bodies], axis=1)  # noqa: E731
        motion = np.stack([np.where(b["free"], 3, np.where(b["hinge"], 2, 0))
                           for b in bodies], axis=1)
        R = np.stack([quat_to_matrix(b["orientation"]) for b in bodies], axis=1)
        L = np.stack([_body_angular_momentum(b) for b in bodies], axis=1)
        return orbit_energy_terms(orbit.n, orbit.gravity_gradient, node_mass, node_x, motion,
                                  np.array([float(b["mass"]) for b in bodies]),
                                  stack("position"), R,
                                  np.stack([b["principal_inertia"] for b in bodies]), L)

    def _frame_rate(self) -> np.ndarray:
        """The world frame's rotation rate relative to inertial space, rad/s: n z_hat in the
        Hill frame of a scene with an orbit (docs/mission.md), zero otherwise."""
        orbit = self.scene.environment.orbit
        n = orbit.n if orbit is not None else 0.0
        return np.array([0.0, 0.0, n])


def _body_angular_momentum(body: dict) -> np.ndarray:
    """World-frame spin angular momentum R diag(I_p) R^T (w + Omega) of a body, (F, 3): the
    engine integrates this L and derives w from it, so this recovers it to round-off. With
    an orbit the recorded w is relative to the turning Hill frame and L is inertial
    (``Omega = n z_hat``, docs/mission.md); without one Omega = 0."""
    R = quat_to_matrix(body["orientation"])
    w_inertial = body["angular_velocity"] + body.get("frame_rate", np.zeros(3))
    in_body = np.einsum("fji,fj->fi", R, w_inertial)
    return np.einsum("fij,fj->fi", R, body["principal_inertia"] * in_body)
