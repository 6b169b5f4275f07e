"""The shipped live sources, registered: QTM (:mod:`core.live.qtm`) and NatNet (:mod:`core.live.natnet`)."""

from __future__ import annotations

from handmocap.core.errors import InputError
from handmocap.core.live import natnet, qtm
from handmocap.core.live.sources import SOURCES, LiveSource, parse_address

BUILTIN = (qtm.KIND, natnet.KIND)


def make_source(kind: str, address: str) -> LiveSource:
    """The source of registered ``kind`` ("qtm", "natnet") for ``address`` (``HOST[:PORT]``)."""
    if kind not in SOURCES:
        raise InputError(f"unknown live source '{kind}': one of {', '.join(sorted(SOURCES))}")
    entry = SOURCES[kind]
    host, port = parse_address(address, entry.default_port)
    return entry.factory(host, port)
