"""PCCL parser: source text -> :mod:`pccl.lang.ast`.

Public functions:

* :func:`parse_program` -- a whole PCCL program (docs/language.md §2-§9);
* :func:`parse_file` -- the same, read from a UTF-8 file;
* :func:`parse_property` -- one property expression (docs/language.md §10).

Every syntax problem is raised as :class:`pccl.lang.errors.PcclError` with the
file name, the source and the line/column of the offending token; no lark
exception ever escapes.

The grammar (``grammar.lark``) is LALR(1) with lark's basic lexer and an
:class:`lark.indenter.Indenter` post-lexer; it is built once, on first use.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import difflib
import gc
import itertools
import math
import os
import re
import sys
from typing import Any, Optional
from collections.abc import Iterator

from lark import Discard, Lark, Token, Transformer, Tree, v_args
from lark.exceptions import (GrammarError, LarkError, UnexpectedCharacters, UnexpectedEOF,
                             UnexpectedInput, UnexpectedToken, VisitError)
from lark.indenter import DedentError, Indenter

from pccl.lang import ast
from pccl.lang.errors import PcclError
from pccl.lang.lalrfast import Fallback, FastLALR, LexFailure, LexTuple, SyntaxFailure

__all__ = ["parse_program", "parse_file", "parse_property"]

_GRAMMAR_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "grammar.lark")

# True while parse_property runs: newlines are then plain white space.
_PROPERTY_MODE: contextvars.ContextVar[bool] = contextvars.ContextVar(
    "pccl_property_mode", default=False)


# --------------------------------------------------------------------------
# Indentation
# --------------------------------------------------------------------------

class _IndentError(Exception):
    """Dedent to a column that matches no enclosing block."""

    def __init__(self, line: int, column: int):
        super().__init__("inconsistent indentation")
        self.line = line
        self.column = column


class _PcclIndenter(Indenter):
    NL_type = "_NL"
    OPEN_PAREN_types = ["LPAR", "LSQB", "LBRACE"]
    CLOSE_PAREN_types = ["RPAR", "RSQB", "RBRACE"]
    INDENT_type = "_INDENT"
    DEDENT_type = "_DEDENT"
    tab_len = 8

    def handle_NL(self, token: Token) -> Iterator[Token]:
        if self.paren_level > 0:
            return
        yield token
        indent_str = token.rsplit("\n", 1)[1]
        indent = indent_str.count(" ") + indent_str.count("\t") * self.tab_len
        if indent > self.indent_level[-1]:
            self.indent_level.append(indent)
            yield Token.new_borrow_pos(self.INDENT_type, indent_str, token)
        else:
            while indent < self.indent_level[-1]:
                self.indent_level.pop()
                yield Token.new_borrow_pos(self.DEDENT_type, indent_str, token)
            if indent != self.indent_level[-1]:
                raise _IndentError(token.end_line or 0, token.end_column or 0)

    def _process(self, stream):
        token = None
        cancel = _CANCEL.get()
        count = 0
        for token in stream:
            count += 1
            if cancel is not None and not count & 4095 and cancel.is_set():
                raise ParseCancelled()
            if token.type == self.NL_type:
                yield from self.handle_NL(token)
            else:
                yield token
            if token.type in self.OPEN_PAREN_types:
                self.paren_level += 1
            elif token.type in self.CLOSE_PAREN_types:
                # An unbalanced closer is a syntax error the parser reports.
                self.paren_level = max(0, self.paren_level - 1)
        while len(self.indent_level) > 1:
            self.indent_level.pop()
            yield Token(self.DEDENT_type, "")  # no position: end of file

    def process(self, stream):
        if _PROPERTY_MODE.get():
            return (t for t in stream if t.type != self.NL_type)
        # A fresh indenter per parse: the instance lark holds is shared, and
        # the indentation state must not be (re-entrancy, threads).
        return _PcclIndenter()._process(stream)


class _FastIndenter:
    """:meth:`_PcclIndenter._process` for the fast path's token tuples
    (pccl.lang.lalrfast), as hooks of its lexer: the same tokens and
    positions, the same error at an inconsistent dedent."""

    def __init__(self):
        self.levels = [0]
        self.paren_level = 0

    def hooks(self) -> dict:
        ind = _PcclIndenter
        hooks: dict[str, Any] = {ind.NL_type: self.newline}
        hooks.update((t, self.open) for t in ind.OPEN_PAREN_types)
        hooks.update((t, self.close) for t in ind.CLOSE_PAREN_types)
        return hooks

    def newline(self, token: LexTuple) -> Iterator[LexTuple]:
        if self.paren_level > 0:
            return
        yield token
        indent_str = token[1].rsplit("\n", 1)[1]
        indent = indent_str.count(" ") + indent_str.count("\t") * _PcclIndenter.tab_len
        levels = self.levels
        if indent > levels[-1]:
            levels.append(indent)
            yield (_PcclIndenter.INDENT_type, indent_str) + token[2:]
        else:
            while indent < levels[-1]:
                levels.pop()
                yield (_PcclIndenter.DEDENT_type, indent_str) + token[2:]
            if indent != levels[-1]:
                raise _IndentError(token[4] or 0, token[5] or 0)

    def open(self, token: LexTuple) -> tuple:
        self.paren_level += 1
        return (token,)

    def close(self, token: LexTuple) -> tuple:
        # An unbalanced closer is a syntax error the parser reports.
        self.paren_level = max(0, self.paren_level - 1)
        return (token,)

    def end(self) -> Iterator[LexTuple]:
        """The dedents at the end of the file (no position)."""
        while len(self.levels) > 1:
            self.levels.pop()
            yield (_PcclIndenter.DEDENT_type, "", None, None, None, None, None, None)


def _fast_tokens(fast: FastLALR, text: str) -> Iterator[LexTuple]:
    """The tokens of ``text`` as the parser sees them (after the indenter),
    for the fast path; cancelled as :func:`cancellable` says."""
    cancel = _CANCEL.get()

    def every() -> None:
        if cancel is not None and cancel.is_set():
            raise ParseCancelled()

    ind = _FastIndenter()
    return itertools.chain(fast.lex(text, ind.hooks(), every if cancel is not None else None),
                           ind.end())


# --------------------------------------------------------------------------
# Grammar (built once)
# --------------------------------------------------------------------------

_LARK: Optional[Lark] = None
#: the fast path over the tables of a Lark (pccl.lang.lalrfast): _LARK's
#: (:func:`_get_fast` makes it again for another _LARK)
_FAST: Optional[FastLALR] = None


def _get_fast() -> FastLALR:
    """The fast path over :func:`_get_lark`'s tables (the state numbers of
    two Lark objects of one grammar may differ: one is never run with the
    other's tables)."""
    global _FAST
    lark = _get_lark()
    fast = _FAST
    if fast is None or fast.lark is not lark:
        fast = _FAST = FastLALR(lark, _TRANSFORMER, lark.parser.parser.parser.callbacks)
    return fast


