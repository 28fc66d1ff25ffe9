"""``--ray HOST:PORT`` on a real Ray cluster of two nodes on this machine.

Each node is a ``ray start --block`` of its own (the head with the resource
``node_a``, the second node joined with ``--address`` and ``node_b``), one
CPU each, each with its own temporary directory and in a session of its
own, so that the test can kill one node's processes (and only those it
started) and always tears the cluster down.  The nodes use token
authentication (the default of a new Ray head) with a token of their own,
given to every process through ``RAY_AUTH_MODE``/``RAY_AUTH_TOKEN``.

Checked: the two actors of ``--workers 2`` run on the two nodes (each
reports its node, in the result's notes), the result equals one worker's,
and losing a worker mid-search, its process alone or its whole node, stops
the search with one message naming the worker and its node and exit status
2: no verdict, no traceback, no hang (a frozen node included)."""

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

import pytest

from conftest import started

FISCHER = "programs/fischer.pccl"
MUTEX = "count(inCs) <= 1"
PCCL = [sys.executable, "-m", "pccl.cli", "explore"]


def _ray_cli() -> str:
    try:
        import ray  # noqa: F401
    except ImportError:
        pytest.skip("ray is not installed (pip install -e '.[ray]' in the pccl checkout): "
                    "no cluster to start")
    exe = shutil.which("ray", path=os.path.dirname(sys.executable)) or shutil.which("ray")
    if exe is None:
        pytest.skip("ray is importable but its command line (ray start) is not on PATH")
    return exe


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _session(sid: int) -> list:
    """The processes of the session ``sid`` (a node this test started)."""
    import psutil
    out = []
    for p in psutil.process_iter(["name", "cmdline"]):
        try:
            if os.getsid(p.pid) == sid and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except (OSError, psutil.Error):
            pass
    return out


def _kill(procs, sig=signal.SIGKILL) -> None:
    for p in procs:
        try:
            os.kill(p.pid, sig)
        except OSError:
            pass


class Cluster:
    """Two ``ray start --block`` nodes; :meth:`down` kills what they started."""

    def __init__(self):
        self.ray = _ray_cli()
        self.port = _free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.root = tempfile.mkdtemp(prefix="pccl-ray-")   # short: Ray's socket paths
        self.env = {**os.environ, "RAY_AUTH_MODE": "token",
                    "RAY_AUTH_TOKEN": secrets.token_hex(16), "RAY_USAGE_STATS_ENABLED": "0",
                    # the head's health checks of the nodes: every 1 s, 3 s to answer, dead
                    # after 5 misses (Ray's defaults 3 s, 10 s, 5: a frozen node took ~65 s
                    # to be declared dead, a minute of the suite)
                    "RAY_health_check_period_ms": "1000", "RAY_health_check_timeout_ms": "3000",
                    "RAY_health_check_failure_threshold": "5"}
        self.nodes: dict = {}          # "node_a"/"node_b" -> the ray start process
        self.ids: dict = {}            # "node_a"/"node_b" -> Ray's node id

    def start_node(self, name: str, head: bool, cpus: int = 1) -> None:
        tmp = os.path.join(self.root, name)
        os.mkdir(tmp)
        cmd = [self.ray, "start", "--block", "--num-cpus", str(cpus), "--node-ip-address", "127.0.0.1",
               "--resources", json.dumps({name: 1}), "--temp-dir", tmp, "--disable-usage-stats",
               "--dashboard-agent-listen-port", str(_free_port())]
        cmd += (["--head", "--port", str(self.port), "--include-dashboard", "false"] if head
                else ["--address", self.address])
        log = open(os.path.join(self.root, name + ".log"), "w")
        self.nodes[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                            env=self.env, start_new_session=True)
        log.close()
        self._wait_log(name, "block forever", 180)

    def _wait_log(self, name: str, text: str, timeout: float) -> None:
        path = os.path.join(self.root, name + ".log")
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with open(path) as f:
                got = f.read()
            if text in got:
                return
            if self.nodes[name].poll() is not None:
                pytest.fail(f"ray start for {name} exited {self.nodes[name].returncode}:\n{got}")
            time.sleep(0.3)
        pytest.fail(f"ray start for {name}: no {text!r} within {timeout} s:\n{got}")

    def node_ids(self, timeout: float = 120) -> dict:
        """Ray's node id of each node, asked from the cluster once both
        have joined (a driver of its own, in a subprocess)."""
        code = ("import json, logging, ray\n"
                f"ray.init(address={self.address!r}, logging_level=logging.WARNING,"
                " log_to_driver=False)\n"
                "print(json.dumps({k: n['NodeID'] for n in ray.nodes() if n['Alive']"
                " for k in n['Resources'] if k.startswith('node_')}))\n")
        end = time.monotonic() + timeout
        while True:
            r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               env=self.env, timeout=timeout)
            ids = json.loads(r.stdout.strip().splitlines()[-1]) if r.returncode == 0 else {}
            if len(ids) == 2 or time.monotonic() > end:
                assert len(ids) == 2, (r.stdout, r.stderr[-2000:])
                return ids
            time.sleep(1)

    def down(self) -> None:
        for p in self.nodes.values():
            procs = _session(p.pid)
            _kill(procs, signal.SIGTERM)
        end = time.monotonic() + 10
        while time.monotonic() < end and any(_session(p.pid) for p in self.nodes.values()):
            time.sleep(0.2)
        for p in self.nodes.values():
            _kill(_session(p.pid))
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
        shutil.rmtree(self.root, ignore_errors=True)


