"""Keep numba's on-disk cache consistent with the engine's source.

Numba re-validates a cached function against its own file only, not against the functions
it calls in other files, so an edited kernel could be run through a stale caller. At import
we hash every engine source file that holds compiled code (the kernels in ``engine/kernels/``,
any other engine module that imports numba, and the state bundles they are typed on) and drop
all cached kernels (``engine/kernels/__pycache__``) when the hash changed; editing the
numba-free modules (the spec, the build, the run loop in Python) keeps the cache.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

_HERE = Path(__file__).parent


def ensure_fresh_cache(root: Path = _HERE) -> None:
    """Drop the cached kernels under ``root/kernels/__pycache__`` when a numba source of the
    engine at ``root`` changed since the stamp there was written."""
    digest = hashlib.sha256()
    for path in sorted(root.glob("*.py")) + sorted((root / "kernels").glob("*.py")):
        text = path.read_bytes()
        if not (b"from numba" in text or b"import numba" in text or path.name == "state.py"):
            continue
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(text)
    cache_dir = root / "kernels" / "__pycache__"
    stamp = cache_dir / "numba-source.sha256"
    want = digest.hexdigest()
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    try:
        cache_dir.mkdir(exist_ok=True)
        for f in list(cache_dir.glob("*.nbi")) + list(cache_dir.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(want)
    except OSError:
        pass  # a read-only install: numba falls back to its own checks