def _get_lark() -> Lark:
    global _LARK
    if _LARK is None:
        with open(_GRAMMAR_PATH, encoding="utf-8") as f:
            grammar = f.read()
        kw = dict(parser="lalr", lexer="basic", start=["program", "property"],
                  postlex=_PcclIndenter(), propagate_positions=True, maybe_placeholders=False)
        # lark checks the file's first line, a hash of the grammar, the
        # options (the cache's own file name among them: a file written
        # under another name, then moved, is never used) and the versions,
        # before it trusts it; a file it cannot read or unpickle (another
        # process half-way through writing it) is built again, and a write
        # that fails is ignored: the cache never makes a parse fail
        path = _lark_cache(grammar)
        _LARK = Lark(grammar, cache=path if path is not None else False, **kw)
        _skip_inlined_positions(_LARK)
        if path is not None:
            _keep_private(path)
    return _LARK


class _InlinedChild:
    """A rule's callback (lark's ``PropagatePositions`` around a builder that
    inlines a single child, a ``?rule``) that returns at once when the rule
    did inline its one child: the positions lark would compute then are the
    child's own, already set.  Every operand goes through eleven such rules
    (``prop`` down to ``atom``, the precedence levels): this is a third of
    lark's tree building (issue 42: checking a large program)."""

    __slots__ = ("whole", "builder")

    def __init__(self, whole):
        self.whole = whole                  # PropagatePositions(builder)
        self.builder = whole.node_builder

    def __call__(self, children):
        if len(children) == 1:
            res = self.builder(children)
            if res is children[0]:
                return res
        return self.whole(children)         # built again (rare: not inlined), with positions


def _skip_inlined_positions(lark: Lark) -> None:
    """Wrap the callbacks of rules that may inline their single child in
    :class:`_InlinedChild` (lark's parser reads the same dict)."""
    from lark.parse_tree_builder import ExpandSingleChild, PropagatePositions
    callbacks = getattr(lark, "_callbacks", None)
    if not isinstance(callbacks, dict):         # another lark: leave it as it is
        return
    for rule, cb in list(callbacks.items()):
        if type(cb) is not PropagatePositions or cb.node_filter is not None:
            continue
        inner, expands = cb.node_builder, False
        while inner is not None:
            if isinstance(inner, ExpandSingleChild):
                expands = True
                break
            inner = getattr(inner, "node_builder", None)
        if expands:
            callbacks[rule] = _InlinedChild(cb)


def _keep_private(path: str) -> None:
    """The cache file lark wrote (with the umask's mode: 0664 under a umask
    of 002) made writable by this user only, so that the next start reads it
    (:func:`pccl.lang.cachedir.private_file`).  No one else could have
    written it: the directory is private."""
    try:
        if os.stat(path).st_mode & 0o022:
            os.chmod(path, 0o644)
    except OSError:             # not written (a read-only disk): nothing to keep
        pass


def _lark_cache(grammar: str) -> Optional[str]:
    """Where the LALR tables of the grammar are cached (lark's own cache, 10x
    faster than building them at every start): pccl's cache directory
    (``$PCCL_CACHE`` or ``~/.cache/pccl``), the file named by the grammar,
    lark's version and Python's; None where the directory is not writable
    or could be written by another user (lark's cache is a pickle:
    :mod:`pccl.lang.cachedir`).  A file there that another user could have
    written is removed unread, and written anew."""
    import hashlib
    import lark
    from pccl.lang.cachedir import private_cache_dir, private_file
    d = private_cache_dir()
    if d is None:
        return None
    tag = f"{grammar}\0{lark.__version__}\0{sys.version_info[:2]}"
    path = os.path.join(d, f"lark-{hashlib.sha256(tag.encode()).hexdigest()[:20]}.cache")
    if not private_file(path):
        try:                    # never read: written anew (the directory is this user's)
            os.unlink(path)
        except OSError:
            return None
    return path


# --------------------------------------------------------------------------
# Tree -> AST
# --------------------------------------------------------------------------

