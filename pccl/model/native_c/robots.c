/* pccl's native engine: the shipped blackboxes' outcomes (instant,
   straight, nondet, nondet-fail) computed in C at a memo miss of DOREACH
   INVOKE, so that a program that moves runs on the level kernel's threads
   without calling Python (issue 43 item 2).  Included by a generated
   module after memo.c (whose memo_site calls robots_fill at a miss of the
   env site) and before module.c (whose method table takes ROBOTS_METHODS).

   Python stays the reference (the blackboxes' .py files, environment.py):
   each outcome here is the one the Python blackbox gives, the positions
   rounded as Environment.round_pos rounds them, bit for bit.  What cannot
   be reproduced exactly is left to Python: robots_fill returns NULL with
   ROBOTS_PY set and the miss goes on the Python path (NativeModel._miss).
   Those cases:
     - obstacles (the world's or a doReach's): shapely (GEOS) decides there;
     - nondet's distance between two regions of three or more corners
       (shapely's distance of convex hulls);
     - a distance whose comparison with its bound the float rounding of
       math.hypot could decide either way: math.hypot (CPython's own
       algorithm) and libm's hypot are both within one unit in the last
       place of the exact value, so a distance within ULPS units of the
       bound goes to Python; likewise a straight step whose rounded end
       could differ between the two (also every straight step that is not
       rounded: a world of resolution 0);
     - a value that is not a plain tuple or list of ints and floats (a long
       int, a bool coordinate), more than ROBOTS_KMAX outcomes.

   The interned values (NativeModel.intern: positions, targets, obstacle
   lists, leg starts, ...) are numbered here when the model's ids are
   numbered in discovery order: a value is known by its marshal encoding
   (version 2, as NativeModel.intern's table), Python numbers the values it
   meets through vintern(), and the blackbox here numbers the positions and
   leg starts it makes under the same lock; Python reads those back
   (vvalue()) when it decodes a state that holds one.  */
#include <math.h>
#include <pthread.h>

/* -- the interned values: id -> marshal encoding, encoding -> id ----------- */
typedef struct { size_t off; uint32_t len; int used; } VEnt;
static VEnt *VE;
static size_t VN, VCAP;                  /* ids 0 .. VN-1 (a hole: used = 0) */
static unsigned char *VB;
static size_t VBN, VBCAP;                /* the encodings, back to back */
static size_t *VSLOT, VSCAP, VCOUNT;     /* open addressing: id + 1, 0 empty */
static pthread_mutex_t VLOCK = PTHREAD_MUTEX_INITIALIZER;

