"""The stale-cache check of engine/_cache.py: numba re-validates a cached kernel against its
own file only, so an edit to a kernel that another kernel calls must drop every cached kernel
in ``engine/kernels/__pycache__``. Run on a copy of the engine's sources, so that the real
cache is left alone; catches a hash that misses ``engine/kernels/`` (a kernel edit would then
keep stale callers) or that covers the numba-free modules (every spec edit would recompile)."""
from __future__ import annotations

import shutil
from pathlib import Path

import engine
from engine._cache import ensure_fresh_cache

ENGINE = Path(engine.__file__).parent


def _copy_sources(dest: Path) -> Path:
    root = dest / "engine"
    for path in ENGINE.rglob("*.py"):
        if "__pycache__" in path.parts:
            continue
        (root / path.relative_to(ENGINE)).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(path, root / path.relative_to(ENGINE))
    return root


def _plant_cached_kernel(root: Path) -> Path:
    cached = root / "kernels" / "__pycache__" / "bonds.bond_node_forces-1.py311.nbi"
    cached.write_bytes(b"stand-in for a numba index")
    return cached


def test_a_kernel_edit_drops_the_cached_kernels(tmp_path):
    root = _copy_sources(tmp_path)
    ensure_fresh_cache(root)  # first import: writes the stamp
    assert (root / "kernels" / "__pycache__" / "numba-source.sha256").is_file()
    cached = _plant_cached_kernel(root)

    ensure_fresh_cache(root)
    assert cached.exists(), "unchanged sources must keep the cache"

    contact_law = root / "kernels" / "contact_law.py"
    contact_law.write_text(contact_law.read_text() + "\n# an edit\n")
    ensure_fresh_cache(root)
    assert not cached.exists(), "a kernel edit must drop the cached kernels"


def test_an_edit_of_the_state_bundles_drops_the_cache_and_a_spec_edit_keeps_it(tmp_path):
    root = _copy_sources(tmp_path)
    ensure_fresh_cache(root)
    cached = _plant_cached_kernel(root)

    spec = root / "model" / "spec.py"
    spec.write_text(spec.read_text() + "\n# an edit\n")
    ensure_fresh_cache(root)
    assert cached.exists(), "the spec holds no compiled code: its edit must keep the cache"

    state = root / "state.py"
    state.write_text(state.read_text() + "\n# an edit\n")
    ensure_fresh_cache(root)
    assert not cached.exists(), "the kernels are typed on the state bundles"


def test_the_engine_keeps_its_stamp_beside_the_kernel_cache():
    # importing engine ran the check on the real sources: the stamp is where numba caches
    assert (ENGINE / "kernels" / "__pycache__" / "numba-source.sha256").is_file()