_SECTION = {"ALLWRITE_HDR": "allwrite", "ALLREAD_HDR": "allread", "LOC_HDR": "loc"}
_TYPE_ALIASES = {"boolean": "bool", "double": "float"}
_NO_SID = -1


# (filename, source) while a property (an option's text) is transformed:
# its spans carry it, so errors point into the option, not the program.
_ORIGIN: contextvars.ContextVar[Optional[tuple]] = contextvars.ContextVar(
    "pccl_span_origin", default=None)


def _tspan(tok: Token) -> ast.Span:
    return ast.Span(tok.line or 0, tok.column or 0, tok.end_line or 0, tok.end_column or 0,
                    _ORIGIN.get())


def _mspan(meta) -> ast.Span:
    if getattr(meta, "empty", True):
        return ast.Span.unknown()
    return ast.Span(meta.line, meta.column, meta.end_line, meta.end_column, _ORIGIN.get())


def _join(start: ast.Span, end: ast.Span) -> ast.Span:
    return ast.Span(start.line, start.column, end.end_line, end.end_column, start.origin)


#: Longest integer literal: Python's limit on converting digits to int and back.
MAX_INT_DIGITS = 4300


class _Syntax(Exception):
    """A syntax problem found while building the AST (turned into PcclError)."""

    def __init__(self, message: str, span: ast.Span):
        super().__init__(message)
        self.message = message
        self.span = span


class _Section:
    """Intermediate value for a declaration section."""

    def __init__(self, items):
        self.items = items


