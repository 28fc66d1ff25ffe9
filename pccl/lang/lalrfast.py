"""A faster way to run a lark LALR parser whose trees a transformer turns
into something else at once (issue 42: checking a 60,000-line program).

lark builds a parse tree (a ``Tree`` per rule, a ``Token`` per terminal,
positions propagated from child to parent by its ``PropagatePositions``
callback) and the transformer then walks that tree.  :class:`FastLALR` runs
the *same* LALR tables, lexer regular expression and tree-shaping plan (which
children a rule keeps, which ``_rule`` it splices, which ``?rule`` it
inlines), read from the built :class:`lark.Lark` object, but calls the
transformer's methods as each rule is reduced, with the positions lark would
have given the tree, and without building the tree:

* tokens are tuples until a rule keeps one (then a real ``Token``);
* a ``?rule`` that inlines its only child costs a table look-up;
* ``meta`` is a small object with lark's fields (``line``, ``column``,
  ``end_line``, ``end_column``, ``empty``), computed as lark's
  ``PropagatePositions`` does (a node starts at its first child's container
  and ends at its last child's: a parenthesised expression's container
  includes its parentheses).

At a syntax error it stops where lark's parser would and raises what lark
would need to report it: :class:`LexFailure` (lark's lexer raises
``UnexpectedCharacters`` there) or :class:`SyntaxFailure`, from which
:meth:`FastLALR.unexpected_token` makes lark's ``UnexpectedToken`` (the
same state stack, the same tokens on the value stack, a tree for each
rule's value), so that the caller reports it as before.  Anything else it
does not handle (an error of the transformer, any surprise) raises
:class:`Fallback`: the caller parses the text again the ordinary way.  A
grammar or a lark whose shape it does not recognise (another callback
chain, several lexer expressions, a lexer callback that is not a keyword
test) turns it off (:attr:`FastLALR.usable` false).  The tests compare its
results, spans and errors included, with the ordinary path's on the
repository's programs and on 1,200 mutated ones
(tests/lang/test_parser_fast.py).
"""
from __future__ import annotations

import functools
from typing import Any, Optional
from collections.abc import Callable, Iterable, Iterator

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedToken

__all__ = ["FastLALR", "Fallback", "LexFailure", "LexTuple", "SyntaxFailure"]

#: (type, value, line, column, end_line, end_column, start_pos, end_pos): a
#: token before any rule keeps it; the box of its position is the tuple itself
#: (a box: fields 2-5 the line, column, end line and end column, as lark's
#: ``PropagatePositions`` takes them from a token or a node's container; a
#: node's box is ``(None, None, ...)``, or its only child's box)
LexTuple = tuple


class Fallback(Exception):
    """Not for the fast path: parse the text the ordinary way."""


class LexFailure(Fallback):
    """No terminal matches at ``pos`` (line ``line``, column ``column``):
    where lark's lexer raises ``UnexpectedCharacters``."""

    def __init__(self, pos: int, line: int, column: int):
        super().__init__("unexpected character")
        self.pos, self.line, self.column = pos, line, column


class SyntaxFailure(Fallback):
    """The table has no action for ``token`` (a :data:`LexTuple`, or None:
    the end of the input after ``last``): where lark's parser raises
    ``UnexpectedToken``, with the stacks it would have
    (:meth:`FastLALR.unexpected_token` makes lark's exception)."""

    def __init__(self, fast: FastLALR, token: Optional[LexTuple], last: Optional[LexTuple],
                 start: str, state_stack: list, values: list, boxes: list):
        super().__init__("unexpected token")
        self.fast, self.token, self.last, self.start = fast, token, last, start
        self.state_stack, self.values, self.boxes = state_stack, values, boxes

    def unexpected_token(self) -> UnexpectedToken:
        """lark's exception here (:meth:`FastLALR.unexpected_token`)."""
        return self.fast.unexpected_token(self)


class _Meta:
    """The fields of ``lark.tree.Meta`` a builder reads."""

    __slots__ = ("empty", "line", "column", "end_line", "end_column")

    def __init__(self, box):
        if box is None:
            self.empty = True
        else:
            self.empty = False
            self.line = box[2]
            self.column = box[3]
            self.end_line = box[4]
            self.end_column = box[5]


