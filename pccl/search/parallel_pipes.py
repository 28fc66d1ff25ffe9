"""The processes transport of a parallel search (``--workers N``): worker 0
runs in the coordinator's process, workers 1..N-1 are forked processes
behind :mod:`multiprocessing` pipes (:class:`_Pipes`); the balanced level
(:func:`_balanced_step`, :class:`_Balancer`); message framing (:func:`_send`,
:func:`_read`); waiting for a message (polling, the load, pinning a worker
to a core); a worker's process and its signals (:func:`_serve`).  See
:mod:`pccl.search.parallel` for the design."""

from __future__ import annotations

import gc
import io
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import struct
import time as _time
from multiprocessing.reduction import ForkingPickler
from typing import Optional

import numpy as np

from pccl.search.parallel_worker import _LITTER, _Worker


# ---------------------------------------------------------------------------
# Transports: how the rounds reach the workers
# ---------------------------------------------------------------------------

def _spin_seconds(default: float = 0.05) -> float:
    """Seconds a process polls for a message before it blocks (see
    :func:`_recv`): ``PCCL_SPIN`` in the environment (``0``: block at once),
    else 50 ms."""
    try:
        return max(0.0, float(os.environ.get("PCCL_SPIN", default)))
    except ValueError:
        return default


_SPIN = _spin_seconds()
#: without ``PCCL_SPIN``, poll only while the machine is not overloaded
_SPIN_AUTO = "PCCL_SPIN" not in os.environ
_LOAD = [0.0, False]         # when last read, and whether overloaded then


def _runnable() -> Optional[int]:
    """The processes running or waiting for a core right now (the kernel's
    count in ``/proc/loadavg``, this one included), or None where there is
    no such file."""
    try:
        with open("/proc/loadavg", "rb") as f:
            return int(f.read().split()[3].split(b"/")[0])
    except (OSError, ValueError, IndexError):
        return None


def _overloaded() -> bool:
    """Whether a waiting process should block at once instead of polling:
    when more processes are runnable right now than the machine has cores
    (a poller would then take a core from its partner or from another job;
    5 us to read; the machine's cores, not this process's: a pinned worker
    may use one).  Beside one busy loop on 2 cores, fischer 3 agents k=2
    with 2 native workers: 0.82x one worker polling, 0.84x blocking;
    pinned (:func:`_pin`) 0.89x polling, 0.96x blocking; idle the same
    either way (docs/scale-out.md).  Without the kernel's count: the
    1-minute load average against four times the cores (read at most once
    a second; measured on a shared machine at load 11, blocking won 2x; at
    load 3.8 polling did)."""
    cores = os.cpu_count() or 1     # the kernel's counts are the machine's, not this process's
    now = _runnable()
    if now is not None:
        return now > cores
    t = _time.monotonic()
    if t - _LOAD[0] > 1.0:
        _LOAD[0] = t
        try:
            _LOAD[1] = os.getloadavg()[0] > 4 * cores
        except (OSError, AttributeError):      # pragma: no cover - no load average
            _LOAD[1] = False
    return bool(_LOAD[1])


#: ``PCCL_PIN=0`` in the environment: never pin a worker to a core
_PIN = os.environ.get("PCCL_PIN", "1") != "0"


def _pin(wid: int, n: int) -> Optional[set]:
    """Pin worker ``wid`` of ``n`` to one core of its own when the workers
    are exactly as many as the cores this process may use (so no core is
    left out, and two such searches on one machine still share every core);
    returns the cores it had, to restore, or None when not pinned.  Beside a
    competing job the scheduler then moves only that job between the cores,
    instead of moving the workers away from their caches: fischer 3 agents
    k=2 with 2 native workers beside one busy loop 0.86x one worker
    unpinned, 0.95x pinned; idle 1.72x and 1.71x (docs/scale-out.md).
    ``PCCL_PIN=0`` turns it off."""
    if not _PIN:
        return None
    try:
        cpus = sorted(os.sched_getaffinity(0))
        if len(cpus) != n or n < 2:
            return None
        os.sched_setaffinity(0, {cpus[wid]})
    except (AttributeError, OSError):       # pragma: no cover - non-Linux
        return None
    return set(cpus)