@v_args(meta=True)
class _ToAst(Transformer):
    """Builds ast nodes.  Statements get sid -1 here; ``_number`` assigns
    the real sids in source order afterwards."""

    def transform(self, tree):
        return _transform_iteratively(self, tree)

    #: rule name -> the bound method that builds it (lark's ``getattr`` of a
    #: ``v_args`` method makes a new wrapper, ``functools.update_wrapper``
    #: included, at every node: a tenth of the parse)
    _methods: Optional[dict] = None

    def _call_userfunc(self, tree, new_children=None):
        children = new_children if new_children is not None else tree.children
        methods = self._methods
        if methods is None:
            methods = self._methods = {}
        f = methods.get(tree.data)
        if f is None:
            try:
                f = methods[tree.data] = getattr(self, tree.data)
            except AttributeError:
                return self.__default__(tree.data, children, tree.meta)
        try:
            wrapper = getattr(f, "visit_wrapper", None)
            if wrapper is not None:
                return f.visit_wrapper(f, tree.data, children, tree.meta)
            return f(children)
        except GrammarError:
            raise
        except Exception as e:
            raise VisitError(tree.data, tree, e) from e

    # ---- expressions -----------------------------------------------------

    def name(self, meta, children):
        (tok,) = children
        return ast.Name(str(tok), _tspan(tok))

    def int_lit(self, meta, children):
        (tok,) = children
        digits = len(str(tok).lstrip("0"))
        if digits > MAX_INT_DIGITS:
            raise _Syntax(f"integer literal too long ({digits} digits; at most "
                          f"{MAX_INT_DIGITS})", _tspan(tok))
        return ast.IntLit(int(tok), _tspan(tok))

    def float_lit(self, meta, children):
        (tok,) = children
        value = float(tok)
        if not math.isfinite(value):
            raise _Syntax(f"float literal {tok} is out of range (a float is at most about "
                          f"1.8e308)", _tspan(tok))
        return ast.FloatLit(value, _tspan(tok))

    def true_lit(self, meta, children):
        return ast.BoolLit(True, _tspan(children[0]))

    def false_lit(self, meta, children):
        return ast.BoolLit(False, _tspan(children[0]))

    def list_lit(self, meta, children):
        return ast.ListLit(tuple(children), _mspan(meta))

    def call(self, meta, children):
        return ast.Call(str(children[0]), tuple(children[1:]), _mspan(meta))

    def index(self, meta, children):
        base, idx = children
        return ast.Index(base, idx, _mspan(meta))

    def field(self, meta, children):
        base, tok = children
        return ast.Field(base, str(tok), _mspan(meta))

    def unop(self, meta, children):
        op, operand = children
        return ast.Unary(str(op), operand, _mspan(meta))

    def binop(self, meta, children):
        left, op, right = children
        return ast.Binary(str(op), left, right, _mspan(meta))

    def quant(self, meta, children):
        kind, var, body = children
        return ast.Quant(str(kind), str(var), body, _mspan(meta))

    def leadsto(self, meta, children):
        p, q = children[0], children[2]
        bound = children[4] if len(children) > 3 else None
        return ast.Temporal("leadsto", p, q, bound, _mspan(meta))

    def eventually(self, meta, children):
        return ast.Temporal("eventually", children[1], None, None, _mspan(meta))

    def reachable(self, meta, children):
        return ast.Temporal("reachable", children[1], None, None, _mspan(meta))

    def property(self, meta, children):
        return children[0]

    # ---- declarations ----------------------------------------------------

    def type(self, meta, children):
        tok = children[0]
        name = _TYPE_ALIASES.get(str(tok), str(tok))
        elem = children[1] if len(children) > 1 else None
        span = _mspan(meta)
        if name == "List" and elem is None:
            raise _Syntax("'List' needs an element type, e.g. 'List<int>'", span)
        if name != "List" and elem is not None:
            raise _Syntax(f"only 'List' takes a type argument, not '{name}'", span)
        return ast.TypeRef(name, elem, span)

    def array_size(self, meta, children):
        return ("size", children[0])

    def initializer(self, meta, children):
        return ("init", children[0])

    def vardecl(self, meta, children):
        typ, tok = children[0], children[1]
        opts = dict(children[2:])
        # section is filled in by the enclosing section
        return ast.VarDecl("", typ, str(tok), opts.get("size"), opts.get("init"), _mspan(meta),
                           name_span=_tspan(tok))

    def enumdecl(self, meta, children):
        name = children[1]
        members = [str(t) for t in children[2:]]
        seen = set()
        for t in children[2:]:
            if str(t) in seen:
                raise _Syntax(f"duplicate member '{t}' in enum '{name}'", _tspan(t))
            seen.add(str(t))
        return ast.EnumDecl("", str(name), tuple(members), _mspan(meta), name_span=_tspan(name),
                            member_spans=tuple(_tspan(t) for t in children[2:]))

    def _section(self, children):
        section = _SECTION[children[0].type]
        return _Section(tuple(dataclasses.replace(d, section=section) for d in children[1:]))

    def allwrite_sec(self, meta, children):
        return self._section(children)

    def allread_sec(self, meta, children):
        return self._section(children)

    def loc_sec(self, meta, children):
        return self._section(children)

    # ---- statements ------------------------------------------------------

    def assign(self, meta, children):
        target, value = children
        return ast.Assign(_NO_SID, target, value, _mspan(meta))

    def call_stmt(self, meta, children):
        return ast.CallStmt(_NO_SID, str(children[0]), tuple(children[1:]), _mspan(meta))

    def skip_stmt(self, meta, children):
        return ast.Skip(_NO_SID, _tspan(children[0]))

    def block(self, meta, children):
        return tuple(children)

    def if_stmt(self, meta, children):
        kw, cond, body = children[0], children[1], children[2]
        branches = [(cond, body)]
        orelse: tuple = ()
        for c in children[3:]:
            if c[0] == "elif":
                branches.append((c[1], c[2]))
            else:
                orelse = c[1]
        last = orelse if orelse else branches[-1][1]
        return ast.If(_NO_SID, tuple(branches), orelse, _join(_tspan(kw), last[-1].span))

    def elif_clause(self, meta, children):
        return ("elif", children[2], children[3])

    def else_clause(self, meta, children):
        return ("else", children[1])

    def while_stmt(self, meta, children):
        kw, cond, body = children
        return ast.While(_NO_SID, cond, body, _join(_tspan(kw), body[-1].span))

    def atomic_stmt(self, meta, children):
        kw, body = children
        return ast.Atomic(_NO_SID, body, _join(_tspan(kw), body[-1].span))

    # ---- program ---------------------------------------------------------

    def init_sec(self, meta, children):
        return ("init", tuple(children[1:]))

    def guard(self, meta, children):
        return children[1]

    def effect(self, meta, children):
        return (children[0], tuple(children[1:]))

    def event(self, meta, children):
        name, guard, (eff_tok, body) = children
        end = body[-1].span if body else _tspan(eff_tok)
        return ast.Event(str(name), guard, body, _join(_tspan(name), end), name_span=_tspan(name))

    def invariant(self, meta, children):
        if len(children) == 2:
            return ast.Invariant(str(children[0]), children[1], _mspan(meta),
                                 name_span=_tspan(children[0]))
        return ast.Invariant(None, children[0], _mspan(meta))

    def invariant_sec(self, meta, children):
        return ("invariants", tuple(children[1:]))

    def header(self, meta, children):
        return ("name", str(children[1]))

    def program(self, meta, children):
        name = None
        decls: list = []
        init: tuple = ()
        events: list = []
        invariants: tuple = ()
        for c in children:
            if isinstance(c, _Section):
                decls.extend(c.items)
            elif isinstance(c, ast.Event):
                events.append(c)
            elif c[0] == "name":
                name = c[1]
            elif c[0] == "init":
                init = c[1]
            elif c[0] == "invariants":
                invariants = c[1]
        return ast.Program(name, tuple(decls), init, tuple(events), invariants)


def _transform_iteratively(self, tree):
    """Transformer.transform without recursion: a chain of 3,000 operators
    is a tree 3,000 levels deep, beyond Python's recursion limit."""
    stack: list[tuple[Tree, Iterator, list]] = [(tree, iter(tree.children), [])]
    while True:
        node, it, acc = stack[-1]
        for c in it:
            if isinstance(c, Tree):
                stack.append((c, iter(c.children), []))
                break
            res = self._call_userfunc_token(c) if isinstance(c, Token) and self.__visit_tokens__ \
                else c
            if res is not Discard:
                acc.append(res)
        else:
            stack.pop()
            res = self._call_userfunc(node, acc)
            if not stack:
                return None if res is Discard else res
            if res is not Discard:
                stack[-1][2].append(res)


_TRANSFORMER = _ToAst()


# --------------------------------------------------------------------------
# Statement numbering and program-only checks
# --------------------------------------------------------------------------

#: Deepest block nesting accepted (if/while/atomic inside each other).
MAX_BLOCK_NESTING = 100


