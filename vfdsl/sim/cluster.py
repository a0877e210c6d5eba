"""Connecting to a Dask distributed scheduler for ``vfdsl simulate --cluster``.

The address is probed before any work starts, within ``limits.CONNECT_TIMEOUT`` seconds in all: connect,
Dask's handshake, and an ``identity`` request whose answer must come from a scheduler. Whatever answers at
the address must speak Dask's protocol: a server that answers something else (an HTTP server, a
database) makes Dask's reader take its bytes for frame lengths and try to allocate exabytes, or wait for
bytes that never come; every such failure becomes one clear error naming the address.
"""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

from vfdsl.errors import VfError
from vfdsl import limits

_HINT = "start one (`dask scheduler`, then `dask worker ADDRESS`) or run without --cluster"
_ADDRESS = "an address like tcp://host:8786, as `dask scheduler` prints it"


async def _identity(address: str, timeout: float) -> object:
    from distributed.comm import connect as comm_connect

    comm = await comm_connect(address, timeout=timeout)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def _run_to_end(coroutine):
    """The coroutine's result, also when called from a running event loop (a notebook), in a thread of its own."""
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return asyncio.run(coroutine)
    with ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(asyncio.run, coroutine).result()


def checked_address(address: str) -> str:
    """``address`` when it is one (``[scheme://]host:port``, a port from 1 to 65535, or a scheduler's inproc:// in this
    process), else VfError: an empty, portless or misspelt address was taken as not given (''), or said to answer but
    not as a scheduler ('foo')."""
    from distributed.comm.addressing import get_address_host_port, normalize_address, parse_address

    try:
        normalize_address(address)
        inproc = parse_address(address)[0] == "inproc"          # a scheduler in this process: no port
        port = 1 if inproc else get_address_host_port(address)[1] if address else 0
    except ValueError as exc:
        raise VfError(f"{address!r} is not the address of a Dask scheduler ({exc})", hint=_ADDRESS) from None
    if not 1 <= port <= 65535:
        raise VfError(f"{address!r} is not the address of a Dask scheduler"
                      + (": it is empty" if not address else f" (port {port}: a port is 1 to 65535)"), hint=_ADDRESS)
    return address


def probe(address: str, timeout: float | None = None) -> None:
    """Raise a :class:`VfError` unless ``address`` is one (:func:`checked_address`) and a Dask scheduler answers
    there within ``timeout`` seconds (default ``limits.CONNECT_TIMEOUT``)."""
    timeout = limits.CONNECT_TIMEOUT if timeout is None else timeout
    checked_address(address)
    try:
        reply = _run_to_end(asyncio.wait_for(_identity(address, timeout), timeout))
    except (asyncio.TimeoutError, TimeoutError):
        raise VfError(f"cannot reach a Dask scheduler at {address!r}: no answer within {timeout:g} s",
                      hint=_HINT) from None
    except OSError as exc:
        raise VfError(f"cannot reach a Dask scheduler at {address!r}: {exc}", hint=_HINT) from None
    except MemoryError:
        raise VfError(f"{address!r} answers, but not as a Dask scheduler (its bytes read as a message of "
                      "exabytes)", hint=_HINT) from None
    except Exception as exc:                   # any other protocol failure of a foreign server
        raise VfError(f"{address!r} answers, but not as a Dask scheduler ({type(exc).__name__}: {exc})",
                      hint=_HINT) from None
    if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
        raise VfError(f"{address!r} answers, but not as a Dask scheduler (it says {str(reply)[:80]!r})", hint=_HINT)


def connect(address: str, timeout: float | None = None):
    """A ``distributed.Client`` of the scheduler at ``address`` (probed first), or a :class:`VfError`."""
    from distributed import Client

    timeout = limits.CONNECT_TIMEOUT if timeout is None else timeout
    probe(address, timeout)
    try:
        return Client(address, timeout=f"{timeout:g}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise VfError(f"cannot reach a Dask scheduler at {address!r} within {timeout:g} s: {exc}",
                      hint=_HINT) from None