static uint64_t vhash(const unsigned char *k, size_t n) {
  uint64_t h = 0xCBF29CE484222325ULL ^ n;
  for (size_t q = 0; q < n; q++) { h ^= k[q]; h *= 0x100000001B3ULL; }
  h ^= h >> 29; h *= 0xBF58476D1CE4E5B9ULL; h ^= h >> 32;
  return h;
}
static void vclear(void) {
  pthread_mutex_lock(&VLOCK);
  free(VE); free(VB); free(VSLOT);
  VE = NULL; VB = NULL; VSLOT = NULL;
  VN = VCAP = VBN = VBCAP = VSCAP = VCOUNT = 0;
  pthread_mutex_unlock(&VLOCK);
}
/* (VLOCK held) the id of encoding k, or -1 */
static int64_t vfind(const unsigned char *k, size_t n) {
  if (!VSCAP) return -1;
  size_t sl = vhash(k, n) & (VSCAP - 1);
  for (;;) {
    size_t o = VSLOT[sl];
    if (!o) return -1;
    const VEnt *e = VE + (o - 1);
    if (e->len == n && !memcmp(VB + e->off, k, n)) return (int64_t)(o - 1);
    sl = (sl + 1) & (VSCAP - 1);
  }
}
static int vrehash(void) {
  size_t cap = VSCAP ? 2 * VSCAP : 1024;
  size_t *t = calloc(cap, sizeof(size_t));
  if (!t) return -1;
  for (size_t i = 0; i < VN; i++) {
    if (!VE[i].used) continue;
    size_t sl = vhash(VB + VE[i].off, VE[i].len) & (cap - 1);
    while (t[sl]) sl = (sl + 1) & (cap - 1);
    t[sl] = i + 1;
  }
  free(VSLOT); VSLOT = t; VSCAP = cap;
  return 0;
}
/* (VLOCK held) encoding k as id i (i >= VN: new; holes below it); -1 on no memory */
static int vadd(size_t i, const unsigned char *k, size_t n) {
  if (2 * (VCOUNT + 1) > VSCAP && vrehash()) return -1;
  if (i >= VCAP) {
    size_t cap = VCAP ? 2 * VCAP : 1024;
    while (cap <= i) cap *= 2;
    VEnt *e = realloc(VE, sizeof(VEnt) * cap);
    if (!e) return -1;
    VE = e; VCAP = cap;
  }
  if (VBN + n > VBCAP) {
    size_t cap = VBCAP ? 2 * VBCAP : 65536;
    while (cap < VBN + n) cap *= 2;
    unsigned char *b = realloc(VB, cap);
    if (!b) return -1;
    VB = b; VBCAP = cap;
  }
  for (size_t q = VN; q < i; q++) VE[q].used = 0;
  if (i >= VN) VN = i + 1;
  memcpy(VB + VBN, k, n);
  VE[i].off = VBN; VE[i].len = (uint32_t)n; VE[i].used = 1;
  VBN += n;
  size_t sl = vhash(k, n) & (VSCAP - 1);
  while (VSLOT[sl]) sl = (sl + 1) & (VSCAP - 1);
  VSLOT[sl] = i + 1;
  VCOUNT++;
  return 0;
}
/* the id of encoding k, numbered next when new; -1 on no memory */
static int64_t vintern_c(const unsigned char *k, size_t n) {
  pthread_mutex_lock(&VLOCK);
  int64_t i = vfind(k, n);
  if (i < 0 && !vadd(VN, k, n)) i = (int64_t)(VN - 1);
  pthread_mutex_unlock(&VLOCK);
  return i;
}
/* a copy of id i's encoding into buf (at most cap bytes): its length, -1 if
   there is no such id, -2 if it is longer than cap */
static long vget(int64_t i, unsigned char *buf, size_t cap) {
  long r = -1;
  pthread_mutex_lock(&VLOCK);
  if (i >= 0 && (size_t)i < VN && VE[i].used) {
    if (VE[i].len > cap) r = -2;
    else { memcpy(buf, VB + VE[i].off, VE[i].len); r = (long)VE[i].len; }
  }
  pthread_mutex_unlock(&VLOCK);
  return r;
}

/* -- marshal (version 2): the few shapes a position, a target, a leg start
   or an empty obstacle list takes -------------------------------------- */
#define ROBOTS_ENC 4096                  /* the longest encoding read */
#define ROBOTS_PTS 64                    /* the most points of a leg start */
static uint32_t rd32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
/* one number at p (int 'i' or float 'g'): its value in *x and the bytes
   read, 0 when it is something else */
static int rnum(const unsigned char *p, const unsigned char *end, double *x) {
  if (p < end && *p == 'g' && end - p >= 9) { memcpy(x, p + 1, 8); return 9; }
  if (p < end && *p == 'i' && end - p >= 5) { *x = (double)(int32_t)rd32(p + 1); return 5; }
  return 0;
}
/* a tuple or list ('(' or '[') of numbers at p: their count (at most max) in
   *n, the bytes read; 0 when it is something else */
static int rvec(const unsigned char *p, const unsigned char *end, double *x, int max, int *n) {
  if (end - p < 5 || (*p != '(' && *p != '[')) return 0;
  uint32_t c = rd32(p + 1);
  if (c > (uint32_t)max) return 0;
  const unsigned char *q = p + 5;
  for (uint32_t k = 0; k < c; k++) {
    int r = rnum(q, end, x + k);
    if (!r) return 0;
    q += r;
  }
  *n = (int)c;
  return (int)(q - p);
}
/* a position (2 or 3 numbers, finite, as Environment's outcome check
   wants them): 1, else 0 */
