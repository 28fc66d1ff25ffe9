/* pccl's native engine: the reduced step rstep (the ample set of
   partial-order reduction, then statement merging, as reduce.Reduced
   composes them), the canonical key canon (symmetry) and the stall
   signature, over the tables the generated module defines before it
   includes this file (native_gen.py Generator.reduced_c: POR, MERGE, SYM,
   MERGEOK, BID, SHID, SIGSLOTS; step.c's step(), the agents' table AGENT
   and RHO; por.c's ample() and movable() under POR; dead.c's dead_bits()
   and dead_apply() under DEAD; NCTR, CTRSLOT, CTRCAP under CTRS). */
#if !POR
/* what merging reads of partial-order reduction when it is off */
static MAYBE_UNUSED const unsigned char PSPENT[] = {0};
static inline int movable(const V *s, int i) { (void)s; (void)i; return 0; }
#endif
/* statement merging: run agent i's following mergeable steps in the
   successor at BUF[k] (Merger._chain: one successor per step, a chain
   stops where it revisits (pc, counter, locals) after 32 steps: those
   identities kept in SEEN, found through the open-addressing table SLOT) */
#define IDW (2 + NLOC)
#define NSLOT 4096
static __thread V *SEEN;           /* per thread, on the heap (kfree_tls) */
static __thread int16_t *SLOT;
#if MERGE
static uint64_t idhash(const V *id) {
  uint64_t h = 0x9E3779B97F4A7C15ULL;
  for (int q = 0; q < IDW; q++) { h ^= (uint64_t)id[q]; h *= 0xBF58476D1CE4E5B9ULL; h ^= h >> 31; }
  return h;
}
static int sigeq(const V *a, const V *b) {
  for (int q = 0; q < NSIGSLOTS; q++) if (a[SIGSLOTS[q]] != b[SIGSLOTS[q]]) return 0;
  return 1;
}
/* s0: the state the transition leaves.  A chain that ran a step writing
   the stall signature's data (movable 2) and ends with the signature of
   s0 is cut right after its first change (Merger._cut) */
static int chain(const V *s0, Py_ssize_t k, int i) {
  V cur[NS], cut[NS];
  memcpy(cur, BUF + NS * k, sizeof cur);
  const int a0 = AG0 + AW * i;
  int n = 0, nseen = 0, marks = 0, ncut = -1;
  if (POR && !sigeq(cur, s0)) { memcpy(cut, cur, sizeof cut); ncut = 0; }
  for (;;) {
    V pc = cur[a0];
    if ((uint64_t)pc >= NPC || cur[a0 + 3] != S_RUNNING || n >= MERGE_LIMIT) break;
    int mv = 0;
    if (cur[a0 + 1] + RHO[i] > KEEPN0) {
      /* spent: only its own plain statements (Independence.spent_local) */
      if (!(POR && PSPENT[pc])) break;
    } else if (!MERGEOK[pc]) {
      if (!POR) break;
      mv = movable(cur, i);
      if (!mv) break;
    }
    if (n >= 32) {
      if (!SEEN) {
        SEEN = malloc(sizeof(V) * (MERGE_LIMIT + 1) * IDW);
        SLOT = malloc(sizeof(int16_t) * NSLOT);
        if (!SEEN || !SLOT) { free(SEEN); free(SLOT); SEEN = NULL; SLOT = NULL; ovf = 1; return -1; }
      }
      V *id = SEEN + IDW * nseen;
      id[0] = pc; id[1] = cur[a0 + 1];
      memcpy(id + 2, cur + a0 + 4, sizeof(V) * NLOC);
      if (!nseen) memset(SLOT, -1, sizeof(int16_t) * NSLOT);
      size_t sl = idhash(id) & (NSLOT - 1);
      int hit = 0;
      while (SLOT[sl] >= 0) {
        if (!memcmp(SEEN + IDW * SLOT[sl], id, sizeof(V) * IDW)) { hit = 1; break; }
        sl = (sl + 1) & (NSLOT - 1);
      }
      if (hit) break;
      SLOT[sl] = (int16_t)nseen++;
    }
    Py_ssize_t b = BN;
    if (AGENT[i](cur)) return -1;
    if (BN == b) break;
    memcpy(cur, BUF + NS * b, sizeof cur);
    BN = b;
    n++;
    if (mv == 2) {
      marks = 1;
      if (ncut < 0 && !sigeq(cur, s0)) { memcpy(cut, cur, sizeof cut); ncut = n; }
    }
  }
  if (marks && ncut >= 0 && sigeq(cur, s0)) { memcpy(cur, cut, sizeof cur); n = ncut; }
  if (n) { memcpy(BUF + NS * k, cur, sizeof cur); BCH[k] = n; }
  return 0;
}
#endif
/* the reduced successors of s appended to the buffer: the ample set of
   partial-order reduction (else every successor), each merged */
