"""The command line's options: how flags are spelt (:data:`FLAGS`, :func:`cli_spelling`),
the parameter types, the option groups the commands share, exit statuses and errors."""

from __future__ import annotations

import sys

import click

from pccl.lang.errors import PcclError

#: Options whose flag is not ``--`` + the name with ``-`` for ``_``.  The flags
#: are spelt here only: the engine, the API and the outputs name options by
#: placeholders (``{depth=10}``, :func:`pccl.lang.errors.spell`) that the API
#: writes as keywords and the CLI as flags (:func:`cli_spelling`).
FLAGS = {"agents": "--agents", "rates": "--rate", "overrides": "--set",
         "invariants": "--invariant", "deadlock": "--no-deadlock", "find_all": "--all",
         "properties": "--property", "timelock": "--no-timelock",
         "stall": "--no-stall", "shorten": "--no-shorten"}
#: Options written with their short flag when given with a value (as the
#: verdict's note has always said it: ``-b nondet explores every timing``).
SHORT_FLAGS = {"blackbox": "-b"}


def flag(name: str) -> str:
    """The command-line flag of the option ``name``."""
    return FLAGS.get(name, "--" + name.replace("_", "-"))


def cli_spelling(name: str, value) -> "str | None":
    """An option as the command line spells it: ``--fastest``, ``--workers 1``,
    ``--no-timelock`` for ``timelock=False``, ``--rate 1=2`` (for
    :func:`pccl.lang.errors.spell`); None for a name that is no option."""
    from pccl.model.options import OPTION_NAMES
    if name not in OPTION_NAMES:
        return None
    if value is not None and name in SHORT_FLAGS:
        return f"{SHORT_FLAGS[name]} {value}"
    f = flag(name)
    if value is None or value == "True" or (value == "False" and f.startswith("--no-")):
        return f
    return f"{f} {value}"


def _render(err: PcclError) -> str:
    """``err`` as the command line says it: its options as flags."""
    return err.respell(cli_spelling).render()

BLACKBOX_HELP = ("environment model: instant, straight, nondet, nondet-fail, pymunk, or "
                 "module:attribute for your own [default: straight; explore: nondet for a "
                 "program that calls doReach: every timing, and every failure straight or "
                 "pymunk could report]")


class RateType(click.ParamType):
    name = "AGENT=RATE"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            a, r = value.split("=")
            a, r = int(a), int(r)
        except ValueError:
            self.fail(f"{value!r} is not AGENT=RATE (for example 1=2)", param, ctx)
        if a < 0:
            self.fail(f"{value!r}: agents are numbered from 0", param, ctx)
        if r < 1:
            self.fail(f"{value!r}: a rate is a positive integer", param, ctx)
        return a, r


class FiniteFloat(click.FloatRange):
    """A float range that also refuses nan and inf (click lets them through)."""

    def convert(self, value, param, ctx):
        import math
        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return rv