static int rpos(const unsigned char *p, long len, double *x, int *n) {
  const unsigned char *end = p + len;
  int r = rvec(p, end, x, 3, n);
  if (!r || p + r != end || *n < 2) return 0;
  for (int k = 0; k < *n; k++) if (!isfinite(x[k])) return 0;
  return 1;
}
/* a target: None (*none = 1) or a position-like tuple (at least x and y) */
static int rtarget(const unsigned char *p, long len, double *x, int *n, int *none) {
  *none = len == 1 && p[0] == 'N';
  if (*none) return 1;
  const unsigned char *end = p + len;
  double y[8];
  int r = rvec(p, end, y, 8, n);
  if (!r || p + r != end || *n < 2) return 0;
  for (int k = 0; k < 2; k++) { if (!isfinite(y[k])) return 0; x[k] = y[k]; }
  return 1;
}
/* a leg start: a tuple of points (each a tuple of at least x and y) */
static int rstart(const unsigned char *p, long len, double (*pt)[2], int *n) {
  const unsigned char *end = p + len;
  if (len < 5 || *p != '(') return 0;
  uint32_t c = rd32(p + 1);
  if (c > ROBOTS_PTS) return 0;
  const unsigned char *q = p + 5;
  for (uint32_t k = 0; k < c; k++) {
    double y[8]; int m;
    int r = rvec(q, end, y, 8, &m);
    if (!r || m < 2 || !isfinite(y[0]) || !isfinite(y[1])) return 0;
    pt[k][0] = y[0]; pt[k][1] = y[1];
    q += r;
  }
  *n = (int)c;
  return q == end;
}
/* an empty obstacle cell (None, () or []): what obstacles_of leaves out */
static int rnoobs(const unsigned char *p, long len) {
  return (len == 1 && p[0] == 'N') || (len == 5 && (p[0] == '(' || p[0] == '[') && !rd32(p + 1));
}
static void wr32(unsigned char *p, uint32_t v) {
  p[0] = (unsigned char)v; p[1] = (unsigned char)(v >> 8);
  p[2] = (unsigned char)(v >> 16); p[3] = (unsigned char)(v >> 24);
}
/* the id of the position (x, y, z) (a tuple of three floats) */
static int64_t vpos(const double *x) {
  unsigned char b[32];
  b[0] = '('; wr32(b + 1, 3);
  for (int k = 0; k < 3; k++) { b[5 + 9 * k] = 'g'; memcpy(b + 6 + 9 * k, x + k, 8); }
  return vintern_c(b, 32);
}
/* the id of a leg start: a tuple of (x, y) float pairs */
static int64_t vstart(const double (*pt)[2], int n) {
  unsigned char b[5 + ROBOTS_PTS * 23];
  b[0] = '('; wr32(b + 1, (uint32_t)n);
  unsigned char *q = b + 5;
  for (int k = 0; k < n; k++) {
    q[0] = '('; wr32(q + 1, 2);
    q[5] = 'g'; memcpy(q + 6, &pt[k][0], 8);
    q[14] = 'g'; memcpy(q + 15, &pt[k][1], 8);
    q += 23;
  }
  return vintern_c(b, (size_t)(q - b));
}

/* -- the world and the blackbox (robots_setup) ---------------------------- */
enum { BB_OFF, BB_INSTANT, BB_STRAIGHT, BB_NONDET, BB_NONDET_FAIL };
#define ROBOTS_KMAX 729                  /* outcomes (3^6): labels made ahead */
#define ROBOTS_ULPS 4                    /* hypot's units in the last place */
static int RB_KIND, RB_SITE = -1, RB_AG0, RB_AW, RB_MV, RB_ENVS;
static double RB_RES, RB_SPEED, RB_DELTA, RB_RADIUS, RB_TOL;
static int RB_LAB[ROBOTS_KMAX];
static int RB_NLAB;
/* outcomes made in C, misses left to Python (ROBOTS_PY set) */
static size_t RB_FILLS, RB_PYTHON;
static __thread int ROBOTS_PY;

/* Environment.round_pos of one coordinate: round(round(c / res) * res, 9)
   + 0.0 (Python's round: half to even, as rint; round(x, 9): the decimal
   string of x correctly rounded to 9 places, read back, as printf and
   strtod do); 0 when it cannot be done exactly here */
static int round_coord(double c, double *out) {
  if (!(RB_RES > 0)) { *out = c + 0.0; return 1; }
  double q = c / RB_RES;
  if (!isfinite(q) || fabs(q) >= 4503599627370496.0) return 0;   /* 2^52 */
  double r = rint(q) * RB_RES;
  char buf[512];
  int n = snprintf(buf, sizeof buf, "%.9f", r);
  if (n <= 0 || n >= (int)sizeof buf) return 0;
  *out = strtod(buf, NULL) + 0.0;
  return 1;
}
/* the rounded position (x, y, z) of a blackbox's (2 or 3 numbers) */
static int round_pos3(const double *p, int n, double *out) {
  for (int k = 0; k < 3; k++)
    if (!round_coord(k < n ? p[k] : 0.0, out + k)) return 0;
  if (n == 2) out[2] = 0.0;        /* (round_pos pads the rounded pair) */
  return 1;
}

