"""Keep numba's on-disk cache consistent with the engine's source.

Numba re-validates a cached function against its own file only, not against the functions
it calls in other files, so an edited kernel could be run through a stale caller. At import
we hash every engine source file and drop all cached kernels when the hash changed.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

_HERE = Path(__file__).parent


def ensure_fresh_cache() -> None:
    digest = hashlib.sha256()
    for path in sorted(_HERE.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    stamp = _HERE / "__pycache__" / "numba-source.sha256"
    want = digest.hexdigest()
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    cache_dir = _HERE / "__pycache__"
    try:
        cache_dir.mkdir(exist_ok=True)
        for f in list(cache_dir.glob("*.nbi")) + list(cache_dir.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(want)
    except OSError:
        pass  # a read-only install: numba falls back to its own checks
