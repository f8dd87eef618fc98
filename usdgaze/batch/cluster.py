"""Running shots on a running ``dask.distributed`` cluster (``usdgaze batch --dask ADDRESS``): each shot
one task, records streamed back as they finish; dask is imported only here, and only when asked for."""

from __future__ import annotations

import time
import uuid
from typing import Iterator

from usdgaze.batch import engine
from usdgaze.batch.manifest import Shot

DASK_CONNECT_S = 10
"""Seconds to reach the scheduler at --dask before saying it cannot be reached."""


def _connect(client_type, address: str):
    """``client_type(address)`` within DASK_CONNECT_S seconds (and half that for the handshake), from a daemon
    thread: at a port that accepts and never answers a dask handshake (the dashboard's HTTP on :8787)
    distributed's own timeouts never fired, and the command hung."""
    import threading

    done: dict = {}

    def connect() -> None:
        try:
            done["client"] = client_type(address, timeout=f"{DASK_CONNECT_S}s")
        except BaseException as exc:  # handed to the caller, who says it in one line
            done["error"] = exc

    thread = threading.Thread(target=connect, name="usdgaze-dask-connect", daemon=True)
    thread.start()
    wait = 1.5 * DASK_CONNECT_S
    thread.join(wait)
    if "error" in done:
        raise done["error"]
    if "client" not in done:
        raise TimeoutError(f"no dask handshake in {wait:g} s (is it a scheduler's port, not its dashboard's?)")
    return done["client"]


def run_dask(shots: list[Shot], address: str, force: bool) -> Iterator[dict]:
    """Records as shots finish, each shot one task on the dask.distributed cluster at ``address``."""
    from usdgaze.errors import UsdGazeError

    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise UsdGazeError("--dask needs dask.distributed: pip install 'usdgaze[dask]'") from None
    if address.strip().lower().startswith("tls://"):
        from distributed.security import Security

        # Said before connecting: distributed's own TypeError for it raced its client's start (an empty
        # AssertionError now and then).
        if Security().get_connection_args("client").get("ssl_context") is None:
            raise UsdGazeError(f"--dask {address}: cannot connect with that protocol here (no TLS security in dask's "
                               "configuration: distributed.comm.tls)")
    try:
        # A bounded wait: at a port that is no scheduler (the dashboard's HTTP on :8787) the handshake
        # never completed, and a closed port took distributed's default 30 s to say so.
        client = _connect(Client, address)
    except ValueError as exc:  # distributed's parse of the address
        raise UsdGazeError(f"--dask {address!r}: not a scheduler address such as tcp://host:8786 ({exc})") from None
    except TypeError as exc:  # a protocol this installation cannot speak: ucx:// without UCX, tls:// without a context
        raise UsdGazeError(f"--dask {address}: cannot connect with that protocol here ({exc})") from None
    except Exception as exc:  # refused, timed out, or bytes that are no dask protocol (a MemoryError of 3 EiB)
        raise UsdGazeError(f"--dask {address}: cannot connect to a dask scheduler there ({type(exc).__name__}: "
                           f"{' '.join(str(exc).split())[:200]})") from None
    with client:
        futures = {client.submit(engine.run_shot, shot, force, True, key=f"usdgaze-{shot.name}-{uuid.uuid4().hex[:8]}",
                                 pure=False): shot for shot in shots}
        start = time.perf_counter()
        for future in dask_completed(futures):
            try:
                yield future.result()
            except Exception as exc:  # run_shot never raises: the task's worker died (KilledWorker), or it was lost
                yield engine.died(futures[future], time.perf_counter() - start,
                            f"its dask task failed ({type(exc).__name__}: {' '.join(str(exc).split())[:300]})")