/* -- nondet's geometry (blackboxes/_geometry.py) ------------------------- */
static int cmp_pt(const void *a, const void *b) {
  const double *x = a, *y = b;
  if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
  if (x[1] != y[1]) return x[1] < y[1] ? -1 : 1;
  return 0;
}
static double cross3(const double *o, const double *a, const double *b) {
  return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}
/* convex_hull: the sorted distinct points (x + 0.0, y + 0.0), collinear
   ones dropped (Andrew's monotone chain), sorted; the count */
static int hull(double (*pt)[2], int n, double (*out)[2]) {
  for (int k = 0; k < n; k++) { pt[k][0] += 0.0; pt[k][1] += 0.0; }
  qsort(pt, (size_t)n, sizeof pt[0], cmp_pt);
  int m = 0;
  for (int k = 0; k < n; k++)
    if (!m || cmp_pt(pt[k], pt[m - 1])) { pt[m][0] = pt[k][0]; pt[m][1] = pt[k][1]; m++; }
  if (m <= 2) {
    for (int k = 0; k < m; k++) { out[k][0] = pt[k][0]; out[k][1] = pt[k][1]; }
    return m;
  }
  double lower[ROBOTS_PTS + 2][2], upper[ROBOTS_PTS + 2][2], ch[2 * ROBOTS_PTS + 4][2];
  int lo = 0, up = 0, c = 0;
  for (int k = 0; k < m; k++) {
    while (lo >= 2 && cross3(lower[lo - 2], lower[lo - 1], pt[k]) <= 0) lo--;
    lower[lo][0] = pt[k][0]; lower[lo][1] = pt[k][1]; lo++;
  }
  for (int k = m - 1; k >= 0; k--) {
    while (up >= 2 && cross3(upper[up - 2], upper[up - 1], pt[k]) <= 0) up--;
    upper[up][0] = pt[k][0]; upper[up][1] = pt[k][1]; up++;
  }
  /* sorted(set(lower[:-1] + upper[:-1])) */
  for (int k = 0; k < lo - 1; k++) { ch[c][0] = lower[k][0]; ch[c][1] = lower[k][1]; c++; }
  for (int k = 0; k < up - 1; k++) { ch[c][0] = upper[k][0]; ch[c][1] = upper[k][1]; c++; }
  qsort(ch, (size_t)c, sizeof ch[0], cmp_pt);
  int w = 0;
  for (int k = 0; k < c; k++)
    if (!w || cmp_pt(ch[k], out[w - 1])) { out[w][0] = ch[k][0]; out[w][1] = ch[k][1]; w++; }
  return w;
}
/* whether hypot(a, b) < bound as math.hypot decides it: 1, 0, or -1 when
   the two hypots (each within an ulp of the exact value) may disagree */
static int hypot_lt(double a, double b, double bound) {
  double h = hypot(a, b), lo = h, hi = h;
  for (int k = 0; k < ROBOTS_ULPS; k++) { lo = nextafter(lo, -INFINITY); hi = nextafter(hi, INFINITY); }
  if (hi < bound) return 1;
  if (!(lo < bound)) return 0;
  return -1;
}
/* _point_segment(p, a, b) < bound (1, 0, -1 as hypot_lt) */
static int point_segment_lt(double px, double py, double ax, double ay, double bx, double by,
                            double bound) {
  double ux = bx - ax, uy = by - ay;
  double L2 = ux * ux + uy * uy;
  if (L2 == 0.0) return hypot_lt(px - ax, py - ay, bound);
  double v = ((px - ax) * ux + (py - ay) * uy) / L2;
  double w = v < 1.0 ? v : 1.0;    /* min(1.0, v) */
  double k = w > 0.0 ? w : 0.0;    /* max(0.0, w) */
  return hypot_lt(px - (ax + k * ux), py - (ay + k * uy), bound);
}
static double orient(double px, double py, double qx, double qy, double rx, double ry) {
  return (qx - px) * (ry - py) - (qy - py) * (rx - px);
}
/* segment_distance(a, b, c, d) < bound (1, 0, -1) */
static int segment_lt(const double *a, const double *b, const double *c, const double *d,
                      double bound) {
  double d1 = orient(c[0], c[1], d[0], d[1], a[0], a[1]);
  double d2 = orient(c[0], c[1], d[0], d[1], b[0], b[1]);
  double d3 = orient(a[0], a[1], b[0], b[1], c[0], c[1]);
  double d4 = orient(a[0], a[1], b[0], b[1], d[0], d[1]);
  if ((d1 > 0 && 0 > d2) || (d1 < 0 && 0 < d2)) {
    if ((d3 > 0 && 0 > d4) || (d3 < 0 && 0 < d4)) return 0.0 < bound;
  }
  int r[4] = {point_segment_lt(a[0], a[1], c[0], c[1], d[0], d[1], bound),
              point_segment_lt(b[0], b[1], c[0], c[1], d[0], d[1], bound),
              point_segment_lt(c[0], c[1], a[0], a[1], b[0], b[1], bound),
              point_segment_lt(d[0], d[1], a[0], a[1], b[0], b[1], bound)};
  int amb = 0;
  for (int k = 0; k < 4; k++) { if (r[k] == 1) return 1; if (r[k] < 0) amb = 1; }
  return amb ? -1 : 0;
}