# reduction kinds
_PASS = 0        # a ?rule with one child, kept: the child goes up as it is
_BUILD = 1       # anything else


class _Plan:
    __slots__ = ("kind", "size", "origin", "include", "expand1", "splice_only", "method", "name",
                 "take", "ends_fixed")

    def __init__(self, kind, size, origin, include, expand1, splice_only, method, name,
                 ends_fixed):
        self.kind = kind
        self.size = size
        self.origin = origin
        self.include = include          # ((index, splice, is_terminal), ...)
        self.expand1 = expand1
        self.splice_only = splice_only  # a _rule: its value is its children (a list)
        self.method = method            # transformer method(meta, children)
        self.name = name
        self.ends_fixed = ends_fixed    # the first and last symbols never derive nothing
        # the children: None all raw ones; (i, ...) those; () splices too (see include)
        if any(splice for _, splice, _ in include):
            self.take: Optional[tuple] = ()
        elif [i for i, _, _ in include] == list(range(size)):
            self.take = None
        else:
            self.take = tuple(i for i, _, _ in include)


class FastLALR:
    """The fast path for ``lark`` (LALR, basic lexer) and ``transformer``
    (whose rule methods take ``(meta, children)``, as ``v_args(meta=True)``
    ones do)."""

    def __init__(self, lark: Lark, transformer: Any, callbacks: dict):
        self.usable = False
        self.lark = lark        # whose tables these are (state numbers are its own)
        try:
            if lark.options.parser != "lalr" or lark.options.lexer != "basic":
                raise Fallback()
            try:
                lexer = lark.parser.lexer.lexer            # PostLexConnector -> BasicLexer
                table = lark.parser.parser.parser.parse_table
            except AttributeError:
                raise Fallback() from None
            self._read_lexer(lexer)
            self._read_rules(transformer, callbacks)
            self._read_table(table)
            self.usable = True
        except Fallback:
            pass

    # ---- reading lark's plan ------------------------------------------------

    def _read_lexer(self, lexer: Any) -> None:
        from lark.lexer import UnlessCallback
        scanner = lexer.scanner
        if len(scanner._mres) != 1:
            raise Fallback()
        self.regex = scanner._mres[0]
        if any(type(cb) is not UnlessCallback for cb in lexer.callback.values()):
            raise Fallback()
        self.keyword_tests = dict(lexer.callback)
        self.newline_types = frozenset(lexer.newline_types)
        self.ignore_types = frozenset(lexer.ignore_types)
        if any(typ in self.ignore_types for typ in self.keyword_tests):
            raise Fallback()

    def _read_rules(self, transformer: Any, callbacks: dict) -> None:
        nullable = _nullable(callbacks)
        self.plans: list[_Plan] = []
        self.rule_index: dict = {}
        kept_terminals: set[str] = set()
        for rule, cb in callbacks.items():
            plan = _plan_of(rule, cb, transformer, nullable)
            kept_terminals.update(rule.expansion[i].name for i, _, is_term in plan.include
                                  if is_term)
            self.rule_index[rule] = len(self.plans)
            self.plans.append(plan)
        self.kept_terminals = frozenset(kept_terminals)

    def _read_table(self, table: Any) -> None:
        """state -> {symbol: next state (shift or goto) | ~plan (reduce)}"""
        from lark.parsers.lalr_analysis import Shift
        states: dict = {}
        for state, actions in table.states.items():
            row = {}
            for sym, (action, arg) in actions.items():
                if action is Shift:
                    row[sym] = arg
                elif arg in self.rule_index:
                    row[sym] = ~self.rule_index[arg]
                else:
                    raise Fallback()
            states[state] = row
        self.states = states
        self.passes: dict = {}      # (below, top, lookahead) -> top: _pass_run's
        self.start_states = dict(table.start_states)
        self.end_states = dict(table.end_states)

    # ---- the lexer -----------------------------------------------------------

    def _special(self, hooks: dict) -> dict[str, int]:
        """What a token type needs besides a tuple: 1 newlines counted, 2
        ignored, 4 a keyword test, 8 a hook (a plain type: none of these)."""
        special: dict[str, int] = {}
        for flag, types in ((1, self.newline_types), (2, self.ignore_types),
                            (4, self.keyword_tests), (8, hooks)):
            for typ in types:
                special[typ] = special.get(typ, 0) | flag
        return special

    def lex(self, text: str, hooks: Optional[dict] = None,
            every: Optional[Callable[[], None]] = None) -> Iterator[LexTuple]:
        """lark's basic lexer, as tuples (:data:`LexTuple`).  ``hooks``:
        token type -> a function of the token that returns the tokens to
        give instead (a post-lexer such as an indenter, without a generator
        around the lexer's); ``every``: called every 4,096 tokens."""
        keyword_tests = self.keyword_tests
        hooks = hooks or {}
        special = self._special(hooks)
        keywords: dict = {}
        pos, line, line_start, count = 0, 1, 0, 0
        # finditer skips what no terminal matches: a gap is lark's error
        for m in self.regex.finditer(text):
            start, end = m.span()
            if start != pos:
                raise LexFailure(pos, line, pos - line_start + 1)
            if end == pos:
                raise Fallback()
            typ = m.lastgroup
            sp = special.get(typ)
            if sp is None:
                yield (typ, m.group(0), line, pos - line_start + 1, line, end - line_start + 1,
                       pos, end)
            else:
                value = m.group(0)
                column = pos - line_start + 1
                end_line = line
                if sp & 1:
                    k = value.count("\n")
                    if k:
                        end_line = line + k
                        line_start = pos + value.rindex("\n") + 1
                if not sp & 2:
                    if sp & 4:
                        seen = keywords.get(typ)
                        if seen is None:
                            seen = keywords[typ] = {}
                        t = seen.get(value)
                        if t is None:   # UnlessCallback's test, without its token
                            t = seen[value] = keyword_tests[typ].scanner.fullmatch(value) or typ
                        typ = t
                    tok = (typ, value, line, column, end_line, end - line_start + 1, pos, end)
                    if typ in hooks:
                        yield from hooks[typ](tok)
                    else:
                        yield tok
                line = end_line
            pos = end
            count += 1
            if every is not None and not count & 4095:
                every()
        if pos != len(text):
            raise LexFailure(pos, line, pos - line_start + 1)

    # ---- the parser ----------------------------------------------------------

    def _pass_run(self, below: int, top: int, typ: str) -> int:
        """The top state after the ?rules that inline their only child
        (:data:`_PASS`) reduced in state ``top`` (``below`` under it) with
        the lookahead ``typ``, one after the other."""
        states, plans = self.states, self.plans
        act = states[top].get(typ)
        while act is not None and act < 0 and plans[~act].kind == _PASS:
            top = states[below].get(plans[~act].origin)
            if top is None or top < 0:
                raise Fallback()
            act = states[top].get(typ)
        return top

    def parse(self, tokens: Iterable[LexTuple], start: str) -> Any:
        """The transformer's result for the token tuples ``tokens``; raises
        :class:`Fallback` where the ordinary path must decide."""
        states = self.states
        plans = self.plans
        kept = self.kept_terminals
        end_state = self.end_states[start]
        state_stack: list = [self.start_states[start]]
        values: list = []
        boxes: list = []
        passes = self.passes
        tok = None
        for tok in tokens:
            typ = tok[0]
            while True:
                act = states[state_stack[-1]].get(typ)
                if act is None:
                    raise SyntaxFailure(self, tok, None, start, state_stack, values, boxes)
                if act >= 0:
                    state_stack.append(act)
                    if typ in kept:
                        values.append(_token(tok))
                    else:
                        values.append(None)
                    boxes.append(tok)
                    break
                p = plans[~act]
                if p.kind == _PASS:
                    # a run of ?rules inlining their one child (an operand
                    # going up the precedence levels) changes the top state
                    # only, as a function of the state below, the top one
                    # and the lookahead: looked up once
                    key = (state_stack[-2], state_stack[-1], typ)
                    top = passes.get(key)
                    if top is None:
                        top = passes[key] = self._pass_run(*key)
                    state_stack[-1] = top
                else:
                    _reduce(p, values, boxes, state_stack, states)
        # $END (lark's borrows the last token's position: only errors use it)
        while True:
            act = states[state_stack[-1]].get("$END")
            if act is None:
                raise SyntaxFailure(self, None, tok, start, state_stack, values, boxes)
            if act >= 0:
                raise Fallback()
            if _reduce(plans[~act], values, boxes, state_stack, states) == end_state:
                return values[-1]

    def unexpected_token(self, failure: SyntaxFailure) -> UnexpectedToken:
        """lark's ``UnexpectedToken`` for ``failure``, as its LALR parser
        raises it (the token, the expected terminals, an interactive parser
        at the point of failure: the same state stack, and a value stack
        with the same tokens and a tree for each rule's value)."""
        from lark.lexer import LexerThread
        from lark.parsers.lalr_interactive_parser import InteractiveParser
        from lark.parsers.lalr_parser_state import ParseConf, ParserState
        parser = self.lark.parser.parser.parser
        conf = ParseConf(parser.parse_table, parser.callbacks, failure.start)
        value_stack: list = []
        for v, box in zip(failure.values, failure.boxes):
            if v is None:                   # a token no rule keeps (its box is its tuple)
                value_stack.append(_token_slow(box))
            else:                           # a kept token, or a rule's value (lark's: a tree)
                value_stack.append(v if isinstance(v, Token) else Tree("_fast", []))
        no_lexer = LexerThread(None, None)  # type: ignore[arg-type]
        state = ParserState(conf, no_lexer, list(failure.state_stack), value_stack)
        if failure.token is not None:
            token = _token_slow(failure.token)
        elif failure.last is not None:
            token = Token.new_borrow_pos("$END", "", _token_slow(failure.last))
        else:
            token = Token("$END", "", 0, 1, 1)
        expected = {s for s in conf.states[state.position] if s.isupper()}
        e = UnexpectedToken(token, expected, state=state, interactive_parser=None)
        e.interactive_parser = InteractiveParser(parser, state, state.lexer)
        return e


