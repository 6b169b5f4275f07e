"""OptiTrack Motive through NatNet, with the ``natnet`` client (PyPI ``natnet``, MIT, maintained; compared in
the README with OptiTrack's own sample repackaged as ``natnetsdk`` and with ``new-natnet-client``).

Unicast only: the client sends ``NAT_CONNECT`` to the server's command port (1510 by default) and Motive
answers with its server info (application, version, NatNet version) and streams each frame of mocap data to
the address the request came from. NatNet versions 3.0 to 4.x are read; another is refused in one line.
Points are the frame's labelled-marker list (Motive 2+ streams every reconstructed point there, unlabelled
ones flagged; a marker of a marker set or rigid body carries its model id), in metres with Y up by
default; they are turned to mm, Z up: ``(x, y, z) -> 1000 (x, -z, y)`` (as Motive's CSV export is read).
A frame number is the frame prefix's. A labelled marker's label is its name in Motive's data descriptions
(asked for on connecting): the frames that arrive before the descriptions are held back (at most
:data:`DESCRIBE_S` seconds, then labelled ``model:marker``) so that every frame of a recording names the same
marker alike.

The client's own threads print a traceback and die on a packet they cannot parse, so the client is driven
synchronously here (``update_sync`` when its socket has data) on a thread of ours that catches such errors:
garbage or a truncated packet ends the stream with one line. Motive sends nothing when a client goes away, so
a server gone shows as silence: no frame for :data:`SILENCE_S` seconds is a failure.
"""

from __future__ import annotations

import contextlib
import io
import select
import socket
import struct
import threading
import time
from typing import Any

import numpy as np
from natnet import DataDescriptions, DataFrame, NatNetClient
from natnet.exceptions import NatNetError
from natnet.version import Version

from handmocap.core.live.sources import (
    LiveFrame,
    LiveSource,
    Sink,
    SourceError,
    SourceKind,
    is_loopback,
    register_source,
)

DEFAULT_PORT = 1510
OLDEST, NEWEST = Version(3, 0), Version(4, 99)
SILENCE_S = 2.0
DESCRIBE_S = 1.0
UNLABELLED_FLAG = 0x10
RECEIVE_BUFFER = 8 << 20


def motive_to_lab(points: np.ndarray) -> np.ndarray:
    """Motive's metres, Y up ``(N,3)`` -> mm, Z up."""
    return np.stack([points[:, 0], -points[:, 2], points[:, 1]], axis=1) * 1000.0


