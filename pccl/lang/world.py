"""Worlds: where the robots are, what the uninterpreted functions return,
and which obstacles are solid (docs/worlds.md).

A world is read from a TOML file given with ``--world FILE``.  Every key is
optional; unknown keys are errors.  Layout::

    # top level
    agents = 2                  # number of agents (integer >= 1)
    resolution = 0.01           # positions are compared/rounded to this (> 0)
    radius = 0.25               # robot disc radius (> 0)
    mass = 1.0                  # robot mass, pymunk only (> 0)
    speed = 1.0                 # robot speed, distance per time unit (> 0)
    tolerance = 0.05            # pymunk: done when this close to the target
                                #   (> 0; default 5 * resolution)
    no_progress_time = 3.0      # pymunk: fail after this long without
                                #   progress toward the target (> 0)
    arena = [[0, 0], [10, 10]]  # [[xmin, ymin], [xmax, ymax]]: bounds used to
                                #   lay out agents without a start (not solid)
    start = [[0, 0], [2, 0, 1]] # start positions [x, y] or [x, y, z]; fewer
                                #   than agents is fine (the rest are laid out
                                #   automatically), more is fine (extra unused)

    [functions]                 # uninterpreted zero-argument functions
    getInput = [[1, 1], [4, 0]] # any name; arrays become tuples, numbers,
    getObs = [[[2, 2], [3, 2], [3, 3]]]   # booleans and strings are kept

    [[obstacles]]               # one table per solid obstacle
    polygon = [[2, 2], [3, 2], [3, 3]]    # >= 3 points, a valid polygon

Defaults: ``getInput`` is an empty list when not given, ``getObs`` is the
world's obstacle polygons (so a program that passes ``getObs()`` to
``doReach`` avoids exactly the world's obstacles).  ``getObs`` given
explicitly must be a list of polygons (each >= 3 ``[x, y]`` points).

Automatic start positions (:meth:`World.start_positions`): agents without a
given start are placed deterministically, spaced ``3 * radius`` apart (rounded
up to the resolution), never within ``3 * radius`` of another start and never
within ``1.5 * radius`` of an obstacle.  With an ``arena`` they fill a grid
inside it row by row from the bottom-left corner (keeping ``1.5 * radius``
from its edges); without one they go on the line ``y = 0`` from ``x = 0``
toward ``+x``.

Every problem in a world file raises :class:`~pccl.lang.errors.PcclError` with
the file name, its text and the line/column of the offending key or value.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from typing import Any, NoReturn, Optional

from pccl.lang.data import TOML_NAMES, is_finite_number, is_integer, is_number, kind
from pccl.lang.errors import PcclError
from pccl.lang.tomlpos import TomlSource, decode_error_location, long_integer_location

Point3 = tuple  # (x, y, z)
Polygon = tuple  # ((x, y), ...)

TOP_KEYS = ("agents", "resolution", "radius", "mass", "speed", "tolerance",
            "no_progress_time", "arena", "start", "functions", "obstacles")
OBSTACLE_KEYS = ("polygon",)

#: Largest coordinate accepted in a world file: far from the float limit, so
#: that rounding to the resolution and moving by speed * δ stay finite.
MAX_COORD = 1e12
#: Most agents a model may have (each is a tuple in every state).
MAX_AGENTS = 10_000
MAX_INT_DIGITS = 4300

DEFAULT_RESOLUTION = 0.01
DEFAULT_NO_PROGRESS_TIME = 3.0
TOLERANCE_FACTOR = 5.0  # default tolerance = TOLERANCE_FACTOR * resolution


@dataclass(frozen=True)
class World:
    """An immutable, hashable world description (blackboxes cache on it)."""
    n_agents: Optional[int] = None
    starts: tuple = ()
    resolution: float = DEFAULT_RESOLUTION
    arena: Optional[tuple] = None
    radius: float = 0.25
    mass: float = 1.0
    speed: float = 1.0
    tolerance: Optional[float] = None          # None -> 5 * resolution
    no_progress_time: float = DEFAULT_NO_PROGRESS_TIME
    obstacles: tuple = ()
    functions: tuple = ()
    filename: Optional[str] = field(default=None, compare=False)

    def __post_init__(self):
        if self.tolerance is None:
            object.__setattr__(self, "tolerance",
                               TOLERANCE_FACTOR * self.resolution)

    def functions_dict(self) -> dict:
        """Uninterpreted function name -> value (lists are tuples)."""
        return dict(self.functions)

    # ------------------------------------------------------------------
    def start_positions(self, n: int) -> tuple:
        """``n`` start positions ``(x, y, z)``: the given starts first, the
        rest laid out automatically (see the module docstring)."""
        given = [tuple(float(c) for c in s[:3]) + (0.0,) * (3 - len(s[:3]))
                 for s in self.starts[:n]]
        out = list(given)
        if len(out) >= n:
            return tuple(out)
        r = self.radius
        spacing = _snap_up(3.0 * r, self.resolution)
        margin = _snap_up(1.5 * r, self.resolution)
        clear_obs = 1.5 * r
        geoms = _obstacle_geoms(self.obstacles)

        def free(x: float, y: float) -> bool:
            for p in out:
                if math.hypot(p[0] - x, p[1] - y) < spacing - 1e-9:
                    return False
            if geoms:
                import shapely
                pt = shapely.Point(x, y)
                for g in geoms:
                    if g.distance(pt) < clear_obs:
                        return False
            return True

        for x, y in self._candidates(spacing, margin):
            if free(x, y):
                out.append((x, y, 0.0))
                if len(out) == n:
                    return tuple(out)
        raise PcclError(
            f"cannot place {n} agents: the arena has room for only "
            f"{len(out)} (robots are laid out {spacing:g} apart)",
            filename=self.filename)

    def _candidates(self, spacing: float, margin: float):
        res = self.resolution
        if self.arena is None:
            i = 0
            while True:
                yield (_snap(i * spacing, res), 0.0)
                i += 1
        (xmin, ymin), (xmax, ymax) = self.arena
        y = ymin + margin
        while y <= ymax - margin + 1e-9:
            x = xmin + margin
            while x <= xmax - margin + 1e-9:
                yield (_snap(x, res), _snap(y, res))
                x += spacing
            y += spacing


def default_world() -> World:
    """The world without a file: agents on a line, empty functions."""
    return World(functions=(("getInput", ()), ("getObs", ())))


# ----------------------------------------------------------------------
# Loading
# ----------------------------------------------------------------------

def load_world(path) -> World:
    """Read and check a TOML world file (layout in the module docstring)."""
    filename = str(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise PcclError(f"world file not found: {filename}",
                        filename=filename) from None
    except IsADirectoryError:
        raise PcclError(f"world file is a directory: {filename}",
                        filename=filename) from None
    except OSError as e:
        raise PcclError(f"cannot read world file: {e.strerror or e}",
                        filename=filename) from None
    try:
        source = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise PcclError(f"world file is not valid UTF-8 ({e.reason})",
                        filename=filename) from None
    return parse_world(source, filename)


def parse_world(source: str, filename: Optional[str] = None) -> World:
    """Like :func:`load_world`, from the file's text."""
    try:
        data = tomllib.loads(source)
    except tomllib.TOMLDecodeError as e:
        msg, line, col = decode_error_location(e, source)
        raise PcclError(f"invalid TOML: {msg}", filename=filename,
                        source=source, line=line, column=col) from None
    except ValueError:      # an integer of more than 4,300 digits
        line, col, end = long_integer_location(source, MAX_INT_DIGITS) or (None, None, None)
        raise PcclError(f"integer too long (at most {MAX_INT_DIGITS} digits)",
                        filename=filename, source=source, line=line, column=col,
                        end_column=end) from None
    return WorldChecker(source, filename).world(data)


