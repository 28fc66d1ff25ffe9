"""Fuzzing pccl replay with mutated trace files (issue 20: trace files are data).

Real trace files written by ``--trace-out`` (an explore violation, a
liveness lasso, a time-lock lasso, a ``reachable`` witness and a run) are
mutated at random, seeded: keys deleted, values of another type, lists cut
short, steps swapped, numbers made huge, negative or fractional, bytes
corrupted, the text cut off.  Each mutant is replayed in-process through the
CLI (the conftest ``cli()`` helper fails on any exception or traceback) and:

* the exit status is 0, 1 or 2;
* a mutant the JSON Schema (docs/trace-format.schema.json) refuses exits 2:
  the hand-written checks and the schema agree;
* a mutant that parses to the very same document (as JSON, types included)
  replays as the original did;
* a mutant that differs in what replay re-derives (the steps, the initial
  and final states, the lasso's cycle_start, the witness, the violation of
  a run or of a safety counterexample, ...) exits 2: a file whose path or
  verdict was changed must never reproduce -- unless its steps are still a
  real path of the model (two independent steps swapped), which a second,
  plain path check in this file decides.  Fields replay cannot re-derive
  (the free text of a message, a sha256, the version of pccl) may change
  without that.
"""

from __future__ import annotations

import json
import os
import random
from pathlib import Path

import jsonschema
import pytest

from conftest import cli

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
TESTS = ROOT / "tests" / "programs"

SOURCES = {
    "violation": ("explore", ROOT / "docs" / "examples" / "lost_update.pccl", "--reduce", "none"),
    "lasso": ("explore", TESTS / "rdv_meet.pccl", "--world", TESTS / "rdv_wall.toml", "-b",
              "straight", "--property", "eventually forall i: exited[i]"),
    "timelock": ("explore", TESTS / "tl_spin.pccl"),
    "witness": ("explore", PROGRAMS / "fischer.pccl", "--set", "k=0", "--property",
                "reachable count(inCs) == 1"),
    "run": ("run", PROGRAMS / "race.pccl", "--world", PROGRAMS / "race.toml", "-b", "instant",
            "--seed", "3"),
}
#: PCCL_FUZZ_MUTANTS=2000 for a longer search (CI runs the default)
SCHEMA = jsonschema.Draft202012Validator(
    json.loads((ROOT / "docs" / "trace-format.schema.json").read_text()))
MUTANTS_PER_SOURCE = int(os.environ.get("PCCL_FUZZ_MUTANTS", "70"))


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    out = {}
    for name, args in SOURCES.items():
        path = d / f"{name}.json"
        res = cli(*args, "--trace-out", path)
        assert res.exit_code in (0, 1), res.output
        rep = cli("replay", path)
        assert rep.exit_code in (0, 1) and "reproduced" in rep.output, rep.output
        out[name] = (path.read_bytes(), rep.exit_code)
    return out


# -- mutations ------------------------------------------------------------------

def _paths(x, prefix=()):
    """Every path into a parsed document (the document itself is ())."""
    yield prefix
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(x, list):
        for n, v in enumerate(x):
            yield from _paths(v, prefix + (n,))


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def _set(doc, path, value):
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


OTHER_VALUES = [None, True, False, 0, -1, 1.5, "x", "", [], {}, [1, 2], {"a": 1},
                10 ** 40, -10 ** 40, 1e308, -0.0]


def mutate(rng: random.Random, data: bytes) -> bytes:
    op = rng.choice(["delete", "retype", "retype", "truncate", "swap", "number", "number",
                     "bytes", "cut"])
    if op == "bytes":
        b = bytearray(data)
        for _ in range(rng.randint(1, 3)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b)
    if op == "cut":
        return data[:rng.randrange(len(data))]
    doc = json.loads(data)
    paths = list(_paths(doc))
    # half the time a path into the steps, where replay does most of its work
    in_steps = [p for p in paths if p[:1] == ("steps",)]
    pick = lambda ps: ps[rng.randrange(len(ps))]  # noqa: E731
    path = pick(in_steps if in_steps and rng.random() < 0.5 else paths)
    if op == "delete":
        dicts = [p for p in paths if p and isinstance(_get(doc, p[:-1]), dict)]
        path = pick(dicts)
        del _get(doc, path[:-1])[path[-1]]
    elif op == "retype":
        doc = _set(doc, path, rng.choice(OTHER_VALUES))
    elif op == "truncate":
        lists = [p for p in paths if isinstance(_get(doc, p), list) and _get(doc, p)]
        if lists:
            p = pick(lists)
            lst = _get(doc, p)
            del lst[rng.randrange(len(lst)):]
    elif op == "swap":
        steps = doc.get("steps") or []
        if len(steps) >= 2:
            i, j = rng.sample(range(len(steps)), 2)
            steps[i], steps[j] = steps[j], steps[i]
            if rng.random() < 0.5:              # renumbered, so that the indexes look right
                for n, st in enumerate(steps):
                    st["index"] = n + 1
    elif op == "number":
        nums = [p for p in paths if isinstance(_get(doc, p), (int, float))
                and not isinstance(_get(doc, p), bool)]
        if nums:
            p = pick(nums)
            v = _get(doc, p)
            doc = _set(doc, p, rng.choice([10 ** 50, -v - 1, v + 0.5, v + 1, float(v), 1e308]))
    return json.dumps(doc, indent=rng.choice([None, 1])).encode()


# -- the oracle --------------------------------------------------------------------