#: balanced levels (see :meth:`_Pipes.level`); ``PCCL_BALANCE=0``: off
_BALANCE = os.environ.get("PCCL_BALANCE", "1") != "0"
#: ... with the native engine only when asked for (``PCCL_BALANCE=1``): measured
#: on fischer 3 agents k=2 (docs/scale-out.md, "Native workers"), the static
#: split spent 15-20 % less CPU and was faster in 6 of 7 pairs, idle and beside
#: a busy loop (moving native states and sorting the candidates back into key
#: order cost more than the imbalance)
_BALANCE_NATIVE = os.environ.get("PCCL_BALANCE") == "1"
#: ... for levels of at least this many states (~15 ms of work or more
#: for one worker; measured: on a loaded machine, balancing fischer k=2's
#: levels of ~1,600 states cost more than it gained)
_BALANCE_LEVEL = 8192


def _recv(conn):
    """``conn.recv()``, first freeing discarded states (a slice at a time,
    while no message is there: freeing a level's candidates costs about as
    much as a tenth of expanding it) and polling for up to :data:`_SPIN`
    seconds.  A process that blocks gives up its core; when its message
    arrives it waits for the scheduler (on a busy machine, behind other jobs
    for a time slice; on an idle virtual machine, for the core to wake up),
    twice per BFS level.  The wait between rounds is short (the other
    workers' share of a level), so polling through it keeps the core."""
    return _read(_ready([conn]))


def _ready(conns: list):
    """The first of ``conns`` with a message waiting (see :func:`_recv`:
    frees discarded states, polls, then blocks)."""
    def first():
        for c in conns:
            if c.poll(0):
                return c
        return None
    c = first()
    while _LITTER and c is None:
        states = _LITTER[-1]
        if states:
            del states[-2048:]
        else:
            _LITTER.pop()
        c = first()
    if _SPIN > 0 and c is None and not (_SPIN_AUTO and _overloaded()):
        clock, pass_turn = _time.perf_counter, getattr(os, "sched_yield", lambda: None)
        end = clock() + _SPIN
        while c is None and clock() < end:
            pass_turn()     # a process waiting for a core (my partner?) gets this one
            c = first()
    if c is None:
        c = multiprocessing.connection.wait(conns)[0]
    return c


#: States a worker expands between two looks for another worker's request
#: (:func:`_balanced_step`, :meth:`_Pipes._balance`): ~0.2-0.5 ms of work.
_CHUNK = 64
#: ... times this for the native engine (a state costs ~0.5 us to expand there,
#: against ~3.5 us in Python; a look costs a poll of the pipe: measured on
#: fischer 3 agents k=1, 8.18 s of CPU with 8 times, 7.70 s with 32, 7.48 s
#: unbalanced)
_NATIVE_CHUNK = 32


def _chunk(w: "_Worker") -> int:
    """The states ``w`` expands between two looks for a request."""
    return _CHUNK * _NATIVE_CHUNK if w.succ_batch is not None else _CHUNK
#: A worker asked for work hands over half of what it has left, if that is
#: at least this many states (moving a state costs about as much as
#: expanding it: pickled, sent, unpickled).
_MIN_GIVE = 32


def _half(left: int) -> int:
    return left // 2 if left >= _MIN_GIVE else 0


