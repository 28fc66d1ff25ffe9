"""``pccl fmt``, ``lsp`` and ``cache``: the formatter, the language server, the native module cache."""

from __future__ import annotations

import sys

import click

from pccl.cli.options import Choice, _fail
from pccl.lang.errors import PcclError


@click.command(name="fmt", short_help="Format programs in the canonical layout.")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, allow_dash=True))
@click.option("--check", is_flag=True,
              help="write nothing; exit 1 if a file would change (for CI)")
@click.option("--diff", "show_diff", is_flag=True,
              help="write nothing; print the changes as a unified diff, exit 1 if any")
@click.option("--lang", type=Choice(["pccl", "koord"]), default=None,
              help="read every file as this language [default: koord for .koord/.krd "
                   "files, else pccl; standard input: pccl]")
def fmt_cmd(files, check, show_diff, lang):
    """Rewrite each PROGRAM in the canonical layout (docs/editors.md):
    indentation, spacing and blank lines only; comments and line structure
    are kept, and the program's meaning never changes.  `-` reads standard
    input and writes the result to standard output (`--lang koord` for a
    Koord program there)."""
    import difflib

    from pccl.tools.fmt import FormatterBug, format_source
    changed = []
    for path in files:
        try:
            if path == "-":
                source = sys.stdin.read()
            else:
                try:
                    with open(path, encoding="utf-8-sig", newline="") as fh:
                        source = fh.read()
                except (OSError, UnicodeDecodeError) as e:
                    raise PcclError(f"cannot read '{path}': {getattr(e, 'strerror', None) or e}",
                                    filename=path) from None
            out = format_source(source, "<stdin>" if path == "-" else path, lang)
        except PcclError as e:
            _fail(e)
        except FormatterBug as e:
            click.echo(f"pccl fmt: internal error, file left as it is: {e}", err=True)
            sys.exit(2)
        if path == "-" and not (check or show_diff):
            click.echo(out, nl=False)
            continue
        if out == source:
            continue
        changed.append(path)
        if show_diff:
            click.echo("".join(difflib.unified_diff(source.splitlines(True), out.splitlines(True),
                                                    path, path + " (formatted)")), nl=False)
        elif check:
            click.echo(f"would reformat {path}")
        else:
            with open(path, "w", encoding="utf-8", newline="") as fh:
                fh.write(out)
            click.echo(f"reformatted {path}")
    if (check or show_diff) and changed:
        sys.exit(1)


@click.command(short_help="Language server for editors (LSP over stdio).")
def lsp():
    """Run the PCCL language server on standard input and output: diagnostics,
    hover, definitions, references, symbols, completion, formatting
    (docs/editors.md).  Needs the `lsp` extra: pip install -e '.[lsp]' in the pccl
    checkout."""
    try:
        import lsprotocol  # noqa: F401
        import pygls  # noqa: F401
    except ImportError as e:
        from pccl.lang.errors import install_hint
        click.echo(f"pccl lsp: error: {e.name or 'pygls'} is not installed; "
                   f"{install_hint('lsp')}", err=True)
        sys.exit(2)
    from pccl.tools.lsp import serve
    serve()


@click.command(name="cache", short_help="The native engine's module cache: size, bound, --clear.")
@click.option("--clear", is_flag=True, help="remove every compiled module of the cache")
@click.option("--format", "fmt", type=Choice(["text", "json"]), default="text",
              show_default=True)
def cache_cmd(clear, fmt):
    """Show the native engine's module cache (--engine native compiles one
    module per program into $PCCL_CACHE or ~/.cache/pccl): its directory,
    how many modules it holds, their size and the bound ($PCCL_CACHE_SIZE,
    default 100M; 0: none), beyond which the least recently used modules
    are removed after a new one is compiled.  --clear removes them all
    (docs/scale-out.md#the-native-module-cache)."""
    import json
    import os

    from pccl.model import native_build as NV
    from pccl.search.memory import format_size
    try:
        bound = NV.cache_bound()
    except PcclError as e:
        _fail(e)
    d = NV.cache_dir()
    removed = NV.clear_cache(d) if clear and os.path.isdir(d) else (0, 0)
    mods = NV.cache_modules(d)
    size = sum(m[1] for m in mods)
    if fmt == "json":
        click.echo(json.dumps({"directory": d, "modules": len(mods), "bytes": size,
                               "bound_bytes": bound, "removed": removed[0],
                               "removed_bytes": removed[1]}, indent=2))
        return
    if clear:
        click.echo(f"removed {removed[0]:,} modules ({format_size(removed[1])})")
    click.echo(f"directory  {d}")
    click.echo(f"modules    {len(mods):,} ({format_size(size)})")
    click.echo(f"bound      {format_size(bound) if bound is not None else 'none'} "
               f"(${NV.CACHE_SIZE_ENV})")
