"""Qualisys QTM through its real-time protocol, with Qualisys's own SDK ``qtm-rt`` (asyncio).

The source connects to the little-endian port (22223 by default, base port + 1), sets protocol version
:data:`RT_VERSION`, reads the capture rate and the 3D labels (``GetParameters General 3D``) and streams
``3D`` (the markers QTM identified, with their labels) and ``3DNoLabels`` (the unidentified ones) of every
frame (``StreamFrames AllFrames``); ``GetState`` first, so that the sink hears whether QTM is capturing already.
Points are QTM's float32 mm as sent; a labelled marker QTM has not found in a frame (NaN) is no point. QTM's
events (capture started/stopped...) reach the sink by name.

The SDK parses what it is sent without checks (a packet header declaring fewer than 8 bytes loops for ever),
so the byte stream is framed and checked here first (:class:`_CheckedProtocol`): garbage or a truncated
component ends the connection with one line. Capture control (``TakeControl``, ``New``, ``Start``, ``Stop``,
``Save NAME``) is :meth:`QtmSource.control`.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import re
import struct
import threading
import time
from typing import Any
from xml.etree import ElementTree

import numpy as np
import qtm_rt
from qtm_rt.packet import QRTComponentType, QRTEvent, QRTPacket
from qtm_rt.protocol import QRTCommandException, QTMProtocol

from handmocap.core.live.sources import SOURCES, LiveFrame, LiveSource, Sink, SourceError, SourceKind, register_source

RT_VERSION = "1.25"
DEFAULT_PORT = 22223
_HEADER = struct.Struct("<II")
_COMPONENT = struct.Struct("<II")
_KNOWN_TYPES = range(0, 10)
_MAX_PACKET = 64 << 20
EVENT_NAMES = {event: re.sub(r"(?<!^)(?=[A-Z])", " ", event.name.removeprefix("Event")).lower()
               for event in QRTEvent}


class _CheckedProtocol(QTMProtocol):
    """QTMProtocol with the byte stream framed and checked before the SDK parses it."""

    def __init__(self, *args: Any, on_garbage: Any = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending = b""
        self.on_garbage = on_garbage
        self.broken = False
        self.last_error = ""
        self.closed: asyncio.Future = self.loop.create_future()

    def _on_error(self, response: Any) -> None:
        self.last_error = _text(response)
        super()._on_error(response)

    def connection_lost(self, exc: Exception | None) -> None:
        if not self.closed.done():
            self.closed.set_result(None)
        super().connection_lost(exc)

    def data_received(self, data: bytes) -> None:
        if self.broken:
            return
        self._pending += data
        complete = 0
        buffer = self._pending
        while len(buffer) - complete >= _HEADER.size:
            size, kind = _HEADER.unpack_from(buffer, complete)
            if size < _HEADER.size or size > _MAX_PACKET or kind not in _KNOWN_TYPES:
                self._garbage(f"a packet header that is no RT packet (size {size}, type {kind})")
                return
            if len(buffer) - complete < size:
                break
            if kind == 3 and not _data_packet_ok(buffer[complete + _HEADER.size:complete + size]):
                self._garbage("a data packet whose components overrun it (truncated or garbage)")
                return
            complete += size
        self._pending = buffer[complete:]
        if complete:
            try:
                super().data_received(buffer[:complete])
            except Exception as error:  # noqa: BLE001 - the SDK's parser on a packet it cannot read
                self._garbage(f"a packet the QTM SDK cannot read ({type(error).__name__}: {error})")

    def _garbage(self, what: str) -> None:
        self.broken = True
        if self.on_garbage is not None:
            self.on_garbage(f"QTM sent {what}; the connection is closed")
        if self.transport is not None:
            self.transport.close()


def _data_packet_ok(body: bytes) -> bool:
    """The components of a data packet body (after the 8-byte header) fit in it."""
    if len(body) < 16:
        return False
    count = struct.unpack_from("<I", body, 12)[0]
    position = 16
    for _ in range(count):
        if position + _COMPONENT.size > len(body):
            return False
        size, kind = _COMPONENT.unpack_from(body, position)
        if size < _COMPONENT.size or position + size > len(body) or not 1 <= kind <= 19:
            return False
        if kind in (1, 2) and size >= 16:
            markers = struct.unpack_from("<I", body, position + 8)[0]
            if 16 + markers * (12 if kind == 1 else 16) > size:
                return False
        position += size
    return True


class QtmSource(LiveSource):
    """A QTM real-time connection (module docstring)."""

    kind = "qtm"
    label = "Qualisys QTM"

    def __init__(self, host: str, port: int = DEFAULT_PORT, version: str = RT_VERSION) -> None:
        super().__init__(host, port)
        self.version = version
        self.labels: list[str] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._connection: qtm_rt.QRTConnection | None = None
        self._sink: Sink | None = None
        self._stopping = False
        self._failed = False

    # --- connection on the source's own asyncio loop ---------------------------------------------------

    def start(self, sink: Sink, timeout: float = 5.0) -> None:
        self.stop()
        self._sink, self._stopping, self._failed = sink, False, False
        loop = asyncio.new_event_loop()
        self._loop = loop
        ready: dict[str, Any] = {}
        started = threading.Event()

        def run() -> None:
            asyncio.set_event_loop(loop)
            try:
                loop.run_until_complete(self._connect(timeout))
            except SourceError as error:
                ready["error"] = str(error)
            except (TimeoutError, OSError, RuntimeError) as error:
                ready["error"] = f"cannot connect to QTM at {self.address}: {_reason(error)}"
            started.set()
            if "error" not in ready:
                loop.run_forever()
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

        self._thread = threading.Thread(target=run, name="live-qtm", daemon=True)
        self._thread.start()
        started.wait(timeout + 5.0)
        if "error" in ready or not started.is_set():
            self._thread.join(2.0)
            raise SourceError(ready.get("error", f"QTM at {self.address} did not answer within {timeout:.0f} s"))
        self.connected = True

    async def _connect(self, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        try:
            _, protocol = await asyncio.wait_for(loop.create_connection(
                lambda: _CheckedProtocol(loop=loop, on_event=self._on_event, on_disconnect=self._on_disconnect,
                                         on_garbage=self._fail), self.host, self.port), timeout)
        except ConnectionRefusedError:
            raise SourceError(f"nothing answers at {self.address}: is QTM running, with the real-time "
                              "output on that port?") from None
        assert isinstance(protocol, _CheckedProtocol)
        try:
            version = asyncio.ensure_future(protocol.set_version(self.version))
            await asyncio.wait([version, protocol.closed], timeout=timeout, return_when=asyncio.FIRST_COMPLETED)
            if not version.done():
                version.cancel()
                raise SourceError(f"QTM at {self.address} refused the connection: {protocol.last_error}"
                                  if protocol.last_error else f"QTM at {self.address} did not answer")
            version.result()
        except QRTCommandException as error:
            if protocol.transport is not None:
                protocol.transport.close()
            # QTM's own error first: when it closed the connection right after it, the SDK says "Not connected!"
            answer = protocol.last_error or _text(error.value)
            if "version" not in answer.lower():
                raise SourceError(f"QTM at {self.address} refused the connection: {answer}") from None
            raise SourceError(f"QTM at {self.address} does not speak RT protocol version {self.version} "
                              f"({answer})") from None
        connection = qtm_rt.QRTConnection(protocol, timeout=timeout)
        self._connection = connection
        try:
            parameters = await connection.get_parameters(parameters=["general", "3d"])
            self.frame_rate, self.labels = _parse_parameters(parameters)
            with contextlib.suppress(QRTCommandException, TimeoutError):
                await asyncio.wait_for(connection.get_state(), timeout)   # its event says whether QTM captures
            await connection.stream_frames(frames="allframes", components=["3d", "3dnolabels"],
                                           on_packet=self._on_packet)
        except QRTCommandException as error:
            protocol.transport.close()
            raise SourceError(f"QTM at {self.address} refused to stream: {_text(error.value)}") from None
        if protocol.broken:
            raise SourceError(f"QTM at {self.address} sent data this program cannot read")

    def stop(self) -> None:
        loop, thread = self._loop, self._thread
        self._stopping = True
        if loop is not None and thread is not None and thread.is_alive():
            def close() -> None:
                if self._connection is not None and self._connection.has_transport():
                    self._connection.disconnect()
                loop.stop()
            loop.call_soon_threadsafe(close)
            thread.join(5.0)
        self._loop = self._thread = self._connection = None
        self.connected = False

    # --- callbacks on the loop's thread -----------------------------------------------------------------

    def _on_packet(self, packet: QRTPacket) -> None:
        received = time.perf_counter()
        try:
            points, labels = _packet_points(packet, self.labels)
        except (struct.error, ValueError, IndexError) as error:
            self._fail(f"QTM sent a frame this program cannot read ({error})")
            return
        if self._sink is not None:
            self._sink.frame(LiveFrame(int(packet.framenumber), packet.timestamp * 1e-6, points, labels, received))

    def _on_event(self, event: QRTEvent) -> None:
        if self._sink is not None:
            self._sink.event(EVENT_NAMES.get(event, str(event)))

    def _on_disconnect(self, error: Exception | None) -> None:
        if not self._stopping:
            self._fail(f"QTM at {self.address} closed the connection"
                       + (f" ({_reason(error)})" if error is not None else ""))

    def _fail(self, message: str) -> None:
        if self._failed or self._stopping or not self.connected:    # while connecting, start() says why
            return
        self._failed = True
        self.connected = False
        if self._sink is not None:
            self._sink.failed(message)
        if self._loop is not None:
            self._loop.call_soon(self._loop.stop)

    # --- capture control --------------------------------------------------------------------------------

    def control(self, command: str, argument: str = "") -> str:
        """``takecontrol [password]``, ``releasecontrol``, ``new``, ``start``, ``stop``, ``save NAME``, ``close``:
        QTM's answer (one line); SourceError when QTM refuses (e.g. another client has control)."""
        loop, connection = self._loop, self._connection
        if loop is None or connection is None:
            raise SourceError("not connected to QTM")
        calls = {"takecontrol": lambda: connection.take_control(argument),
                 "releasecontrol": connection.release_control, "new": connection.new, "start": connection.start,
                 "stop": connection.stop, "close": connection.close,
                 "save": lambda: connection.save(argument, overwrite=True)}
        if command not in calls:
            raise SourceError(f"unknown QTM command '{command}': one of {', '.join(calls)}")
        if command == "save" and not argument.strip():
            raise SourceError("save needs the take's name")
        future = asyncio.run_coroutine_threadsafe(calls[command](), loop)
        try:
            return _text(future.result(10.0))
        except QRTCommandException as error:
            raise SourceError(f"QTM refused '{command}': {_text(error.value)}") from None
        except TimeoutError:
            raise SourceError(f"QTM did not answer '{command}' within 10 s") from None