static int rstep(const V *s) {
#if POR || MERGE
  Py_ssize_t b0 = BN;
#endif
#if POR
  if (s[V_PHASE] == PH_DISCRETE) {
    int a = ample(s, b0);     /* por.c */
    if (a < 0) return -1;
    if (a) goto chains;
  }
#endif
  if (step(s)) return -1;
  goto chains;
chains:
#if MERGE
  if (s[V_PHASE] == PH_DISCRETE)
    for (Py_ssize_t k = b0; k < BN; k++) {
      BIDX[k] = (int32_t)(k - b0);
      int i = __atomic_load_n(&LABAG, __ATOMIC_ACQUIRE)[BLAB[k]];   /* the label's agent (-1: none) */
      if (i >= 0 && chain(s, k, i)) return -1;
    }
#endif
  return ovf ? -1 : 0;
}
/* counter saturation (counters.py): agent j's loc: slot CTRSLOT[c] above
   its cap CTRCAP[c] is the cap (the tables: counters.py Counters.c_tables) */
#if CTRS
static int ctrs_need(const V *s) {
  for (int j = 0; j < NAG; j++)
    for (int c = 0; c < NCTR; c++)
      if (s[AG0 + AW * j + 4 + CTRSLOT[c]] > CTRCAP[c]) return 1;
  return 0;
}
static void ctrs_apply(V *s) {
  for (int j = 0; j < NAG; j++)
    for (int c = 0; c < NCTR; c++) {
      V *x = s + AG0 + AW * j + 4 + CTRSLOT[c];
      if (*x > CTRCAP[c]) *x = CTRCAP[c];
    }
}
#endif
/* symmetry: the canonical representative of s's orbit under permutations
   of the agents (each agent's whole block moves; id-valued slots BID of a
   block and SHID of shared, and the lock queue, renamed).  Agents are
   sorted by their blocks with ids masked (own id, another's), which shared
   id variables name them and their place in the lock queue; agents that
   name others are tried in every order among equals, the least vector
   wins.  A canonical form of the orbit, as reduce.py's key is: the two
   keys identify the same states. */
#define SIGW (AW + NSHID + 1)
#define MSELF (INT64_MIN + 1)
#define MOTHER (INT64_MIN + 2)
#if SYM
static int vcmp(const V *a, const V *b, int n) {
  for (int q = 0; q < n; q++) if (a[q] != b[q]) return a[q] < b[q] ? -1 : 1;
  return 0;
}
static void build(const V *s, const int *order, V *out) {
  int r[NAG];
  for (int p = 0; p < NAG; p++) r[order[p]] = p;
  memcpy(out, s, sizeof(V) * AG0);
  for (int k = 0; k < NAG; k++) if (out[LQ0 + k] >= 0 && out[LQ0 + k] < NAG) out[LQ0 + k] = r[out[LQ0 + k]];
  for (int q = 0; q < NSHID; q++) {
    V x = out[SHID[q]];
    if (x >= 0 && x < NAG) out[SHID[q]] = r[x];
  }
  for (int p = 0; p < NAG; p++) {
    V *b = out + AG0 + AW * p;
    memcpy(b, s + AG0 + AW * order[p], sizeof(V) * AW);
    for (int q = 0; q < NBID; q++) {
      V x = b[BID[q]];
      if (x >= 0 && x < NAG) b[BID[q]] = r[x];
    }
  }
}
/* canon calls it on a group of order (a = order + start, start + len <= NAG),
   which gcc's -Warray-bounds, inlining it, cannot tell */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Warray-bounds"
