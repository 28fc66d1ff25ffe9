"""A self-contained HTML viewer of a trace (``--html FILE``, ``pccl view``).

The page is one file: the template ``viewer_assets/viewer.html`` with the
style sheet ``viewer.css``, the script ``viewer.js`` and the data inlined, so
it opens from disk with no network access.  The data is the *trace document*
of :mod:`pccl.output.traces` (the same object ``--trace-out`` writes: one encoder),
plus what the document does not hold and a picture needs:

* ``source``: the program's text (``{"path", "text"}``, or ``null``);
* ``world``: the arena, obstacles, start positions and robot radius;
* ``motion``: whether the program can move a robot (else the page draws a
  per-agent timeline instead of the arena);
* ``at``: per state (initial, then after each step), every agent's pending
  computation as ``describe_k`` says it, when the states are known (a
  ``view`` of a file that cannot be replayed derives it from the next step);
* ``text``: when the model and the path are known, the command line's text
  of the path, made by the functions that print it (one formatter: the page
  never words a step differently from the CLI): ``steps`` (each step as
  ``run --trace`` and a counterexample print it, :func:`~pccl.output.display.format_step`)
  and ``summary`` (``[[k, line]]``: the ``time steps:`` lines of ``pccl run``,
  each with the step after which its first time step's state holds,
  :func:`~pccl.output.views.time_steps`); else ``null`` and the page words
  them itself from the recorded steps;
* ``types``: the declared type of every shared and agent variable
  (``{"shared": {name: type}, "agent": {name: type}}``, a type
  ``{"kind", "elem"}`` as :class:`~pccl.lang.types.Ty`), so that a
  ``List<int>`` of three elements is shown as a list and an
  ``ItemPosition`` as a position; ``null`` when the model is not known
  (then only the position and target cells are shown as positions).
"""

from __future__ import annotations

import html
import json
import math
import os
from importlib import resources
from typing import Any, Optional

from pccl.lang.errors import PcclError

ASSETS = "viewer_assets"


def _asset(name: str) -> str:
    return resources.files("pccl.output").joinpath(ASSETS, name).read_text(encoding="utf-8")


def world_data(world) -> dict:
    """The parts of a :class:`~pccl.lang.world.World` the arena draws."""
    if world is None:
        return {"arena": None, "obstacles": [], "starts": [], "radius": 0.25}
    return {"arena": None if world.arena is None else [list(p) for p in world.arena],
            "obstacles": [[[float(c) for c in p[:2]] for p in poly] for poly in world.obstacles],
            "starts": [[float(c) for c in p[:2]] for p in world.starts],
            "radius": float(world.radius)}


def _read_source(path) -> Optional[str]:
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except (OSError, UnicodeDecodeError, TypeError):
        return None


def source_data(model=None, source_file: Optional[str] = None) -> Optional[dict]:
    """The program's text: the model's (it was parsed from it), else the file
    ``source_file`` (a file the caller checked: for a trace, the one with
    the recorded sha256, :func:`pccl.tools.replay.recorded_file`).  Never a
    file a trace merely names."""
    prog = getattr(model, "program", None)
    if prog is not None and prog.source:
        return {"path": prog.filename, "text": prog.source}
    if source_file is not None:
        text = _read_source(source_file)
        if text is not None:
            return {"path": source_file, "text": text}
    return None


def _shown_path(path, embed_paths: bool):
    """A path as a page shows it: an absolute one, or one that climbs out
    (``../``), as its file name only (a page is shared: the author's
    directories stay theirs), unless ``embed_paths``."""
    if embed_paths or not isinstance(path, str):
        return path
    if os.path.isabs(path) or ".." in path.replace("\\", "/").split("/"):
        return os.path.basename(path)
    return path


