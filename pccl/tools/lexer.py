"""A Pygments lexer for PCCL, registered as ``pccl`` (entry point
``pygments.lexers``), so that ``pygmentize -l pccl`` and the code blocks of
Sphinx or MkDocs highlight PCCL.  Its tokens follow ``grammar.lark``:
section headers, reserved words, built-in functions (:mod:`pccl.lang.builtins`),
types, numbers, operators and both kinds of comment."""

from __future__ import annotations

from pygments.lexer import RegexLexer, bygroups, words
from pygments.token import Comment, Keyword, Name, Number, Operator, Punctuation, Whitespace

from pccl.lang.builtins import BUILTINS, READONLY_FLAGS

__all__ = ["PcclLexer"]

#: Reserved words of grammar.lark (and the statement keywords' capitalised forms).
KEYWORDS = ("if", "else", "while", "atomic", "Atomic", "skip", "pre", "Pre", "eff", "Eff",
            "forall", "exists", "eventually", "reachable", "within")
TYPES = ("int", "bool", "boolean", "float", "double", "ItemPosition", "ObstacleList", "List")


class PcclLexer(RegexLexer):
    name = "PCCL"
    aliases = ["pccl"]
    filenames = ["*.pccl"]
    mimetypes = ["text/x-pccl"]

    tokens = {
        "root": [
            (r"\n", Whitespace),
            (r"[\t \f\r]+", Whitespace),
            (r"//[^\n]*", Comment.Single),
            (r"/\*(?:[^*]|\*(?!/))*\*/", Comment.Multiline),
            (r"(?i)(agent)([\t ]*::)([\t ]*)([A-Za-z_]\w*)",
             bygroups(Keyword.Declaration, Punctuation, Whitespace, Name.Class)),
            (r"(?i)(allwrite|mw|allread|sw|local|loc|init|invariants?)([\t ]*:)",
             bygroups(Keyword.Namespace, Punctuation)),
            (r"(enum)(\s+)([A-Za-z_]\w*)", bygroups(Keyword.Declaration, Whitespace, Name.Class)),
            (r"(true|false)\b", Keyword.Constant),
            (words(KEYWORDS, suffix=r"\b"), Keyword),
            (words(TYPES, suffix=r"\b"), Keyword.Type),
            (words(tuple(BUILTINS), suffix=r"(?=\s*\()"), Name.Builtin),
            (words(tuple(READONLY_FLAGS), suffix=r"\b"), Name.Builtin.Pseudo),
            (r"([A-Za-z_]\w*)(\s*)(\()(\s*)(\))(\s*)(:)",
             bygroups(Name.Function, Whitespace, Punctuation, Whitespace, Punctuation,
                      Whitespace, Punctuation)),
            (r"(?:[0-9]+\.[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[0-9]+[eE][+-]?[0-9]+", Number.Float),
            (r"[0-9]+", Number.Integer),
            (r"[A-Za-z_]\w*", Name),
            (r"->|~>|\|\||&&|==|!=|<=|>=|[<>+\-*/%!=]", Operator),
            (r"[()\[\]{},:;.]", Punctuation),
        ],
    }
