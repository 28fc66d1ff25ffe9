"""Collision checking (``--collisions``, docs/blackboxes.md).

A robot's *footprint* is the disc of ``world.radius`` around its position,
in the plane (x, y; z is ignored: obstacles are vertical prisms and the
shipped blackboxes are planar).  A configuration has a collision when

* two footprints overlap: centre distance ``< 2 * radius - EPS``.  Robots
  that merely touch (distance exactly ``2 * radius``) do not collide;
* a footprint overlaps a world obstacle polygon (``world.obstacles``): the
  distance from the centre to the polygon (0 inside it) is
  ``< radius - EPS``.  Touching the boundary is not a collision.

Every robot takes part, whatever its status: an exited or stuck robot still
occupies space.  The obstacles an agent passes to ``doReach`` are not
checked here: they are the program's view of the world, the world file's
``[[obstacles]]`` are what is solid.

:func:`collisions` returns one message per colliding pair and per (agent,
obstacle) overlap, in a deterministic order: agent pairs by (i, j), then
agent/obstacle overlaps by (agent, obstacle).  Obstacles are numbered from
1, in the order of the world file's ``[[obstacles]]`` tables (as the world
file's own error messages number them).  :func:`contacts` gives the same
information as structured records (the plotter uses it to ring the robots).

Speed: the engine calls :func:`collisions` once per distinct position tuple
(it caches by positions).  Agent pairs are a pure-Python distance test with
a bounding-box pre-check; obstacle tests first reject by the obstacle's
bounding box grown by the radius, then ask a prepared shapely polygon.  The
prepared geometries are built once per world (cached by identity, then by
value).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

EPS = 1e-9

_CACHE_LIMIT = 64


@dataclass(frozen=True)
class Contact:
    """One collision: two agents (``obstacle is None``) or an agent and an
    obstacle (``j is None``, ``obstacle`` = 1-based index)."""
    i: int
    j: Optional[int]
    obstacle: Optional[int]
    pos_i: tuple
    pos_j: Optional[tuple]
    distance: float            # centre distance (pairs) or centre-to-polygon distance
    message: str


class _Geometry:
    """A world's obstacles, prepared for fast disc-overlap tests."""

    __slots__ = ("radius", "items")

    def __init__(self, world):
        import shapely
        self.radius = float(world.radius)
        r = self.radius
        items = []
        for k, poly in enumerate(world.obstacles or ()):
            pts = [(float(p[0]), float(p[1])) for p in poly]
            if len(pts) >= 3:
                g = shapely.Polygon(pts)
                if not g.is_valid:
                    g = shapely.make_valid(g)
            elif len(pts) == 2:
                g = shapely.LineString(pts)
            elif len(pts) == 1:
                g = shapely.Point(pts[0])
            else:
                continue
            if g.is_empty:
                continue
            shapely.prepare(g)
            x0, y0, x1, y1 = g.bounds
            items.append((k + 1, g, (x0 - r, y0 - r, x1 + r, y1 + r)))
        self.items = tuple(items)


_by_id: dict = {}
_by_value: dict = {}


def _geometry(world) -> _Geometry:
    hit = _by_id.get(id(world))
    if hit is not None and hit[0] is world:
        return hit[1]
    key = (float(world.radius), tuple(world.obstacles or ()))
    geo = _by_value.get(key)
    if geo is None:
        geo = _Geometry(world)
        if len(_by_value) >= _CACHE_LIMIT:
            _by_value.clear()
        _by_value[key] = geo
    if len(_by_id) >= _CACHE_LIMIT:
        _by_id.clear()
    _by_id[id(world)] = (world, geo)      # holds the world: its id stays unique
    return geo


def fmt_xy(p) -> str:
    """``(x, y)`` with at most 6 significant decimals, trailing zeros cut."""
    return f"({_num(p[0])}, {_num(p[1])})"


def _num(x) -> str:
    x = float(x)
    if x == 0:
        return "0"
    s = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def contacts(world, positions) -> list[Contact]:
    """Every collision in ``positions`` (one ``(x, y[, z])`` per agent), as
    :class:`Contact` records in deterministic order."""
    geo = _geometry(world)
    r = geo.radius
    lim = 2.0 * r - EPS
    out: list[Contact] = []
    pts = [(float(p[0]), float(p[1])) for p in positions]
    n = len(pts)
    for i in range(n):
        xi, yi = pts[i]
        for j in range(i + 1, n):
            xj, yj = pts[j]
            dx, dy = xj - xi, yj - yi
            if dx >= lim or -dx >= lim or dy >= lim or -dy >= lim:
                continue
            d = math.hypot(dx, dy)
            if d < lim:
                out.append(Contact(
                    i, j, None, pts[i], pts[j], d,
                    f"collision: agent {i} at {fmt_xy(pts[i])} and agent {j} at "
                    f"{fmt_xy(pts[j])} overlap (centre distance {_num(d)} < "
                    f"2 × radius {_num(2 * r)})"))
    if geo.items:
        import shapely
        rlim = r - EPS
        for i in range(n):
            x, y = pts[i]
            for k, g, (bx0, by0, bx1, by1) in geo.items:
                if x <= bx0 or x >= bx1 or y <= by0 or y >= by1:
                    continue
                if shapely.intersects_xy(g, x, y):
                    d = 0.0
                else:
                    d = g.distance(shapely.Point(x, y))
                    if not d < rlim:
                        continue
                where = "inside" if d == 0.0 else f"{_num(d)} from it, radius {_num(r)}"
                out.append(Contact(
                    i, None, k, pts[i], None, d,
                    f"collision: agent {i} at {fmt_xy(pts[i])} overlaps obstacle {k} "
                    f"({where})"))
    return out


def collisions(world, positions) -> list[str]:
    """One message per overlapping pair of robot footprints and per robot
    footprint overlapping a world obstacle (see the module docstring);
    empty when the configuration is collision-free."""
    return [c.message for c in contacts(world, positions)]
