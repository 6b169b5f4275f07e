"""Checking a Dask scheduler address before anything of a batch starts.

``handmocap batch --scheduler ADDRESS`` (and the GUI's batch panel) take the address of a running
``dask.distributed`` scheduler. :func:`check_scheduler_address` checks it against what the installed
``distributed`` can reach, so that a bad address is one clear line before the session, the output folder
or a cluster is touched:

- ``tcp://HOST:PORT`` (``HOST:PORT`` alone means tcp), ``ws://HOST:PORT``: a host name or address (IPv6 in
  brackets) and a port 1..65535;
- ``tls://HOST:PORT``, ``wss://HOST:PORT``: the same, and TLS certificates in the Dask configuration
  (``distributed.comm.tls.ca-file``, ``.client.cert``, ``.client.key``);
- ``ucx://HOST:PORT``: only where a UCX backend is installed (``distributed-ucxx``; ``distributed`` itself
  no longer has one);
- ``inproc://ADDRESS/PID/N``: a scheduler inside this same process (as in tests).
"""

from __future__ import annotations

import os
import re

from handmocap.core.errors import InputError

#: schemes a batch may use, in the order the message lists them
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
_HOST = re.compile(r"(?:[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}"
                   r"[A-Za-z0-9])?)*\.?|\[[0-9A-Fa-f:.]{2,45}(?:%[A-Za-z0-9]+)?\]")
_INPROC = re.compile(r"[^/\s]{1,100}/([0-9]{1,10})/[0-9]{1,10}")


def check_scheduler_address(address: str) -> str:
    """The scheduler ``address`` with its scheme (``tcp://`` added to ``HOST:PORT``); InputError (one line)
    when it is not one the installed ``distributed`` can reach (module docstring)."""
    text = address.strip()
    shown = _shown(text)
    if not text:
        raise InputError("--scheduler is empty; give tcp://HOST:PORT")
    scheme, separator, rest = text.partition("://")
    if not separator:
        scheme, rest = "tcp", text
    scheme = scheme.lower()
    if scheme not in SCHEMES:
        raise InputError(f"scheduler address {shown}: unknown scheme '{_shown(scheme, 12)}' "
                         f"(use {', '.join(s + '://' for s in SCHEMES)})")
    if scheme == "inproc":
        match = _INPROC.fullmatch(rest)
        if match is None or int(match.group(1)) != os.getpid():
            raise InputError(f"scheduler address {shown}: inproc:// names a scheduler inside this same process "
                             f"(inproc://ADDRESS/{os.getpid()}/N); reach another process's scheduler with "
                             "tcp://HOST:PORT")
        return f"inproc://{rest}"
    host, port = _host_port(rest, shown)
    if scheme == "ucx" and not _ucx_available():
        raise InputError(f"scheduler address {shown}: ucx:// needs a UCX backend for Dask (the distributed-ucxx "
                         "package), which is not installed here; use tcp://HOST:PORT")
    if scheme in ("tls", "wss") and not _tls_configured():
        raise InputError(f"scheduler address {shown}: {scheme}:// needs TLS certificates in the Dask configuration "
                         "(distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .key): none are set, "
                         "or they cannot be read")
    return f"{scheme}://{host}:{port}"


def _host_port(rest: str, shown: str) -> tuple[str, int]:
    host, colon, port_text = rest.rpartition(":")
    if not colon or not host:
        raise InputError(f"scheduler address {shown}: give HOST:PORT (e.g. tcp://192.168.1.20:8786)")
    if not _HOST.fullmatch(host):
        raise InputError(f"scheduler address {shown}: '{_shown(host, 60)}' is not a host name or address "
                         "(an IPv6 address goes in brackets)")
    if not (port_text.isascii() and port_text.isdigit() and len(port_text) <= 5 and 1 <= int(port_text) <= 65535):
        raise InputError(f"scheduler address {shown}: the port must be a number within 1..65535, "
                         f"not '{_shown(port_text, 12)}'")
    return host, int(port_text)


def _ucx_available() -> bool:
    """Whether the installed ``distributed`` has a working UCX backend (its own is a stub that says to install
    distributed-ucxx)."""
    try:
        from distributed.comm.registry import get_backend

        get_backend("ucx").get_connector()
        return True
    except Exception:  # noqa: BLE001 - any failure means: no usable backend
        return False


def _tls_configured() -> bool:
    """Whether the Dask configuration gives the client a TLS context (certificates set)."""
    try:
        from distributed.security import Security

        return Security().get_connection_args("client").get("ssl_context") is not None
    except Exception:  # noqa: BLE001 - unreadable certificates: not configured
        return False


def _shown(text: str, limit: int = 80) -> str:
    """``text`` on one line, cut to ``limit`` characters."""
    flat = "".join(char if char.isprintable() else "?" for char in text)
    return flat if len(flat) <= limit else flat[:limit - 3] + "..."
