"""A small Python client of the Brush Studio HTTP API (``brush-studio serve --headless``).

    from studio.service.client import Client

    client = Client("http://127.0.0.1:8000", token=None)
    run_id = client.submit("scene.json")            # a path, a dict, JSON text or a Scene
    info = client.wait(run_id)                      # tqdm bar over simulated time
    client.download(run_id, "run.h5")               # the HDF5 result file
    data = client.series(run_id, "brushes/brush/root_force")
    t, fz = data["time"], data["values"][:, 2]      # numpy arrays

    study_id = client.submit_study("wedge", {"preset": "wedge_60", "depth_mm": 2})
    client.wait(study_id)                           # tqdm bar over the study's runs
    client.files(study_id)                          # ["force_depth.csv", ...]
    client.download_file(study_id, "force_depth.csv", "out/force_depth.csv")

Errors from the server raise :class:`ApiError` with the HTTP status and the server's message
(for an invalid scene, ``problems`` lists every bad field).
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any, Optional, Union

FINAL_STATUSES = frozenset({"completed", "stopped", "failed", "cancelled"})


class ApiError(RuntimeError):
    """An error answer of the server: ``status`` (HTTP), ``detail`` (its message or
    field-level problems), ``problems`` (for a 422 on a scene: dicts with field, value,
    allowed)."""

    def __init__(self, status: int, detail: Any, message: Optional[str] = None):
        self.status = status
        self.detail = detail
        self.problems = [d for d in detail if isinstance(d, dict) and "field" in d] \
            if isinstance(detail, list) else []
        if message is None:
            if self.problems:
                message = "; ".join(f"{p['field']} = {p.get('value')!r}: {p['allowed']}"
                                    for p in self.problems)
            else:
                message = str(detail)
        super().__init__(f"HTTP {status}: {message}")


class Client:
    """``base_url``: the server (default ``$BRUSH_STUDIO_URL`` or http://127.0.0.1:8000);
    ``token``: its bearer token (default ``$BRUSH_STUDIO_TOKEN``)."""

    def __init__(self, base_url: Optional[str] = None, token: Optional[str] = None,
                 timeout: float = 60.0):
        import httpx

        base_url = base_url or os.environ.get("BRUSH_STUDIO_URL") or "http://127.0.0.1:8000"
        token = token if token is not None else os.environ.get("BRUSH_STUDIO_TOKEN")
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        self.base_url = base_url.rstrip("/")
        self._http = httpx.Client(base_url=self.base_url, headers=headers, timeout=timeout)

    # ------------------------------------------------------------------ plumbing
    def _request(self, method: str, url: str, **kwargs):
        r = self._http.request(method, url, **kwargs)
        if r.status_code >= 400:
            try:
                body = r.json()
                detail = body.get("detail", body) if isinstance(body, dict) else body
                message = body.get("message") if isinstance(body, dict) else None
            except ValueError:
                detail, message = r.text, None
            raise ApiError(r.status_code, detail, message)
        return r

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ API
    def health(self) -> dict:
        return self._request("GET", "/api/health").json()

    def submit(self, scene: Union[str, Path, dict, Any], name: Optional[str] = None,
               idempotency_key: Optional[str] = None) -> str:
        """Submit a scene: a path to a scene JSON file, a dict, JSON text or an
        ``engine.Scene``; returns the run id. Mesh shapes must name uploaded meshes
        (:meth:`upload_mesh`). ``idempotency_key``: the same key submitted again returns
        the first run's id (safe to retry after a lost answer)."""
        if hasattr(scene, "to_json"):
            text = scene.to_json()
        elif isinstance(scene, dict):
            text = json.dumps(scene, allow_nan=True)
        elif isinstance(scene, Path) or (isinstance(scene, str)
                                         and not scene.lstrip().startswith("{")):
            text = Path(scene).read_text()
        else:
            text = str(scene)
        params = {"name": name} if name else None
        headers = {"Content-Type": "application/json"}
        if idempotency_key:
            headers["Idempotency-Key"] = str(idempotency_key)
        r = self._request("POST", "/api/runs", content=text.encode(), params=params,
                          headers=headers)
        return r.json()["id"]

    def get(self, run_id: str) -> dict:
        return self._request("GET", f"/api/runs/{run_id}").json()

    def list(self, status: Optional[str] = None) -> list[dict]:
        return self._request("GET", "/api/runs",
                             params={"status": status} if status else None).json()

    def cancel(self, run_id: str) -> dict:
        return self._request("DELETE", f"/api/runs/{run_id}").json()

    def purge(self, run_id: str) -> dict:
        """Delete a run (cancelled first if it runs) and its files on the server:
        ``{"id", "purged", "freed_bytes"}``."""
        return self._request("DELETE", f"/api/runs/{run_id}",
                             params={"purge": "true"}).json()

    def wait(self, run_id: str, progress: bool = True, poll: float = 0.5,
             timeout: Optional[float] = None) -> dict:
        """Poll until the run (or study) has finished; returns its final state.
        ``progress``: a tqdm bar over simulated time with steps/s and ETA (for a study: over
        its progress, 0..1, with its message). TimeoutError after ``timeout`` s."""
        from tqdm import tqdm

        deadline = None if timeout is None else time.monotonic() + timeout
        bar = None
        try:
            while True:
                info = self.get(run_id)
                study = info.get("kind") == "study"
                if study:
                    if progress and bar is None:
                        bar = tqdm(total=1.0, desc=f"study {run_id}", dynamic_ncols=True,
                                   bar_format="{desc} {percentage:3.0f}%|{bar}| "
                                              "[{elapsed}{postfix}]")
                    if bar is not None:
                        bar.n = min(float(info.get("progress") or 0.0), 1.0)
                        bar.set_postfix_str(f"{info['status']}, {info.get('message') or ''}",
                                            refresh=False)
                        bar.refresh()
                else:
                    until = info.get("until")
                    if progress and bar is None and until:
                        bar = tqdm(total=float(until), unit="s", desc=f"run {run_id}",
                                   dynamic_ncols=True,
                                   bar_format="{desc} {percentage:3.0f}%|{bar}| "
                                              "t = {n:.4g}/{total:.4g} s [{elapsed}{postfix}]")
                    if bar is not None:
                        sim = info.get("sim_time") or 0.0
                        bar.n = min(float(sim), bar.total)
                        rate, eta = info.get("steps_per_s"), info.get("eta_s")
                        post = [info["status"]]
                        if rate:
                            post.append(f"{rate:,.0f} steps/s")
                        if eta is not None and math.isfinite(eta) and \
                                info["status"] == "running":
                            post.append(f"ETA {eta:.0f} s")
                        bar.set_postfix_str(", ".join(post), refresh=False)
                        bar.refresh()
                if info["status"] in FINAL_STATUSES:
                    return info
                if deadline is not None and time.monotonic() > deadline:
                    raise TimeoutError(f"{'study' if study else 'run'} {run_id} is still "
                                       f"{info['status']} after {timeout} s")
                time.sleep(poll)
        finally:
            if bar is not None:
                bar.close()

    def download(self, run_id: str, path: Union[str, Path]) -> Path:
        """Save the run's HDF5 result file to ``path`` (written to a temporary name, then
        renamed: an interrupted download leaves no half file)."""
        return self._download(f"/api/runs/{run_id}/result", path)

    def _download(self, url: str, path: Union[str, Path]) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".part")
        with self._http.stream("GET", url) as r:
            if r.status_code >= 400:
                r.read()
                try:
                    detail = r.json().get("detail")
                except ValueError:
                    detail = r.text
                raise ApiError(r.status_code, detail)
            with open(tmp, "wb") as f:
                for chunk in r.iter_bytes():
                    f.write(chunk)
        os.replace(tmp, path)
        return path

    def channels(self, run_id: str) -> list[str]:
        return self._request("GET", f"/api/runs/{run_id}/series").json()["channels"]

    def series(self, run_id: str, channel: str, start: int = 0, stop: Optional[int] = None,
               step: int = 1) -> dict:
        """One channel as numpy arrays: ``{"time": (n,), "values": (n, ...), "status"}``
        (non-finite values come back as NaN)."""
        import numpy as np

        params: dict = {"channel": channel, "start": start, "step": step}
        if stop is not None:
            params["stop"] = stop
        data = self._request("GET", f"/api/runs/{run_id}/series", params=params).json()
        values = data["series"][channel]["values"]
        return {"time": np.array(data["time"], dtype=float),
                "values": np.array(values, dtype=float),
                "status": data["status"], "n_frames": data["n_frames"]}

    # ------------------------------------------------------------------ studies
    def submit_study(self, study: str, options: Optional[dict] = None,
                     name: Optional[str] = None) -> str:
        """Submit a study (``wedge``, ``spin``, ``refinement``, ``convergence``, ...) with
        its options by name (``{"preset": "wedge_60", "depth_mm": 2, "nodes": 3}``; see
        :meth:`study_types`); returns the job id. :class:`ApiError` (422) names a bad
        study or option."""
        body: dict = {"study": study, "options": options or {}}
        if name:
            body["name"] = name
        return self._request("POST", "/api/studies", json=body).json()["id"]

    def study(self, study_id: str) -> dict:
        return self._request("GET", f"/api/studies/{study_id}").json()

    def studies(self, status: Optional[str] = None) -> list[dict]:
        return self._request("GET", "/api/studies",
                             params={"status": status} if status else None).json()

    def study_types(self) -> dict:
        """Each study's options (name, kind, help, default, ...)."""
        return self._request("GET", "/api/study-types").json()

    def cancel_study(self, study_id: str) -> dict:
        return self._request("DELETE", f"/api/studies/{study_id}").json()

    def files(self, study_id: str) -> list[str]:
        """The study's output files so far (names relative to its folder)."""
        data = self._request("GET", f"/api/studies/{study_id}/files").json()
        return [f["name"] for f in data["files"]]

    def download_file(self, study_id: str, name: str, path: Union[str, Path]) -> Path:
        """Save one output file of a study (a name from :meth:`files`) to ``path``."""
        from urllib.parse import quote

        return self._download(f"/api/studies/{study_id}/files/{quote(name)}", path)

    def presets(self) -> list[dict]:
        return self._request("GET", "/api/presets").json()

    def preset(self, name: str) -> dict:
        return self._request("GET", f"/api/presets/{name}").json()

    def upload_mesh(self, path: Union[str, Path]) -> dict:
        """Upload an STL/OBJ/PLY file; returns its description, whose ``ref``
        (``"mesh:<id>"``) a scene's mesh shape names as ``file``."""
        path = Path(path)
        with open(path, "rb") as f:
            r = self._request("POST", "/api/meshes",
                              files={"file": (path.name, f, "application/octet-stream")})
        return r.json()