class _Numberer:
    def __init__(self):
        self.next = 0
        self.depth = 0

    def stmts(self, stmts: tuple) -> tuple:
        return tuple(self.stmt(s) for s in stmts)

    def stmt(self, s):
        """``s`` with its sid and its blocks' sids, numbered in pre-order."""
        sid = self.next
        self.next += 1
        if isinstance(s, (ast.If, ast.While, ast.Atomic)):
            if self.depth >= MAX_BLOCK_NESTING:
                raise _Syntax(f"blocks nested too deeply (more than {MAX_BLOCK_NESTING} "
                              f"levels)", s.span)
            self.depth += 1
            try:
                s = ast.with_blocks(s, self.stmts)
            finally:
                self.depth -= 1
        return dataclasses.replace(s, sid=sid)


#: a program none of whose text is one of these has no property syntax (the
#: tokens of quantifiers, '->' and the temporal forms): no walk needed
_PROPERTY_WORDS = ("forall", "exists", "->", "~>", "eventually", "reachable")


def _check_no_property_syntax(prog: ast.Program) -> None:
    """Quantifiers and ``->`` belong to properties and invariants only."""
    for node in (*prog.decls, *prog.init, *prog.events):
        for sub in ast.walk(node):
            if isinstance(sub, ast.Quant):
                raise _Syntax(f"'{sub.kind}' is only allowed in properties and invariants", sub.span)
            if isinstance(sub, ast.Binary) and sub.op == "->":
                raise _Syntax("'->' is only allowed in properties and invariants", sub.span)
            if isinstance(sub, ast.Temporal):
                word = "~>" if sub.kind == "leadsto" else sub.kind
                raise _Syntax(f"'{word}' is only allowed in properties and invariants",
                              sub.span)


# --------------------------------------------------------------------------
# Error messages
# --------------------------------------------------------------------------

_NAMES = {
    "SEMICOLON": "';'", "COLON": "':'", "COMMA": "','", "DOT": "'.'",
    "LPAR": "'('", "RPAR": "')'", "LSQB": "'['", "RSQB": "']'",
    "LBRACE": "'{'", "RBRACE": "'}'", "EQUAL": "'='",
    "ARROW": "'->'", "LEADSTO": "'~>'", "OROR": "'||'", "ANDAND": "'&&'", "BANG": "'!'",
    "EQ": "'=='", "NE": "'!='", "LT": "'<'", "LE": "'<='", "GT": "'>'", "GE": "'>='",
    "PLUS": "'+'", "MINUS": "'-'", "STAR": "'*'", "SLASH": "'/'", "PERCENT": "'%'",
    "IDENT": "an identifier", "INT": "a number", "FLOAT": "a number",
    "TRUE": "'true'", "FALSE": "'false'",
    "IF": "'if'", "ELSE": "'else'", "WHILE": "'while'", "ATOMIC": "'atomic'",
    "SKIP": "'skip'", "ENUM": "'enum'", "PRE": "'pre'", "EFF": "'eff'",
    "FORALL": "'forall'", "EXISTS": "'exists'", "EVENTUALLY": "'eventually'",
    "REACHABLE": "'reachable'", "WITHIN": "'within'",
    "AGENT_HDR": "'Agent::'", "ALLWRITE_HDR": "'allwrite:'", "ALLREAD_HDR": "'allread:'",
    "LOC_HDR": "'loc:'", "INIT_HDR": "'Init:'", "INVARIANT_HDR": "'invariant:'",
    "_NL": "end of line", "_INDENT": "an indented block", "_DEDENT": "end of block",
    "$END": "end of file",
}

_HEADER_ORDER = ["AGENT_HDR", "ALLWRITE_HDR", "ALLREAD_HDR", "LOC_HDR",
                 "INIT_HDR", "INVARIANT_HDR"]

_SECTIONS = ("allwrite", "allread", "loc", "Init", "invariant")
_SECTION_ALIASES = {"mw": "allwrite", "sw": "allread", "local": "loc", "init": "Init",
                    "invariants": "invariant"}
_SECTION_ORDER = ("sections come in the order Agent::Name, allwrite:, allread:, loc:, "
                  "Init:, the events Name():, invariant: (each optional)")


def _close_section(word: str) -> Optional[str]:
    """The section header ``word`` most likely misspells, e.g. 'allread:'."""
    names = {n.lower(): n for n in _SECTIONS}
    names.update(_SECTION_ALIASES)
    close = difflib.get_close_matches(word.lower(), list(names), n=1, cutoff=0.6)
    return f"{names[close[0]]}:" if close else None


_BINOPS = {"ARROW", "LEADSTO", "WITHIN", "OROR", "ANDAND", "EQ", "NE", "LT", "LE", "GT", "GE",
           "PLUS", "MINUS", "STAR", "SLASH", "PERCENT"}
_CMP_OPS = {"EQ", "NE", "LT", "LE", "GT", "GE"}
_POSTFIX = {"LSQB", "DOT", "LPAR"}
_STMT_START = {"IF", "WHILE", "ATOMIC", "SKIP", "IDENT"}
_EXPR_START = {"IDENT", "INT", "FLOAT", "TRUE", "FALSE", "LPAR", "LSQB",
               "MINUS", "BANG", "FORALL", "EXISTS", "EVENTUALLY", "REACHABLE"}
_TOP_LEVEL = {"INIT_HDR", "INVARIANT_HDR", "ALLWRITE_HDR", "ALLREAD_HDR", "LOC_HDR"}

# Tokens on the parser's value stack that tell what kind of line we are in.
_CONTEXT = {
    "ALLWRITE_HDR": "declaration", "ALLREAD_HDR": "declaration", "LOC_HDR": "declaration",
    "INVARIANT_HDR": "invariant", "PRE": "'pre(...)'",
    "EFF": "statement", "INIT_HDR": "statement", "IF": "statement", "ELSE": "statement",
    "WHILE": "statement", "ATOMIC": "statement",
}


