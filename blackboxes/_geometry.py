"""Shared geometry for the shipped blackboxes: solid obstacle sets, prepared
once and cached (a blackbox's ``step`` runs millions of times in ``explore``),
and a visibility-graph planner that the pymunk blackbox steers with.

An obstacle is a polygon: a tuple of points whose first two coordinates are
``x`` and ``y``.  Three or more points make a polygon (an invalid one, e.g.
self-intersecting, is repaired with ``shapely.make_valid``); two points a
segment and one point a point: degenerate obstacles are still solid.
"""

from __future__ import annotations

import heapq
import math
from typing import Any, Optional


class _LazyShapely:
    """``shapely``, imported at its first use (a world with obstacles): a
    search of a world without them does not pay for the import at start-up."""

    def __getattr__(self, name: str) -> Any:
        import shapely as real
        globals()["shapely"] = real
        return getattr(real, name)


shapely: Any = _LazyShapely()

_CACHE_LIMIT = 256          # obstacle sets kept
_RESULT_CACHE_LIMIT = 200_000   # per-set memoised segment/point/path queries


def _norm_polygon(poly) -> tuple:
    return tuple((float(p[0]), float(p[1])) for p in poly)


def _geometry(pts: tuple):
    if len(pts) >= 3:
        g = shapely.Polygon(pts)
        if not g.is_valid:
            g = shapely.make_valid(g)
        return g
    if len(pts) == 2:
        return shapely.LineString(pts)
    if len(pts) == 1:
        return shapely.Point(pts[0])
    return None


