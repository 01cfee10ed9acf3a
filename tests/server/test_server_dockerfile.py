"""The Dockerfile, without Docker (it cannot run here): its static promises (non-root user,
ports, health check, CMD), and its install and warm-up RUN steps executed in a fresh
virtual environment on a copy of the build context (as .dockerignore filters it)."""
from __future__ import annotations

import fnmatch
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def instructions(path: Path = ROOT / "Dockerfile") -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) pairs, continuation lines joined, comments dropped."""
    out, buf = [], ""
    for line in path.read_text().splitlines():
        stripped = line.strip()
        if not buf and (not stripped or stripped.startswith("#")):
            continue
        if stripped.endswith("\\"):
            buf += stripped[:-1] + " "
            continue
        buf += stripped
        word, _, rest = buf.partition(" ")
        out.append((word.upper(), rest.strip()))
        buf = ""
    return out


def _ignored(rel: str, patterns: list[str]) -> bool:
    for p in patterns:
        if p.startswith("**/"):
            if fnmatch.fnmatch(Path(rel).name, p[3:]):
                return True
        elif fnmatch.fnmatch(rel, p) or rel.split("/")[0] == p:
            return True
    return False


def copy_context(dest: Path) -> None:
    """The build context as Docker would send it (.dockerignore applied)."""
    patterns = [ln.strip() for ln in (ROOT / ".dockerignore").read_text().splitlines()
                if ln.strip() and not ln.startswith("#")]

    def ignore(folder, names):
        rel_dir = Path(folder).relative_to(ROOT)
        return [n for n in names if _ignored(str(rel_dir / n).lstrip("./") if str(rel_dir)
                                             != "." else n, patterns)]

    shutil.copytree(ROOT, dest, ignore=ignore, symlinks=True)


def test_dockerfile_promises():
    ins = instructions()
    kinds = [k for k, _ in ins]
    assert ins[0][0] == "FROM" and "python:3.11" in ins[0][1]
    users = [a for k, a in ins if k == "USER"]
    assert users and users[-1] not in ("root", "0")
    # the warm-up runs as that user, so the kernel cache it writes stays writable
    assert kinds.index("USER") < max(i for i, (k, a) in enumerate(ins)
                                     if k == "RUN" and "brush-studio demo" in a)
    exposed = {p for k, a in ins if k == "EXPOSE" for p in a.split()}
    cmd = json.loads(next(a for k, a in ins if k == "CMD"))
    assert cmd[:2] == ["brush-studio", "studio"] and "0.0.0.0" in cmd
    studio_port = cmd[cmd.index("--port") + 1]
    api_port = cmd[cmd.index("--api-port") + 1]
    assert {studio_port, api_port} <= exposed
    health = next(a for k, a in ins if k == "HEALTHCHECK")
    assert f"127.0.0.1:{api_port}/api/health" in health
    alt = [ln for ln in (ROOT / "Dockerfile").read_text().splitlines()
           if ln.startswith("# CMD") and "serve" in ln]
    assert alt and "--headless" in alt[0] and f'"{api_port}"' in alt[0]
    ignored = (ROOT / ".dockerignore").read_text()
    assert "**/__pycache__" in ignored and ".git" in ignored  # no stale kernel cache


@pytest.mark.slow  # a cold numba compile of the engine: minutes on a loaded 2-core machine
def test_install_and_warm_up_steps_in_a_fresh_venv(tmp_path):
    ins = instructions()
    workdir = next(a for k, a in ins if k == "WORKDIR")
    runs = [a for k, a in ins if k == "RUN"]
    install = [r for r in runs if "pip install" in r]
    warm = [r for r in runs if "brush-studio" in r and "pip install" not in r]
    assert len(install) == 1 and len(warm) == 1, runs

    app = tmp_path / "app"
    copy_context(app)
    assert not (app / "engine" / "kernels" / "__pycache__").exists()
    assert not (app / ".git").exists()
    venv = tmp_path / "venv"
    # --system-site-packages: the dependencies are already here, nothing to download
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)],
                   check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env['PATH']}", VIRTUAL_ENV=str(venv),
               HOME=str(tmp_path), NUMBA_NUM_THREADS="1")
    for name, value in re.findall(r"(\w+)=(\S+)", next(
            (a for k, a in ins if k == "ENV"), "")):
        env[name] = value
    # the Dockerfile's WORKDIR is the copied build context
    assert workdir == "/app"
    for step in (install[0], warm[0]):
        r = subprocess.run(["bash", "-c", "set -e; " + step.replace(workdir, str(app))],
                           cwd=app, env=env, capture_output=True, text=True, timeout=1800)
        assert r.returncode == 0, f"{step}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"

    # the project the venv runs is the one the Dockerfile's command installed
    where = subprocess.run([str(venv / "bin" / "python"), "-c",
                            "import engine, studio; print(engine.__file__)"],
                           cwd=tmp_path, env=env, capture_output=True, text=True, check=True)
    assert Path(where.stdout.strip()).is_relative_to(app)
    version = subprocess.run([str(venv / "bin" / "brush-studio"), "--version"], cwd=tmp_path,
                             env=env, capture_output=True, text=True, check=True)
    assert re.fullmatch(r"brush-studio \d+\.\d+\.\d+\S*", version.stdout.strip())
    # the warm-up compiled and cached the kernels, and cleaned up after itself
    cache = app / "engine" / "kernels" / "__pycache__"
    assert len(list(cache.glob("*.nbi"))) >= 5 and list(cache.glob("*.nbc"))
    assert (cache / "numba-source.sha256").is_file()
    assert not (app / "warmup").exists()