@pytest.fixture
def cluster():
    c = Cluster()
    try:
        c.start_node("node_a", head=True)
        c.start_node("node_b", head=False)
        c.ids = c.node_ids()
        yield c
    finally:
        c.down()


def _placement(notes) -> list:
    """[(worker, node id prefix, pid)] from the note ``Ray: 2 actors on 2
    nodes: worker 0 on node 1a2b3c4d (127.0.0.1, pid 123); ...``."""
    import re
    note = [n for n in notes if n.startswith("Ray: ")]
    assert len(note) == 1, notes
    return [(int(w), node, int(pid)) for w, node, pid in
            re.findall(r"worker (\d+) on node (\w+) \([^,]*, pid (\d+)\)", note[0])]


def _long_search(c: Cluster):
    """fischer k=4 (396,840 states, tens of seconds on Ray here) on the
    cluster, once its first progress line is out: the search is under way."""
    return started(["explore", FISCHER, "--set", "k=4", "--ray", c.address, "--workers", "2",
                    "--progress", "--progress-interval", "0.2"], "states ", env=c.env,
                   new_session=True)


def _lost_outcome(p, t_kill: float, node_id: str, head_lines: str):
    try:
        out, err = p.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        pytest.fail("the search hung after its worker was lost")
    took = time.monotonic() - t_kill
    assert p.returncode == 2, (out, head_lines + err)
    assert "Traceback" not in err, err
    assert "was lost during the search" in err and f"on node {node_id[:8]}" in err, err
    assert "without a verdict" in err
    assert "no violation" not in out and "violation:" not in out and "exhaustive" not in out, out
    return took, err


@pytest.mark.slow
def test_two_nodes_hold_one_actor_each_and_give_the_one_worker_result(cluster):
    base = PCCL + [FISCHER, "--set", "k=1", "--invariant", MUTEX, "--no-progress",
                   "--format", "json"]
    one = subprocess.run(base, capture_output=True, text=True, timeout=300)
    two = subprocess.run(base + ["--ray", cluster.address, "--workers", "2"],
                         capture_output=True, text=True, timeout=300, env=cluster.env)
    assert one.returncode == two.returncode == 1, two.stderr[-3000:]
    a, b = json.loads(one.stdout), json.loads(two.stdout)
    for k in ("states", "transitions", "max_depth", "initial_states"):
        assert a["statistics"][k] == b["statistics"][k], k
    assert a["status"] == b["status"] and a["message"] == b["message"]
    assert a["violations"] == b["violations"]       # the same shortest counterexample
    placed = _placement(b["notes"])
    assert [w for w, _, _ in placed] == [0, 1]
    # one actor on each node: their node ids are the two nodes' ids
    assert sorted(node for _, node, _ in placed) == sorted(i[:8] for i in cluster.ids.values())
    assert not any(n.startswith("Ray: ") for n in a["notes"])

    # kill the actor on node_b alone (its node stays up) in the middle of a search
    p, lines = _long_search(cluster)
    sid = cluster.nodes["node_b"].pid
    actors = [q for q in _session(sid) if "_RayWorker" in " ".join(q.info["cmdline"] or [])]
    assert len(actors) == 1, [q.info["cmdline"] for q in _session(sid)]
    t = time.monotonic()
    _kill(actors)
    took, err = _lost_outcome(p, t, cluster.ids["node_b"], lines)
    assert f"pid {actors[0].pid})" in err, err
    assert took < 60, took