def _balanced_step(w: "_Worker", conn, *args) -> None:
    """A forked worker's side of a balanced level (:meth:`_Pipes.level`):
    commit the decision, expand my share a chunk at a time, answering the
    coordinator's requests for work (``("steal", None)`` -> ``("loot",
    (numbers, states) or None)``) in between; then say ``("hungry", None)``
    and expand the states the coordinator hands over (``("work", (numbers,
    states))``) until it says ``("finish", None)``; the caller then finishes
    the step (:meth:`_Worker.finish_step`), while worker 0 finishes its own."""
    w.start_level(*args)
    poll = conn.poll

    def recv():
        return _read(conn)

    def send(msg) -> None:
        _send(conn, msg)

    chunk = _chunk(w)

    def expand_all():
        while w.expand_some(chunk):
            while poll(0):
                kind, _ = recv()
                assert kind == "steal", kind
                send(("loot", w.give(_half(w.remaining()))))
    expand_all()
    while True:
        send(("hungry", None))
        kind, value = _recv(conn)
        while kind == "steal":          # asked before my "hungry" arrived
            send(("loot", None))
            kind, value = _recv(conn)
        if kind == "work":
            w.take(*value)
            expand_all()
            continue
        assert kind == "finish", kind
        return


#: ``prctl`` option: the signal a process gets when its parent dies (Linux).
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int) -> None:
    """Ask the kernel to kill this process when its parent dies (Linux:
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)``); a parent already gone by now
    means exit at once.  ``PCCL_PDEATHSIG=0`` in the environment skips the
    ``prctl`` (the tests use it to check the portable fallback: the pipe to
    the parent closes, and :func:`_serve` returns)."""
    if os.environ.get("PCCL_PDEATHSIG") == "0" or not hasattr(os, "getppid"):
        return
    try:
        import ctypes
        import ctypes.util
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):       # not Linux: the closed pipe tells
        return
    if os.getppid() != parent:              # died before the prctl
        os._exit(0)


def _serve(conn, model, wid, n, deadlock, find_all, columns=None, parent=None,
           inherited=(), fastest=False):
    # The coordinator alone handles Ctrl-C and SIGTERM (sent to the whole
    # process group by a terminal or a job control): a worker ignores both
    # and stops when the coordinator says so, or when its pipe closes.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    for c in inherited:     # the coordinator's ends of the pipes: else its death is no EOF
        c.close()
    if parent is not None:
        _die_with_parent(parent)
    gc.disable()
    _pin(wid, n)
    w = _Worker(model, wid, n, deadlock, find_all, columns, fastest)
    w.defer_free = True
    while True:
        try:
            cmd, args = _recv(conn)
        except EOFError:
            return
        if cmd == "stop":
            return
        try:
            if cmd == "lstep":
                _balanced_step(w, conn, *args)
                reply = ("ok", w.finish_step())
            elif cmd == "pstep":      # a step that moves states first (_rebalance)
                (decision, at_bound), gives, expect = args
                w.commit(decision)
                for k in gives:           # one hand-over per receiver, in the plan's order
                    _send(conn, ("loot", w.handoff(k)))
                for _ in range(expect):
                    kind, loot = _recv(conn)
                    assert kind == "work", kind
                    w.receive(loot)
                w.begin(at_bound)
                w.expand_some(None)
                reply = ("ok", w.finish_step())
            else:
                reply = ("ok", getattr(w, cmd)(*args))
        except BaseException as exc:         # report, do not hang the coordinator
            reply = ("error", exc)
        try:
            _send(conn, reply)
        except (OSError, BrokenPipeError):
            return


#: A message this small is sent without waiting for the receiver to read
#: (the socket buffers hold ~200 KB; see :meth:`_Pipes.level`).
_EARLY = 64 * 1024


#: Buffers (numpy arrays) of at least this many bytes travel beside a
#: message's pickle, not inside it (:func:`_dumps`)
_ASIDE_BYTES = 1 << 16