def _diff(a, b, prefix=()):
    """The paths where two parsed documents differ (as JSON, types included)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in set(a) | set(b):
            if k not in a or k not in b:
                out.append(prefix + (k,))
            else:
                out.extend(_diff(a[k], b[k], prefix + (k,)))
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [p for x, y, n in zip(a, b, range(len(a))) for p in _diff(x, y, prefix + (n,))]
    return [] if json.dumps(a) == json.dumps(b) else [prefix]


def _dropped_leg_start(doc, path: tuple) -> bool:
    """Whether ``path`` names an agent's ``legStart`` that ``doc`` does not
    have (optional: older files have none)."""
    if not path or path[-1] != "legStart":
        return False
    node = doc
    for k in path[:-1]:
        try:
            node = node[k]
        except (KeyError, IndexError, TypeError):
            return False
    return isinstance(node, dict) and "legStart" not in node


def _j(x) -> str:
    return json.dumps(x, sort_keys=True, default=str)


def is_real_path(doc: dict) -> bool:
    """Whether the steps of ``doc`` are a path of its model from its initial
    state to its final state: a second, plain implementation (every step's
    whole record compared at once) for the rare mutant that replay accepts
    though its steps changed (two independent steps swapped, say)."""
    from pccl.output import traces as T
    from pccl.api import make_model
    c = doc["config"]
    m = make_model(c["program"]["path"], world=(c["world"] or {}).get("path"),
                   blackbox=c["blackbox"], agents=c["agents"], delta=c["delta"], n0=c["n0"],
                   rates={i: r for i, r in enumerate(c["rates"]) if r != 1},
                   events=c["events"], collisions=c["collisions"],
                   overrides=c["overrides"], invariants=tuple(c["invariants"]),
                   properties=tuple(c.get("property_options", ())), max_time=c["max_time"],
                   abstract_time=c["abstract_time"], reduce="none")
    def typed(st, like=None):
        """The state as the trace writes it; a leg start (``legStart``, optional:
        files written before it existed replay without it) only where ``like``
        (the file's record) has one."""
        d = T.normal(T.state_typed(m, st))
        if like is not None:
            for a, b in zip(d.get("agents", ()), like.get("agents", ())):
                if isinstance(a, dict) and isinstance(b, dict) and "legStart" not in b:
                    a.pop("legStart", None)
        return _j(d)
    state = next((s for s in m.init_states() if typed(s, doc["initial"]) == _j(doc["initial"])), None)
    if state is None:
        return False
    for rec in doc["steps"]:
        nxt = [b for lab, b in m.successors(state)
               if _j(T.normal(T.step_record(m, rec["index"], lab, state, b))) == _j(rec)]
        if not nxt:
            return False
        state = nxt[0]
    return typed(state, doc["final"]) == _j(doc["final"])


def rederived(path: tuple, source: str, doc: dict) -> bool:
    """Whether replay re-derives (so must refuse a change of) what ``path`` names."""
    if len(path) == 0 or path[0] in ("steps", "initial", "final", "format", "version"):
        return True
    if path in (("config",), ("result",), ("config", "command"), ("config", "agents"),
                ("result", "cycle_start"), ("result", "violation"),
                ("result", "violation", "kind"), ("result", "violation", "name")):
        return True
    if path[:2] == ("result", "witness"):
        return True
    if path[0] == "result" and source == "run":
        return True                 # the runner re-derives status, message, violation
    if path[:2] == ("result", "violation") and source == "violation":
        return True                 # a safety violation's whole record
    return False


@pytest.mark.slow          # ~6 s of CPU, up to ~25 s on a loaded machine; CI runs it
def test_mutated_trace_files_exit_0_1_or_2_and_never_reproduce_a_changed_path(
        sources, tmp_path):
    checked = refused = others = 0
    for name, (data, original_exit) in sources.items():
        original = json.loads(data)
        rng = random.Random(f"replay-fuzz-{name}")
        for k in range(MUTANTS_PER_SOURCE):
            mutant = mutate(rng, data)
            path = tmp_path / f"{name}-{k}.json"
            path.write_bytes(mutant)
            res = cli("replay", path)
            assert res.exit_code in (0, 1, 2), (name, k, res.output)
            try:
                doc = json.loads(mutant)
            except ValueError:
                doc = None
            where = f"{name} mutant {k}: {res.output[-300:]}"
            if doc is None:
                assert res.exit_code == 2, where
            elif not SCHEMA.is_valid(doc):
                # the hand-written checks of pccl/output/tracecheck.py and the schema
                # agree: a file the schema refuses is refused
                assert res.exit_code == 2, where
                assert "reproduced:" not in res.output, where
            else:
                # a leg start dropped is a file of before leg starts: the same path
                changed = [p for p in _diff(original, doc) if not _dropped_leg_start(doc, p)]
                if not changed:
                    assert res.exit_code == original_exit, where
                elif any(rederived(p, name, original) for p in changed):
                    if res.exit_code != 2:
                        # only another real path (same config and verdict) may reproduce
                        assert not [p for p in changed if p[:1] not in (("steps",), ("final",))]
                        assert is_real_path(doc), (changed[:3], where)
                        assert res.exit_code == original_exit, where
                        others += 1
                    else:
                        assert "reproduced:" not in res.output, where
            refused += res.exit_code == 2
            checked += 1
    assert checked == MUTANTS_PER_SOURCE * len(SOURCES)
    print(f"{checked} mutants, {refused} refused, {others} other real paths reproduced")
    assert refused > checked // 2            # most mutants are refused, with a message
