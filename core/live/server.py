"""The stand-in server: replays a take over QTM's real-time protocol or NatNet on loopback, at its rate, so
that the real client libraries connect and stream 3D points (rehearsal, the demo, the tests).

It binds to 127.0.0.1 only. QTM (TCP, little-endian port): the welcome ``QTM RT Interface connected``,
``Version`` (1.8 up to ``qtm_max_version``; another version is refused with an error packet),
``QTMVersion``, ``ByteOrder``, ``GetState`` (an event packet), ``GetParameters`` (General: the frequency; 3D:
the labels, Z up), ``StreamFrames AllFrames|Frequency:n|FrequencyDivisor:n`` with ``3D``, ``3DRes``,
``3DNoLabels``, ``3DNoLabelsRes`` (``Stop``), and capture control: ``TakeControl [password]`` (one master at
a time), ``ReleaseControl``, ``New``, ``Start``, ``Stop``, ``Save NAME [overwrite]``, ``Close``, each with
QTM's answer and event. NatNet (UDP command port): ``NAT_CONNECT`` answered with the server info (NatNet
4.1), keep-alives, ``NAT_REQUEST_MODELDEF`` (a marker set of the take's labels), requests answered
``NAT_RESPONSE`` 0, ``NAT_DISCONNECT``; each frame of mocap data (NatNet 4.1 layout: marker sets, legacy
markers, rigid bodies, skeletons, assets, labelled markers, force plates, devices, suffix) is sent to every
client address that connected, in metres with Y up as Motive streams.

``unlabelled``: every point goes out unlabelled, shuffled per frame; otherwise the take's labelled columns
go out as labelled markers (QTM's 3D component, NatNet marker set 1) and the rest unlabelled. The take
loops unless ``loop=False``; the replay starts with the first client that asks for frames.
``garbage`` (tests): after that many frames, send bytes no client can read.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
import threading
import time
from dataclasses import dataclass, field
from xml.sax.saxutils import escape

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take, is_marker_label

PROTOCOLS = ("qtm", "natnet")
HOST = "127.0.0.1"
QTM_VERSIONS = (1, 8), (1, 26)
NATNET_VERSION = (4, 1, 0, 0)
MOTIVE_VERSION = (3, 1, 0, 0)
_EVENTS = {"connected": 1, "connection closed": 2, "capture started": 3, "capture stopped": 4,
           "capture saved": 13}


@dataclass
class Replay:
    """The frames to send: per frame the labelled points ``(L,3)`` mm (NaN: not seen) of ``labels``, and the
    unlabelled points ``(U_f,3)`` mm."""

    rate: float
    labels: list[str]
    labelled: np.ndarray
    unlabelled: list[np.ndarray] = field(default_factory=list)

    @property
    def frames(self) -> int:
        return len(self.unlabelled)


def make_replay(take: Take, rate: float | None = None, unlabelled: bool = False, seed: int = 0) -> Replay:
    """What :class:`StandInServer` sends for ``take`` (module docstring); ``rate`` Hz (default: the take's)."""
    rate = float(rate or take.frame_rate or 0.0)
    if not rate > 0 or not np.isfinite(rate):
        raise InputError("the replay needs a frame rate: give --rate HZ")
    positions = np.asarray(take.marker_positions, dtype=float)
    if positions.ndim != 3 or not len(positions):
        raise InputError("the take has no frames to replay")
    named = np.array([is_marker_label(name) for name in take.marker_names], dtype=bool) if not unlabelled else \
        np.zeros(len(take.marker_names), dtype=bool)
    rng = np.random.default_rng(seed)
    others = []
    for frame in positions[:, ~named]:
        points = frame[np.isfinite(frame).all(axis=1)]
        others.append(points[rng.permutation(len(points))] if unlabelled else points)
    return Replay(rate, [name for name, keep in zip(take.marker_names, named, strict=True) if keep],
                  positions[:, named], others)


class StandInServer:
    """Serves one replay over ``protocol`` on 127.0.0.1:``port`` from a thread of its own (:meth:`start`,
    :meth:`stop`), or in the caller's loop (:meth:`serve`)."""

    def __init__(self, replay: Replay, protocol: str, port: int, loop_take: bool = True,
                 qtm_max_version: tuple[int, int] = QTM_VERSIONS[1], password: str = "",
                 single_client: bool = False, garbage_after: int | None = None) -> None:
        if protocol not in PROTOCOLS:
            raise InputError(f"protocol must be one of {', '.join(PROTOCOLS)}, not '{protocol}'")
        if not 0 <= port < 65536:
            raise InputError(f"port {port} is not a port number")
        self.replay, self.protocol, self.port, self.loop_take = replay, protocol, port, loop_take
        self.qtm_max_version, self.password, self.single_client = qtm_max_version, password, single_client
        self.garbage_after = garbage_after
        self.frames_sent = 0
        self.frame_number = 0
        self.capturing = False
        self.master: object | None = None
        self.saved: list[str] = []
        #: every QTM command received, as sent (what a test or a rehearsal checks the clients asked for), and
        #: every event sent with the number of the last frame sent before it (frames and events share a stream)
        self.commands: list[str] = []
        self.events: list[tuple[str, int]] = []
        self._clients: list[_QtmClient] = []
        self._natnet_clients: dict[tuple[str, int], float] = {}
        self._transport: asyncio.DatagramTransport | None = None
        self._server: asyncio.AbstractServer | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._done: asyncio.Event | None = None
        self.bound = threading.Event()
        self.error = ""

    # --- running ----------------------------------------------------------------------------------------

    def start(self) -> StandInServer:
        """Serve on a thread; returns once listening (InputError when the port cannot be bound)."""
        def run() -> None:
            with contextlib.suppress(asyncio.CancelledError):
                asyncio.run(self.serve())

        self._thread = threading.Thread(target=run, name=f"stand-in-{self.protocol}", daemon=True)
        self._thread.start()
        self.bound.wait(10.0)
        if self.error:
            raise InputError(self.error)
        return self

    def stop(self) -> None:
        loop, done = self._loop, self._done
        if loop is not None and done is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(done.set)
        if self._thread is not None:
            self._thread.join(5.0)

    async def serve(self, duration: float | None = None) -> None:
        """Listen and stream until :meth:`stop` (or ``duration`` seconds)."""
        self._loop = asyncio.get_running_loop()
        self._done = asyncio.Event()
        try:
            if self.protocol == "qtm":
                self._server = await asyncio.start_server(self._qtm_client, HOST, self.port)
                self.port = self._server.sockets[0].getsockname()[1]
            else:
                self._transport, _ = await self._loop.create_datagram_endpoint(
                    lambda: _NatNetProtocol(self), local_addr=(HOST, self.port))
                self.port = self._transport.get_extra_info("sockname")[1]
        except OSError as error:
            self.error = f"cannot listen on {HOST}:{self.port}: {error.strerror or error}"
            self.bound.set()
            raise InputError(self.error) from None
        self.bound.set()
        streamer = asyncio.create_task(self._stream())
        try:
            if duration is None:
                await self._done.wait()
            else:
                with contextlib.suppress(asyncio.TimeoutError):
                    await asyncio.wait_for(self._done.wait(), duration)
        finally:
            streamer.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await streamer
            for client in list(self._clients):
                client.writer.close()
            if self._server is not None:
                self._server.close()
            if self._transport is not None:
                self._transport.close()

    async def _stream(self) -> None:
        """Send frame after frame at the replay's rate (a schedule, not a sleep per frame, so no drift), from
        the take's first frame once the first client asks for frames."""
        loop = asyncio.get_running_loop()
        while not (self._natnet_clients or any(client.components for client in self._clients)):
            await asyncio.sleep(0.005)
        period = 1.0 / self.replay.rate
        start = loop.time()
        index = 0
        while True:
            frame = index % self.replay.frames
            if index and frame == 0 and not self.loop_take:
                return
            self.frame_number = index + 1
            if self.garbage_after is not None and index >= self.garbage_after:
                self._send_garbage()
            elif self.protocol == "qtm":
                for client in list(self._clients):
                    client.send_frame(self, frame, index)
            else:
                self._send_natnet_frame(frame, index)
            self.frames_sent += 1
            index += 1
            delay = start + index * period - loop.time()
            await asyncio.sleep(max(delay, 0.0))

    # --- QTM ------------------------------------------------------------------------------------------

    async def _qtm_client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        client = _QtmClient(writer)
        if self.single_client and self._clients:
            client.send(0, "Another client is connected to this stand-in server (it serves one)")
            await writer.drain()
            writer.close()
            return
        self._clients.append(client)
        client.send(1, "QTM RT Interface connected")
        try:
            while True:
                header = await reader.readexactly(8)
                size, kind = struct.unpack("<II", header)
                if size < 8 or size > 1 << 20:
                    break
                body = await reader.readexactly(size - 8)
                if kind in (1, 2):
                    self._qtm_command(client, body.rstrip(b"\0").decode("utf-8", "replace").strip())
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            if client in self._clients:
                self._clients.remove(client)
            if self.master is client:
                self.master = None
            writer.close()

    def _qtm_command(self, client: _QtmClient, text: str) -> None:
        self.commands.append(text)
        words = text.split()
        command = words[0].lower() if words else ""
        rest = words[1:]
        if command == "version":
            version = _version(rest[0] if rest else "")
            if version is None or not QTM_VERSIONS[0] <= version <= self.qtm_max_version:
                client.send(0, f"Version NOT supported: {rest[0] if rest else ''} (this server speaks 1.8 to "
                               f"{self.qtm_max_version[0]}.{self.qtm_max_version[1]})")
            else:
                client.version = version
                client.send(1, f"Version set to {version[0]}.{version[1]}")
        elif command == "qtmversion":
            client.send(1, "QTM Version is 2024.2 (build 1) handmocap stand-in")
        elif command == "byteorder":
            client.send(1, "Byte order is little endian")
        elif command == "getstate":
            client.event("capture started" if self.capturing else "connected")
        elif command == "getparameters":
            client.send(2, self._qtm_parameters())
        elif command == "streamframes":
            self._qtm_stream(client, rest)
        elif command == "takecontrol":
            if self.master is client:
                client.send(1, "You are already master")
            elif self.master is not None:
                client.send(0, "The client control is already taken by another client")
            elif self.password and (rest[0] if rest else "") != self.password:
                client.send(0, "Wrong or missing password")
            else:
                self.master = client
                client.send(1, "You are now master")
        elif command == "releasecontrol":
            if self.master is client:
                self.master = None
                client.send(1, "You are now a regular client")
            else:
                client.send(1, "You are already a regular client")
        elif command in ("new", "start", "stop", "save", "close"):
            self._qtm_control(client, command, rest)
        else:
            client.send(0, "Parse error")

    def _qtm_control(self, client: _QtmClient, command: str, rest: list[str]) -> None:
        if self.master is not client:
            client.send(0, "Command not allowed in slave mode: take control first")
            return
        if command == "new":
            client.send(1, "Creating new connection")
            self._broadcast("connected")
        elif command == "start":
            self.capturing = True
            client.send(1, "Starting measurement")
            self._broadcast("capture started")
        elif command == "stop":
            if not self.capturing:
                client.send(0, "No measurement to stop")
                return
            self.capturing = False
            client.send(1, "Stopping measurement")
            self._broadcast("capture stopped")
        elif command == "save":
            name = " ".join(word for word in rest if word.lower() != "overwrite")
            if not name:
                client.send(0, "Save needs a file name")
                return
            self.saved.append(name)
            client.send(1, "Measurement saved")
            self._broadcast("capture saved")
        else:
            client.send(1, "Closing connection")
            self._broadcast("connection closed")

    def _broadcast(self, event: str) -> None:
        self.events.append((event, self.frame_number))
        for other in self._clients:
            other.event(event)

    def _qtm_stream(self, client: _QtmClient, rest: list[str]) -> None:
        words = [word.lower() for word in rest]
        if words[:1] == ["stop"]:
            client.components = []
            return
        divisor = 1
        if words and words[0].startswith("frequencydivisor:"):
            divisor = max(1, _int(words[0].split(":", 1)[1], 1))
        elif words and words[0].startswith("frequency:"):
            divisor = max(1, round(self.replay.rate / max(_int(words[0].split(":", 1)[1], 1), 1)))
        components = [word for word in words[1:] if word in ("3d", "3dres", "3dnolabels", "3dnolabelsres")]
        if not components:
            client.send(0, "No valid component: this stand-in streams 3D, 3DRes, 3DNoLabels and 3DNoLabelsRes")
            return
        client.components, client.divisor = components, divisor

    def _qtm_parameters(self) -> str:
        labels = "".join(f"<Label><Name>{escape(name)}</Name><RGBColor>16711680</RGBColor></Label>"
                         for name in self.replay.labels)
        return (f"<QTM_Parameters_Ver_1.25><General><Frequency>{self.replay.rate:g}</Frequency>"
                f"<Capture_Time>{self.replay.frames / self.replay.rate:g}</Capture_Time></General>"
                f"<The_3D><AxisUpwards>+Z</AxisUpwards><Labels>{len(self.replay.labels)}</Labels>{labels}"
                "</The_3D></QTM_Parameters_Ver_1.25>")

    # --- NatNet ---------------------------------------------------------------------------------------

    def _natnet_request(self, data: bytes, address: tuple[str, int]) -> None:
        if len(data) < 4 or self._transport is None:
            return
        message, _size = struct.unpack_from("<HH", data)
        now = time.monotonic()
        if message == 0:                        # NAT_CONNECT
            self._natnet_clients[address] = now
            name = b"Motive (handmocap stand-in)".ljust(256, b"\0")
            self._transport.sendto(_natnet(1, name + bytes(MOTIVE_VERSION) + bytes(NATNET_VERSION)), address)
        elif message == 10:                     # NAT_KEEPALIVE
            if address in self._natnet_clients:
                self._natnet_clients[address] = now
        elif message == 4:                      # NAT_REQUEST_MODELDEF
            self._transport.sendto(_natnet(5, self._natnet_descriptions()), address)
        elif message == 2:                      # NAT_REQUEST (a command string)
            self._transport.sendto(_natnet(3, struct.pack("<i", 0)), address)
        elif message == 9:                      # NAT_DISCONNECT
            self._natnet_clients.pop(address, None)

    def _natnet_descriptions(self) -> bytes:
        if not self.replay.labels:
            return struct.pack("<I", 0)
        names = b"".join(name.encode("utf-8")[:255] + b"\0" for name in self.replay.labels)
        body = b"take\0" + struct.pack("<I", len(self.replay.labels)) + names
        return struct.pack("<I", 1) + struct.pack("<II", 0, len(body)) + body

    def _send_natnet_frame(self, frame: int, index: int) -> None:
        if self._transport is None or not self._natnet_clients:
            return
        packet = _natnet(7, self._natnet_frame(frame, index))
        for address in list(self._natnet_clients):
            self._transport.sendto(packet, address)

    def _natnet_frame(self, frame: int, index: int) -> bytes:
        replay = self.replay
        labelled = replay.labelled[frame]
        seen = np.isfinite(labelled).all(axis=1)
        ids = np.concatenate([(1 << 16) | (np.flatnonzero(seen) + 1),
                              50000 + np.arange(len(replay.unlabelled[frame]))]).astype(np.uint32)
        points = np.concatenate([labelled[seen], replay.unlabelled[frame]])
        flags = np.concatenate([np.zeros(int(seen.sum())), np.full(len(replay.unlabelled[frame]), 0x10)])
        motive = np.stack([points[:, 0], points[:, 2], -points[:, 1]], axis=1) / 1000.0
        record = np.zeros(len(points), dtype=[("id", "<u4"), ("xyz", "<f4", 3), ("size", "<f4"),
                                              ("param", "<u2"), ("residual", "<f4")])
        record["id"], record["xyz"], record["size"] = ids, motive, 0.014
        record["param"], record["residual"] = flags, 0.0001
        marker_sets = b""
        count = 0
        if replay.labels:
            xyz = np.where(seen[:, None], np.stack([labelled[:, 0], labelled[:, 2], -labelled[:, 1]], axis=1) / 1000,
                           0.0).astype("<f4")
            marker_sets = b"take\0" + struct.pack("<I", len(labelled)) + xyz.tobytes()
            count = 1
        empty = struct.pack("<II", 0, 0)
        stamp = int(index / replay.rate * 1e7)
        suffix = struct.pack("<IId", 0, 0, index / replay.rate) + struct.pack("<QQQ", stamp, stamp, stamp) \
            + struct.pack("<II", int(index / replay.rate), 0) + struct.pack("<H", 1 if self.capturing else 0)
        return (struct.pack("<I", index + 1)
                + struct.pack("<II", count, len(marker_sets)) + marker_sets
                + empty                                      # legacy "other" markers
                + empty + empty + empty                      # rigid bodies, skeletons, assets
                + struct.pack("<II", len(record), record.nbytes) + record.tobytes()
                + empty + empty                              # force plates, devices
                + suffix)

    def _send_garbage(self) -> None:
        junk = bytes(range(7, 250, 3)) * 3
        if self.protocol == "qtm":
            for client in list(self._clients):
                client.writer.write(struct.pack("<II", 4, 3) + junk)
        elif self._transport is not None:
            for address in list(self._natnet_clients):
                self._transport.sendto(struct.pack("<HH", 7, len(junk)) + junk[:40], address)


class _QtmClient:
    def __init__(self, writer: asyncio.StreamWriter) -> None:
        self.writer = writer
        self.version = (1, 0)
        self.components: list[str] = []
        self.divisor = 1

    def send(self, kind: int, text: str) -> None:
        body = text.encode("utf-8") + b"\0"
        self.writer.write(struct.pack("<II", 8 + len(body), kind) + body)

    def event(self, name: str) -> None:
        self.writer.write(struct.pack("<IIB", 9, 6, _EVENTS[name]))

    def send_frame(self, server: StandInServer, frame: int, index: int) -> None:
        if not self.components or index % self.divisor:
            return
        replay = server.replay
        parts = []
        for component in self.components:
            residual = component.endswith("res")
            if component.startswith("3dnolabels"):
                points = replay.unlabelled[frame]
                record = np.zeros(len(points), dtype=[("xyz", "<f4", 3), ("id", "<u4")] +
                                  ([("residual", "<f4")] if residual else []))
                record["xyz"], record["id"] = points, np.arange(1, len(points) + 1)
                kind = 10 if residual else 2
            else:
                points = replay.labelled[frame]
                record = np.zeros(len(points), dtype=[("xyz", "<f4", 3)] + ([("residual", "<f4")] if residual else []))
                record["xyz"] = points
                kind = 9 if residual else 1
            if residual:
                record["residual"] = np.where(np.isfinite(points).all(axis=1), 0.5, -1.0)
            body = struct.pack("<IHH", len(record), 0, 0) + record.tobytes()
            parts.append(struct.pack("<II", 8 + len(body), kind) + body)
        payload = struct.pack("<qII", int(index / replay.rate * 1e6), index + 1, len(parts)) + b"".join(parts)
        self.writer.write(struct.pack("<II", 8 + len(payload), 3) + payload)


class _NatNetProtocol(asyncio.DatagramProtocol):
    def __init__(self, server: StandInServer) -> None:
        self.server = server

    def datagram_received(self, data: bytes, address: tuple[str, int]) -> None:
        self.server._natnet_request(data, address)


def _natnet(message: int, body: bytes) -> bytes:
    return struct.pack("<HH", message, len(body) & 0xFFFF) + body


def _version(text: str) -> tuple[int, int] | None:
    major, _, minor = text.partition(".")
    try:
        return int(major), int(minor)
    except ValueError:
        return None


def _int(text: str, default: int) -> int:
    try:
        return int(text)
    except ValueError:
        return default
