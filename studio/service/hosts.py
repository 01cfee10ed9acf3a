"""Which Host names a server bound to an address answers (the service's and the studio's
guard against DNS rebinding: docs/api.md, "Safety"), shared by ``brush-studio serve`` and
``brush-studio studio``."""
from __future__ import annotations

import ipaddress


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def allowed_hosts(host: str, extra=()) -> "set[str] | None":
    """The names a request's Host may give: the bound address, its loopback aliases when it
    is a loopback address, and ``extra``; None (unchecked) for a wildcard bind without
    ``extra``."""
    names = {h for h in extra if h}
    if host in ("0.0.0.0", "::", ""):
        return names | {"localhost", "127.0.0.1", "::1"} if names else None
    names.add(host)
    if is_loopback(host):
        names |= {"localhost", "127.0.0.1", "::1"}
    return names