def _without_paths(doc: dict) -> dict:
    """The trace document with its files' absolute paths left out
    (``config.program``/``config.world``: ``absolute`` dropped, an absolute
    ``path`` or ``relative`` path, or one that climbs out, cut to its file
    name)."""
    cfg = doc.get("config")
    if not isinstance(cfg, dict):
        return doc
    cfg = dict(cfg)
    for key in ("program", "world"):
        rec = cfg.get(key)
        if isinstance(rec, dict):
            rec = {k: v for k, v in rec.items() if k != "absolute"}
            for k in ("path", "relative"):
                if k in rec:
                    rec[k] = _shown_path(rec[k], False)
            cfg[key] = rec
    return {**doc, "config": cfg}


def motion_of(model=None, doc: Optional[dict] = None) -> bool:
    """Whether to draw an arena: the program calls doReach (known from the
    model), else the trace moves somebody or sends somebody somewhere."""
    if model is not None:
        from pccl.model.compile import program_moves
        return program_moves(model.program)
    for st in (doc or {}).get("steps") or []:
        if st.get("rule") == "DOREACH INVOKE":
            return True
        for ch in st.get("changes") or []:
            if ch["cell"].get("cell") in ("position", "target"):
                return True
    return False


def type_data(ty) -> Optional[dict]:
    """A declared type as the page reads it: ``{"kind", "elem"}``."""
    if ty is None:
        return None
    return {"kind": ty.kind, "elem": type_data(getattr(ty, "elem", None))}


def types_of(model) -> dict:
    lay = model.compiled.layout
    return {"shared": {v.name: type_data(v.ty) for v in lay.shared},
            "agent": {v.name: type_data(v.ty) for v in list(lay.allread) + list(lay.local)}}


def text_of(model, states, labels) -> dict:
    """The command line's text of the path (see the module's ``text``)."""
    from pccl.output import display as D
    from pccl.output import views
    steps = [D.format_step(model, n + 1, lab, states[n], states[n + 1])
             for n, lab in enumerate(labels)]
    summary = [[k, line] for k, line in views.time_steps(model, views.summary_of(states, labels))]
    return {"steps": steps, "summary": summary}


def watch_function(model, text: str, k: int = 0) -> tuple:
    """``(type, fn(st))`` of the watched expression ``text`` (``--watch``,
    the expression box of ``pccl serve``): parsed and checked as a property
    expression of the program (any type; names file ``--watch #k+1``, caret
    and all, when wrong), compiled by the compiler that evaluates
    invariants: pccl's own semantics."""
    from pccl.lang.checker import check_watch
    from pccl.lang.parser import parse_property
    if not isinstance(text, str) or not text.strip():
        raise PcclError("an expression to watch must be non-empty text", filename=f"--watch #{k + 1}")
    fname = f"--watch #{k + 1}"
    expr = parse_property(text, filename=fname)
    ty = check_watch(expr, model.compiled.info, filename=fname, source=text)
    return ty, model.compiled.state_predicate(expr)[1]


def watch_values(model, states, texts) -> list:
    """Each watched expression's value in every state: ``[{"text", "type",
    "values": [text per state], "numbers": [number or null per state]}]``
    (a value shown as :func:`~pccl.lang.values.format_value` shows it; a
    number or bool also as a number, for the plot; a state where it cannot
    be evaluated: ``could not be evaluated: …`` and null)."""
    from pccl.lang.values import format_value
    out = []
    for k, text in enumerate(texts):
        ty, fn = watch_function(model, text, k)
        values: list = []
        numbers: list = []
        for st in states:
            try:
                v = fn(st)
            except Exception as e:          # as an invariant: reported, not raised
                values.append(f"could not be evaluated: {e}")
                numbers.append(None)
                continue
            values.append(format_value(v, ty))
            numbers.append(float(v) if isinstance(v, (bool, int, float)) and math.isfinite(v) else None)
        out.append({"text": text.strip(), "type": str(ty), "values": values, "numbers": numbers})
    return out


