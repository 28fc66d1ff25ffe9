"""The Ray transport of a parallel search (``--ray ADDRESS``): one Ray actor
per partition (:class:`_RayTransport`), reaching a cluster, Ray's errors
(:class:`RayUnavailable`, :class:`RayWorkerLost`).  See
:mod:`pccl.search.parallel` for the design."""

from __future__ import annotations

import os
from typing import Any, Optional


from pccl.search.parallel_worker import _Worker, available_workers


#: The message when ``--ray`` is asked for without Ray installed.
def _ray_hint() -> str:
    """pccl.lang.errors.install_hint("ray"), spelt here (the same two cases): this module imports only
    generic modules (tests/acceptance/test_architecture.py).  realpath: from the editable install's
    link tree (build/__editable__.pccl-*/), this file is a link to the checkout's."""
    import os
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
    if os.path.isfile(os.path.join(root, "pyproject.toml")):
        return f"pip install -e '{root}[ray]'"
    import importlib.metadata       # installed from a wheel: the extra's packages
    try:
        reqs = importlib.metadata.requires("pccl") or []
    except importlib.metadata.PackageNotFoundError:
        reqs = []
    wanted = [r.split(";", 1)[0].strip() for r in reqs if 'extra == "ray"' in r.replace("'", '"')]
    if wanted:
        return "pip install " + " ".join(f"'{r}'" for r in wanted)
    return "pip install -e '.[ray]' in the pccl checkout"


RAY_MISSING = "{ray} needs Ray, an optional extra: " + _ray_hint()


#: seconds to wait for a Ray head's port to answer before giving up
RAY_CONNECT_TIMEOUT = 10.0


def probe_ray_address(address: str, timeout: float = RAY_CONNECT_TIMEOUT) -> None:
    """Raise :class:`RayUnavailable` unless something accepts a TCP
    connection at ``address`` (``HOST:PORT`` or ``ray://HOST:PORT``; other
    forms, such as ``auto``, are left to Ray).  Without this, ``ray.init``
    keeps retrying an address where nothing listens."""
    import socket
    rest = address[len("ray://"):] if address.startswith("ray://") else address
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit() or not host:
        return
    host = host.strip("[]")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise RayUnavailable(
            f"{{ray={address}}}: nothing answers at {host}:{port} ({why}); start the head "
            f"there with `ray start --head --port {port}`, or use {{ray=local}}") from None


class RayUnavailable(RuntimeError):
    """Ray is not installed, or cannot be started or reached (the front
    ends turn this into their own error message)."""


def import_ray():
    """The ``ray`` module, or :class:`RayUnavailable` saying how to install it."""
    try:
        import ray
    except ImportError:
        raise RayUnavailable(RAY_MISSING) from None
    return ray


class RayWorkerLost(RayUnavailable):
    """A Ray actor (a worker) died, or its node did, during the search: its
    partition of the visited states is gone, so the search cannot go on and
    has no verdict.  The message names the worker, its node and Ray's reason
    (the front ends report it with exit status 2, as Ray's other failures)."""


class _RayWorker(_Worker):
    """A worker as a Ray actor: :meth:`ready` also says where it runs."""

    def ready(self):
        super().ready()
        import ray
        return (self.wid, ray.get_runtime_context().get_node_id(),
                ray.util.get_node_ip_address(), os.getpid())


#: seconds between two looks at the cluster (are the actors' nodes alive?)
#: while a round waits for the actors' replies
RAY_POLL = 5.0


def _env_seconds(name: str, default: float) -> float:
    """A number of seconds from the environment (``default`` when unset)."""
    text = os.environ.get(name)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0 or value == float("inf"):
        raise RayUnavailable(f"{name}={text}: expected a number of seconds above 0")
    return value


#: The prefix of the module names a blackbox loaded from a ``.py`` file gets
#: (``pccl.blackboxes._import``): no other process can import them by name.
_FILE_MODULE_PREFIX = "_pccl_user_blackbox_"


def _pickle_user_code_by_value(ray) -> None:
    """A user blackbox loaded from a file (``--blackbox FILE.py:ATTR``)
    lives in a module the actors cannot import: its classes and functions
    go to them by value (cloudpickle), not as a reference to that module
    (oracle finding R1: the actors died, "worker 0 of 2 was lost")."""
    import sys
    for name, module in list(sys.modules.items()):
        if name.startswith(_FILE_MODULE_PREFIX):
            ray.cloudpickle.register_pickle_by_value(module)


