"""A Ray cluster to run on: the one at a user's ADDRESS, or a local one bound to loopback.

Why loopback for a local cluster: Ray's servers (GCS, raylet, workers' gRPC, agents) listen on
the node's IP, which Ray resolves to the machine's reachable address even when told
``127.0.0.1``, so a "local" cluster would be open to the network. Ray keeps every server on
loopback only when it believes clusters are unsupported on the platform
(``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``, read by Ray and by the processes it starts); we set
that for the start of the cluster only, pass ``127.0.0.1`` as the node address, turn the
dashboard off, and check the result. Connecting to a remote ADDRESS is the user's explicit
choice: Ray's own token authentication and network setup apply there.

An unreachable ADDRESS fails in a few seconds with one line (Ray itself would retry for minutes):
the GCS port is probed with a plain TCP connect first.
"""

from __future__ import annotations

import builtins
import contextlib
import logging
import os
import socket
from collections.abc import Iterator
from types import ModuleType

from sim.errors import DexaugError

__all__ = ["LOCAL", "ScaleError", "import_ray", "ray_cluster"]

log = logging.getLogger(__name__)

#: the ``--ray`` value (its ``const``) that means "start a local cluster on loopback"
LOCAL = "local"
#: seconds the reachability probe of a remote ADDRESS waits
PROBE_TIMEOUT_S = 3.0
_LOOPBACK = "127.0.0.1"
_CLUSTER_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


class ScaleError(DexaugError):
    """Ray is missing, a cluster cannot be reached or started, or a task failed for a reason
    that is not the input's (the message says which)."""


def import_ray() -> ModuleType:
    """The ``ray`` module, or a one-line :class:`ScaleError` naming the extra to install."""
    try:
        import ray
    except ImportError:
        raise ScaleError("Ray is not installed: pip install 'dexaug[ray]' (or run without --ray "
                         "for the local process pool)") from None
    return ray


def _host_port(address: str) -> tuple[str, int] | None:
    """``(host, port)`` of ``host:port`` or ``ray://host:port``; None for ``auto`` and other
    forms Ray resolves itself."""
    bare = address.removeprefix("ray://")
    host, sep, port = bare.rpartition(":")
    if not sep or not port.isdigit():
        return None
    return host.strip("[]") or _LOOPBACK, int(port)


def _probe(address: str) -> None:
    target = _host_port(address)
    if target is None:
        return
    try:
        with socket.create_connection(target, timeout=PROBE_TIMEOUT_S):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ScaleError(f"cannot reach the Ray cluster at {address}: {reason} (start it with "
                         "`ray start --head`, or use --ray without an address for a local "
                         "cluster)") from None


def _start_local(ray: ModuleType, num_cpus: int | None) -> None:
    """``ray.init`` of a new local cluster whose servers all listen on loopback."""
    from ray._private import ray_constants

    saved_env, saved_flag = os.environ.get(_CLUSTER_ENV), ray_constants.ENABLE_RAY_CLUSTER
    os.environ[_CLUSTER_ENV] = "0"             # for the processes Ray starts now
    ray_constants.ENABLE_RAY_CLUSTER = False   # for this process's own address resolution
    try:
        ray.init(num_cpus=num_cpus, include_dashboard=False, _node_ip_address=_LOOPBACK,
                 log_to_driver=False, logging_level=logging.ERROR, configure_logging=False)
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = saved_flag
        if saved_env is None:
            os.environ.pop(_CLUSTER_ENV, None)
        else:
            os.environ[_CLUSTER_ENV] = saved_env
    gcs = ray.get_runtime_context().gcs_address
    if not gcs.startswith(f"{_LOOPBACK}:"):
        ray.shutdown()
        raise ScaleError(f"the local Ray cluster did not bind to loopback (GCS at {gcs}); "
                         "refusing to run on it")


@contextlib.contextmanager
def ray_cluster(address: str | None = LOCAL, *, num_cpus: int | None = None) -> Iterator[ModuleType]:
    """Ray, initialised for the block: a new local cluster on loopback (``address`` None or
    :data:`LOCAL`; ``num_cpus`` worker CPUs, default all cores), or the cluster at ``address``
    (``host:port`` of its GCS, ``ray://host:port`` or ``auto``). A Ray already initialised in
    this process (a test's cluster) is used as it is and left running.

    Raises:
        ScaleError: Ray is not installed, or the cluster cannot be reached or started.
    """
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    # Ray's driver swaps the process's print for its progress-bar-safe one on first use and
    # never puts it back; this process's print is not Ray's to keep
    saved_print = builtins.print
    try:
        try:
            if address in (None, LOCAL):
                _start_local(ray, num_cpus)
            else:
                _probe(address)
                ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR,
                         configure_logging=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise ScaleError(f"cannot start or reach the Ray cluster {address or LOCAL}: "
                             f"{' '.join(str(exc).split())}") from None
        log.info("Ray cluster %s: %s CPUs", ray.get_runtime_context().gcs_address,
                 ray.cluster_resources().get("CPU", 0))
        try:
            yield ray
        finally:
            ray.shutdown()
    finally:
        builtins.print = saved_print