def _join_words(items: list[str]) -> str:
    if len(items) == 1:
        return items[0]
    return ", ".join(items[:-1]) + " or " + items[-1]


def _context(exc: UnexpectedToken) -> Optional[str]:
    ip = getattr(exc, "interactive_parser", None)
    if ip is None:
        return None
    for v in reversed(ip.parser_state.value_stack):
        if isinstance(v, Token) and v.type in _CONTEXT:
            return _CONTEXT[v.type]
    return None


def _event_name(exc: UnexpectedToken) -> Optional[str]:
    """The pending event name, if the parser is at ``Name`` of ``Name():``
    at the top level."""
    ip = getattr(exc, "interactive_parser", None)
    if ip is None:
        return None
    stack = ip.parser_state.value_stack
    if not stack or not (isinstance(stack[-1], Token) and stack[-1].type == "IDENT"):
        return None
    if all(isinstance(v, Tree) or (isinstance(v, Token) and v.type == "_NL") for v in stack[:-1]):
        return str(stack[-1])
    return None


def _describe_expected(expected: set[str], exc: UnexpectedToken, eof_word: str) -> str:
    exp = set(expected)
    categories: list[str] = []
    if {"INT", "FLOAT", "TRUE", "LPAR"} <= exp:
        categories.append("an expression")
        exp -= _EXPR_START
    elif "OROR" in exp:
        # After a complete expression operators are always possible
        # continuations: name what would end the expression instead.
        rest = exp - _BINOPS - _POSTFIX
        if not rest:
            return "an operator"
        exp = rest
    if exp == {"SEMICOLON", "_NL"}:
        ctx = _context(exc)
        return "';' or end of line" + (f" after {ctx}" if ctx else "")
    if "$END" in exp:
        exp.discard("_NL")  # only at the very start of a file: not worth naming
    if _STMT_START <= exp:
        categories.insert(0, "a statement")
        exp -= _STMT_START | {"_DEDENT"}
    if {"ENUM", "IDENT"} <= exp:
        categories.insert(0, "a declaration")
        exp -= {"ENUM", "IDENT", "_DEDENT"}
    if "IDENT" in exp and (exp & _TOP_LEVEL or "$END" in exp):
        categories.append("an event")
        exp.discard("IDENT")
    # Listed as: categories, punctuation and keywords, single-token
    # categories, section headers in program order, then end of line/file.
    punct, singles, headers, ends = [], [], [], []
    for t in exp:
        if t in _HEADER_ORDER:
            headers.append(t)
        elif t in ("_NL", "_DEDENT", "$END"):
            ends.append(t)
        elif _NAMES.get(t, "'").startswith("'"):
            punct.append(_NAMES.get(t, t))
        else:
            singles.append(_NAMES[t])
    words = categories + sorted(set(punct)) + sorted(set(singles))
    words += [_NAMES[t] for t in sorted(headers, key=_HEADER_ORDER.index)]
    words += [eof_word if t == "$END" else _NAMES[t]
              for t in sorted(ends, key=["_NL", "_DEDENT", "$END"].index)]
    return _join_words(words) if words else "something else"


def _eof_position(source: str) -> tuple[int, int]:
    lines = source.splitlines()
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].strip():
            return i + 1, len(lines[i].rstrip()) + 1
    return 1, 1


def _show_char(ch: str) -> str:
    if ch.isprintable() and not ch.isspace():
        return f"'{ch}'"
    return f"U+{ord(ch):04X}"


def _token_error(exc: UnexpectedToken, text: str, source: str, filename: str,
                 property_mode: bool) -> PcclError:
    tok = exc.token
    eof_word = "end of input" if property_mode else "end of file"
    try:
        expected = exc.interactive_parser.accepts()
    except Exception:  # pragma: no cover - defensive
        expected = set(exc.expected)
    ttype = tok.type
    line = getattr(tok, "line", None)
    column = getattr(tok, "column", None)
    end_column = None
    at_eof = ttype == "$END" or line is None
    if ttype == "_DEDENT" and not at_eof:
        end_pos = getattr(tok, "end_pos", None)
        if end_pos is not None and text[end_pos:].strip() == "":
            at_eof = True
    if at_eof:
        what = f"unexpected {eof_word}"
        line, column = _eof_position(source)
    elif ttype == "_NL":
        what = "unexpected end of line"
    elif ttype == "_INDENT":
        return PcclError("unexpected indentation", filename=filename, source=source,
                         line=tok.end_line, column=tok.end_column)
    elif ttype == "_DEDENT":
        what = "unexpected dedent"
        line, column = tok.end_line, tok.end_column
    else:
        what = f"unexpected '{tok.value}'"
        if tok.end_line == tok.line:
            end_column = tok.end_column
        if ttype in ("FORALL", "EXISTS") and "FORALL" not in expected and expected & _EXPR_START:
            return PcclError(f"{what}: a quantifier inside an expression must be "
                             f"parenthesised, e.g. '(forall i: ...)'",
                             filename=filename, source=source, line=line,
                             column=column, end_column=end_column)
    if ttype in _CMP_OPS and "OROR" in expected and not expected & _CMP_OPS:
        return PcclError(f"{what}: comparisons cannot be chained (use '&&')",
                         filename=filename, source=source, line=line,
                         column=column, end_column=end_column)
    message = f"{what}: expected {_describe_expected(expected, exc, eof_word)}"
    if ttype == "EQUAL" and "EQ" in expected:
        message += " (did you mean '=='?)"
    event = _event_name(exc)
    if expected == {"LPAR"} and event is not None:
        close = _close_section(event) if ttype == "COLON" else None
        if close:
            # 'Name:' at the top level, close to a section header: misspelt
            return PcclError(f"unknown section '{event}:' (did you mean '{close}'?); "
                             f"{_SECTION_ORDER}",
                             filename=filename, source=source, line=line,
                             column=column - len(event) if column else column,
                             end_column=end_column)
        message += f" after event name '{event}'"
    if ttype in _HEADER_ORDER and ttype not in expected and ttype != "AGENT_HDR":
        message += f"; {_SECTION_ORDER}"
    return PcclError(message, filename=filename, source=source, line=line,
                     column=column, end_column=end_column)