/* -- one robot's motion, read from the state ----------------------------- */
typedef struct {
  double p[3]; int np;             /* position */
  double t[2]; int tnone;          /* target (x, y) or None */
  int done, fail;
  double st[ROBOTS_PTS][2]; int nst;    /* leg start */
  V pos_id, start_id;
  double reg[ROBOTS_PTS + 2][2]; int nreg;   /* nondet's region */
} Robot;
/* option of one robot: position id, done, fail, start id */
typedef struct { V pos, done, fail, start; } Opt;

static int read_robot(const V *s, int j, Robot *r) {
  unsigned char b[ROBOTS_ENC];
  const V *a = s + RB_AG0 + RB_AW * j + RB_MV;
  long n = vget(a[0], b, sizeof b);
  if (n < 0 || !rpos(b, n, r->p, &r->np)) return 0;
  int nt;
  n = vget(a[1], b, sizeof b);
  if (n < 0 || !rtarget(b, n, r->t, &nt, &r->tnone)) return 0;
  n = vget(a[2], b, sizeof b);
  if (n < 0 || !rnoobs(b, n)) return 0;          /* obstacles: Python (shapely) */
  if ((a[4] != 0 && a[4] != 1) || (a[5] != 0 && a[5] != 1)) return 0;
  r->done = (int)a[4]; r->fail = (int)a[5];
  n = vget(a[6], b, sizeof b);
  if (n < 0 || !rstart(b, n, r->st, &r->nst)) return 0;
  r->pos_id = a[0]; r->start_id = a[6];
  return 1;
}
/* settled(m): -1 when the controller moves the robot, else (done, fail) as bits */
static int settled_bits(const Robot *r) {
  if (!r->tnone && !(r->fail || r->done)) return -1;
  return (!r->tnone && r->done && !r->fail) | (!r->tnone && r->fail) << 1;
}
static int opt_hold(const Robot *r, Opt *o, int bits) {
  double q[3];
  if (!round_pos3(r->p, r->np, q)) return 0;
  int64_t id = vpos(q);
  if (id < 0) return 0;
  o->pos = id; o->done = bits & 1; o->fail = bits >> 1 & 1; o->start = r->start_id;
  return 1;
}
static int opt_at(const double *x, Opt *o, V done, V start) {
  double q[3];
  if (!round_pos3(x, 3, q)) return 0;
  int64_t id = vpos(q);
  if (id < 0) return 0;
  o->pos = id; o->done = done; o->fail = 0; o->start = start;
  return 1;
}
/* straight's one step of a moving robot (no obstacles): 0 to leave it to Python */
static int straight_step(const Robot *r, Opt *o) {
  double x = r->p[0], y = r->p[1], z = r->np > 2 ? r->p[2] : 0.0;
  double dx = r->t[0] - x, dy = r->t[1] - y;
  double reach = RB_SPEED * RB_DELTA, lim = reach + 1e-9;
  double h = hypot(dx, dy), lo = h, hi = h;
  for (int k = 0; k < ROBOTS_ULPS; k++) { lo = nextafter(lo, -INFINITY); hi = nextafter(hi, INFINITY); }
  if (hi <= lim) {
    double q[3] = {r->t[0], r->t[1], z};
    return opt_at(q, o, 1, r->start_id);
  }
  if (lo <= lim || !(RB_RES > 0)) return 0;
  /* x + dx * (reach / d) rounded: the same at both ends of d's interval
     (each step is monotone in d), so the same for math.hypot's d */
  double a[3] = {x + dx * (reach / lo), y + dy * (reach / lo), z};
  double b[3] = {x + dx * (reach / hi), y + dy * (reach / hi), z};
  double qa[3], qb[3];
  if (!round_pos3(a, 3, qa) || !round_pos3(b, 3, qb)) return 0;
  if (qa[0] != qb[0] || qa[1] != qb[1]) return 0;
  int64_t id = vpos(qa);
  if (id < 0) return 0;
  o->pos = id; o->done = 0; o->fail = 0; o->start = r->start_id;
  return 1;
}

