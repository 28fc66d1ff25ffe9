"""The generated successor function (``Model.plain_successors``: the loop
over agents unrolled, ``counter + ρ(i) ≤ n0`` folded) gives the very
transitions of the generic :meth:`Model.successors`, in the same order, on
every reachable state."""

import os

import pytest

from pccl.api import make_model
from pccl.model.engine import Model

from conftest import reachable

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROOT = os.path.dirname(HERE)

CASES = [
    ("programs/fischer.pccl", dict(overrides={"k": "1", "d": "1"})),
    ("programs/fischer.pccl", dict(agents=3, overrides={"k": "0", "d": "1"}, rates={1: 2},
                                   n0=2)),
    ("programs/race.pccl", dict(world="programs/race.toml", blackbox="nondet")),
    ("programs/race_nonatomic.pccl", dict(world="programs/race.toml", blackbox="nondet",
                                          agents=3)),
    ("programs/formation.pccl", dict(world="programs/formation.toml", blackbox="straight")),
    ("tests/programs/eng_lock.pccl", {}),
    ("tests/programs/eng_assert.pccl", {}),
    ("tests/programs/ref_rand.pccl", {}),
    ("tests/programs/ref_events.pccl", dict(events="first")),
    ("programs/leader.pccl", dict(blackbox="nondet", agents=3)),
]


@pytest.mark.parametrize("program,kw", CASES, ids=[f"{p}-{i}" for i, (p, _) in enumerate(CASES)])
def test_unrolled_successors_equal_the_generic_ones(program, kw):
    path = os.path.join(ROOT, program)
    if not os.path.exists(path):
        pytest.skip(f"{program} not shipped")
    kw = dict(kw)
    if "world" in kw:
        kw["world"] = os.path.join(ROOT, kw["world"])
    m = make_model(path, reduce="none", **kw)
    assert m.plain_successors is not None and m.successors is m.plain_successors
    n = 0
    for st in reachable(m, 20_000):
        assert m.plain_successors(st) == Model.successors(m, st)
        n += 1
    assert n > 10


def test_large_teams_use_the_generic_method():
    m = make_model(os.path.join(ROOT, "programs/fischer.pccl"), agents=Model.UNROLL_AGENTS + 1,
                   reduce="none", overrides={"k": "0"})
    st = next(iter(m.init_states()))
    assert m.plain_successors(st) == Model.successors(m, st)
    assert getattr(m.plain_successors, "__func__", None) is Model.successors