def _dumps(obj) -> list:
    """A message as the frames :func:`_send_frames` writes: its pickle
    (protocol 5) behind a header of the sizes of its large buffers, then
    those buffers as they lie in memory.  ``Connection.send`` copied each
    array into the pickle and the receiver copied it out of a stream again:
    measured, forked from a process of 1.6 GB, 208 MB of arrays took 1.46 s
    that way and 0.54 s as frames (race_robust with 4 robots, 2 workers:
    worker 1's part of the recorded graph 2.27 s against 0.84 s)."""
    bufs: list = []

    def aside(b: pickle.PickleBuffer) -> bool:
        raw = b.raw()
        if raw.nbytes < _ASIDE_BYTES:
            return True         # in the pickle
        bufs.append(raw)
        return False
    f = io.BytesIO()
    ForkingPickler(f, 5, True, aside).dump(obj)
    head = struct.pack(f"<I{len(bufs)}Q", len(bufs), *(b.nbytes for b in bufs))
    return [head + f.getbuffer(), *bufs]


def _size(frames: list) -> int:
    return sum(memoryview(fr).nbytes for fr in frames)


def _send_frames(conn, frames: list) -> None:
    for fr in frames:
        conn.send_bytes(fr)


def _send(conn, obj) -> None:
    """``conn.send(obj)``, its large arrays beside the pickle (:func:`_dumps`)."""
    _send_frames(conn, _dumps(obj))


def _read(conn):
    """The message :func:`_send` wrote, read from ``conn`` (its large
    arrays straight into their own memory, writable)."""
    first = conn.recv_bytes()
    k, = struct.unpack_from("<I", first)
    sizes = struct.unpack_from(f"<{k}Q", first, 4)
    bufs = []
    for n in sizes:
        b = np.empty(n, dtype=np.uint8)
        conn.recv_bytes_into(b)
        bufs.append(b)
    return pickle.loads(memoryview(first)[4 + 8 * k:], buffers=bufs)