/* the outcomes of DOREACH INVOKE in state s as the memo's value ([n, then
   per outcome its label and the written slots: phase, env, then per agent
   counter, position, done, fail, start]) in *out (malloc'd); 0 to leave it
   to Python */
static int robots_outcomes(const V *s, V **out, Py_ssize_t *outlen) {
  Robot *rb = malloc(sizeof(Robot) * NAG);
  Opt (*opts)[3] = malloc(sizeof(Opt[3]) * NAG);
  int nopt[NAG], ok = 0;
  V *val = NULL;
  if (!rb || !opts) goto done;
  for (int j = 0; j < NAG; j++) if (!read_robot(s, j, rb + j)) goto done;
  int64_t empty = -1;
  int moving[NAG];
  for (int j = 0; j < NAG; j++) {
    Robot *r = rb + j;
    int bits = settled_bits(r);
    moving[j] = 0;
    nopt[j] = 1;
    if (bits >= 0) { if (!opt_hold(r, &opts[j][0], bits)) goto done; continue; }
    if (RB_KIND == BB_STRAIGHT) { if (!straight_step(r, &opts[j][0])) goto done; continue; }
    double q[3] = {r->t[0], r->t[1], r->np > 2 ? r->p[2] : 0.0};
    if (RB_KIND == BB_INSTANT) { if (!opt_at(q, &opts[j][0], 1, r->start_id)) goto done; continue; }
    /* nondet: exactly at the target, no leg start: arrived */
    if (empty < 0 && (empty = vstart(NULL, 0)) < 0) goto done;
    if (r->p[0] == r->t[0] && r->p[1] == r->t[1] && !r->nst) {
      if (!opt_hold(r, &opts[j][0], 1)) goto done;
      opts[j][0].start = empty;
      continue;
    }
    if (!opt_hold(r, &opts[j][0], 0)) goto done;          /* stays */
    if (!opt_at(q, &opts[j][1], 1, empty)) goto done;     /* arrives */
    nopt[j] = 2;
    moving[j] = 1;
  }
  if (RB_KIND == BB_NONDET || RB_KIND == BB_NONDET_FAIL) {
    /* the regions: the hull of the position, the leg start and (moving) the target */
    for (int j = 0; j < NAG; j++) {
      Robot *r = rb + j;
      double pts[ROBOTS_PTS + 2][2];
      int n = 0;
      pts[n][0] = r->p[0]; pts[n][1] = r->p[1]; n++;
      for (int k = 0; k < r->nst; k++) { pts[n][0] = r->st[k][0]; pts[n][1] = r->st[k][1]; n++; }
      if (settled_bits(r) < 0) { pts[n][0] = r->t[0]; pts[n][1] = r->t[1]; n++; }
      r->nreg = hull(pts, n, r->reg);
    }
    double bodies = 2.0 * (RB_RADIUS + RB_TOL);
    for (int j = 0; j < NAG; j++) {
      if (!moving[j]) continue;
      int fails = RB_KIND == BB_NONDET_FAIL || RB_SPEED * RB_DELTA < 10.0 * RB_RES;
      for (int i = 0; i < NAG && !fails; i++) {
        if (i == j) continue;
        const Robot *a = rb + j, *b = rb + i;
        if (a->nreg > 2 || b->nreg > 2) goto done;     /* shapely's hull distance */
        int r = segment_lt(a->reg[0], a->reg[a->nreg - 1], b->reg[0], b->reg[b->nreg - 1], bodies);
        if (r < 0) goto done;
        fails = r;
      }
      if (fails) {          /* fails where it is; the leg start stays */
        if (!opt_hold(rb + j, &opts[j][2], 2)) goto done;
        nopt[j] = 3;
      }
    }
  }
  /* the product, the first robot the most significant; equal outcomes once */
  Py_ssize_t n = 1;
  for (int j = 0; j < NAG; j++) { n *= nopt[j]; if (n > ROBOTS_KMAX) goto done; }
  Py_ssize_t w = 2 + 5 * NAG;      /* the written slots */
  val = malloc(sizeof(V) * (size_t)(1 + n * (1 + w)));
  if (!val) goto done;
  Py_ssize_t m = 0;
  int idx[NAG];
  for (Py_ssize_t c = 0; c < n; c++) {
    Py_ssize_t rest = c;
    for (int j = NAG - 1; j >= 0; j--) { idx[j] = (int)(rest % nopt[j]); rest /= nopt[j]; }
    V *e = val + 1 + m * (1 + w);
    e[1] = PH_DISCRETE; e[2] = s[RB_ENVS];
    for (int j = 0; j < NAG; j++) {
      const Opt *o = &opts[j][idx[j]];
      V *x = e + 3 + 5 * j;
      x[0] = 0; x[1] = o->pos; x[2] = o->done; x[3] = o->fail; x[4] = o->start;
    }
    int dup = 0;
    for (Py_ssize_t q = 0; q < m && !dup; q++)
      dup = !memcmp(val + 1 + q * (1 + w) + 1, e + 1, sizeof(V) * (size_t)w);
    if (dup) continue;
    if (m >= RB_NLAB) goto done;
    e[0] = RB_LAB[m];
    m++;
  }
  val[0] = m;
  *out = val; *outlen = 1 + m * (1 + w);
  val = NULL;
  ok = 1;
done:
  free(rb); free(opts); free(val);
  return ok;
}