def _packet_points(packet: QRTPacket, names: list[str]) -> tuple[np.ndarray, list[str]]:
    """The points of a data packet (N,3) mm: the labelled markers found (NaN: not found) then the unlabelled."""
    parts, labels = [], []
    if QRTComponentType.Component3d in packet.components:
        _, markers = packet.get_3d_markers()
        labelled = np.array([(m.x, m.y, m.z) for m in markers], dtype=float).reshape(-1, 3)
        found = np.isfinite(labelled).all(axis=1)
        parts.append(labelled[found])
        labels += [names[i] if i < len(names) else f"marker {i + 1}" for i in np.flatnonzero(found)]
    if QRTComponentType.Component3dNoLabels in packet.components:
        _, markers = packet.get_3d_markers_no_label()
        unlabelled = np.array([(m.x, m.y, m.z) for m in markers], dtype=float).reshape(-1, 3)
        unlabelled = unlabelled[np.isfinite(unlabelled).all(axis=1)]
        parts.append(unlabelled)
        labels += [""] * len(unlabelled)
    points = np.concatenate(parts) if parts else np.empty((0, 3))
    return points, labels if any(labels) else []


def _parse_parameters(xml: bytes | str) -> tuple[float | None, list[str]]:
    """The capture rate (Hz) and the 3D labels of a ``GetParameters General 3D`` answer."""
    text = xml.decode("utf-8", "replace") if isinstance(xml, bytes) else str(xml)
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError:
        raise SourceError("QTM's parameters are not readable XML") from None
    rate_text = root.findtext("General/Frequency")
    try:
        rate = float(rate_text) if rate_text else None
    except ValueError:
        rate = None
    labels = [label.findtext("Name") or "" for label in root.findall("The_3D/Label")]
    return (rate if rate and rate > 0 else None), labels


def _text(value: Any) -> str:
    return (value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)).strip()


def _reason(error: BaseException) -> str:
    return getattr(error, "strerror", None) or str(error) or type(error).__name__


logging.getLogger("qtm_rt").setLevel(logging.CRITICAL)   # its errors come back here as one line each

KIND = SourceKind("qtm", QtmSource.label, DEFAULT_PORT, QtmSource)
register_source(KIND)
__all__ = ["SOURCES", "QtmSource"]