static int next_perm(int *a, int n) {
  int i = n - 2;
  while (i >= 0 && a[i] >= a[i + 1]) i--;
  if (i < 0) { for (int l = 0, h = n - 1; l < h; l++, h--) { int t = a[l]; a[l] = a[h]; a[h] = t; } return 0; }
  int j = n - 1;
  while (a[j] <= a[i]) j--;
  int t = a[i]; a[i] = a[j]; a[j] = t;
  for (int l = i + 1, h = n - 1; l < h; l++, h--) { t = a[l]; a[l] = a[h]; a[h] = t; }
  return 1;
}
#pragma GCC diagnostic pop
#endif
static void canon(const V *s0, V *out) {
#if DEAD
  uint64_t dd[NAG];
  V dm[NS];
  const V *s = s0;
  if (dead_bits(s0, dd)) { memcpy(dm, s0, sizeof dm); dead_apply(dm, dd); s = dm; }
#else
  const V *s = s0;
#endif
#if CTRS
  V cm[NS];            /* counter saturation: counters above their cap clamped (counters.py) */
  if (ctrs_need(s)) { memcpy(cm, s, sizeof cm); ctrs_apply(cm); s = cm; }
#endif
#if SYM
  V g[NAG][SIGW];
  int order[NAG], other = 0;
  for (int j = 0; j < NAG; j++) {
    V *x = g[j];
    memcpy(x, s + AG0 + AW * j, sizeof(V) * AW);
    for (int q = 0; q < NBID; q++) {
      V v = x[BID[q]];
      if (v >= 0) { if (v == j) x[BID[q]] = MSELF; else { x[BID[q]] = MOTHER; other = 1; } }
    }
    for (int q = 0; q < NSHID; q++) x[AW + q] = s[SHID[q]] == j;
    V p = -1;
    for (int k = 0; k < NAG; k++) if (s[LQ0 + k] == j) { p = k; break; }
    x[AW + NSHID] = p;
    order[j] = j;
  }
  /* stable insertion sort; the first SYMFIX agents stay in place (the
     renamings that fix them: reduce.py's Plan.fixed) */
  for (int a = SYMFIX + 1; a < NAG; a++) {
    int t = order[a], b = a;
    while (b > SYMFIX && vcmp(g[order[b - 1]], g[t], SIGW) > 0) { order[b] = order[b - 1]; b--; }
    order[b] = t;
  }
  int ties = 0;
  if (other)
    for (int a = SYMFIX + 1; a < NAG; a++) if (!vcmp(g[order[a - 1]], g[order[a]], SIGW)) { ties = 1; break; }
  build(s, order, out);
  if (!ties) return;
  /* the groups of equal agents, each tried in every order (a fixed agent
     is a group of its own) */
  int start[NAG], len[NAG], ng = 0;
  for (int a = 0; a < NAG; ) {
    int b = a + 1;
    while (b < NAG && b > SYMFIX && !vcmp(g[order[a]], g[order[b]], SIGW)) b++;
    start[ng] = a; len[ng] = b - a; ng++;
    a = b;
  }
  V tmp[NS];
  for (;;) {
    int gi = ng - 1;
    while (gi >= 0 && !next_perm(order + start[gi], len[gi])) gi--;
    if (gi < 0) break;
    build(s, order, tmp);
    if (vcmp(tmp, out, NS) < 0) memcpy(out, tmp, sizeof tmp);
  }
#else
  memcpy(out, s, sizeof(V) * NS);
#endif
}
