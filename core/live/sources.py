"""The live source interface and its registry.

A source connects to a capture system and calls ``sink.frame(LiveFrame)`` for every frame of 3D points it
receives, from a thread of its own (:meth:`LiveSource.start`), until :meth:`LiveSource.stop`. What goes wrong
(the server gone, garbage, a protocol version we do not speak, a second client refused) reaches
``sink.failed(message)`` as one line, and the source stops; :meth:`LiveSource.start` may then be called again
(the capture reconnects). Capture-system events (QTM's capture started/stopped) reach ``sink.event(name)``.

Adding a system is one module and one :func:`register_source`: ``SOURCES[kind]`` makes a source from an
address ``HOST[:PORT]`` (the system's default port when omitted).
"""

from __future__ import annotations

import ipaddress
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from handmocap.core.errors import InputError


class SourceError(InputError):
    """A live source cannot connect or stream (one line for the operator)."""


@dataclass
class LiveFrame:
    """One frame as received: the system's ``number`` (frames dropped on the way show as gaps), its
    ``timestamp_s`` (the system's clock; NaN unknown), ``points (N,3)`` mm in a Z-up lab frame exactly as
    received (converted only from the system's units and axes), the system's own ``labels`` per point
    ("" unlabelled; empty list when it sends none), and ``received`` (``time.perf_counter()`` when the packet
    had been read)."""

    number: int
    timestamp_s: float
    points: np.ndarray
    labels: list[str] = field(default_factory=list)
    received: float = 0.0


class Sink(Protocol):
    """Where a source delivers frames, events and failures (called from the source's thread)."""

    def frame(self, frame: LiveFrame) -> None: ...

    def event(self, name: str) -> None: ...

    def failed(self, message: str) -> None: ...


class LiveSource(ABC):
    """A connection to one capture system (module docstring). ``frame_rate`` (Hz) is known once connected."""

    kind = ""
    label = ""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.frame_rate: float | None = None
        self.connected = False

    @property
    def address(self) -> str:
        return f"{self.host}:{self.port}"

    @abstractmethod
    def start(self, sink: Sink, timeout: float = 5.0) -> None:
        """Connect and stream on a thread of its own; returns once streaming or raises :class:`SourceError`."""

    @abstractmethod
    def stop(self) -> None:
        """Stop streaming and disconnect (idempotent)."""

    def control(self, command: str, argument: str = "") -> str:
        """Capture control (start, stop, new, save NAME) when the system offers it; one-line result."""
        raise SourceError(f"{self.label} offers no capture control here")


@dataclass(frozen=True)
class SourceKind:
    """A registered system: ``kind`` (the CLI option), ``label`` (for people), ``default_port``, ``factory``."""

    kind: str
    label: str
    default_port: int
    factory: Callable[[str, int], LiveSource]


SOURCES: dict[str, SourceKind] = {}


def register_source(kind: SourceKind) -> None:
    """Add (or replace) a system in :data:`SOURCES`."""
    SOURCES[kind.kind] = kind


def parse_address(text: str, default_port: int) -> tuple[str, int]:
    """``HOST[:PORT]`` -> (host, port); InputError (one line) when malformed."""
    host, _, port_text = str(text).strip().rpartition(":") if ":" in str(text) else (str(text).strip(), "", "")
    host = host.strip("[]")
    if not host:
        raise InputError(f"'{text}' is not an address: give HOST or HOST:PORT")
    if not port_text:
        return host, default_port
    try:
        port = int(port_text)
    except ValueError:
        raise InputError(f"'{text}': the port must be a number from 1 to 65535") from None
    if not 0 < port < 65536:
        raise InputError(f"'{text}': the port must be a number from 1 to 65535")
    return host, port


def is_loopback(host: str) -> bool:
    """True for a loopback address (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