def _plan_of(rule: Any, cb: Any, transformer: Any, nullable: set) -> _Plan:
    """What lark's callback ``cb`` for ``rule`` does, as a :class:`_Plan`."""
    from lark.parse_tree_builder import (ChildFilterLALR_NoPlaceholders, ExpandSingleChild,
                                         PropagatePositions)
    f = getattr(cb, "whole", cb)            # pccl.lang.parser._InlinedChild
    if type(f) is not PropagatePositions or f.node_filter is not None:
        raise Fallback()
    f = f.node_builder
    size = len(rule.expansion)
    include = tuple((i, False, sym.is_term) for i, sym in enumerate(rule.expansion))
    if type(f) is ChildFilterLALR_NoPlaceholders:
        include = tuple((i, bool(splice), rule.expansion[i].is_term) for i, splice in f.to_include)
        f = f.node_builder
    expand1 = type(f) is ExpandSingleChild
    if expand1:
        f = f.node_builder
    if not (isinstance(f, functools.partial) and f.func is Tree and len(f.args) == 1):
        raise Fallback()
    name = f.args[0]
    if expand1 and any(not sym.is_term and sym.name in nullable for sym in rule.expansion):
        raise Fallback()        # lark would give an inlined empty node its parent's position
    splice_only = rule.origin.name.startswith("_")
    always_inlined = expand1 and len(include) == 1 and not include[0][1]
    method = None
    if splice_only:
        if expand1:
            raise Fallback()
    elif not always_inlined:        # (a ?rule with one child kept: no method)
        method = getattr(transformer, name, None)
        if method is None or getattr(method, "visit_wrapper", None) is None:
            raise Fallback()
        method = method.base_func       # bound: (meta, children)
    ends_fixed = bool(size) and all(sym.is_term or sym.name not in nullable
                                    for sym in (rule.expansion[0], rule.expansion[-1]))
    return _Plan(_PASS if always_inlined and size == 1 else _BUILD, size, rule.origin.name,
                 include, expand1, splice_only, method, name, ends_fixed)