class _RayTransport:
    """One Ray actor per partition.  ``address``: ``"local"`` starts a Ray
    instance on this machine (stopped again after the search); anything
    else is passed to ``ray.init(address=...)`` (``"auto"``, ``HOST:PORT``,
    ``ray://HOST:PORT``).  If this process is already connected to Ray
    (``ray.is_initialized()``), that connection is used and left open.

    The actors are spread over the cluster's nodes (``SPREAD``); each says
    where it runs (:attr:`placement`, in the result's notes).  An actor that
    dies, or whose node does, stops the search with :class:`RayWorkerLost`
    naming it: Ray reports the death to a waiting call, and while a round
    waits the transport also looks every :data:`RAY_POLL` seconds whether
    the actors' nodes are still alive, so a lost node never leaves the
    search waiting.  Actors that cannot be placed (a cluster without room)
    fail after ``PCCL_RAY_START_TIMEOUT`` seconds (default 300)."""

    #: actors may run on machines that do not see the coordinator's files:
    #: their checkpoint partitions travel to the coordinator, which writes them
    shared_files = False

    def __init__(self, n: Optional[int], address: str):
        self.n: Any = n                # None until start(): one per CPU of the cluster
        self.address = address
        self.actors: list = []
        self.actor_ids: dict = {}      # actor id (hex) -> worker number
        self.placement: list = []      # per worker: (node id, node address, pid)
        self.owned = False
        self.ray = import_ray()

    @staticmethod
    def connect(ray, address: str, cpus: int) -> bool:
        """Connect to Ray; True when this call started (and must stop) it."""
        import logging
        if ray.is_initialized():
            return False
        quiet = dict(include_dashboard=False, logging_level=logging.WARNING,
                     log_to_driver=False, configure_logging=True)
        if address != "local":
            probe_ray_address(address)      # ray.init retries an address that never answers
        try:
            if address == "local":
                ray.init(num_cpus=cpus, **quiet)
            else:
                ray.init(address=address, **quiet)
        except Exception as exc:
            hint = ""
            if address != "local" and "RAY_AUTH_MODE" not in os.environ:
                hint = ("; if the cluster uses token authentication (recent Ray turns it on "
                        "for a new head), set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN to the "
                        "head's token (its ~/.ray/auth_token)")
            raise RayUnavailable(f"{{ray={address}}}: cannot start or reach Ray: {exc}{hint}") from None
        return True

    def start(self, model, deadlock: bool, find_all: bool, columns=None,
              fastest: bool = False) -> None:
        ray = self.ray
        limit = _env_seconds("PCCL_RAY_START_TIMEOUT", 300.0)
        self.owned = self.connect(ray, self.address, self.n or available_workers())
        cpus = ray.cluster_resources().get("CPU", 0)
        if self.n is None:          # workers="auto": one per CPU of the cluster
            self.n = max(1, int(cpus))
        per = 1 if cpus >= self.n else max(0.01, cpus / self.n)
        actor = ray.remote(num_cpus=per, scheduling_strategy="SPREAD")(_RayWorker)
        _pickle_user_code_by_value(ray)
        ref = ray.put(model)
        self.actors = [actor.remote(ref, w, self.n, deadlock, find_all, columns, fastest)
                       for w in range(self.n)]
        self.actor_ids = {a._actor_id.hex(): w for w, a in enumerate(self.actors)}
        refs = [a.ready.remote() for a in self.actors]
        _, pending = ray.wait(refs, num_returns=len(refs), timeout=limit)
        if pending:
            waiting = [w for w, r in enumerate(refs) if r in pending]
            raise RayUnavailable(
                f"{{ray={self.address}}}: {len(waiting)} of the {self.n} actors (worker"
                f"{'s' if len(waiting) > 1 else ''} {', '.join(map(str, waiting))}) did not "
                f"start within {limit:g} s (the cluster has {cpus:g} CPUs); give fewer "
                f"{{workers}} or add nodes (PCCL_RAY_START_TIMEOUT=SECONDS waits longer)")
        self.placement = [tuple(r[1:]) for r in self._get(refs)]

    def placement_note(self) -> str:
        """Where the actors ran, for the result's notes: ``Ray: 2 actors on
        2 nodes: worker 0 on node 1a2b3c4d (10.0.0.1, pid 123); ...``."""
        k, nodes = len(self.placement), len({p[0] for p in self.placement})
        where = "; ".join(f"worker {w} on node {node[:8]} ({ip}, pid {pid})"
                          for w, (node, ip, pid) in enumerate(self.placement))
        return (f"Ray: {k} actor{'s' if k != 1 else ''} on {nodes} "
                f"node{'s' if nodes != 1 else ''}: {where}")

    def _who(self, w: int) -> str:
        if w < len(self.placement):
            node, ip, pid = self.placement[w]
            return f"worker {w} of {self.n} (the Ray actor on node {node[:8]} at {ip}, pid {pid})"
        return f"worker {w} of {self.n}"

    def _lost(self, exc: BaseException, workers=()) -> "RayWorkerLost":
        """The error for a lost actor: which one (from Ray's error, or the
        nodes the cluster reports dead), and Ray's reason."""
        w = self.actor_ids.get(getattr(exc, "actor_id", None) or "")
        lost = [w] if w is not None else list(workers) or self._on_dead_nodes()
        who = " and ".join(self._who(v) for v in lost) if lost else "a worker (a Ray actor)"
        reason = " ".join(str(exc).split())
        if len(reason) > 300:
            reason = reason[:300] + "…"
        return RayWorkerLost(
            f"{{ray={self.address}}}: {who} was lost during the search ({type(exc).__name__}: "
            f"{reason}). Its part of the visited states is gone: the search stops without a "
            f"verdict; resume it from its last checkpoint with {{resume=DIR}} if it ran with "
            f"{{checkpoint=DIR}}, else start it again")

    def _on_dead_nodes(self) -> list:
        """The workers whose node the cluster reports dead (none if the
        cluster cannot be asked)."""
        try:
            dead = {n["NodeID"] for n in self.ray.nodes() if not n.get("Alive", True)}
        except Exception:
            return []
        return [w for w, p in enumerate(self.placement) if p[0] in dead]

    def _get(self, refs):
        ray = self.ray
        errors = ray.exceptions
        lost_kinds = (errors.RayActorError, errors.ObjectLostError, errors.NodeDiedError,
                      errors.WorkerCrashedError)
        while True:
            try:
                return ray.get(refs, timeout=RAY_POLL)
            except errors.GetTimeoutError:
                lost = self._on_dead_nodes()
                if lost:
                    raise self._lost(errors.NodeDiedError(
                        "the cluster reports the node dead"), lost) from None
            except errors.RayTaskError as exc:
                cause = getattr(exc, "cause", None)
                if isinstance(cause, lost_kinds):       # an input from a lost actor
                    raise self._lost(cause) from None
                if isinstance(cause, Exception):    # as the pipes transport: the worker's own error
                    raise cause from None
                raise
            except lost_kinds as exc:
                raise self._lost(exc) from None

    def all(self, cmd: str, per_worker: list) -> list:
        return self._get([getattr(a, cmd).remote(*args)
                          for a, args in zip(self.actors, per_worker)])

    def level(self, per_worker: list, size: int = 0):
        """One level: the *step* round, then the *decide* round.  Only the
        small part of each step reply comes to the coordinator; the
        candidates stay in the object store as references, which the
        *decide* calls pass to their owners (Ray moves them actor to actor,
        and starts an owner's *decide* once its inputs exist)."""
        n = self.n
        refs = [a.step.options(num_returns=n + 1).remote(*args)
                for a, args in zip(self.actors, per_worker)]
        decided = [a.decide.remote(*(refs[g][o] for g in range(n)))
                   for o, a in enumerate(self.actors)]
        return self._get([r[n] for r in refs]), self._get(decided)

    def call(self, w: int, cmd: str, *args):
        return self._get(getattr(self.actors[w], cmd).remote(*args))

    def drain(self) -> None:
        pass            # the actors are killed by stop()

    def stop(self) -> None:
        ray = self.ray
        for a in self.actors:
            try:
                ray.kill(a)
            except Exception:
                pass
        self.actors = []
        if self.owned:
            ray.shutdown()
            self.owned = False
