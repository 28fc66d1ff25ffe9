"""Programs and options to a model: the one construction every front end
(the API, the CLI, replay) uses.  Loading a program (a path, source text or
an AST), ``--set`` overrides, the blackbox ``explore`` picks for a program
that moves, and :func:`build_model`: the :class:`~pccl.model.engine.Model`
the options describe, seen through its reductions.  ``pccl.api``
re-exports these."""

from __future__ import annotations

import dataclasses
import os
import random
from typing import Optional, Union

from pccl.lang import ast as A
from pccl.lang.errors import OptionError
from pccl.model.compile import program_moves
from pccl.model.options import CommonOptions, model_choices
from pccl.model.reduce import Reduced


def load_program(program: Union[str, os.PathLike, A.Program], *, source: bool = False,
                 lang: Optional[str] = None) -> A.Program:
    """``program`` as an AST: a Program as it is; text (``source``) or a
    file read as ``lang`` (``"pccl"``, ``"koord"``; None: a file's suffix
    decides, text is PCCL)."""
    from pccl.lang.files import parse_program_file, parse_program_text
    if isinstance(program, A.Program):
        return program
    if source:
        return parse_program_text(str(program), "<input>", lang)
    return parse_program_file(program, lang)    # PCCL, or Koord (.koord, .krd, lang: docs/koord.md)


def load_world_arg(world):
    from pccl.lang.world import World, load_world
    if world is None or isinstance(world, World):
        return world
    return load_world(os.fspath(world))


def apply_overrides(prog: A.Program, overrides) -> A.Program:
    """Replace the initialisers of shared variables: ``{"k": "2"}`` (TLC-style
    constants).  Values are PCCL expressions."""
    from pccl.lang.parser import parse_property
    if not overrides:
        return prog
    overrides = dict(overrides)
    decls = []
    for d in prog.decls:
        if isinstance(d, A.VarDecl) and d.name in overrides:
            text = overrides.pop(d.name)
            expr = parse_property(str(text), filename=f"{{overrides}} {d.name}")
            d = dataclasses.replace(d, init=expr)
        decls.append(d)
    if overrides:
        names = ", ".join(sorted(overrides))
        raise OptionError("overrides", f"no variable named {names} in {prog.filename}")
    return dataclasses.replace(prog, decls=tuple(decls))


#: The blackbox ``explore`` uses for a program that calls doReach when none is
#: given: every travel time, so no timing bug hides behind a fixed schedule.
EXPLORE_MOVING_DEFAULT = "nondet"
#: Why it was chosen, as the header of ``pccl explore`` says it.
MOVING_DEFAULT_REASON = "default for programs that move"
def explore_blackbox(prog: A.Program, blackbox=None):
    """The blackbox ``explore`` uses for ``prog`` and why: ``(blackbox, reason)``.
    An explicit ``blackbox`` is kept (reason None); without one a program
    that moves gets ``nondet`` (every timing), others the run default."""
    if blackbox is not None:
        return blackbox, None
    if program_moves(prog):
        return EXPLORE_MOVING_DEFAULT, MOVING_DEFAULT_REASON
    return None, None



def build_model(program, opts: CommonOptions, *, rng: Optional[random.Random] = None,
                explore: bool = False) -> Reduced:
    """The model ``opts`` describe (already checked), seen through the
    reductions they ask for.  ``explore``: choose the blackbox as ``pccl
    explore`` does when none is given (:func:`explore_blackbox`)."""
    prog = apply_overrides(load_program(program, source=opts.source, lang=opts.lang),
                           opts.overrides)
    blackbox, reason = (explore_blackbox(prog, opts.blackbox) if explore
                        else (opts.blackbox, None))
    opts = opts.replace(blackbox=blackbox)
    if rng is not None and opts.rand_policy is None:
        opts = opts.replace(rand_policy=lambda n, agent, span: rng.randint(0, n))
    from pccl.model.koord import model_for
    model = model_for(prog, opts)       # PCCL's semantics, or Koord's (pccl/model/koord.py)
    model.blackbox_reason = reason
    model.world_given = opts.world is not None      # read by the checked section's notes
    return Reduced(model, model_choices(opts)[1])