/* memo_site's miss of the env site k (key: the memo's key of s): the
   entry made in C and put in the memo (kt: in the level kernel, which then
   holds MLOCK shared on return, as memo_miss_kernel); NULL with ROBOTS_PY
   set when Python must make it, NULL without it on no memory */
static const V *robots_fill(const V *s, int k, const V *key, int kl, int kt) {
  ROBOTS_PY = 0;
  if (k != RB_SITE || RB_KIND == BB_OFF) { ROBOTS_PY = 1; return NULL; }
  V *val; Py_ssize_t vl;
  if (!robots_outcomes(s, &val, &vl)) {
    ROBOTS_PY = 1;
    __atomic_fetch_add(&RB_PYTHON, 1, __ATOMIC_RELAXED);
    return NULL;
  }
  const V *e;
  if (kt) pthread_rwlock_wrlock(&MLOCK);
  e = memo_find(key, kl);          /* (another thread's may be there) */
  if (!e) e = memo_put(key, kl, val, vl);
  if (kt) pthread_rwlock_unlock(&MLOCK);
  free(val);
  if (!e) return NULL;
  __atomic_fetch_add(&RB_FILLS, 1, __ATOMIC_RELAXED);
  if (kt) {
    pthread_rwlock_rdlock(&MLOCK);
    e = memo_find(key, kl);
  }
  return e;
}