def _char_error(exc: UnexpectedCharacters, text: str, source: str, filename: str) -> PcclError:
    pos = exc.pos_in_stream
    ch = text[pos] if pos is not None and 0 <= pos < len(text) else ""
    msg = f"unexpected character {_show_char(ch)}" if ch else "unexpected character"
    hints = {"&": "'&&'", "|": "'||'"}
    if ch in hints:
        msg += f" (did you mean {hints[ch]}?)"
    return PcclError(msg, filename=filename, source=source, line=exc.line, column=exc.column)


_FIRST_LINE_INDENT = re.compile(r"[\t \f]+(?=[^\s/])")
_UNTERMINATED = re.compile(r"//[^\n]*|/\*(?:[^*]|\*(?!/))*\*/|/\*")


def _check_comments(text: str, source: str, filename: str) -> None:
    if "/*" not in text:
        return
    for m in _UNTERMINATED.finditer(text):
        if m.group() == "/*":
            line = text.count("\n", 0, m.start()) + 1
            column = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
            raise PcclError("unterminated block comment ('/*' without '*/')",
                            filename=filename, source=source, line=line,
                            column=column, end_column=column + 2)


# --------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------

class ParseCancelled(Exception):
    """The parse was given up: the event of :func:`cancellable` was set (a
    language server's check superseded by a newer text)."""


#: the event that cancels the parses of this context (None: never)
_CANCEL: contextvars.ContextVar[Optional[Any]] = contextvars.ContextVar(
    "pccl_parse_cancel", default=None)


@contextlib.contextmanager
def cancellable(event) -> Iterator[None]:
    """Parses in this block stop with :class:`ParseCancelled` soon (within
    4,096 tokens) after ``event`` (a ``threading.Event``) is set."""
    reset = _CANCEL.set(event)
    try:
        yield
    finally:
        _CANCEL.reset(reset)


