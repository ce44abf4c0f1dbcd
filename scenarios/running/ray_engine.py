"""Ray, the engine that runs work across processes or a cluster: a local instance or a
connection to one (:func:`ray_engine`), the options checked before anything starts
(:func:`check_engine_options`). Sweeps, a fleet's training per building and partitioned fleet
planners run inside it."""

from __future__ import annotations

import logging
import os
import re
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pinn_mpc.errors import InputError, setting
from scenarios.records import EngineRecord

__all__ = ["check_engine_options", "ray_engine"]

_ADDRESS = re.compile(r"^(ray://)?(?P<host>[A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>\d{1,5})$")
_CONNECT_TIMEOUT_S = 5.0


def check_engine_options(address: str | None, workers: int | None) -> None:
    """Refuse a malformed or unreachable ``--address`` (before anything is written: Ray itself
    waits minutes for a head node that is not there) and ``--workers`` with ``--address``."""
    if address is not None and workers is not None:
        raise InputError(
            f"sweep: {setting('workers')} sizes the local Ray instance; with {setting('address')} the cluster's CPUs "
            f"decide, so leave {setting('workers')} out"
        )
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if address is None or address == "auto":
        return
    match = _ADDRESS.match(address)
    if match is None:
        raise InputError(
            f"sweep: {setting('address')} {address!r} is not a Ray address; give HOST:PORT of the head "
            "node (e.g. 10.0.0.5:6379), ray://HOST:10001, or auto"
        )
    host, port = match.group("host").strip("[]"), int(match.group("port"))
    try:
        with socket.create_connection((host, port), timeout=_CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        raise InputError(
            f"sweep: no Ray head node answers at {address} ({exc.strerror or exc}); start one "
            f"with `ray start --head` (it prints the address) or leave {setting('address')} out"
        ) from None


@contextmanager
def ray_engine(address: str | None, workers: int | None) -> Iterator[EngineRecord]:
    """Start a local Ray instance (``workers`` CPUs, default all) or connect to ``address``;
    yield the engine record of ``summary.json``; shut down (or disconnect) at the end."""
    import ray

    check_engine_options(address, workers)
    options: dict[str, Any] = {
        "include_dashboard": False,
        "logging_level": logging.ERROR,
        "log_to_driver": False,
    }
    try:
        if address is None:
            ray.init(num_cpus=workers or os.cpu_count() or 1, **options)
        else:
            ray.init(address=address, **options)
    except (ConnectionError, RuntimeError, ValueError, TimeoutError) as exc:
        where = "start a local instance" if address is None else f"connect to {address}"
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(
            f"sweep: cannot {where} with Ray ({first}); check the address "
            f"(`ray status` on the head node prints it) or leave {setting('address')} out"
        ) from exc
    try:
        resources = {k: v for k, v in ray.cluster_resources().items() if k in ("CPU", "GPU", "memory")}
        resources["nodes"] = sum(1 for n in ray.nodes() if n.get("Alive"))
        yield {"name": "ray", "version": ray.__version__, "resources": resources}
    finally:
        ray.shutdown()