class Obstacles:
    """A set of solid obstacles with fast, memoised point and segment tests."""

    def __init__(self, polygons: tuple):
        self.polygons = polygons                       # normalised, deduplicated
        geoms = [g for g in (_geometry(p) for p in polygons)
                 if g is not None and not g.is_empty]
        self.empty = not geoms
        self.union = shapely.union_all(geoms) if geoms else None
        if self.union is not None:
            shapely.prepare(self.union)
            self.bounds = self.union.bounds
        else:
            self.bounds = (math.inf, math.inf, -math.inf, -math.inf)
        self._points: dict = {}
        self._segments: dict = {}
        self._near: dict = {}
        self._roadmaps: dict = {}
        self._pymunk_parts: Optional[tuple] = None

    # -- queries ---------------------------------------------------------
    def contains_point(self, x: float, y: float) -> bool:
        """True if (x, y) lies inside an obstacle or on its boundary."""
        if self.empty:
            return False
        b = self.bounds
        if x < b[0] or x > b[2] or y < b[1] or y > b[3]:
            return False
        key = (x, y)
        hit = self._points.get(key)
        if hit is None:
            hit = bool(shapely.intersects_xy(self.union, x, y))
            if len(self._points) >= _RESULT_CACHE_LIMIT:
                self._points.clear()
            self._points[key] = hit
        return hit

    def blocks_segment(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """True if the closed segment (x0, y0)-(x1, y1) touches an obstacle."""
        if self.empty:
            return False
        b = self.bounds
        if (max(x0, x1) < b[0] or min(x0, x1) > b[2]
                or max(y0, y1) < b[1] or min(y0, y1) > b[3]):
            return False
        key = (x0, y0, x1, y1)
        hit = self._segments.get(key)
        if hit is None:
            if x0 == x1 and y0 == y1:
                hit = bool(shapely.intersects_xy(self.union, x0, y0))
            else:
                seg = shapely.LineString(((x0, y0), (x1, y1)))
                hit = bool(self.union.intersects(seg))  # type: ignore[union-attr]
            if len(self._segments) >= _RESULT_CACHE_LIMIT:
                self._segments.clear()
            self._segments[key] = hit
        return hit

    def near_segment(self, x0: float, y0: float, x1: float, y1: float,
                     clearance: float) -> bool:
        """True if the closed segment (x0, y0)-(x1, y1) comes closer than
        ``clearance`` to an obstacle (touching it included)."""
        if self.empty:
            return False
        b = self.bounds
        c = clearance
        if (max(x0, x1) < b[0] - c or min(x0, x1) > b[2] + c
                or max(y0, y1) < b[1] - c or min(y0, y1) > b[3] + c):
            return False
        key = (x0, y0, x1, y1, c)
        hit = self._near.get(key)
        if hit is None:
            g = (shapely.Point(x0, y0) if x0 == x1 and y0 == y1
                 else shapely.LineString(((x0, y0), (x1, y1))))
            hit = bool(shapely.distance(self.union, g) < c)
            if len(self._near) >= _RESULT_CACHE_LIMIT:
                self._near.clear()
            self._near[key] = hit
        return hit

    def near_points(self, points: tuple, clearance: float) -> bool:
        """True if the convex hull of ``points`` (``(x, y)`` pairs, at least
        one) comes closer than ``clearance`` to an obstacle (touching it
        included)."""
        if self.empty:
            return False
        if len(points) <= 2:
            a, b = points[0], points[-1]
            return self.near_segment(float(a[0]), float(a[1]), float(b[0]), float(b[1]),
                                     clearance)
        b = self.bounds
        c = clearance
        xs = [float(q[0]) for q in points]
        ys = [float(q[1]) for q in points]
        if (max(xs) < b[0] - c or min(xs) > b[2] + c
                or max(ys) < b[1] - c or min(ys) > b[3] + c):
            return False
        key = (tuple(points), c)
        hit = self._near.get(key)
        if hit is None:
            g = shapely.MultiPoint([(x, y) for x, y in zip(xs, ys)]).convex_hull
            hit = bool(shapely.distance(self.union, g) < c)
            if len(self._near) >= _RESULT_CACHE_LIMIT:
                self._near.clear()
            self._near[key] = hit
        return hit

    def roadmap(self, radius: float) -> "Roadmap":
        rm = self._roadmaps.get(radius)
        if rm is None:
            rm = self._roadmaps[radius] = Roadmap(self, radius)
        return rm

    def pymunk_parts(self) -> tuple:
        """(convex vertex lists, segments): the obstacles as pymunk-ready
        convex pieces (non-convex polygons are triangulated)."""
        if self._pymunk_parts is None:
            convex: list = []
            segments: list = []
            if self.union is not None:
                for g in shapely.get_parts(self.union):
                    _pieces(g, convex, segments)
            self._pymunk_parts = (tuple(convex), tuple(segments))
        return self._pymunk_parts


def _pieces(g, convex: list, segments: list) -> None:
    kind = g.geom_type
    if kind == "Polygon":
        if g.is_empty or g.area <= 0:
            return
        hull = g.convex_hull
        if not g.interiors and hull.area - g.area <= 1e-9 * max(1.0, hull.area):
            convex.append(tuple(g.exterior.coords)[:-1])
        else:
            for tri in shapely.get_parts(shapely.constrained_delaunay_triangles(g)):
                if tri.area > 0:
                    convex.append(tuple(tri.exterior.coords)[:-1])
    elif kind in ("LineString", "LinearRing"):
        cs = list(g.coords)
        segments.extend(zip(cs, cs[1:]))
    elif kind == "Point":
        segments.append(((g.x, g.y), (g.x, g.y)))
    else:  # collections
        for part in shapely.get_parts(g):
            _pieces(part, convex, segments)


EMPTY = Obstacles(())
_cache: dict = {}
_id_cache: dict = {}


def obstacles_of(*parts) -> Obstacles:
    """The :class:`Obstacles` made of the union of ``parts`` (each a tuple of
    polygons), cached by value (and by identity, for speed)."""
    if not any(parts):
        return EMPTY
    ids = tuple(map(id, parts))
    hit = _id_cache.get(ids)
    if hit is not None and all(a is b for a, b in zip(hit[0], parts)):
        return hit[1]
    try:
        key = tuple(parts)
        hash(key)
    except TypeError:
        key = tuple(tuple(_norm_polygon(p) for p in part) for part in parts)
    obs = _cache.get(key)
    if obs is None:
        seen: dict = {}
        for part in parts:
            for poly in part:
                seen.setdefault(_norm_polygon(poly), None)
        obs = Obstacles(tuple(seen))
        if len(_cache) >= _CACHE_LIMIT:
            _cache.clear()
        _cache[key] = obs
    if len(_id_cache) >= _CACHE_LIMIT:
        _id_cache.clear()
    _id_cache[ids] = (parts, obs)          # holds the parts: ids stay unique
    return obs


def segment_distance(a, b, c, d) -> float:
    """The distance between the closed segments a-b and c-d (points are
    ``(x, y, ...)``; only x and y count)."""
    ax, ay, bx, by = float(a[0]), float(a[1]), float(b[0]), float(b[1])
    cx, cy, dx, dy = float(c[0]), float(c[1]), float(d[0]), float(d[1])
    if _segments_cross(ax, ay, bx, by, cx, cy, dx, dy):
        return 0.0
    return min(_point_segment(ax, ay, cx, cy, dx, dy),
               _point_segment(bx, by, cx, cy, dx, dy),
               _point_segment(cx, cy, ax, ay, bx, by),
               _point_segment(dx, dy, ax, ay, bx, by))


def convex_hull(points) -> tuple:
    """The vertices of the convex hull of ``points`` (``(x, y, ...)``; only x
    and y count) as a canonical tuple of ``(x, y)`` float pairs: sorted,
    collinear points dropped (Andrew's monotone chain).  One point for
    equal points, two for collinear ones."""
    pts = sorted({(float(q[0]) + 0.0, float(q[1]) + 0.0) for q in points})
    if len(pts) <= 2:
        return tuple(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower: list = []
    for q in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    upper: list = []
    for q in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    return tuple(sorted(set(lower[:-1] + upper[:-1])))


def hull_diameter(points) -> float:
    """The largest distance between two of ``points``."""
    return max((math.hypot(a[0] - b[0], a[1] - b[1]) for a in points for b in points),
               default=0.0)


def hulls_distance(a: tuple, b: tuple) -> float:
    """The distance between the convex hulls of the point tuples ``a`` and
    ``b`` (0 when they meet)."""
    if len(a) <= 2 and len(b) <= 2:
        return segment_distance(a[0], a[-1], b[0], b[-1])
    ga = shapely.MultiPoint(list(a)).convex_hull
    gb = shapely.MultiPoint(list(b)).convex_hull
    return float(shapely.distance(ga, gb))


def _point_segment(px, py, ax, ay, bx, by) -> float:
    ux, uy = bx - ax, by - ay
    L2 = ux * ux + uy * uy
    if L2 == 0.0:
        return math.hypot(px - ax, py - ay)
    k = max(0.0, min(1.0, ((px - ax) * ux + (py - ay) * uy) / L2))
    return math.hypot(px - (ax + k * ux), py - (ay + k * uy))


def _segments_cross(ax, ay, bx, by, cx, cy, dx, dy) -> bool:
    """Proper or improper intersection of two segments (collinear overlaps
    are found by the point–segment distances, which are then 0)."""
    def orient(px, py, qx, qy, rx, ry):
        return (qx - px) * (ry - py) - (qy - py) * (rx - px)
    d1 = orient(cx, cy, dx, dy, ax, ay)
    d2 = orient(cx, cy, dx, dy, bx, by)
    d3 = orient(ax, ay, bx, by, cx, cy)
    d4 = orient(ax, ay, bx, by, dx, dy)
    return ((d1 > 0 > d2 or d1 < 0 < d2) and (d3 > 0 > d4 or d3 < 0 < d4))


# ----------------------------------------------------------------------
# Visibility-graph planning for disc robots
# ----------------------------------------------------------------------

INNER = 0.95   # segments may not enter the obstacles inflated by INNER * r
OUTER = 1.2    # waypoints: corners of the obstacles inflated by OUTER * r


class Roadmap:
    """Shortest paths for a disc of radius ``r`` among an obstacle set.

    Waypoints are the corners of the obstacles inflated (mitred) by
    ``OUTER * r``; a straight leg is free if it does not touch the obstacles
    inflated by ``INNER * r``.  The path from ``p`` to ``t`` is the shortest
    one in the visibility graph over ``p``, the waypoints and ``t``
    (Dijkstra, ties broken by waypoint order, so it is deterministic).  An
    end point that is itself inside the inner inflation (a robot pressed
    into an obstacle, a target closer than ``r`` to one) is exempt within
    ``r`` of itself, so that it can still leave or approach the obstacle.
    If no path exists the path is the straight line (the robot will push
    against the obstacle and fail for lack of progress).
    """

    def __init__(self, obstacles: Obstacles, radius: float):
        self.radius = r = radius
        u = obstacles.union
        assert u is not None, "a roadmap is built only around obstacles"
        inner = u.buffer(INNER * r, join_style="mitre")
        outer = u.buffer(OUTER * r, join_style="mitre")
        shapely.prepare(inner)
        self.inner = inner
        self.ibounds = inner.bounds
        verts: dict = {}
        for poly in shapely.get_parts(outer):
            for ring in [poly.exterior, *poly.interiors]:
                for c in list(ring.coords)[:-1]:
                    verts.setdefault((round(c[0], 9), round(c[1], 9)), None)
        self.verts = list(verts)
        n = len(self.verts)
        self.adj: list[list] = [[] for _ in range(n)]
        for i in range(n):
            a = self.verts[i]
            for j in range(i + 1, n):
                b = self.verts[j]
                if not self._blocked(a, b, False, False):
                    d = math.hypot(a[0] - b[0], a[1] - b[1])
                    self.adj[i].append((j, d))
                    self.adj[j].append((i, d))
        self._vis: dict = {}
        self._paths: dict = {}

    def _inside(self, p) -> bool:
        b = self.ibounds
        if p[0] < b[0] or p[0] > b[2] or p[1] < b[1] or p[1] > b[3]:
            return False
        return bool(shapely.intersects_xy(self.inner, p[0], p[1]))

    def _blocked(self, a, b, clip_a: bool, clip_b: bool) -> bool:
        ax, ay = a
        bx, by = b
        L = math.hypot(bx - ax, by - ay)
        if clip_a or clip_b:
            r = self.radius
            if L <= r * (clip_a + clip_b):
                return False
            ux, uy = (bx - ax) / L, (by - ay) / L
            if clip_a:
                ax, ay = ax + r * ux, ay + r * uy
            if clip_b:
                bx, by = bx - r * ux, by - r * uy
        bb = self.ibounds
        if (max(ax, bx) < bb[0] or min(ax, bx) > bb[2]
                or max(ay, by) < bb[1] or min(ay, by) > bb[3]):
            return False
        if ax == bx and ay == by:
            return bool(shapely.intersects_xy(self.inner, ax, ay))
        return bool(self.inner.intersects(shapely.LineString(((ax, ay), (bx, by)))))

    def _visible(self, p, clip: bool) -> list:
        key = (p, clip)
        vis = self._vis.get(key)
        if vis is None:
            vis = []
            for i, v in enumerate(self.verts):
                if not self._blocked(p, v, clip, False):
                    vis.append((i, math.hypot(p[0] - v[0], p[1] - v[1])))
            if len(self._vis) >= _RESULT_CACHE_LIMIT:
                self._vis.clear()
            self._vis[key] = vis
        return vis

    def path(self, p, t) -> tuple:
        """``(waypoints, length)``: the legs to follow from ``p`` (excluded)
        to ``t`` (included, last) and the path's length."""
        key = (p, t)
        hit = self._paths.get(key)
        if hit is None:
            hit = self._plan(p, t)
            if len(self._paths) >= _RESULT_CACHE_LIMIT:
                self._paths.clear()
            self._paths[key] = hit
        return hit

    def _plan(self, p, t) -> tuple:
        direct = math.hypot(t[0] - p[0], t[1] - p[1])
        clip_p, clip_t = self._inside(p), self._inside(t)
        if not self._blocked(p, t, clip_p, clip_t):
            return ((t,), direct)
        n = len(self.verts)
        target_in = {i: d for i, d in self._visible(t, clip_t)}
        if not target_in:
            return ((t,), direct)
        dist = [math.inf] * n
        prev: list = [None] * n
        heap = []
        for i, d in self._visible(p, clip_p):
            dist[i] = d
            heap.append((d, i))
        heapq.heapify(heap)
        best, best_last = math.inf, None
        while heap:
            d, i = heapq.heappop(heap)
            if d > dist[i] or d >= best:
                continue
            if i in target_in and d + target_in[i] < best:
                best, best_last = d + target_in[i], i
            for j, w in self.adj[i]:
                nd = d + w
                if nd < dist[j]:
                    dist[j], prev[j] = nd, i
                    heapq.heappush(heap, (nd, j))
        if best_last is None:
            return ((t,), direct)
        legs = [t]
        v: Optional[int] = best_last
        while v is not None:
            legs.append(self.verts[v])
            v = prev[v]
        legs.reverse()
        return (tuple(legs), best)