@contextlib.contextmanager
def without_gc() -> Iterator[None]:
    """Python's cyclic garbage collector paused (then restored as it was).

    Parsing allocates a few objects per token (lark's tokens and trees, the
    AST) and frees almost none until the end, so the collector's young
    collections keep promoting them and its full collections walk every
    live object: the whole AST built so far *and* everything the process
    holds besides (the language server keeps the last analysis of every
    open document).  That made checking grow faster than linearly with the
    document (measured, issue 42: ``pccl check`` on a 60,000-line program,
    10.5 s of CPU with the collector, 5.6 s without, in a process holding
    the previous parse).  The trees hold no reference cycles the parse
    needs collected: reference counting frees them."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _normalise(source: str) -> str:
    text = source.replace("\r\n", "\n").replace("\r", "\n")
    if not text.endswith("\n"):
        text += "\n"
    return text


def _lark_error_of(failure: SyntaxFailure) -> Optional[UnexpectedToken]:
    """lark's exception for the fast path's syntax error; None where lark's
    classes cannot be made (another lark: the ordinary path reports it)."""
    try:
        return failure.unexpected_token()
    except Exception:   # noqa: BLE001
        return None


def _checked_text(source: str, filename: str, property_mode: bool) -> str:
    """``source`` normalised, after the checks made before lark sees it."""
    if not isinstance(source, str):
        raise PcclError(f"source must be text, not {type(source).__name__}", filename=filename)
    text = _normalise(source)
    _check_comments(text, source, filename)
    if not property_mode:
        # Lark sees no newline before the first line, so its indentation
        # would go unnoticed: reject it here as the Indenter would.
        m = _FIRST_LINE_INDENT.match(text)
        if m:
            raise PcclError("unexpected indentation", filename=filename, source=source,
                            line=1, column=m.end() + 1)
    return text


def _fast_program(text: str) -> ast.Program:
    """The program ``text`` (normalised) parsed by the fast path
    (:mod:`pccl.lang.lalrfast`: lark's tables, no parse tree).  Raises, at
    a syntax error, what lark's parser would meet there
    (:class:`SyntaxFailure`, :class:`LexFailure`, :class:`_IndentError`:
    reported as the ordinary path reports them), or :class:`Fallback` for a
    text it leaves to the ordinary path (an error of the AST builder: the
    ordinary path reports a syntax error after it first)."""
    fast = _get_fast()
    if not fast.usable:
        raise Fallback()
    try:
        return fast.parse(_fast_tokens(fast, text), "program")
    except (_Syntax, RecursionError):
        raise Fallback() from None


def _parse(source: str, filename: str, start: str, fast: bool = True):
    """``source`` parsed from ``start`` and built (a program without its
    statement numbers); ``fast`` false: never by the fast path (the tests
    compare the two)."""
    property_mode = start == "property"
    text = _checked_text(source, filename, property_mode)
    lark = _get_lark()
    if not property_mode and fast:
        try:
            return _fast_program(text)
        except ParseCancelled:
            raise
        except SyntaxFailure as f:      # the error lark would raise, reported as always
            unexpected = _lark_error_of(f)
            if unexpected is not None:
                raise _token_error(unexpected, text, source, filename, False) from None
        except LexFailure as f:
            raise _char_error(UnexpectedCharacters(text, f.pos, f.line, f.column), text,
                              source, filename) from None
        except _IndentError as e:
            raise lark_failure(e, source, filename) from None
        except Exception:   # noqa: BLE001 - Fallback, or a surprise: the ordinary path decides
            pass
    reset = _PROPERTY_MODE.set(property_mode)
    try:
        try:
            tree = lark.parse(text, start=start)
        finally:
            _PROPERTY_MODE.reset(reset)
        origin = _ORIGIN.set((filename, source) if property_mode else None)
        try:
            result = _TRANSFORMER.transform(tree)
        finally:
            _ORIGIN.reset(origin)
    except UnexpectedToken as e:
        raise _token_error(e, text, source, filename, property_mode) from None
    except UnexpectedCharacters as e:
        raise _char_error(e, text, source, filename) from None
    except (UnexpectedEOF, _IndentError, VisitError, RecursionError, DedentError, UnexpectedInput,
            LarkError) as e:
        raise lark_failure(e, source, filename) from None
    return result


def lark_failure(e: BaseException, source: str, filename: str) -> BaseException:
    """The error to raise for a failure of lark or of the AST builder ``e``
    that is not a token or a character error (those the front end reports
    itself, with what it expected): an end of file, inconsistent
    indentation, a builder's syntax error, nesting too deep; an exception of
    the builder that is none of these is raised as it is.  The PCCL parser
    and the Koord front end (pccl/lang/koord.py) share it."""
    if isinstance(e, UnexpectedEOF):  # not produced by the LALR parser, but be safe
        line, column = _eof_position(source)
        return PcclError("unexpected end of file", filename=filename, source=source,
                         line=line, column=column)
    if isinstance(e, _IndentError):
        return PcclError("inconsistent indentation (dedent does not match any outer level)",
                         filename=filename, source=source, line=e.line, column=e.column)
    if isinstance(e, VisitError):
        orig = e.orig_exc
        if isinstance(orig, _Syntax):
            return PcclError(orig.message, filename=filename, source=source, span=orig.span)
        if isinstance(orig, RecursionError):
            return PcclError("program is nested too deeply", filename=filename, source=source)
        return orig
    if isinstance(e, RecursionError):
        return PcclError("program is nested too deeply", filename=filename, source=source)
    # defensive: DedentError, another UnexpectedInput or LarkError
    e_line = getattr(e, "line", None)
    e_col = getattr(e, "column", None)
    return PcclError(f"syntax error: {e}".splitlines()[0], filename=filename, source=source,
                     line=e_line if isinstance(e_line, int) and e_line > 0 else None,
                     column=e_col if isinstance(e_col, int) and e_col > 0 else None)


def parse_program(source: str, filename: str = "<input>") -> ast.Program:
    """Parse a whole PCCL program.

    Fills ``filename``, ``source`` and ``n_statements`` of the returned
    :class:`ast.Program`; statement sids are 0..n_statements-1 in source order.
    """
    with without_gc():
        return _parse_program(source, filename)


def _parse_program(source: str, filename: str) -> ast.Program:
    prog = _parse(source, filename, "program")
    try:
        numberer = _Numberer()
        init = numberer.stmts(prog.init)
        events = tuple(dataclasses.replace(ev, body=numberer.stmts(ev.body))
                       for ev in prog.events)
        prog = dataclasses.replace(prog, init=init, events=events, filename=filename,
                                   source=source, n_statements=numberer.next)
        if any(word in source for word in _PROPERTY_WORDS):
            _check_no_property_syntax(prog)
    except _Syntax as e:
        raise PcclError(e.message, filename=filename, source=source, span=e.span) from None
    except RecursionError:
        raise PcclError("program is nested too deeply", filename=filename,
                        source=source) from None
    return prog


def parse_file(path) -> ast.Program:
    """Read a UTF-8 file and parse it as a program (the file name is ``str(path)``)."""
    return read_and_parse(path, parse_program)


def read_and_parse(path, parse) -> ast.Program:
    """Read the UTF-8 file ``path`` and return ``parse(source, filename)``
    (the file name is ``str(path)``); a file that cannot be read, or is not
    UTF-8, is a :class:`PcclError`.  The one reader of every front end."""
    filename = os.fspath(path)
    if isinstance(filename, bytes):
        filename = os.fsdecode(filename)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        reason = e.strerror or str(e)
        raise PcclError(f"cannot read '{filename}': {reason}", filename=filename) from None
    try:
        source = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise PcclError(f"cannot read '{filename}': not valid UTF-8 "
                        f"(byte 0x{data[e.start]:02x} at offset {e.start})",
                        filename=filename, line=line) from None
    return parse(source, filename)


def parse_property(source: str, filename: str = "<property>") -> ast.Expr:
    """Parse one property expression (docs/language.md §10): ordinary expressions
    plus ``a -> b``, ``forall i: e`` and ``exists i: e``.  Newlines are white
    space here; one trailing ``;`` is allowed."""
    return _parse(source, filename, "property")