def _reduce(p: _Plan, values: list, boxes: list, state_stack: list, states: dict) -> int:
    """One reduction by ``p`` on the stacks; the state it goes to."""
    size = p.size
    box: Optional[tuple]
    if size == 1:               # a box's fields 2-5 are its position: one child's is the node's
        raw = [values.pop()]
        rboxes = [boxes.pop()]
        state_stack.pop()
        box = rboxes[0]
    elif size:
        raw = values[-size:]
        rboxes = boxes[-size:]
        del values[-size:]
        del boxes[-size:]
        del state_stack[-size:]
        if p.ends_fixed:    # its first and last symbols always cover text
            first, lastb = rboxes[0], rboxes[-1]
            box = (None, None, first[2], first[3], lastb[4], lastb[5])
        else:
            box = _cover(rboxes)
    else:
        raw, box = [], None
    take = p.take
    if take is None:
        children = raw
    elif take:
        children = [raw[i] for i in take]
    else:
        children = []
        for i, splice, _ in p.include:
            if not splice:
                children.append(raw[i])
            elif children:
                children.extend(raw[i])
            else:               # lark's too: a left recursion grows one list
                children = raw[i]
    if p.expand1 and len(children) == 1:
        value = children[0]
        if isinstance(value, Token):    # lark leaves a token's position alone
            box = (None, None, value.line, value.column, value.end_line, value.end_column)
    elif p.splice_only:
        value = children
    else:
        value = p.method(_Meta(box), children)
    values.append(value)
    boxes.append(box)
    target = states[state_stack[-1]].get(p.origin)
    if target is None or target < 0:
        raise Fallback()
    state_stack.append(target)
    return target


