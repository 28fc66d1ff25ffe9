"""The built-in functions of PCCL (docs/language.md §8), in one table.

The static checker (:mod:`pccl.lang.checker`) reads this table to check calls;
the compiler reads it to know which functions exist and what they return.

Type descriptors (strings, interpreted by the checker):

==============  =============================================================
``int``         an int
``float``       a number: an int widens to float
``bool``        a bool
``pos``         an ``ItemPosition``
``obstacles``   an ``ObstacleList`` (``getObs()``, or the empty list ``[]``)
``list``        any ``List<T>``; the function is polymorphic in ``T``
``list-var``    a ``List<T>`` *variable* (or an indexed element that is one):
                the statement rewrites it in place
``elem``        the element type ``T`` of the first (list) argument
``any``         a value from outside the program (world file): fits any type
==============  =============================================================

``kind`` is ``statement`` (only as a statement: ``doReach(t, o);``),
``expression`` (only inside an expression: it returns a value),
``uninterpreted`` (an expression whose value comes from the world file or a
registered Python function; zero arguments, type ``any``) or ``property``
(``count(v)``, only inside property expressions; its argument is the *name*
of a boolean per-agent variable, not a value).

``in_properties`` says whether a property expression may call the function:
properties are evaluated over the global state, so functions that need an
agent (``getAgentIndex``, ``getPosition``), chance (``rand``) or the outside
world (uninterpreted functions) are program-only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class Builtin:
    name: str
    arities: tuple[int, ...]          # accepted argument counts
    params: tuple[str, ...]           # descriptor of each parameter position
    result: Optional[str]             # descriptor of the result; None for statements
    kind: str                         # statement | expression | uninterpreted | property
    in_properties: bool               # may a property expression call it?
    doc: str

    @property
    def is_statement(self) -> bool:
        return self.kind == "statement"

    @property
    def is_expression(self) -> bool:
        return self.kind in ("expression", "uninterpreted", "property")

    def arity_text(self) -> str:
        """``2``, ``2 or 3``: for messages."""
        return " or ".join(str(a) for a in self.arities)


def _b(name, arities, params, result, kind, in_properties, doc) -> Builtin:
    return Builtin(name, tuple(arities), tuple(params), result, kind,
                   in_properties, doc)


BUILTINS: dict[str, Builtin] = {b.name: b for b in [
    # ---- statements ----------------------------------------------------
    _b("doReach", [2], ["pos", "obstacles"], None, "statement", False,
       "ask the controller to move this agent to the target, avoiding the obstacles"),
    _b("exit", [0], [], None, "statement", False,
       "this agent stops for good"),
    _b("assert", [1], ["bool"], None, "statement", False,
       "a violation when the condition is false"),
    _b("add", [2], ["list-var", "elem"], None, "statement", False,
       "append the value to the list variable"),
    _b("remove", [2], ["list-var", "elem"], None, "statement", False,
       "remove the first occurrence of the value; the agent is stuck if absent"),
    # ---- expression functions -----------------------------------------
    _b("getAgentIndex", [0], [], "int", "expression", False,
       "this agent's id, 0..N-1"),
    _b("getNumAgents", [0], [], "int", "expression", True,
       "the number of agents N"),
    _b("rand", [1], ["int"], "int", "expression", False,
       "an integer in 0..n inclusive (a branch per value in explore)"),
    _b("getPosition", [0], [], "pos", "expression", False,
       "this agent's position"),
    _b("ItemPosition", [2, 3], ["float", "float", "float"], "pos", "expression", True,
       "the position (x, y[, z]); z defaults to 0"),
    _b("dist", [2], ["pos", "pos"], "float", "expression", True,
       "Euclidean distance of two positions"),
    _b("head", [1], ["list"], "elem", "expression", True,
       "the first element of a non-empty list"),
    _b("isEmpty", [1], ["list"], "bool", "expression", True,
       "whether the list is empty"),
    _b("size", [1], ["list"], "int", "expression", True,
       "the number of elements of the list"),
    _b("contains", [2], ["list", "elem"], "bool", "expression", True,
       "whether the value occurs in the list"),
    # ---- uninterpreted: values from the world file ----------------------
    _b("getInput", [0], [], "any", "uninterpreted", False,
       "a value given by the world file (default: the empty list)"),
    _b("getObs", [0], [], "any", "uninterpreted", False,
       "a value given by the world file (default: the empty list)"),
    # ---- properties only ----------------------------------------------
    _b("count", [1], ["bool-var"], "int", "property", True,
       "the number of agents whose boolean local or allread variable holds"),
]}

#: Names of the statement functions, expression functions, uninterpreted ones.
STATEMENTS = frozenset(n for n, b in BUILTINS.items() if b.kind == "statement")
EXPRESSIONS = frozenset(n for n, b in BUILTINS.items() if b.kind == "expression")
UNINTERPRETED = frozenset(n for n, b in BUILTINS.items() if b.kind == "uninterpreted")


def uninterpreted(name: str) -> Builtin:
    """The table entry for an extra uninterpreted function a world file defines."""
    return _b(name, [0], [], "any", "uninterpreted", False,
              "a value given by the world file")


#: Read-only per-agent flags set by the controller: name -> type descriptor.
READONLY_FLAGS: dict[str, str] = {
    "doReach_done": "bool",
    "doReach_fail": "bool",
}