@pytest.mark.slow
@pytest.mark.parametrize("how", ["killed", "frozen"])
def test_a_node_lost_mid_search_is_named_and_ends_the_search(cluster, how):
    """The machine of node_b dies (SIGKILL to its raylet, its actor,
    everything: seconds until the error) or freezes (SIGSTOP: its sockets
    stay open and nothing answers, as behind a broken network; the cluster
    marks it dead when its health checks fail: about 20 s with this
    cluster's settings, about a minute with Ray's defaults)."""
    p, lines = _long_search(cluster)
    node_b = _session(cluster.nodes["node_b"].pid)
    assert any("raylet" in (q.info["name"] or "") for q in node_b)
    t = time.monotonic()
    _kill(node_b, signal.SIGKILL if how == "killed" else signal.SIGSTOP)
    took, err = _lost_outcome(p, t, cluster.ids["node_b"], lines)
    assert took < 150, took


@pytest.mark.slow
def test_actors_that_cannot_be_placed_fail_after_the_start_timeout():
    """A head without CPUs (as many clusters start theirs) and no other
    node: the actors stay pending; the search says so after
    PCCL_RAY_START_TIMEOUT seconds, exit status 2 (before: it waited for
    ever).  And, on the same cluster, pccl without the cluster's token: the
    message says how token authentication is set up."""
    c = Cluster()
    try:
        c.start_node("node_a", head=True, cpus=0)
        no_token = {k: v for k, v in c.env.items() if not k.startswith("RAY_AUTH")}
        r = subprocess.run(PCCL + [FISCHER, "--set", "k=0", "--ray", c.address, "--no-progress"],
                           capture_output=True, text=True, env=no_token, timeout=240)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-3000:]
        assert f"--ray {c.address}: cannot start or reach Ray" in r.stderr
        assert "set RAY_AUTH_MODE=token and RAY_AUTH_TOKEN to the head's token" in r.stderr
        t = time.monotonic()
        r = subprocess.run(PCCL + [FISCHER, "--set", "k=0", "--ray", c.address, "--workers", "2",
                                   "--no-progress"], capture_output=True, text=True,
                           env={**c.env, "PCCL_RAY_START_TIMEOUT": "5"}, timeout=240)
        assert r.returncode == 2, r.stderr[-3000:]
        assert "2 of the 2 actors (workers 0, 1) did not start within 5 s" in r.stderr, r.stderr
        assert "the cluster has 0 CPUs" in r.stderr and "Traceback" not in r.stderr
        assert time.monotonic() - t < 120
    finally:
        c.down()


@pytest.mark.parametrize("value", ["abc", "0", "-3", "inf", ""])
def test_a_bad_start_timeout_is_named(value, monkeypatch):
    from pccl.search.parallel_ray import RayUnavailable, _env_seconds
    monkeypatch.setenv("PCCL_RAY_START_TIMEOUT", value)
    with pytest.raises(RayUnavailable, match=f"PCCL_RAY_START_TIMEOUT={value}: expected a number "
                                             f"of seconds above 0"):
        _env_seconds("PCCL_RAY_START_TIMEOUT", 300.0)
    monkeypatch.setenv("PCCL_RAY_START_TIMEOUT", "2.5")
    assert _env_seconds("PCCL_RAY_START_TIMEOUT", 300.0) == 2.5
    monkeypatch.delenv("PCCL_RAY_START_TIMEOUT")
    assert _env_seconds("PCCL_RAY_START_TIMEOUT", 300.0) == 300.0
