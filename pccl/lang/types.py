"""PCCL's types: one representation for the checker, the compiler and the display.

The checker resolves every declared type to a :class:`Ty`
(:class:`~pccl.lang.checker.CheckedProgram` holds them); the compiler coerces
values to them and the display names enum members through them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional


@dataclass(frozen=True)
class Ty:
    """A PCCL type.  ``kind`` is one of int, bool, float, pos, obstacles,
    list (``elem`` set), enum (``enum`` names it, ``members`` lists its
    members in order), array (``elem`` and ``size`` set), any (a value from
    outside the program: fits every type).  Two enum types are equal when
    they have the same name."""
    kind: str
    elem: Optional["Ty"] = None
    enum: Optional[str] = None
    size: Optional[int] = None
    members: Optional[tuple] = field(default=None, compare=False)

    def __str__(self) -> str:
        if self.kind == "list":
            return f"List<{self.elem}>"
        if self.kind == "enum":
            return str(self.enum)
        if self.kind == "array":
            return f"{self.elem}[{self.size}]"
        return _KIND_NAMES.get(self.kind, self.kind)

    @property
    def is_number(self) -> bool:
        return self.kind in ("int", "float")

    @property
    def item(self) -> "Ty":
        """The element type of a list or an array (which always has one)."""
        assert self.elem is not None, self.kind
        return self.elem


_KIND_NAMES = {"pos": "ItemPosition", "obstacles": "ObstacleList"}

INT = Ty("int")
BOOL = Ty("bool")
FLOAT = Ty("float")
POS = Ty("pos")
OBSTACLES = Ty("obstacles")
ANY = Ty("any")


def list_of(elem: Ty) -> Ty:
    return Ty("list", elem=elem)


def array_of(elem: Ty, size: int) -> Ty:
    return Ty("array", elem=elem, size=size)


def enum_ty(name: str, members: Optional[tuple] = None) -> Ty:
    """The enum type ``name`` (equal to every other ``enum_ty(name)``)."""
    return Ty("enum", enum=name, members=None if members is None else tuple(members))


#: The built-in table's type descriptors (pccl/lang/builtins.py) that name one type.
DESCRIPTORS = {"int": INT, "bool": BOOL, "float": FLOAT, "pos": POS,
               "obstacles": OBSTACLES, "any": ANY}

#: Type names of the surface syntax (the parser also accepts the aliases
#: ``boolean`` and ``double``).
TYPE_NAMES = {"int": INT, "bool": BOOL, "boolean": BOOL, "float": FLOAT,
              "double": FLOAT, "ItemPosition": POS, "ObstacleList": OBSTACLES}
BUILTIN_TYPE_NAMES = frozenset(TYPE_NAMES) | {"List"}


def assignable(dst: Ty, src: Ty) -> bool:
    """Does a value of type ``src`` fit a slot of type ``dst``?"""
    if dst.kind == "any" or src.kind == "any":
        return True
    if dst == src:
        return True
    if dst.kind == "float" and src.kind == "int":
        return True
    if dst.kind == "list" and src.kind == "list":
        assert dst.elem is not None and src.elem is not None
        return assignable(dst.elem, src.elem)
    if dst.kind == "obstacles" and src.kind == "list" and src.elem is not None \
            and src.elem.kind == "any":
        return True                       # [] as "no obstacles"
    return False


def compatible(a: Ty, b: Ty) -> bool:
    """May ``a == b`` be asked?"""
    return assignable(a, b) or assignable(b, a)


def join(a: Ty, b: Ty) -> Optional[Ty]:
    """The type of a list literal holding an ``a`` and a ``b``, or None."""
    if a.kind == "any":
        return b
    if b.kind == "any" or a == b:
        return a
    if a.is_number and b.is_number:
        return FLOAT
    if a.kind == "list" and b.kind == "list":
        assert a.elem is not None and b.elem is not None
        e = join(a.elem, b.elem)
        return None if e is None else list_of(e)
    return None


def indexes_agent(section: str, is_array: bool, n_indexes: int, *, in_property: bool) -> bool:
    """The per-agent indexing rule (docs/language.md §4): whether the first
    index of ``x[...]...``, ``x`` a variable of ``section`` indexed
    ``n_indexes`` times, picks an agent.  The checker types and the
    compiler compiles index chains by it.

    A shared (allwrite) variable has no agent index.  In a property every
    per-agent variable (loc or allread) takes the agent index first
    (``v[i]``, ``v[i][k]``).  In the program only an allread variable does:
    a scalar's ``x[j]`` is agent j's component; an array's ``x[k]`` is this
    agent's element k and ``x[j][k]`` agent j's element k."""
    if section == "allwrite":
        return False
    if in_property:
        return True
    return section == "allread" and (not is_array or n_indexes >= 2)