class _Pipes:
    """Worker 0 in this process; workers 1..n-1 forked, behind pipes.  A
    round sends to the forked workers first, runs worker 0 meanwhile, then
    collects the replies."""

    #: the workers see the coordinator's files (they write their checkpoint partitions)
    shared_files = True

    def __init__(self, n: int):
        self.n = n
        self.conns: list = []
        self.procs: list = []
        self.outstanding = [0] * n
        self.local: Optional[_Worker] = None
        #: the cores this process had before worker 0 was pinned to one (:func:`_pin`)
        self.unpinned: Optional[set] = None
        #: the last rebalanced step's moves: (receiver, the states' numbers)
        self.handed: list = []

    def start(self, model, deadlock: bool, find_all: bool, columns=None,
              fastest: bool = False) -> None:
        ctx = multiprocessing.get_context("fork")
        me = os.getpid()
        for w in range(1, self.n):
            a, b = ctx.Pipe()
            p = ctx.Process(target=_serve, args=(b, model, w, self.n, deadlock, find_all,
                                                 columns, me, [*self.conns, a], fastest),
                            daemon=True)
            p.start()
            b.close()
            self.conns.append(a)
            self.procs.append(p)
        self.local = _Worker(model, 0, self.n, deadlock, find_all, columns, fastest)
        self.local.defer_free = self.n > 1     # freed while waiting for the others
        self.unpinned = _pin(0, self.n)        # (after the fork: the workers pin themselves)

    def stop(self) -> None:
        for c in self.conns:
            try:
                _send(c, ("stop", ()))
            except (OSError, BrokenPipeError):
                pass
            c.close()
        for p in self.procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join()
        self.conns, self.procs, self.local = [], [], None
        _LITTER.clear()
        if self.unpinned is not None:
            os.sched_setaffinity(0, self.unpinned)
            self.unpinned = None

    def _result(self, w):
        status, value = _recv(self.conns[w - 1])
        self.outstanding[w] -= 1
        if status == "error":
            raise value
        return value

    def all(self, cmd: str, per_worker: list) -> list:
        for w in range(1, self.n):
            _send(self.conns[w - 1], (cmd, per_worker[w]))
            self.outstanding[w] += 1
        mine = getattr(self.local, cmd)(*per_worker[0])
        return [mine] + [self._result(w) for w in range(1, self.n)]

    #: the pipes can move a level's states between workers (:func:`_rebalance`)
    moves_states = True

    def level(self, per_worker: list, size: int = 0, plan=None):
        """One level: the *step* round, then the *decide* round, pipelined:
        an owner's *decide* is sent as soon as the coordinator holds the
        candidates of every other generator for it (``--workers 2``: with
        the message that ends worker 1's step, so it decides straight after
        its step, without waiting for the coordinator to read its reply).

        The step is *balanced* (:meth:`_balance`): the workers expand their
        shares a chunk at a time, and one that runs out of work gets half of
        what another has left, so that a worker slowed down (by another job
        on its core) does not hold the level up.  The moved states' successors
        stay with the worker that expanded them (it holds those admitted),
        so the shares of the next level follow the workers' speeds and
        states move again only when the speeds change.  Results do not depend
        on who expanded what: candidates are ordered by their keys.
        Only a level of at least :data:`_BALANCE_LEVEL` states (``size``) is
        balanced: a request for work waits for the other worker to be
        running, and on a small level that wait costs more than the
        imbalance.  ``PCCL_BALANCE=0`` in the environment expands each share
        where it lies, as before (for comparison).

        Returns (the rest of each step reply, each owner's new keys)."""
        n, local = self.n, self.local
        assert local is not None, "start() first"
        parts: list = [None] * n            # parts[g]: generator g's candidates by owner
        sent = [False] * n
        if plan:
            self._moved_step(per_worker, plan)
            parts[0] = local.finish_step()
        elif n > 1 and _BALANCE and size >= _BALANCE_LEVEL and (
                local.succ_batch is None or (_BALANCE_NATIVE and not getattr(local.m, "stable_ids", False))):
            for w in range(1, n):
                _send(self.conns[w - 1], ("lstep", per_worker[w]))
                self.outstanding[w] += 1
            local.start_level(*per_worker[0])
            self._balance()
            for o in range(1, n):           # every forked worker waits for this
                _send(self.conns[o - 1], ("finish", None))
            parts[0] = local.finish_step()  # meanwhile they finish theirs
        else:
            for w in range(1, n):
                _send(self.conns[w - 1], ("step", per_worker[w]))
                self.outstanding[w] += 1
            parts[0] = local.step(*per_worker[0])
        ready: list = [None] * n            # pickled decide messages not sent yet

        def send_ready():
            for o in range(1, n):
                if sent[o]:
                    continue
                if ready[o] is None and all(parts[g] is not None for g in range(n) if g != o):
                    ready[o] = _dumps(("decide", tuple(
                        None if g == o else parts[g][o] for g in range(n))))
                # Worker o may itself be writing its (large) step reply: a
                # message larger than what the socket buffers could block
                # both writers.  So early only if small, else once o's reply is in.
                if ready[o] is not None and (_size(ready[o]) <= _EARLY or parts[o] is not None):
                    _send_frames(self.conns[o - 1], ready[o])
                    self.outstanding[o] += 1
                    sent[o], ready[o] = True, None
        send_ready()
        for w in range(1, n):
            parts[w] = self._result(w)
            send_ready()
        mine = local.decide(*(parts[g][0] for g in range(n)))
        return [p[n] for p in parts], [mine] + [self._result(o) for o in range(1, n)]

    def _moved_step(self, per_worker: list, plan: list) -> None:
        """A step that first moves states ``plan`` (``[(giver, receiver,
        count)]``, :func:`_rebalance`): each giver hands the last ``count``
        states of its level over (through this process when neither is
        worker 0), then every worker expands its share as in a static step;
        worker 0's is expanded here, the forked workers' replies follow."""
        local = self.local
        assert local is not None
        gives: list = [[] for _ in range(self.n)]
        expects = [0] * self.n
        for g, r, k in plan:
            gives[g].append(k)
            expects[r] += 1
        for w in range(1, self.n):
            if gives[w] or expects[w]:
                assert not (gives[w] and expects[w]), plan
                msg = ("pstep", (per_worker[w], gives[w], expects[w]))
            else:
                msg = ("step", per_worker[w])
            _send(self.conns[w - 1], msg)
            self.outstanding[w] += 1
        decision, at_bound = per_worker[0]
        local.commit(decision)
        self.handed = []                # (receiver, numbers) of the states moved
        for g, r, k in plan:
            if g == 0:
                loot = local.handoff(k)
            else:
                kind, loot = _recv(self.conns[g - 1])
                if kind == "error":
                    self.outstanding[g] -= 1
                    raise loot
                assert kind == "loot", kind
            self.handed.append((r, loot[0]))
            if r == 0:
                local.receive(loot)
            else:
                _send(self.conns[r - 1], ("work", loot))
        local.begin(at_bound)
        local.expand_some(None)

    def _balance(self) -> None:
        """Worker 0's side of a balanced step, in this process
        (:class:`_Balancer`)."""
        assert self.local is not None
        _Balancer(self.local, self.conns, self.outstanding).run()

    def call(self, w: int, cmd: str, *args):
        if w == 0:
            return getattr(self.local, cmd)(*args)
        _send(self.conns[w - 1], (cmd, args))
        self.outstanding[w] += 1
        return self._result(w)

    def drain(self) -> None:
        """After an interrupt: collect the replies still on their way."""
        for w in range(1, self.n):
            while self.outstanding[w] > 0:
                try:
                    self._result(w)
                except Exception:
                    pass