class NatNetSource(LiveSource):
    """A NatNet unicast connection to Motive (module docstring)."""

    kind = "natnet"
    label = "OptiTrack Motive (NatNet)"

    def __init__(self, host: str, port: int = DEFAULT_PORT) -> None:
        super().__init__(host, port)
        self.client: NatNetClient | None = None
        self.server_version = ""
        self.marker_names: dict[int, str] = {}
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._sink: Sink | None = None
        self._described = False
        self._held: list[tuple[Any, float]] = []
        self._asked = 0.0

    def start(self, sink: Sink, timeout: float = 5.0) -> None:
        self.stop()
        self._sink = sink
        self._stop.clear()
        self._described, self._held, self._asked = False, [], time.perf_counter()
        local = "127.0.0.1" if is_loopback(self.host) else "0.0.0.0"
        client = NatNetClient(server_ip_address=self.host, local_ip_address=local, command_port=self.port,
                              data_port=self.port + 1, use_multicast=False)
        client.on_data_frame_received_event.handlers.append(self._on_frame)
        client.on_data_description_received_event.handlers.append(self._on_descriptions)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                client.connect(timeout=timeout)
        except TimeoutError:
            client.shutdown()
            raise SourceError(f"no NatNet server answers at {self.address} within {timeout:.0f} s: is Motive "
                              "streaming (unicast) on that command port?") from None
        except (OSError, struct.error, UnicodeDecodeError, ValueError) as error:
            client.shutdown()
            raise SourceError(f"cannot connect to NatNet at {self.address}: {_reason(error)}") from None
        info = client.server_info
        version = client.protocol_version
        if info is None or version is None or not OLDEST <= version <= NEWEST:
            client.shutdown()
            raise SourceError(f"the NatNet server at {self.address} speaks NatNet {version}; this program reads "
                              f"NatNet {OLDEST} to 4.x")
        self.server_version = f"{info.application_name} {info.server_version} (NatNet {version})"
        self.client = client
        for sock in _sockets(client):      # room for a few seconds of frames while the labeller is busy
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        with contextlib.suppress(OSError):
            client.request_modeldef()
        self._asked = time.perf_counter()
        self._last = time.perf_counter()
        self._thread = threading.Thread(target=self._run, name="live-natnet", daemon=True)
        self._thread.start()
        self.connected = True

    def _run(self) -> None:
        client = self.client
        assert client is not None
        sockets = _sockets(client)
        message = ""
        while not self._stop.is_set():
            try:
                if sockets:
                    readable = bool(select.select(sockets, [], [], 0.1)[0])
                else:
                    time.sleep(0.001)
                    readable = True
                if readable:
                    with contextlib.redirect_stdout(io.StringIO()):
                        client.update_sync()
            except (struct.error, UnicodeDecodeError, ValueError, IndexError, TypeError, NatNetError) as error:
                message = f"the NatNet server at {self.address} sent a packet this program cannot read " \
                          f"({type(error).__name__}: {error}); the stream is closed"
                break
            except OSError as error:
                message = f"the NatNet connection to {self.address} failed: {_reason(error)}"
                break
            if not self._described and time.perf_counter() - self._asked > DESCRIBE_S:
                self._release()                 # no descriptions: the frames held go on, labelled by ids
            if time.perf_counter() - self._last > SILENCE_S:
                message = f"no frame from the NatNet server at {self.address} for {SILENCE_S:.0f} s: it is gone"
                break
        self.connected = False
        if message and not self._stop.is_set() and self._sink is not None:
            self._sink.failed(message)

    def _on_descriptions(self, descriptions: DataDescriptions) -> None:
        names: dict[int, str] = {}
        for marker_set in getattr(descriptions, "marker_sets", ()) or ():
            for index, name in enumerate(getattr(marker_set, "marker_names", ()) or ()):
                names[index + 1] = str(name)
        self.marker_names = names
        self._release()

    def _release(self) -> None:
        """Deliver the frames held back until the marker names were known."""
        self._described = True
        held, self._held = self._held, []
        for frame, received in held:
            self._deliver(frame, received)

    def _on_frame(self, frame: DataFrame) -> None:
        received = time.perf_counter()
        self._last = received
        if not self._described:
            self._held.append((frame, received))
            return
        self._deliver(frame, received)

    def _deliver(self, frame: DataFrame, received: float) -> None:
        markers = frame.labeled_markers or ()
        if markers:
            points = motive_to_lab(np.array([marker.pos for marker in markers], dtype=float).reshape(-1, 3))
            labels = ["" if (marker.param or 0) & UNLABELLED_FLAG or marker.model_id == 0
                      else self.marker_names.get(marker.marker_id, f"{marker.model_id}:{marker.marker_id}")
                      for marker in markers]
        else:
            points = motive_to_lab(np.array(frame.unlabeled_marker_pos or (), dtype=float).reshape(-1, 3))
            labels = []
        finite = np.isfinite(points).all(axis=1)
        timestamp = getattr(frame.suffix, "timestamp", float("nan"))
        if self._sink is not None:
            self._sink.frame(LiveFrame(int(frame.prefix.frame_number), float(timestamp), points[finite],
                                       [label for label, ok in zip(labels, finite, strict=False) if ok]
                                       if any(labels) else [], received))

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        self._thread = None
        if self.client is not None:
            with contextlib.suppress(OSError):
                self.client.send_request(NatNetClient.NAT_DISCONNECT)
            self.client.shutdown()
        self.client = None
        self.connected = False


def _sockets(client: NatNetClient) -> list[socket.socket]:
    """The client's command and data sockets (it keeps them private; frames arrive on the command socket)."""
    return [sock for sock in (getattr(client, "_NatNetClient__command_socket", None),
                              getattr(client, "_NatNetClient__data_socket", None)) if sock is not None]


def _reason(error: Any) -> str:
    return getattr(error, "strerror", None) or str(error) or type(error).__name__


KIND = SourceKind("natnet", NatNetSource.label, DEFAULT_PORT, NatNetSource)
register_source(KIND)