def _cover(rboxes: list) -> Optional[tuple]:
    """The box from the first child's start to the last child's end (of the
    children that cover text), as lark's ``PropagatePositions``."""
    for first in rboxes:
        if first is not None:
            break
    else:
        return None
    for lastb in reversed(rboxes):
        if lastb is not None:
            return (None, None, first[2], first[3], lastb[4], lastb[5])
    return None         # not reached


def _nullable(rules: Iterable) -> set:
    """The names of the nonterminals that can derive the empty text."""
    rules = list(rules)
    nullable: set = set()
    changed = True
    while changed:
        changed = False
        for r in rules:
            if r.origin.name not in nullable and all(
                    not s.is_term and s.name in nullable for s in r.expansion):
                nullable.add(r.origin.name)
                changed = True
    return nullable


_TOKEN_SLOTS = ("type", "value", "start_pos", "line", "column", "end_line", "end_column", "end_pos")


def _token_slow(t: LexTuple) -> Token:
    typ, value, line, column, end_line, end_column, start_pos, end_pos = t
    return Token(typ, value, start_pos, line, column, end_line, end_column, end_pos)


def _token_quick(t: LexTuple) -> Token:
    """``Token(...)`` without its constructor's argument handling (a third
    of its cost); used only where it makes the same token (checked below)."""
    tok = _new_str(Token, t[1])
    tok.type, tok.value, tok.line, tok.column, tok.end_line, tok.end_column, tok.start_pos, \
        tok.end_pos = t
    return tok


_new_str = str.__new__


def _same_tokens() -> bool:
    t = ("IDENT", "abc", 3, 4, 3, 7, 20, 23)
    try:
        a, b = _token_slow(t), _token_quick(t)
        return (type(a) is type(b) and str(a) == str(b)
                and all(getattr(a, s) == getattr(b, s) for s in _TOKEN_SLOTS)
                and set(getattr(Token, "__slots__", ())) <= set(_TOKEN_SLOTS))
    except Exception:           # noqa: BLE001 - another lark: use its constructor
        return False


_token = _token_quick if _same_tokens() else _token_slow
