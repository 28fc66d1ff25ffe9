"""The ``pccl`` command line: run, check and explore PCCL programs.

One module per command group (``cmd_run``: check, run; ``cmd_explore``;
``cmd_traces``: replay, view, serve, graph; ``cmd_simulate``; ``cmd_utility``:
fmt, lsp, cache), the shared options in :mod:`pccl.cli.options` and the
output files in :mod:`pccl.cli.files`; this module is the ``pccl`` group
(the entry point ``pccl.cli:main``)."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator, MutableMapping

import click

# The commands' modules are imported when a command is looked up (its name on
# the command line, or every name for `pccl --help`), not here: `pccl
# --version` and `pccl check` then load (and, without bytecode, compile) only
# the modules they run (issue 43, item 4; tests/acceptance/test_version.py).
#: command name -> (module, attribute)
COMMANDS = {
    "check": ("pccl.cli.cmd_run", "check"), "run": ("pccl.cli.cmd_run", "run"),
    "explore": ("pccl.cli.cmd_explore", "explore"),
    "replay": ("pccl.cli.cmd_traces", "replay"), "view": ("pccl.cli.cmd_traces", "view"),
    "serve": ("pccl.cli.cmd_traces", "serve"), "graph": ("pccl.cli.cmd_traces", "graph"),
    "simulate": ("pccl.cli.cmd_simulate", "simulate"),
    "fmt": ("pccl.cli.cmd_utility", "fmt_cmd"), "lsp": ("pccl.cli.cmd_utility", "lsp"),
    "cache": ("pccl.cli.cmd_utility", "cache_cmd"),
}
#: names this module gives from the modules it does not import up front
_ELSEWHERE = {"FLAGS": "pccl.cli.options", "flag": "pccl.cli.options",
              "cli_spelling": "pccl.cli.options", "_progress_printer": "pccl.cli.cmd_explore"}

#: the exit statuses (the help's epilog of the group and of run, explore, graph)
EXIT_STATUS_HELP = ("Exit status: 0 the properties hold (exhaustive, or within the bounds "
                    "named; a 'reachable P' has a witness), 1 a violation (also a liveness "
                    "counterexample, a time-lock, a stall, an unreachable 'reachable P', a stalled "
                    "run), 2 bad input (the program, the world, an option) or a limit of the "
                    "tool (out of memory, rand over 1,000,000 outcomes), "
                    "130 interrupted (Ctrl-C), 143 terminated (SIGTERM). With --exit-codes "
                    "detailed (run, explore) a violation exits 11 deadlock/stall, 12 "
                    "invariant/collision, 13 temporal property, 14 assertion/stuck, "
                    "15 time-lock, 16 --max-steps.")

__all__ = ["main", "FLAGS", "flag", "cli_spelling", "_progress_printer"]

def _print_version(ctx, value) -> None:
    """``--version``: what a bug report needs to say what ran
    (:mod:`pccl.tools.about`; imports no engine module)."""
    if not value or ctx.resilient_parsing:
        return
    from pccl.tools.about import version_lines
    click.echo("\n".join(version_lines()))
    ctx.exit()


class _Commands(MutableMapping):
    """The group's ``commands``: every name known from the start
    (:data:`COMMANDS`), each command imported when it is first read."""

    def __init__(self, lazy: dict) -> None:
        self._lazy = dict(lazy)
        self._loaded: dict = {}

    def __getitem__(self, name: str) -> click.Command:
        if name not in self._loaded:
            if name not in self._lazy:
                raise KeyError(name)
            module, attr = self._lazy.pop(name)
            self._loaded[name] = getattr(importlib.import_module(module), attr)
        return self._loaded[name]

    def __setitem__(self, name: str, command: click.Command) -> None:
        self._lazy.pop(name, None)
        self._loaded[name] = command

    def __delitem__(self, name: str) -> None:
        if self._lazy.pop(name, None) is None:
            del self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter([*self._loaded, *self._lazy])

    def __len__(self) -> int:
        return len(self._loaded) + len(self._lazy)


class _Main(click.Group):
    """The ``pccl`` group: its commands imported when looked up
    (:class:`_Commands`).  Ctrl-C and SIGTERM outside a search exit 130 and
    143, not click's "Aborted!" with status 1 (which means a violation)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.commands = _Commands(COMMANDS)

    def invoke(self, ctx):
        import signal
        import threading

        from pccl.cli.options import _interrupted_status, _on_sigterm, _signal
        previous = None
        _signal["term"] = False
        try:
            if threading.current_thread() is threading.main_thread():
                previous = signal.signal(signal.SIGTERM, _on_sigterm)
            return super().invoke(ctx)
        except KeyboardInterrupt:
            click.echo("pccl: interrupted", err=True)
            sys.exit(_interrupted_status(130))
        except MemoryError:
            # what the command held is released with its frames by now
            from pccl.search.memory import peak_rss_bytes
            click.echo(f"pccl {ctx.invoked_subcommand or ''}: out of memory: the process could "
                       f"not allocate more (peak memory {peak_rss_bytes() / 2**20:,.1f} MiB; a "
                       f"limit such as ulimit -v, or the machine's memory); give --max-memory "
                       f"below that limit to stop cleanly as a bound", err=True)
            sys.exit(2)
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


@click.group(cls=_Main, epilog=EXIT_STATUS_HELP,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True,
              callback=lambda ctx, param, value: _print_version(ctx, value),
              help="Show the version, the native engine's availability, the extras installed, "
                   "Python and the platform, and exit.")
def main():
    """pccl: run and model-check PCCL programs for teams of robots.

    \b
      pccl check PROGRAM            parse and type-check only
      pccl run PROGRAM              one seeded execution against a physics model
      pccl explore PROGRAM          every interleaving, breadth-first, with
                                    shortest counterexamples
      pccl replay FILE              re-execute a trace file (--trace-out)
      pccl view FILE -o F.html      a self-contained HTML viewer of a trace file
      pccl serve PROGRAM            interactive explorer in the browser (127.0.0.1)
      pccl graph PROGRAM -o F.dot   the reachable state graph (DOT or JSON)
      pccl simulate PROGRAM --runs N  many seeded runs: outcomes and their seeds
      pccl fmt PROGRAM...           canonical layout (--check: exit 1 if not)
      pccl lsp                      language server for editors (stdio)
      pccl cache                    the native engine's module cache (--clear)

    A violation is a stuck agent, a failed assertion or invariant, a deadlock,
    a time-lock, a stall, a failed temporal property (--property: eventually P, P ~> Q,
    P ~> Q within T, reachable P) or (with --collisions) a collision.
    """


def __getattr__(name: str):
    """``FLAGS``, ``flag``, ``cli_spelling``, ``_progress_printer``: from
    the module that defines them, imported on first use."""
    if name in _ELSEWHERE:
        return getattr(importlib.import_module(_ELSEWHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

if __name__ == "__main__":  # pragma: no cover
    main()
