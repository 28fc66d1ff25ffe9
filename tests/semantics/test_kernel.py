"""The rule kernel's interface (semantics/rules.py): what a rule may read from
the model (RuleContext), the decoded k-cell heads (KHead) and the STATEMENT
rule split per kind of statement."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from conftest import FISCHER, PROGRAMS, model_of
from pccl.api import load_program, make_model
from pccl.model.layout import AGS, PC
from pccl.lang.world import load_world
from pccl.semantics import rules as R

ROOT = Path(__file__).resolve().parents[2]


def _protocol_members(proto) -> set:
    names = set(getattr(proto, "__annotations__", {}))
    names |= {n for n, v in vars(proto).items() if callable(v) and not n.startswith("_")}
    return names


def test_rules_read_only_what_rule_context_lists():
    """Every ``m.X`` (and ``m.ctl.Y``) in the rule kernel is a member of the
    protocol, and every member of the protocol is read by some rule."""
    src = (ROOT / "semantics" / "rules.py").read_text()
    code = "\n".join(line.split("#", 1)[0] for line in src.splitlines())
    read = set(re.findall(r"(?<![\w.])m\.(\w+)", code))
    read_ctl = set(re.findall(r"(?<![\w.])m\.ctl\.(\w+)", code))
    context = _protocol_members(R.RuleContext)
    cells = _protocol_members(R.KCells)
    assert read <= context, f"rules read {sorted(read - context)} outside RuleContext"
    assert read_ctl <= cells, f"rules read ctl.{sorted(read_ctl - cells)} outside KCells"
    assert context <= read, f"RuleContext lists {sorted(context - read)}, which no rule reads"
    assert cells <= read_ctl


def test_the_model_offers_the_rule_context():
    m = make_model(load_program(FISCHER), agents=2)
    for name in _protocol_members(R.RuleContext):
        assert hasattr(m, name), name
    for name in _protocol_members(R.KCells):
        assert hasattr(m.ctl, name), name


#: KHead fields each kind sets (the rest stay None), as KHead's docstring lists them.
FIELDS = {
    R.K_EMPTY: set(), R.K_END: set(), R.K_AEND: {"next_pc"}, R.K_ACQ: {"body_pc", "sid"},
    R.K_SIMPLE: {"fn", "next_pc", "sid"}, R.K_IF: {"fn", "branch_pcs", "sid"},
    R.K_WHILE: {"fn", "body_pc", "next_pc", "sid"}, R.K_ASSERT: {"fn", "next_pc", "sid"},
    R.K_ATOMIC: {"request_pc", "body_pc", "sid"}, R.K_DOREACH: {"fn", "next_pc", "sid"},
    R.K_EXIT: {"sid"},
}

EVERY_KIND = """
allwrite:
  int s = 0;

loc:
  int x = 0;
  List<int> l = [];

Go():
  pre(x < 3);
  eff:
    x = x + 1;
    if (x == 1):
      add(l, x);
    else:
      skip;
    while (x < 2):
      x = x + 1;
    assert(x > 0);
    atomic:
      s = s + 1;
      atomic:
        s = s + 1;
    doReach(ItemPosition(1.0, 1.0, 0.0), getObs());
    if (x == 3):
      exit();
"""


@pytest.fixture(scope="module")
def every_kind():
    m = model_of(EVERY_KIND, agents=2)
    m.prepare()                    # intern (and decode) every reachable k cell
    return m


def test_each_head_kind_sets_its_own_fields(every_kind):
    m = every_kind
    kinds = set()
    for pc in range(len(m.ctl.cells)):
        head = m.ctl.info(pc)
        kinds.add(head.kind)
        have = {f for f in ("fn", "next_pc", "body_pc", "branch_pcs", "request_pc", "sid")
                if getattr(head, f) is not None}
        assert have == FIELDS[head.kind], (pc, head)
        assert head.rules == R.AGENT_RULES[head.kind]
        assert head.rules_spent == R.AGENT_RULES_SPENT[head.kind]
        assert m.ctl.info(pc) is head               # built once per pc
    assert kinds == set(FIELDS), "the program should reach every kind of head"


def test_statement_is_one_rule_per_kind():
    """STATEMENT's kinds each have their own function, each dispatched from
    the head kind; the dispatcher `statement` reaches the same function."""
    assert set(R.STATEMENT_RULES) == {R.K_SIMPLE, R.K_IF, R.K_WHILE, R.K_ASSERT, R.K_ATOMIC}
    fns = list(R.STATEMENT_RULES.values())
    assert len(set(fns)) == len(fns)
    for kind, fn in R.STATEMENT_RULES.items():
        assert fn in R.AGENT_RULES[kind]
        assert fn.__doc__.startswith("STATEMENT (")


def test_statement_dispatcher_agrees_with_the_per_kind_rules(every_kind):
    """On every state of a small search, `statement` (any head) gives what the
    per-kind rule gives; labels stay ``STATEMENT``."""
    m = every_kind
    frontier, seen, checked = list(m.init_states()), set(), 0
    while frontier and len(seen) < 400:
        st = frontier.pop()
        if st in seen:
            continue
        seen.add(st)
        for i, ag in enumerate(st[AGS]):
            head = m.ctl.info(ag[PC])
            if head.kind in R.STATEMENT_RULES:
                a, b = [], []
                R.STATEMENT_RULES[head.kind](m, st, i, ag, head, a)
                R.statement(m, st, i, ag, head, b)
                assert a == b
                assert all(lab[0] == "STATEMENT" for lab, _ in a)
                checked += 1
        frontier.extend(s for _, s in m.successors(st))
    assert checked > 20


def test_shipped_programs_decode():
    """Every k cell of every shipped program decodes to a head with its rules."""
    for prog in sorted(PROGRAMS.glob("*.pccl")):
        world = prog.with_suffix(".toml")
        if not world.exists():
            world = PROGRAMS / (prog.stem.split("_")[0] + ".toml")
        m = make_model(load_program(str(prog)), agents=2,
                       world=load_world(str(world)) if world.exists() else None)
        m.prepare()
        for pc in range(len(m.ctl.cells)):
            head = m.ctl.info(pc)
            assert head.rules and repr(head).startswith("KHead(K_")


def test_every_rule_says_which_cells_it_changes():
    """As K's rules mention only the cells they rewrite, every rule's docstring
    names its rule and the cells it changes."""
    rules = {r for rs in R.AGENT_RULES.values() for r in rs} | {R.time_advance, R.doreach_invoke}
    for rule in rules:
        doc = rule.__doc__ or ""
        assert re.match(r"[A-Z][A-Z ]+[ .(]", doc), rule.__name__
        assert re.search(r"^\s*Changes ", doc, re.M), rule.__name__