class Choice(click.Choice):
    """click.Choice that also says which choice a misspelt value is closest to."""

    def convert(self, value, param, ctx):
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            import difflib
            close = difflib.get_close_matches(str(value).lower(), list(self.choices), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            self.fail(f"{value!r} is not one of {', '.join(map(repr, self.choices))}{hint}",
                      param, ctx)


class SetType(click.ParamType):
    name = "NAME=EXPR"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        name, sep, expr = value.partition("=")
        if not sep or not name.strip() or not expr.strip():
            self.fail(f"{value!r} is not NAME=EXPR (for example k=2)", param, ctx)
        return name.strip(), expr.strip()


def common_options(f, *, agents_flags=("--agents", "-n")):
    opts = [
        click.option(*agents_flags, "agents", type=click.IntRange(min=1), default=None,
                     help="number of agents (overrides the world's count) [default: world's, else 2]"),
        click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
                     help="world file (TOML): start positions, obstacles, function values"),
        click.option("--blackbox", "-b", default=None, show_default=False, help=BLACKBOX_HELP),
        click.option("--delta", type=FiniteFloat(min=0, min_open=True), default=1.0,
                     show_default=True, help="time step δ"),
        click.option("--n0", type=click.IntRange(min=1), default=1, show_default=True,
                     help="event-block executions per agent per time step"),
        click.option("--rate", "rates", type=RateType(), multiple=True,
                     help="per-agent rate ρ, 1..n0: each event block of agent A costs ρ of the "
                          "n0 per time step, e.g. --n0 2 --rate 1=2 (repeatable)"),
        click.option("--events", type=Choice(["any", "first"]), default="any",
                     show_default=True,
                     help="any enabled event may run, or only the first in source order"),
        click.option("--lang", type=Choice(["pccl", "koord"]), default=None,
                     help="read the program as this language [default: koord for "
                          ".koord/.krd files, else pccl]"),
        click.option("--semantics", type=Choice(["pccl", "koord"]), default=None,
                     help="the execution model: PCCL's (statements interleave) or Koord's "
                          "rounds (one event per robot per round as one transition, "
                          "round-consistent memory; Koord programs only: docs/koord.md) "
                          "[default: koord for Koord programs, else pccl]"),
        click.option("--skip-events", is_flag=True,
                     help="Koord's SkipEvent: a robot may let a round pass although an event "
                          "is enabled (--semantics koord)"),
        click.option("--collisions", is_flag=True,
                     help="report robots overlapping each other or an obstacle"),
        click.option("--set", "overrides", type=SetType(), multiple=True,
                     help="override a variable's initialiser, e.g. --set k=2 (repeatable)"),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def common_options_without_n(f):
    """The common options, with -n left free (simulate's -n is the number of runs)."""
    return common_options(f, agents_flags=("--agents",))


def view_options(f):
    f = click.option("--full", is_flag=True,
                     help="with --view steps: also show the steps that change nothing")(f)
    f = click.option("--view", type=click.Choice(["steps", "swimlane"]), default=None,
                     help="how to show the trace: steps (from the initial state, branches "
                          "named, empty steps folded) or swimlane (one column per agent)")(f)
    return f


def watch_option(f):
    return click.option("--watch", "watch", multiple=True, metavar="EXPR",
                        help="with --html: an expression (a property expression of any type) "
                             "to evaluate in every state of the path, shown in the page's "
                             "expressions panel and plot (repeatable)")(f)


def _check_watch(model, watch, html) -> None:
    """--watch: each expression checks against the program (a PcclError at
    its caret otherwise), and it needs --html."""
    if watch and not html:
        raise PcclError("--watch needs --html (it shows in the page)", filename="--watch")
    from pccl.output.viewer import watch_function
    for k, text in enumerate(watch):
        watch_function(model, text, k)


def _delta(d):
    # 2.0 is 2; a huge integral float stays a float (its int would print 300 digits)
    return int(d) if float(d).is_integer() and abs(d) < 2 ** 53 else d


def _check_repeats(rates, overrides):
    """A repeated --rate for one agent or --set for one variable is a mistake."""
    for opt, pairs, what in (("--rate", rates, "agent"), ("--set", overrides, "variable")):
        names = [k for k, _ in pairs]
        twice = sorted({str(k) for k in names if names.count(k) > 1})
        if twice:
            raise click.BadParameter(f"{what} {', '.join(twice)} given more than once",
                                     param_hint=f"'{opt}'")


def _fail(err: PcclError):
    click.echo(_render(err), err=True)
    sys.exit(2)


_signal = {"term": False}


def _on_sigterm(signum, frame):
    # stop like Ctrl-C (explore prints the statistics so far), exit 143
    _signal["term"] = True
    raise KeyboardInterrupt


def _interrupted_status(code: int) -> int:
    return 143 if code == 130 and _signal["term"] else code


def _exit_status(code: int, kinds, mode: str) -> int:
    """The status to exit with: 143 for SIGTERM, and under ``--exit-codes
    detailed`` a violation's status by its kind (pccl/tools/exitcodes.py)."""
    from pccl.tools.exitcodes import status
    return status(_interrupted_status(code), kinds, mode)

#: ``--exit-codes`` of run and explore (one option, one help text)
_EXIT_CODES = click.option(
    "--exit-codes", "exit_codes", type=Choice(["default", "detailed"]),
    default="default", show_default=True,
    help="detailed: a violation exits 11 deadlock/stall, 12 invariant/collision, "
         "13 temporal property, 14 assertion/stuck, 15 time-lock, 16 --max-steps "
         "(instead of 1)")

def _workers(value):
    if value is None:
        return None
    if value == "auto":
        return value            # the API resolves it: local cores, or the Ray cluster's CPUs
    try:
        n = int(value)
    except ValueError:
        raise click.BadParameter(f"expected a number of processes or 'auto', got {value!r}") from None
    if not 1 <= n <= 256:
        raise click.BadParameter(f"expected 1 to 256 processes, got {n}")
    return n


def _interval(value):
    from pccl.search.checkpoint import parse_interval
    try:
        return parse_interval(value)
    except ValueError as e:
        raise click.BadParameter(str(e)) from None


def _size(value):
    if value is None:
        return None
    from pccl.api import parse_size
    try:
        return parse_size(value)
    except ValueError as e:
        raise click.BadParameter(str(e)) from None