/* -- what Python calls ------------------------------------------------------ */
/* vintern(encoding) -> the id (numbered next when new) */
static PyObject *py_vintern(PyObject *Py_UNUSED(self), PyObject *arg) {
  if (!PyBytes_Check(arg)) { PyErr_SetString(PyExc_TypeError, "bytes"); return NULL; }
  int64_t i = vintern_c((const unsigned char *)PyBytes_AS_STRING(arg), (size_t)PyBytes_GET_SIZE(arg));
  if (i < 0) return PyErr_NoMemory();
  return PyLong_FromLongLong(i);
}
/* vset(id, encoding) -> True, or False when either names another */
static PyObject *py_vset(PyObject *Py_UNUSED(self), PyObject *args) {
  long long i; const char *k; Py_ssize_t n;
  if (!PyArg_ParseTuple(args, "Ly#", &i, &k, &n)) return NULL;
  if (i < 0) { PyErr_SetString(PyExc_ValueError, "a negative id"); return NULL; }
  pthread_mutex_lock(&VLOCK);
  int64_t j = vfind((const unsigned char *)k, (size_t)n);
  int r = j == i ? 1 : j >= 0 ? 0 : ((size_t)i < VN && VE[i].used) ? 0
      : vadd((size_t)i, (const unsigned char *)k, (size_t)n) ? -1 : 1;
  pthread_mutex_unlock(&VLOCK);
  if (r < 0) return PyErr_NoMemory();
  return PyBool_FromLong(r);
}
/* vvalue(id) -> the encoding, or None */
static PyObject *py_vvalue(PyObject *Py_UNUSED(self), PyObject *arg) {
  long long i = PyLong_AsLongLong(arg);
  if (i == -1 && PyErr_Occurred()) return NULL;
  PyObject *out = NULL;
  pthread_mutex_lock(&VLOCK);
  if (i >= 0 && (size_t)i < VN && VE[i].used)
    out = PyBytes_FromStringAndSize((const char *)VB + VE[i].off, VE[i].len);
  pthread_mutex_unlock(&VLOCK);
  if (!out && !PyErr_Occurred()) Py_RETURN_NONE;
  return out;
}
static PyObject *py_vcount(PyObject *Py_UNUSED(self), PyObject *Py_UNUSED(args)) {
  pthread_mutex_lock(&VLOCK);
  size_t n = VN;
  pthread_mutex_unlock(&VLOCK);
  return PyLong_FromSize_t(n);
}
/* robots_setup(kind, site, ag0, aw, mv, envs, (resolution, speed, delta,
   radius, tolerance), labels): the blackbox C computes (0: none), the env
   site, the first robot's block and a block's slots, the offset of a
   robot's position in its block, the env's slot, the
   world, and the labels of outcomes 0, 1, ...; the value table emptied */
static PyObject *py_robots_setup(PyObject *Py_UNUSED(self), PyObject *args) {
  int kind, site, ag0, aw, mv, envs;
  double res, speed, delta, radius, tol;
  PyObject *labs;
  if (!PyArg_ParseTuple(args, "iiiiii(ddddd)O!", &kind, &site, &ag0, &aw, &mv, &envs, &res, &speed, &delta,
                        &radius, &tol, &PyList_Type, &labs))
    return NULL;
  vclear();
  RB_KIND = kind; RB_SITE = site; RB_AG0 = ag0; RB_AW = aw; RB_MV = mv; RB_ENVS = envs;
  RB_RES = res; RB_SPEED = speed; RB_DELTA = delta; RB_RADIUS = radius; RB_TOL = tol;
  RB_NLAB = 0;
  RB_FILLS = RB_PYTHON = 0;
  for (Py_ssize_t q = 0; q < PyList_GET_SIZE(labs) && q < ROBOTS_KMAX; q++) {
    long l = PyLong_AsLong(PyList_GET_ITEM(labs, q));
    if (l == -1 && PyErr_Occurred()) return NULL;
    RB_LAB[q] = (int)l;
    RB_NLAB = (int)q + 1;
  }
  Py_RETURN_NONE;
}
/* robots_stats() -> (outcomes made in C, misses left to Python by C) */
static PyObject *py_robots_stats(PyObject *Py_UNUSED(self), PyObject *Py_UNUSED(args)) {
  return Py_BuildValue("(nn)", (Py_ssize_t)RB_FILLS, (Py_ssize_t)RB_PYTHON);
}
/* round_coord for the tests (None: left to Python) */
static PyObject *py_robots_round(PyObject *Py_UNUSED(self), PyObject *args) {
  double c, res, old = RB_RES, out;
  if (!PyArg_ParseTuple(args, "dd", &c, &res)) return NULL;
  RB_RES = res;
  int ok = round_coord(c, &out);
  RB_RES = old;
  if (!ok) Py_RETURN_NONE;
  return PyFloat_FromDouble(out);
}
#define ROBOTS_METHODS \
  {"vintern", py_vintern, METH_O, "the id of a value's encoding"}, \
  {"vset", py_vset, METH_VARARGS, "a value's encoding as a given id"}, \
  {"vvalue", py_vvalue, METH_O, "the encoding of an id"}, \
  {"vcount", py_vcount, METH_NOARGS, "one more than the largest id"}, \
  {"robots_setup", py_robots_setup, METH_VARARGS, "the blackbox computed in C"}, \
  {"robots_stats", py_robots_stats, METH_NOARGS, "(outcomes made in C, left to Python)"}, \
  {"robots_round", py_robots_round, METH_VARARGS, "a coordinate rounded as round_pos"},