class _Balancer:
    """Worker 0's side of a balanced step (:meth:`_Pipes.level`), in the
    coordinator's process: expand its share a chunk at a time; between
    chunks hand half of what is left to a forked worker that says it is
    ``hungry``; once its own share is done, ask the busy workers for work
    (``steal``, one request at a time) and expand what they hand over, until
    every forked worker is hungry and nothing is left (the other side:
    :func:`_balanced_step`)."""

    def __init__(self, local: "_Worker", conns: list, outstanding: list):
        self.local, self.conns, self.outstanding = local, conns, outstanding
        n = len(conns) + 1
        self.hungry = [True] + [False] * (n - 1)
        self.asked = [False] * n        # a steal request is on its way to worker o
        self.dry = [False] * n          # ... and o had too little to hand over
        self.turn = 0

    def run(self) -> None:
        local, conns = self.local, self.conns
        chunk = _chunk(local)
        while True:
            if local.expand_some(chunk):
                self.pump()
                continue
            self.pump()
            if local.remaining():
                continue
            if all(self.hungry) and not any(self.asked):
                return
            if not any(self.asked):
                self.ask()
            c = _ready(conns)
            self.handle(conns.index(c) + 1, _read(c))

    def handle(self, o: int, msg) -> None:
        kind, value = msg
        if kind == "hungry":
            self.hungry[o] = True
        elif kind == "loot":
            self.asked[o] = False
            if value is None:
                self.dry[o] = True
            else:
                self.local.take(*value)
        elif kind == "error":
            self.outstanding[o] -= 1
            raise value
        else:                   # pragma: no cover - a protocol error
            raise RuntimeError(f"worker {o}: unexpected {kind!r} during a level")

    def pump(self) -> None:
        """Read what has come, and feed the hungry from what I have left."""
        local, conns, hungry = self.local, self.conns, self.hungry
        for o, c in enumerate(conns, 1):
            while c.poll(0):
                self.handle(o, _read(c))
        for o, c in enumerate(conns, 1):
            if hungry[o]:
                loot = local.give(_half(local.remaining()))
                if loot is None:
                    break
                _send(c, ("work", loot))
                hungry[o], self.dry[o] = False, False

    def ask(self) -> None:
        """Ask a busy worker (the next in turn) for half of what it has left."""
        m = len(self.conns)
        for i in range(1, m + 1):
            o = 1 + (self.turn + i) % m
            if not self.hungry[o] and not self.dry[o]:
                _send(self.conns[o - 1], ("steal", None))
                self.asked[o], self.turn = True, o
                return