def data(doc: dict, *, model=None, states=None, labels=None, world=None,
         title: Optional[str] = None, notes: Optional[list] = None,
         source_file: Optional[str] = None, embed_paths: bool = False, watch=()) -> dict:
    """The object the page reads (``window.PCCL_DATA``).  The source shown is
    the model's or ``source_file``'s (:func:`source_data`); absolute paths
    are left out unless ``embed_paths``.  ``states`` and ``labels``: the
    document's path (its states then, with the model, give every agent's
    pending computation, and with ``labels`` too the CLI's text of it).
    ``watch``: expressions to evaluate in every state of the path
    (:func:`watch_values`; they need the model and the states)."""
    if world is None and model is not None:
        world = model.world
    from pccl.model.layout import AGS, PC
    at = text = types = None
    if model is not None and states:
        at = [[model.compiled.describe_k(ag[PC]) for ag in st[AGS]] for st in states]
        if labels is not None and len(labels) == len(states) - 1 == len(doc.get("steps") or []):
            text = text_of(model, states, labels)
    if model is not None:
        types = types_of(model)
    watched = watch_values(model, states, watch) if watch and model is not None and states else []
    src = source_data(model, source_file)
    if src is not None:
        src = {**src, "path": _shown_path(src["path"], embed_paths)}
    if not embed_paths:
        doc = _without_paths(doc)
    return {"trace": doc, "source": src, "world": world_data(world), "motion": motion_of(model, doc),
            "at": at, "text": text, "types": types, "watch": watched,
            "title": title or _title(doc, src), "notes": list(notes or [])}


def _title(doc: dict, src) -> str:
    cfg = doc.get("config") or {}
    path = (src or {}).get("path") or (cfg.get("program") or {}).get("path") or "trace"
    return f"pccl {cfg.get('command', 'trace')} {os.path.basename(str(path))}"


def _script_json(obj: Any) -> str:
    """JSON safe inside a <script> element: no ``</`` and no ``<!--``."""
    text = json.dumps(obj, default=str, separators=(",", ":"), allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026") \
        .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029")


#: the template's markers, in the order they appear in viewer.html
_MARKERS = ("{{TITLE}}", "/*{{CSS}}*/", "/*{{BOOT}}*/", "/*{{JS}}*/")


def _template_parts() -> list:
    """viewer.html cut once at its markers: the text between them, one more
    piece than there are markers (each marker once, in order)."""
    tpl = _asset("viewer.html")
    parts, rest = [], tpl
    for marker in _MARKERS:
        before, sep, rest = rest.partition(marker)
        if not sep or marker in before or marker in rest:
            raise AssertionError(f"viewer.html: the marker {marker} is not there once")
        parts.append(before)
    parts.append(rest)
    return parts


def page(data_obj: Optional[dict], *, mode: str = "static", title: str = "pccl",
         boot: Optional[dict] = None) -> str:
    """The HTML page: ``mode`` ``static`` (a trace, data inline) or ``serve``
    (the interactive explorer of :mod:`pccl.tools.serve`, data from its API).
    The template is cut at its markers first and the pieces joined with what
    fills them, so nothing filled in (a program's text holding a marker, in
    the data) is ever read as template; the data is JSON escaped for a
    ``<script>`` element (:func:`_script_json`).  ``boot``: more of
    ``window.PCCL_BOOT`` (serve's token)."""
    parts = _template_parts()
    fills = [html.escape(title), _asset("viewer.css"),
             "window.PCCL_BOOT = " + _script_json({"mode": mode, "data": data_obj, **(boot or {})})
             + ";",
             _asset("viewer.js")]
    out = [parts[0]]
    for fill, part in zip(fills, parts[1:]):
        out += [fill, part]
    return "".join(out)


def html_of(doc: dict, **kw) -> str:
    d = data(doc, **kw)
    return page(d, mode="static", title=d["title"])


def write(path, doc: dict, **kw) -> None:
    """Write the viewer of ``doc`` to ``path`` (a :class:`PcclError` naming
    the file when it cannot be written)."""
    text = html_of(doc, **kw)
    try:
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as e:
        raise PcclError(f"cannot write viewer: {e.strerror or e}", filename=os.fspath(path)) from None