def _type_name(v: Any) -> str:
    return TOML_NAMES[kind(v)]


_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


class WorldChecker:
    """Checks a decoded world file; each error points at the offending key or
    value in the text (located by :class:`pccl.lang.tomlpos.TomlSource`)."""

    def __init__(self, source: str, filename: Optional[str]):
        self.source = source
        self.filename = filename
        self.toml = TomlSource(source)

    def error(self, message: str, table: Optional[str] = None,
              key: Optional[str] = None, index: int = 0, at_value=True,
              path: tuple = ()) -> NoReturn:
        """Raise a PcclError at ``key`` of ``[table]`` (its value when
        ``at_value``; the element at ``path``, a tuple of array indexes,
        inside the value)."""
        where = (self.toml.locate(table, key, index, at_value=at_value, path=path)
                 if key is not None else None)
        line, column, end = where if where is not None else (None, None, None)
        raise PcclError(message, filename=self.filename, source=self.source,
                        line=line, column=column, end_column=end)

    # -- checking ------------------------------------------------------
    def world(self, data: dict) -> World:
        for key in data:
            if key not in TOP_KEYS:
                self.error(f"unknown key '{key}' in world file; allowed keys: "
                           + ", ".join(sorted(TOP_KEYS)),
                           key=key, at_value=False)
        kw: dict = {}
        if "agents" in data:
            v = data["agents"]
            if not is_integer(v):
                self.error(f"'agents' must be an integer, got {_type_name(v)}",
                           key="agents")
            if v < 1:
                self.error(f"'agents' must be at least 1, got {v}", key="agents")
            if v > MAX_AGENTS:
                self.error(f"'agents' must be at most {MAX_AGENTS:,}, got {v:,}", key="agents")
            kw["n_agents"] = v
        for key in ("resolution", "radius", "mass", "speed", "tolerance",
                    "no_progress_time"):
            if key in data:
                kw[key] = self.positive(data[key], key)
        if "arena" in data:
            kw["arena"] = self.arena(data["arena"])
        if "start" in data:
            kw["starts"] = self.starts(data["start"])
        obstacles = self.obstacles(data.get("obstacles", []))
        kw["obstacles"] = obstacles
        functions = self.functions(data.get("functions", {}))
        functions.setdefault("getInput", ())
        functions.setdefault("getObs", obstacles)
        kw["functions"] = tuple(sorted(functions.items()))
        if kw.get("starts"):
            self.check_starts(kw["starts"], kw.get("arena"), obstacles,
                              kw.get("radius", World.radius))
        return World(filename=self.filename, **kw)

    def check_starts(self, starts: tuple, arena, obstacles: tuple, radius: float) -> None:
        """Each given start lies inside the arena, not inside an obstacle
        (its centre; a disc that touches one is allowed: a robot may start
        against a wall) and apart from the other starts (discs of
        ``radius`` that do not overlap): a robot cannot start where it
        could not stand."""
        for i, q in enumerate(starts):
            x, y = q[0], q[1]
            if arena is not None:
                (x0, y0), (x1, y1) = arena
                if not (x0 <= x <= x1 and y0 <= y <= y1):
                    self.error(f"'start' entry {i + 1} ({x:g}, {y:g}) lies outside the arena "
                               f"[[{x0:g}, {y0:g}], [{x1:g}, {y1:g}]]", key="start", path=(i,))
            for j in range(i):
                d = math.hypot(starts[j][0] - x, starts[j][1] - y)
                if d < 2 * radius - 1e-9:
                    self.error(f"'start' entry {i + 1} ({x:g}, {y:g}) overlaps entry {j + 1} "
                               f"({starts[j][0]:g}, {starts[j][1]:g}): centre distance {d:g} "
                               f"< 2 × radius {2 * radius:g}", key="start", path=(i,))
        geoms = _obstacle_geoms(obstacles)
        if geoms:
            import shapely
            for i, q in enumerate(starts):
                pt = shapely.Point(q[0], q[1])
                for k, g in enumerate(geoms):
                    if g.distance(pt) <= 1e-9:
                        self.error(f"'start' entry {i + 1} ({q[0]:g}, {q[1]:g}) lies inside "
                                   f"obstacle {k + 1}", key="start", path=(i,))

    def positive(self, v: Any, key: str) -> float:
        if not is_number(v):
            self.error(f"'{key}' must be a number, got {_type_name(v)}", key=key)
        if not math.isfinite(v):
            self.error(f"'{key}' must be a finite number, got {v}", key=key)
        if v <= 0:
            self.error(f"'{key}' must be positive, got {v}", key=key)
        return float(v)

    def point(self, v: Any, dims=(2,)) -> Optional[tuple]:
        if not isinstance(v, list) or len(v) not in dims:
            return None
        if not all(is_finite_number(c) for c in v):
            return None
        return tuple(float(c) for c in v)

    def in_range(self, q: tuple, what: str, table, key, index=0, path=()) -> None:
        """Coordinates must stay far from the float limit: positions are
        rounded to the resolution and moved by speed * δ."""
        if any(abs(c) > MAX_COORD for c in q):
            self.error(f"{what}: coordinates must be within ±{MAX_COORD:g}, got "
                       f"{', '.join(f'{c:g}' for c in q)}", table, key, index, path=path)

    def arena(self, v: Any) -> tuple:
        shape = "'arena' must be [[xmin, ymin], [xmax, ymax]]"
        if not isinstance(v, list) or len(v) != 2:
            self.error(shape, key="arena")
        lo, hi = self.point(v[0]), self.point(v[1])
        if lo is None or hi is None:
            self.error(shape + " (numbers)", key="arena")
        self.in_range(lo + hi, "'arena'", None, "arena")
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            self.error(shape + " with xmin < xmax and ymin < ymax", key="arena")
        return (lo, hi)

    def starts(self, v: Any) -> tuple:
        if not isinstance(v, list):
            self.error("'start' must be an array of positions [x, y] or "
                       f"[x, y, z], got {_type_name(v)}", key="start")
        out = []
        for i, p in enumerate(v):
            q = self.point(p, dims=(2, 3))
            if q is None:
                self.error(f"'start' entry {i + 1} must be [x, y] or [x, y, z] "
                           "(numbers)", key="start", path=(i,))
            self.in_range(q, f"'start' entry {i + 1}", None, "start", path=(i,))
            out.append(q if len(q) == 3 else (q[0], q[1], 0.0))
        return tuple(out)

    def polygon(self, v: Any, what: str, table: Optional[str], key: str,
                index: int = 0, path: tuple = ()) -> tuple:
        if not isinstance(v, list):
            self.error(f"{what} must be an array of points [[x, y], ...], got "
                       f"{_type_name(v)}", table, key, index, path=path)
        if len(v) < 3:
            self.error(f"{what} needs at least 3 points, got {len(v)}",
                       table, key, index, path=path)
        pts = []
        for i, p in enumerate(v):
            q = self.point(p, dims=(2, 3))
            if q is None:
                self.error(f"{what}: point {i + 1} must be [x, y] (numbers)",
                           table, key, index, path=path + (i,))
            self.in_range(q, f"{what}: point {i + 1}", table, key, index, path=path + (i,))
            pts.append((q[0], q[1]))
        import shapely
        poly = shapely.Polygon(pts)
        if not poly.is_valid:
            reason = shapely.is_valid_reason(poly)
            m = re.match(r"([A-Za-z -]+)\[([-\d.e]+) ([-\d.e]+)\]", reason)
            if m:
                reason = f"{m.group(1).lower()} at ({m.group(2)}, {m.group(3)})"
            self.error(f"{what} is not a valid polygon ({reason})",
                       table, key, index, path=path)
        if poly.area <= 0:
            self.error(f"{what} has zero area", table, key, index, path=path)
        return tuple(pts)

    def obstacles(self, v: Any) -> tuple:
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.error("'obstacles' must be an array of tables: write each "
                       "obstacle as [[obstacles]] with polygon = [[x, y], ...]",
                       key="obstacles")
        out = []
        for i, table in enumerate(v):
            for key in table:
                if key not in OBSTACLE_KEYS:
                    self.error(f"unknown key '{key}' in obstacle {i + 1}; "
                               "allowed keys: " + ", ".join(OBSTACLE_KEYS),
                               "obstacles", key, i, at_value=False)
            if "polygon" not in table:
                self.error(f"obstacle {i + 1} has no 'polygon'",
                           "obstacles", "polygon", i)
            out.append(self.polygon(table["polygon"],
                                    f"obstacle {i + 1}: 'polygon'",
                                    "obstacles", "polygon", i))
        return tuple(out)

    def functions(self, v: Any) -> dict:
        if not isinstance(v, dict):
            self.error("'functions' must be a table: write [functions] and "
                       "then name = value lines", key="functions")
        out = {}
        for name, value in v.items():
            if not _IDENT.match(name):
                self.error(f"function name '{name}' is not an identifier",
                           "functions", name, at_value=False)
            from pccl.lang.builtins import BUILTINS, UNINTERPRETED
            if name in BUILTINS and name not in UNINTERPRETED:
                self.error(f"function '{name}' shadows the built-in {name}(); "
                           "give the world's function another name",
                           "functions", name, at_value=False)
            if name == "getObs":
                if not isinstance(value, list):
                    self.error("'getObs' must be an array of polygons, got "
                               f"{_type_name(value)}", "functions", name)
                for i, poly in enumerate(value):
                    self.polygon(poly, f"'getObs' polygon {i + 1}",
                                 "functions", name, path=(i,))
            out[name] = self.value(value, name)
        return out

    def value(self, v: Any, name: str):
        if isinstance(v, list):
            return tuple(self.value(x, name) for x in v)
        if isinstance(v, float) and not math.isfinite(v):
            self.error(f"function '{name}': values must be finite numbers, got {v}",
                       "functions", name)
        if isinstance(v, (bool, int, float, str)):
            return v
        self.error(f"function '{name}': unsupported value of type "
                   f"{_type_name(v)} (use numbers, booleans, strings and arrays)",
                   "functions", name)


# ----------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------

def _snap(x: float, res: float) -> float:
    return round(round(x / res) * res, 12)


def _snap_up(x: float, res: float) -> float:
    return round(math.ceil(x / res - 1e-9) * res, 12)


def _obstacle_geoms(obstacles: tuple) -> list:
    if not obstacles:
        return []
    import shapely
    return [shapely.Polygon([(p[0], p[1]) for p in poly]) for poly in obstacles]


def function_location(world, name: str):
    """Where the world file gives ``name`` under ``[functions]``:
    ``(filename, source, line, column, end_column)``, or None (no file, or
    the function is not written there)."""
    fn = getattr(world, "filename", None)
    if not fn:
        return None
    try:
        with open(fn, encoding="utf-8") as f:
            source = f.read()
    except OSError:
        return None
    where = TomlSource(source).locate("functions", name)
    if where is None:
        return None
    return fn, source, where[0], where[1], where[2]
