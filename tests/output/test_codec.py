"""pccl/output/codec.py: one encoder of states and steps, and its decoder.

Two ways to the same configuration: the search's own state, and the state
decoded from its JSON (through a real JSON text); they must be equal, cell
for cell and type for type, on every state the searches below reach.  Steps
likewise: the state before with a step's decoded changes applied is the
state after.  Older trace files (version 1, tests/fixtures/traces_v1/,
written by pccl before the codec) still replay.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from conftest import cli
from pccl.output import codec as C
from pccl.api import make_model
from pccl.model.layout import AGS, PC, REACH, STATUS, T0
from pccl.tools.replay import replay as api_replay

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "programs"
TESTS = ROOT / "tests" / "programs"
V1 = ROOT / "tests" / "fixtures" / "traces_v1"

#: shipped and test programs whose searches cover every kind of cell: shared
#: and per-agent variables of every type, enums, lists, positions, locks and
#: atomic blocks, stuck agents, doReach under nondet (t0, obstacles, flags),
#: Init blocks
MODELS = {
    "lost_update": (ROOT / "docs" / "examples" / "lost_update.pccl", {}),
    "fischer": (PROGRAMS / "fischer.pccl", {"overrides": {"k": "1"}}),
    "race_nonatomic": (PROGRAMS / "race_nonatomic.pccl",
                       {"world": PROGRAMS / "race.toml", "blackbox": "nondet"}),
    "ref_doreach": (TESTS / "ref_doreach.pccl", {"blackbox": "nondet"}),
    "ref_doreach_timed": (TESTS / "ref_doreach.pccl", {"blackbox": "straight",
                                                       "abstract_time": False}),
    "ref_atomic": (TESTS / "ref_atomic.pccl", {}),
    "ref_values": (TESTS / "ref_values.pccl", {}),
    "ref_list": (TESTS / "ref_list.pccl", {}),
    "ref_undef": (TESTS / "ref_undef.pccl", {}),
    "collide": (PROGRAMS / "collide.pccl", {"world": PROGRAMS / "collide.toml",
                                            "blackbox": "straight"}),
}
LIMIT = 1500

_models: dict = {}


def model(name):
    if name not in _models:
        prog, opts = MODELS[name]
        _models[name] = make_model(str(prog), reduce="none", **opts)
    return _models[name]


def reachable(m, limit=LIMIT):
    """Up to ``limit`` states and the transitions between them, breadth first."""
    seen, states, steps = set(), [], []
    todo = list(m.init_states())
    for s in todo:
        seen.add(m.key(s))
    states.extend(todo)
    k = 0
    while k < len(states) and len(states) < limit:
        s = states[k]
        k += 1
        for lab, nxt in m.successors(s):
            steps.append((lab, s, nxt))
            key = m.key(nxt)
            if key not in seen:
                seen.add(key)
                states.append(nxt)
    return states, steps


def through_json(x):
    return json.loads(json.dumps(x))


def same(a, b) -> bool:
    """Equal with the same types at every depth (1 is not 1.0 nor True)."""
    if isinstance(a, tuple):
        return isinstance(b, tuple) and len(a) == len(b) and all(map(same, a, b))
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("name", sorted(MODELS))
def test_every_state_decodes_to_itself(name):
    m = model(name)
    states, steps = reachable(m)
    assert len(states) > 3
    for st in states:
        back = C.decode_state(m, through_json(C.encode_state(m, st)))
        assert same(back, st), (name, st, back)
        assert C.is_complete(back) and C.matches(back, st)
    for lab, a, b in steps:
        back = C.apply_changes(m, a, through_json(C.encode_changes(m, a, b)))
        assert same(back, b), (name, lab)


def test_the_searches_cover_the_cells_the_codec_adds():
    # k items of every kind, stuck codes, t0 and obstacles set by doReach
    seen = set()
    for name in MODELS:
        m = model(name)
        for st in reachable(m)[0]:
            for ag in st[AGS]:
                for item in C.encode_k(m, ag[PC]):
                    seen.add(type(item).__name__ if not isinstance(item, str) else item)
                if C.encode_status(m, ag[STATUS]).get("code"):
                    seen.add("stuck")
                if ag[REACH][T0] is not None:
                    seen.add("t0")
    assert {"int", "end", "atomicEnd", "dict", "stuck", "t0"} <= seen, seen


@settings(max_examples=40, deadline=None)
@given(name=hs.sampled_from(sorted(MODELS)), seed=hs.integers(0, 2**32 - 1),
       length=hs.integers(1, 60))
def test_random_walks_decode_step_by_step(name, seed, length):
    # a random path: each state rebuilt from the previous decoded one and the
    # step's changes, never from the search's own state
    import random
    m = model(name)
    rng = random.Random(seed)
    st = rng.choice(list(m.init_states()))
    rebuilt = C.decode_state(m, through_json(C.encode_state(m, st)))
    for _ in range(length):
        succ = m.successors(st)
        if not succ:
            break
        lab, nxt = rng.choice(succ)
        rec = through_json(C.encode_step(m, 1, lab, st, nxt))
        rebuilt = C.apply_changes(m, rebuilt, rec["changes"])
        st = nxt
        assert same(rebuilt, st), (name, lab)


def test_decoding_is_strict_and_names_the_field():
    m = model("lost_update")
    st = next(iter(m.init_states()))
    j = through_json(C.encode_state(m, st))
    bad = json.loads(json.dumps(j))
    bad["shared"]["total"] = float(bad["shared"]["total"])
    with pytest.raises(C.DecodeError, match=r"state\.shared\.total: expected an int, got the "
                                            r"number 0\.0"):
        C.decode_state(m, bad)
    bad = json.loads(json.dumps(j))
    bad["agents"][1]["k"] = [999]
    with pytest.raises(C.DecodeError, match=r"state\.agents\[1\]\.k\[0\]: expected a statement"):
        C.decode_state(m, bad)
    bad = json.loads(json.dumps(j))
    bad["agents"][0]["lockState"] = "held"
    with pytest.raises(C.DecodeError, match=r"agents\[0\]\.lockState: expected idle, request or"):
        C.decode_state(m, bad)
    # an edited program's statement ids: lenient decoding leaves k open
    bad = json.loads(json.dumps(j))
    bad["agents"][0]["k"] = [999]
    assert C.decode_state(m, bad, lenient=True)[AGS][0][PC] is C.ANY


# ---------------------------------------------------------------------------
# replay compares decoded states
# ---------------------------------------------------------------------------

LOST = ROOT / "docs" / "examples" / "lost_update.pccl"


@pytest.fixture(scope="module")
def lost_v2(tmp_path_factory):
    out = tmp_path_factory.mktemp("v2") / "lost.json"
    assert cli("explore", LOST, "--reduce", "none", "--trace-out", out).exit_code == 1
    return out


def test_replay_compares_the_pending_computation(lost_v2, tmp_path):
    # version 1 had no k: a step that leaves an agent elsewhere in its
    # program than recorded was accepted if the variables agreed
    d = json.loads(lost_v2.read_text())
    assert d["version"] == C.VERSION == 2
    n, ch = next((n, ch) for n, s in enumerate(d["steps"]) for ch in s["changes"]
                 if ch["cell"].get("cell") == "k" and len(ch["new"]) >= 2)
    ch["new"] = ch["new"][1:]            # a real k of the program, one statement further
    bad = tmp_path / "k.json"
    bad.write_text(json.dumps(d))
    r = api_replay(bad)
    assert (r.status, r.exit_status, r.diverged_at) == ("diverged", 2, n + 1), r.message
    assert "the transition is enabled but its changes differ" in r.message
    assert "k[" in r.message           # the only difference is k: it is shown


def test_an_edited_program_still_names_the_step_whose_line_moved(tmp_path):
    # statement ids move when a statement is inserted: k is not compared
    # then, and the divergence is the first step whose statement differs
    prog = tmp_path / "lost.pccl"
    shutil.copy(LOST, prog)
    t = tmp_path / "t.json"
    assert cli("explore", prog, "--reduce", "none", "--trace-out", t).exit_code == 1
    prog.write_text(prog.read_text().replace("    mine = total;", "    skip;\n    mine = total;"))
    r = api_replay(t)
    assert r.diverged_at == 2 and "line 15 now reads 'skip;'" in r.message, r.message


V1_EXPECTED = {
    "lost_update_explore.json": (1, "reproduced: invariant 'noLostUpdate' violated"),
    "lost_update_explore_output.json": (1, "reproduced: invariant 'noLostUpdate' violated"),
    "race_run_clean.json": (0, "reproduced: final"),
    "race_nonatomic_run_stuck.json": (1, "reproduced: agent 1 stuck"),
    "fischer_witness.json": (0, "reproduced: witness"),
    "rdv_lasso.json": (1, "a lasso: the cycle from step 8 closes"),
    "ref_doreach_nondet.json": (1, "reproduced: invariant 'legs[0] + legs[1] < 3' violated"),
}


@pytest.mark.parametrize("name", sorted(V1_EXPECTED))
def test_version_1_files_still_replay(name):
    path = V1 / name
    doc = json.loads(path.read_text())
    assert (doc.get("trace") or doc)["version"] == 1
    code, message = V1_EXPECTED[name]
    r = api_replay(path)
    assert r.exit_status == code and message in r.message, r.message
    assert r.steps_total == len(r.labels)


def test_a_tampered_version_1_file_still_diverges(tmp_path):
    d = json.loads((V1 / "lost_update_explore.json").read_text())
    d["steps"][4]["changes"][0]["new"] = 7
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    r = api_replay(bad)
    assert r.exit_status == 2 and r.diverged_at == 5, r.message


def test_version_1_states_decode_with_the_cells_it_lacks_open():
    d = json.loads((V1 / "ref_doreach_nondet.json").read_text())
    r = api_replay(V1 / "ref_doreach_nondet.json")
    got = C.decode_state(r.model, d["final"])
    assert not C.is_complete(got) and C.matches(got, r.states[-1])
    assert got[AGS][0][PC] is C.ANY and got[AGS][0][REACH][T0] is C.ANY


@pytest.mark.parametrize("cell, new", [
    ({"agent": 0, "cell": "lockState"}, [1]), ({"cell": "phase"}, {"x": 1}),
    ({"agent": 0, "cell": "k"}, "end"), ({"agent": 0, "cell": "status"}, {"status": "stuck"}),
    ({"agent": 0, "var": "mine"}, [0]), ({"var": "nosuch"}, 1), ({"agent": 7, "cell": "k"}, []),
    ({"cell": "env"}, {"a": 1}), ({"agent": 0, "cell": "position"}, [1, 2, 3]),
])
def test_a_change_of_the_wrong_shape_is_a_decode_error(cell, new):
    # every value a file can hold decodes or is one DecodeError naming the
    # field: never another exception
    m = model("lost_update")
    st = next(iter(m.init_states()))
    with pytest.raises(C.DecodeError) as e:
        C.apply_changes(m, st, [{"cell": cell, "old": None, "new": new}], "ch")
    assert e.value.message.startswith("ch[0]"), e.value.message


def test_a_recorded_old_value_is_checked(lost_v2, tmp_path):
    # a step's changes say what each cell was before, too: a file whose old
    # values were rewritten does not reproduce (the fuzz test's mutant)
    d = json.loads(lost_v2.read_text())
    n, k = next((n, k) for n, s in enumerate(d["steps"]) for k, ch in enumerate(s["changes"])
                if ch["cell"] == {"var": "total"})
    d["steps"][n]["changes"][k]["old"] = 99
    bad = tmp_path / "old.json"
    bad.write_text(json.dumps(d))
    r = api_replay(bad)
    assert (r.status, r.diverged_at) == ("diverged", n + 1), r.message
    assert "recorded total 99 ->" in r.message


def test_the_browser_explorer_loads_version_1_and_2_files(lost_v2):
    # pccl serve follows a trace's steps by decoding its states, as replay
    # does (it compared the JSON of every candidate with the file's before,
    # which no version-1 file matches once the encoding grew)
    from pccl.tools import serve as S
    from pccl.output import traces as T
    for path in (V1 / "lost_update_explore.json", lost_v2):
        doc = json.loads(path.read_text())
        m = make_model(str(LOST), reduce="none")
        s = S.Session(m, T.config("explore", m, program=str(LOST)))
        s.load(path.read_text())
        assert len(s.labels) == len(doc["steps"]), path
        assert C.encode_state(m, s.states[-1])["shared"] == doc["final"]["shared"]
