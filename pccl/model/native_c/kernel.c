/* pccl's native engine: the level kernel (explore_levels), included by a
   generated module last. */
/* ---- the level kernel ---------------------------------------------------
   explore_levels(level, first, out, start, threads, slots, fps, parents,
   n, mask, limit, cross, seconds[, rec[, tcol]]): breadth-first search in C from
   level[start:] (level[i] is state number first + i), admitting as the
   explorer's batches would admit: a chunk of KCH states at a time, chunks
   in order, each new successor (its fingerprint not in the table) numbered
   n, n + 1, ... (fps[n] its fingerprint, parents[n] its parent's number,
   indexed in slots) and its state appended to the next level's list (out,
   the next level as far as it is admitted: its states numbered n - len(out)
   on).  Once a level's every chunk is admitted the next level's chunks
   follow, up to `cross` levels after `level`: so that threads never wait
   for a level to end.  With threads > 1 that many threads, this one among
   them, each make chunks (expand, fingerprint, check: no Python, no GIL)
   at most KWIN ahead of the admission; this thread alone admits (holding
   the GIL), and it never waits for the others: when the next chunk is in
   another thread's hands and there is nothing else to make, it makes that
   chunk too (the same states, the same buffer's contents; the first made
   is admitted, the other dropped).  So a slow or descheduled thread holds
   no one up (beside a busy loop, or on narrow levels where the others have
   little to make, the search goes at least at one thread's pace), and the
   result does not depend on the threads.  It stops before
   admitting a chunk that holds a state without successors (why 1), an
   error (2), more successors than room under `limit` (3: the table is to
   grow, or the state budget is met) or a successor that fails okstate and
   is not in the table (4): the explorer's own path takes that chunk; and
   at a chunk's end once `seconds` have passed (why 0, more to do).
   With `rec` (the graph recorder's arrays, GraphRecorder.kernel_arrays:
   transitions' sources and targets as uint32 with the count so far, time
   costs, and with the stall check signatures, change flags and whether a
   change is decided on the successor as made, and with the frozen-team
   check each transition's label number, each state's progress signature
   and progress change flag) the admission records every
   transition and new state there (krecord), and stops before a chunk whose
   transitions do not fit (why 5: the arrays grow).  With `tcol` too (the
   temporal properties' columns, GraphRecorder.kernel_columns: uint64 P/Q
   bits and, under fair arrival, robots under way per state) each candidate's columns are made
   with it (tcols(), temporal.c, on the threads) and a new state's written;
   a candidate whose columns Python must compute makes its chunk the
   batches' (why 2).
   Returns (e: the level it stopped in, 0 for `level`, e >= 1 the e-th
   level after it; the position in it; why; level e's list (None for level
   0, or once it is expanded); its next level's list (out when e is 0);
   (length, last state) of each level 1..e; the largest time of the new
   states of each level 1..e+1, or None; the transitions admitted; the
   labels met; the end of the chunk stopped at; the states admitted; 1
   when nothing more was allowed (the last level it may go into is
   expanded, or a level came out empty), else 0; the transitions recorded
   in all, 0 without `rec`; an interruption raised in a memo miss's Python
   code, which stopped the kernel, or None: the caller raises it once it has
   taken the figures; (the chunks admitted, those of them another thread
   made, the chunks this thread made again because another had them)). */
#include <pthread.h>
#include <time.h>
/* compiled at -O1: 0.1-0.25 s less per module than -O2 and no slower (its
   hot loops are the successor code's, compiled at -O2; Fischer 3 agents
   k=2: 7.75-7.93 s against 7.97-8.23 s, 2026-12-03).  In every module: a
   memo site's miss (the env's included) takes the GIL to call Python, the
   memo's locks held (_MEMO_C) */
#pragma GCC push_options
#pragma GCC optimize ("O1")
#define KCH 128
#define KWIN 512
#define KMAXLV 4096
#define KBLK 65536
#define KTMAX 64                    /* threads at most */
typedef struct {
  Py_ssize_t id;                    /* the chunk it holds, once made (-1: not yet) */
  int helper;                       /* made by a thread other than the caller's */
  V *vec; uint64_t *fp; unsigned char *sus, *labs; int32_t *ns;
  int64_t *sg;                      /* the candidates' stall signatures (recording them) */
  uint64_t *tb, *pd;                /* their temporal columns (temporal.c: recording them) */
  int64_t *psg;                     /* ... and progress signatures (the frozen-team check's) */
  int32_t *lb;                      /* ... and label numbers (the frozen-team check's) */
  Py_ssize_t labcap;                /* labs' size (labels grow on memo misses) */
  Py_ssize_t nc, cap;
  int flag;
} KChunk;
typedef struct {
  /* level 0: the list given; levels 1...: the states admitted, in blocks
     of KBLK pointers (ptr index q is state number pfirst + q; the lists
     hold the references), level L >= 1 from index lo[L]; chunk ids run
     on across levels, level L's from cbase[L] */
  PyObject *level;
  Py_ssize_t first, start, end0;
  PyObject ***blk;
  Py_ssize_t nblk, pfirst, cross;
  Py_ssize_t nptr;                  /* admitted so far (release-stored) */
  Py_ssize_t lo[KMAXLV + 2], cbase[KMAXLV + 2];
  int known;                        /* levels 0..known-1 have their final size */
  int exhausted;                    /* a level came out empty: no chunk from endc on */
  Py_ssize_t endc;
  PyObject *lists[KMAXLV + 1];      /* lists[L]: level L's (L >= 1), until expanded */
  Py_ssize_t llen[KMAXLV + 1];      /* ... then its length and last state */
  PyObject *llast[KMAXLV + 1];
  /* the last level expanded: its states freed one per state admitted, so
     that a new state takes the place of an old one (a whole level freed at
     once empties the allocator's arenas, which go back to the system and
     must be mapped again: measured 8x the page faults, 10% of the time) */
  PyObject *grave;
  long long tmax[KMAXLV + 1];
  Py_ssize_t tn[KMAXLV + 1];        /* new states admitted into lists[L] in this call */
  /* chunk c's buffer (once made) in slot c % KWIN; the buffers (KRING, kept
     between calls: one per slot and one in each thread's hands) not in use
     on a stack, the last freed on top: a buffer taken is most likely still
     in the cache.  The slots change and the stack under mu; a buffer's id
     is set when it is put in its slot, after its contents */
  KChunk **slot;
  KChunk *free_[KWIN + KTMAX];
  int nfree;
  int next, done, stop, sleepers;
  Py_ssize_t helped, dups;          /* chunks admitted that the other threads made; chunks
                                       this thread made again (another thread had them) */
  int slow;                         /* tests: the other threads sleep this many ms a chunk
                                       before putting it in its slot ($PCCL_KERNEL_SLOW_HELPERS) */
  /* the admission's (the calling thread's) */
  uint32_t *slots, *parents;
  uint64_t *fps, mask;
  Py_ssize_t n, n0, limit, trans;
  unsigned char *seen;
  Py_ssize_t nseen;
  int why, lv;                      /* lv: the level of the last chunk admitted, */
  Py_ssize_t pend;                  /* ... and its end */
  double deadline;
  /* the graph recorder's arrays (rec: recording), written by the admission:
     per transition its source and target numbers (ne so far, room for
     ecap), per new state its time cost (dyn) and, with the stall check
     (sig not NULL), its signature and a change flag set on a source when
     a transition out of it changes the signature: of the successor as made
     (bycand: under symmetry a number stands for a renamed state) or of the
     state its number stands for */
  int rec, bycand;
  uint32_t *esrc, *edst;
  Py_ssize_t ne, ecap;
  unsigned char *dyn, *chg;
  int64_t *sig;
  uint64_t *tbits, *tpend;          /* the temporal columns (temporal.c), or NULL */
  /* with the frozen-team check (psig not NULL): per transition its label
     number (elab), per new state its progress signature and a progress
     change flag (pchg), set as chg is */
  int32_t *elab;
  int64_t *psig;
  unsigned char *pchg;
  pthread_mutex_t mu;
  pthread_cond_t cv;
} KJob;
static KChunk KRING[KWIN + KTMAX];
static KChunk *KSLOT[KWIN];
static int KBUSY;
static double know(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}
static void kfree_tls(void) {
  free(BUF); free(BLAB); free(BIDX); free(BCH);
  BUF = NULL; BLAB = BIDX = BCH = NULL; BN = BCAP = 0;
#ifdef IDW
  free(SEEN); free(SLOT); SEEN = NULL; SLOT = NULL;
#endif
}
static int kroom(KChunk *k, Py_ssize_t need) {
  if (need <= k->cap) return 0;
  Py_ssize_t cap = k->cap ? 2 * k->cap : 512;
  while (cap < need) cap *= 2;
  V *v = realloc(k->vec, sizeof(V) * NS * cap);
  if (v) k->vec = v;
  uint64_t *f = realloc(k->fp, 16 * cap);
  if (f) k->fp = f;
  unsigned char *s = realloc(k->sus, cap);
  if (s) k->sus = s;
  int64_t *g = realloc(k->sg, sizeof(int64_t) * cap);
  if (g) k->sg = g;
  uint64_t *tb = realloc(k->tb, 8 * cap);
  if (tb) k->tb = tb;
  uint64_t *pd = realloc(k->pd, 8 * cap);
  if (pd) k->pd = pd;
  int64_t *pg = realloc(k->psg, sizeof(int64_t) * cap);
  if (pg) k->psg = pg;
  int32_t *l = realloc(k->lb, sizeof(int32_t) * cap);
  if (l) k->lb = l;
  if (!v || !f || !s || !g || !tb || !pd || !pg || !l) return -1;
  k->cap = cap;
  return 0;
}
/* room in k->labs for label nl (a label a memo miss added), zeroed */
static int klabs(KChunk *k, Py_ssize_t nl) {
  if (nl < k->labcap) return 0;
  Py_ssize_t cap = k->labcap ? 2 * k->labcap : 256;
  while (cap <= nl) cap *= 2;
  unsigned char *x = realloc(k->labs, cap);
  if (!x) return -1;
  memset(x + k->labcap, 0, cap - k->labcap);
  k->labs = x; k->labcap = cap;
  return 0;
}
/* a chunk made or admitted, the admission free, the end: the waiting
   threads look again (under the lock: a thread checks what it waits for
   under it, so no wake-up is lost) */
static void kwake(KJob *j) {
  pthread_mutex_lock(&j->mu);
  if (j->sleepers) pthread_cond_broadcast(&j->cv);
  pthread_mutex_unlock(&j->mu);
}
/* chunk c's states: level *lv, positions [*a, *b) of it (level 0: of the
   list given; level L >= 1: of the states admitted); 1 when it can be
   made, 0 when not yet (its level's states not all admitted: a whole chunk
   is waited for), -1 never (past the last level or `cross`) */
static int kwhere(KJob *j, Py_ssize_t c, int *lv, Py_ssize_t *a, Py_ssize_t *b) {
  int known = __atomic_load_n(&j->known, __ATOMIC_ACQUIRE);
  int L = 0;
  while (L < known && c >= j->cbase[L + 1]) L++;
  *lv = L;
  if (L > j->cross || (__atomic_load_n(&j->exhausted, __ATOMIC_ACQUIRE) && c >= j->endc)) {
    *a = *b = 0;
    return -1;
  }
  if (L == 0) {
    *a = j->start + c * KCH;
    *b = *a + KCH < j->end0 ? *a + KCH : j->end0;
    return 1;
  }
  *a = j->lo[L] + (c - j->cbase[L]) * KCH;
  if (L < known) {                  /* level L's size is final */
    *b = *a + KCH < j->lo[L + 1] ? *a + KCH : j->lo[L + 1];
    return 1;
  }
  *b = *a + KCH;
  return __atomic_load_n(&j->nptr, __ATOMIC_ACQUIRE) >= *b ? 1 : 0;
}
static inline PyObject *kptr(KJob *j, Py_ssize_t q) {
  return j->blk[q / KBLK][q % KBLK];
}
/* make chunk c: its states' successors, their fingerprints and checks;
   then put it in its slot, unless another thread's copy of chunk c is there
   (or chunk c is admitted: a later chunk's, or a stale copy, is there) */
static void kmake(KJob *j, Py_ssize_t c, int L, Py_ssize_t a, Py_ssize_t b, int mine) {
  pthread_mutex_lock(&j->mu);
  KChunk *k = j->free_[--j->nfree];
  k->id = -1;
  pthread_mutex_unlock(&j->mu);
  k->nc = 0;
  k->flag = 0;
  KDEFER = 0;
  if (klabs(k, __atomic_load_n(&NLABELS, __ATOMIC_ACQUIRE))) k->flag = 2;
  memset(k->labs, 0, k->labcap);
  for (Py_ssize_t i = a; i < b && !k->flag; i++) {
    V sb[NS];
    const V *s = raw_state(L ? kptr(j, i) : PyList_GET_ITEM(j->level, i), sb);
    BN = 0; ovf = 0;
    if (!s || rstep(s)) { k->flag = KDEFER ? 6 : 2; break; }
    k->ns[i - a] = (int32_t)BN;
    if (!BN) { k->flag = 1; break; }
    if (kroom(k, k->nc + BN)) { k->flag = 2; break; }
    for (Py_ssize_t q = 0; q < BN; q++) {
      const V *t = BUF + NS * q;
      Py_ssize_t w = k->nc++;
      memcpy(k->vec + NS * w, t, sizeof(V) * NS);
      if (BLAB[q] >= k->labcap && klabs(k, BLAB[q])) { k->flag = 2; break; }
      k->labs[BLAB[q]] = 1;
      fingerprint_of(t, k->fp + 2 * w);
      if (j->sig) k->sg[w] = sighash(t);
      if (j->psig) { k->psg[w] = psighash(t); k->lb[w] = BLAB[q]; }
      k->sus[w] = !okstate(t);
      if (KDEFER) { k->flag = 6; break; }  /* (a property memo site's miss: the caller's) */
      /* a column Python must compute (a temporal predicate's memo miss
         deferred here is one: it sets ovf, so tcols says unsure): the
         batches take the chunk */
      if (j->tbits && tcols(t, k->tb + w, k->pd + w)) { k->flag = 2; break; }
    }
  }
  if (!mine && j->slow) {           /* (tests: a slow or descheduled thread) */
    struct timespec z = {0, 1000000L * j->slow};
    nanosleep(&z, NULL);
  }
  pthread_mutex_lock(&j->mu);
  KChunk **at = &j->slot[c % KWIN], *e = *at, *drop = k;
  /* (a copy given up at a memo miss, flag 6, stands for the chunk until the
     calling thread's copy replaces it) */
  if (c >= __atomic_load_n(&j->done, __ATOMIC_ACQUIRE)
      && (!e || e->id < c || (e->id == c && e->flag == 6 && k->flag != 6))) {
    drop = e;                       /* (a copy of a chunk admitted, or none) */
    k->helper = !mine;
    __atomic_store_n(&k->id, c, __ATOMIC_RELEASE);
    __atomic_store_n(at, k, __ATOMIC_RELEASE);
  }
  if (drop) { drop->id = -1; j->free_[j->nfree++] = drop; }
  pthread_mutex_unlock(&j->mu);
}
static inline int64_t klookup(const uint32_t *slots, const uint64_t *fps, uint64_t mask, const uint64_t *q) {
  size_t pos = q[1] & mask;
  for (;;) {
    uint32_t e = slots[pos];
    if (e == TEMPTY) return -1;
    if (fps[2 * (size_t)e + 1] == q[1] && fps[2 * (size_t)e] == q[0]) return e;
    pos = (pos + 1) & mask;
  }
}
/* the recorder's transition par -> dst (candidate w of chunk k) */
static inline void krecord(KJob *j, KChunk *k, Py_ssize_t w, Py_ssize_t par, int64_t dst) {
  j->esrc[j->ne] = (uint32_t)par;
  j->edst[j->ne++] = (uint32_t)dst;
  if (j->sig && (j->bycand ? k->sg[w] : j->sig[dst]) != j->sig[par]) j->chg[par] = 1;
  if (j->psig) {
    j->elab[j->ne - 1] = k->lb[w];
    if ((j->bycand ? k->psg[w] : j->psig[dst]) != j->psig[par]) j->pchg[par] = 1;
  }
}
/* admit chunk k, the next in order, of level L, positions [a, b) (the GIL
   held): 0, else why not */
static int kadmit1(KJob *j, KChunk *k, int L, Py_ssize_t a, Py_ssize_t b) {
  uint32_t *slots = j->slots, *parents = j->parents;
  uint64_t *fps = j->fps, mask = j->mask;
  if (k->flag) return k->flag;
  if (j->n + k->nc > j->limit) return 3;
  if (j->rec && j->ne + k->nc > j->ecap) return 5;
  for (Py_ssize_t q = 0; q < k->nc; q++)
    if (k->sus[q] && klookup(slots, fps, mask, k->fp + 2 * q) < 0) return 4;
  if (!j->lists[L + 1]) {
    if (!(j->lists[L + 1] = PyList_New(0))) return -1;
    j->tn[L + 1] = 0;
  }
  PyObject *out = j->lists[L + 1];
  Py_ssize_t w = 0, n = j->n, base = L ? j->pfirst : j->first;
  /* the table's lines fetched ahead: its slot 16 candidates on, the
     fingerprints of the slots a probe will pass 8 on (the table is far
     larger than the cache) */
  for (Py_ssize_t q = 0; q < 16 && q < k->nc; q++) __builtin_prefetch(slots + (k->fp[2 * q + 1] & mask));
  for (Py_ssize_t i = a; i < b; i++) {
    Py_ssize_t par = base + i;
    for (int32_t r = 0; r < k->ns[i - a]; r++, w++) {
      const uint64_t *f = k->fp + 2 * w;
      if (w + 16 < k->nc) __builtin_prefetch(slots + (k->fp[2 * (w + 16) + 1] & mask));
      if (w + 8 < k->nc)
        for (size_t p8 = k->fp[2 * (w + 8) + 1] & mask, r8 = 0; r8 < 4; r8++, p8 = (p8 + 1) & mask) {
          uint32_t e8 = slots[p8];
          if (e8 == TEMPTY) break;
          __builtin_prefetch(fps + 2 * (size_t)e8);
        }
      int64_t hit = klookup(slots, fps, mask, f);
      if (hit >= 0) {
        if (j->rec) krecord(j, k, w, par, hit);
        continue;
      }
      const V *t = k->vec + NS * w;
      Py_ssize_t q = j->nptr;
      if (q / KBLK >= j->nblk) { j->n = n; return 3; }
      if (!j->blk[q / KBLK] && !(j->blk[q / KBLK] = malloc(sizeof(PyObject *) * KBLK))) {
        PyErr_NoMemory(); j->n = n; return -1;
      }
      if (j->grave) {               /* an old state's place for the new one */
        Py_ssize_t g = PyList_GET_SIZE(j->grave);
        if (g) {
          PyObject *old = PyList_GET_ITEM(j->grave, g - 1);
          Py_SET_SIZE(j->grave, g - 1);
          Py_DECREF(old);
        }
      }
      PyObject *st = state_bytes(t);
      if (!st || PyList_Append(out, st)) { Py_XDECREF(st); j->n = n; return -1; }
      j->blk[q / KBLK][q % KBLK] = st;
      Py_DECREF(st);                /* the list holds it */
      __atomic_store_n(&j->nptr, q + 1, __ATOMIC_RELEASE);
      fps[2 * n] = f[0]; fps[2 * n + 1] = f[1];
      parents[n] = (uint32_t)par;
      size_t pos = f[1] & mask;
      while (slots[pos] != TEMPTY) pos = (pos + 1) & mask;
      slots[pos] = (uint32_t)n;
      if (!j->tn[L + 1]++ || t[0] > j->tmax[L + 1]) j->tmax[L + 1] = t[0];
      if (j->rec) {
        j->dyn[n] = phase_cost(t);
        if (j->sig) { j->sig[n] = k->sg[w]; j->chg[n] = 0; }
        if (j->tbits) { j->tbits[n] = k->tb[w]; if (j->tpend) j->tpend[n] = k->pd[w]; }
        if (j->psig) { j->psig[n] = k->psg[w]; j->pchg[n] = 0; }
        krecord(j, k, w, par, n);
      }
      n++;
    }
  }
  j->n = n;
  if (k->labcap > j->nseen) {       /* labels a memo miss added */
    unsigned char *x = realloc(j->seen, k->labcap);
    if (!x) { PyErr_NoMemory(); return -1; }
    memset(x + j->nseen, 0, k->labcap - j->nseen);
    j->seen = x; j->nseen = k->labcap;
  }
  for (Py_ssize_t q = 0; q < k->labcap; q++) j->seen[q] |= k->labs[q];
  j->trans += k->nc;
  return 0;
}
/* level L's every chunk admitted: level L + 1's size is final (its end,
   its chunks' ids); an empty one ends the search */
static void kclose(KJob *j, int L) {
  Py_ssize_t size = j->nptr - j->lo[L + 1];
  if (L >= 1 && j->lists[L]) {      /* expanded: its states are the next level's parents only */
    PyObject *l = j->lists[L];
    j->llen[L] = PyList_GET_SIZE(l);
    j->llast[L] = j->llen[L] ? PyList_GET_ITEM(l, j->llen[L] - 1) : Py_None;
    Py_INCREF(j->llast[L]);
    if (L > 1) {                    /* (level 1 is the caller's list) */
      Py_XDECREF(j->grave);         /* (its states freed as many new ones are made) */
      j->grave = l;
    }
    j->lists[L] = NULL;
  }
  j->lo[L + 2] = j->nptr;
  j->cbase[L + 2] = j->cbase[L + 1] + (size + KCH - 1) / KCH;
  if (L + 2 >= KMAXLV && j->cross > L + 1) j->cross = L + 1;
  if (!size) {
    j->endc = j->cbase[L + 2];
    __atomic_store_n(&j->exhausted, 1, __ATOMIC_RELEASE);
  }
  __atomic_store_n(&j->known, L + 2, __ATOMIC_RELEASE);
}
/* chunk c's buffer when it is made (the calling thread's: only it admits
   and empties the slots of chunks not yet admitted) */
static inline KChunk *kready(KJob *j, int c) {
  KChunk *k = __atomic_load_n(&j->slot[c % KWIN], __ATOMIC_ACQUIRE);
  return k && __atomic_load_n(&k->id, __ATOMIC_ACQUIRE) == c ? k : NULL;
}
/* admit the chunks made, in order (the calling thread) */
static void kadmit(KJob *j, PyThreadState **ts) {
  int held = 0;
  for (;;) {
    int c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE);
    if (j->why || __atomic_load_n(&j->stop, __ATOMIC_ACQUIRE) || __atomic_load_n(&KINTR, __ATOMIC_ACQUIRE))
      break;
    KChunk *k = kready(j, c);
    if (!k || k->flag == 6) break;  /* (given up at a memo miss: kwork makes it) */
    int L;
    Py_ssize_t a, b;
    kwhere(j, c, &L, &a, &b);
    if (!held) { PyEval_RestoreThread(*ts); held = 1; }
    int why = kadmit1(j, k, L, a, b);
    if (why) { j->why = why; break; }
    if (c + 1 == j->cbase[L + 1]) kclose(j, L);     /* the last chunk of level L */
    j->lv = L;
    j->pend = b;
    j->helped += k->helper;
    pthread_mutex_lock(&j->mu);
    __atomic_store_n(&j->slot[c % KWIN], NULL, __ATOMIC_RELEASE);
    k->id = -1;
    j->free_[j->nfree++] = k;
    __atomic_store_n(&j->done, c + 1, __ATOMIC_RELEASE);
    /* the others woken only when there is work for them beside this
       thread's: two chunks ready to make (on levels narrower than that
       they sleep and this thread searches alone, as one thread would) */
    if (j->sleepers) {
      int d = __atomic_load_n(&j->next, __ATOMIC_ACQUIRE), L2;
      Py_ssize_t a2, b2;
      if (d + 1 < c + 1 + KWIN && kwhere(j, d + 1, &L2, &a2, &b2) == 1)
        pthread_cond_broadcast(&j->cv);
    }
    pthread_mutex_unlock(&j->mu);
    if (know() > j->deadline) __atomic_store_n(&j->stop, 1, __ATOMIC_RELEASE);
  }
  if (held) *ts = PyEval_SaveThread();
}
/* a thread's part.  The calling thread (mine): admit the next chunk when it
   is made; else make the next chunk within the window; else, the next
   chunk being in another thread's hands, make it too (it never waits for
   another thread).  The others: make the next chunk within the window,
   else wait for one (the admission, or the end) */
static void kwork(KJob *j, PyThreadState **ts, int mine) {
  for (;;) {
    int c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE), L;
    Py_ssize_t a, b;
    if (__atomic_load_n(&j->stop, __ATOMIC_ACQUIRE) || __atomic_load_n(&KINTR, __ATOMIC_ACQUIRE)) break;
    KChunk *k0 = mine ? kready(j, c) : NULL;
    if (k0 && k0->flag == 6) {      /* another thread gave it up at a memo miss */
      kwhere(j, c, &L, &a, &b);
      kmake(j, c, L, a, b, 1);
      j->dups++;
      continue;
    }
    if (k0) {
      kadmit(j, ts);
      if (j->why) break;
      continue;
    }
    int d = __atomic_load_n(&j->next, __ATOMIC_ACQUIRE);
    int r = d < c + KWIN ? kwhere(j, d, &L, &a, &b) : 0;
    if (r == 1) {
      if (__atomic_compare_exchange_n(&j->next, &d, d + 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE))
        kmake(j, d, L, a, b, mine);
      continue;
    }
    if (r < 0 && d == c) break;     /* every chunk there will be is admitted */
    if (mine && d > c) {            /* chunk c is in another thread's hands */
      kwhere(j, c, &L, &a, &b);
      kmake(j, c, L, a, b, 1);
      j->dups++;
      continue;
    }
    if (!mine && r < 0) return;     /* nothing more to make */
    /* nothing to make now: wait for the admission, more states of an open
       level or the end */
    pthread_mutex_lock(&j->mu);
    j->sleepers++;
    c = __atomic_load_n(&j->done, __ATOMIC_ACQUIRE);
    d = __atomic_load_n(&j->next, __ATOMIC_ACQUIRE);
    if (!__atomic_load_n(&j->stop, __ATOMIC_ACQUIRE) && !(mine && kready(j, c))
        && (d >= c + KWIN || kwhere(j, d, &L, &a, &b) == 0))
      pthread_cond_wait(&j->cv, &j->mu);
    j->sleepers--;
    pthread_mutex_unlock(&j->mu);
  }
  if (mine) {
    __atomic_store_n(&j->stop, 1, __ATOMIC_RELEASE);
    kwake(j);
  }
}

static void *kthread(void *arg) {
  KJob *j = arg;
  PyGILState_STATE g = PyGILState_Ensure();
  PyThreadState *ts = PyEval_SaveThread();
  KT = KHELP = 1;
  kwork(j, &ts, 0);
  kfree_tls();
  KT = KHELP = 0;
  PyEval_RestoreThread(ts);
  PyGILState_Release(g);
  return NULL;
}
static PyObject *explore_levels(PyObject *Py_UNUSED(self), PyObject *args) {
  PyObject *level, *out;
  Py_ssize_t first, start, n, limit, cross;
  int threads;
  double seconds;
  Py_buffer bs, bf, bp, bes = {0}, bed = {0}, bdy = {0}, bsg = {0}, bch = {0}, btb = {0}, btp = {0};
  Py_buffer bel = {0}, bps = {0}, bpc = {0};
  unsigned long long mask;
  PyObject *rec = Py_None, *tcol = Py_None;
  if (!PyArg_ParseTuple(args, "O!nO!niw*w*w*nKnnd|OO", &PyList_Type, &level, &first, &PyList_Type,
                        &out, &start, &threads, &bs, &bf, &bp, &n, &mask, &limit, &cross,
                        &seconds, &rec, &tcol))
    return NULL;
  /* tcol: the temporal columns' arrays (bits, pend: uint64 per state), recorded with rec */
  if (tcol != Py_None && (rec == Py_None || !PyArg_ParseTuple(tcol, "w*|w*", &btb, &btp))) {
    if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "explore_levels: columns without a graph");
    PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bp);
    return NULL;
  }
  Py_ssize_t ne = 0;
  int bycand = 0;
  if (rec != Py_None && !PyArg_ParseTuple(rec, "w*w*nw*|w*w*iw*w*w*", &bes, &bed, &ne, &bdy, &bsg,
                                          &bch, &bycand, &bel, &bps, &bpc)) {
    PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bp);
    if (btb.obj) PyBuffer_Release(&btb);
    if (btp.obj) PyBuffer_Release(&btp);
    return NULL;
  }
  PyObject *res = NULL, *labs = NULL, *lists = NULL, *tms = NULL;
  KJob *j = calloc(1, sizeof(KJob));
  unsigned char *seen = calloc(NLABELS + 1, 1);
  int nth = 0, mine = 0;
  pthread_t th[KTMAX];
  Py_ssize_t end0 = PyList_GET_SIZE(level), nout = PyList_GET_SIZE(out);
  if (start > end0) start = end0;
  if (!j || !seen) { PyErr_NoMemory(); goto done; }
  if (out == level || first < 0 || n < nout || cross < 0 || (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask
      || (Py_ssize_t)(bf.len / 16) < limit || (Py_ssize_t)(bp.len / 4) < limit || limit < n || !XXH
      || (rec != Py_None && (bes.len != bed.len || bes.itemsize != 4 || bed.itemsize != 4
                             || ne < 0 || ne > bes.len / 4 || bdy.len < limit
                             || (bsg.buf && (bsg.itemsize != 8 || bsg.len / 8 < limit
                                               || !bch.buf || bch.len < limit))
                             || (btb.buf && (btb.len / 8 < limit || (btp.buf && btp.len / 8 < limit)))
                             || (bel.buf && (!bsg.buf || bel.itemsize != 4 || bel.len != bes.len
                                             || bps.itemsize != 8 || bps.len / 8 < limit
                                             || bpc.len < limit))))) {
    PyErr_SetString(PyExc_ValueError, "explore_levels: arguments out of range");
    goto done;
  }
  if (KBUSY) { PyErr_SetString(PyExc_RuntimeError, "explore_levels is running"); goto done; }
  memo_lock_init();
  for (Py_ssize_t q = 0; q < KWIN + KTMAX; q++) {
    KChunk *k = KRING + q;
    if (q < KWIN) KSLOT[q] = NULL;
    k->id = -1;
    j->free_[KWIN + KTMAX - 1 - q] = k;
    if (!k->ns) k->ns = malloc(sizeof(int32_t) * KCH);
    if (klabs(k, NLABELS) || !k->ns) { PyErr_NoMemory(); goto done; }
  }
  /* the admitted states' pointers: out's first, then room for `limit` */
  j->nblk = (nout + (limit - n) + KBLK) / KBLK + 1;
  if (!(j->blk = calloc(j->nblk, sizeof(PyObject **)))) { PyErr_NoMemory(); goto done; }
  for (Py_ssize_t q = 0; q < nout; q++) {
    if (!j->blk[q / KBLK] && !(j->blk[q / KBLK] = malloc(sizeof(PyObject *) * KBLK))) {
      PyErr_NoMemory(); goto done;
    }
    j->blk[q / KBLK][q % KBLK] = PyList_GET_ITEM(out, q);
  }
  KBUSY = mine = 1;
  j->level = level; j->first = first; j->start = start; j->end0 = end0;
  j->pfirst = n - nout; j->nptr = nout; j->cross = cross < KMAXLV - 2 ? cross : KMAXLV - 2;
  j->lists[1] = out; j->tn[1] = 0;
  j->known = 1; j->cbase[0] = 0; j->cbase[1] = (end0 - start + KCH - 1) / KCH; j->lo[1] = 0;
  j->slot = KSLOT; j->nfree = KWIN + KTMAX;
  j->slots = bs.buf; j->fps = bf.buf; j->parents = bp.buf; j->mask = mask;
  j->n = j->n0 = n; j->limit = limit; j->seen = seen; j->nseen = NLABELS + 1;
  j->lv = 0; j->pend = end0;
  j->deadline = know() + seconds;
  const char *slow = getenv("PCCL_KERNEL_SLOW_HELPERS");
  j->slow = slow ? atoi(slow) : 0;
  if (rec != Py_None) {
    j->rec = 1; j->bycand = bycand;
    j->esrc = bes.buf; j->edst = bed.buf; j->ne = ne; j->ecap = bes.len / 4;
    j->dyn = bdy.buf;
    j->sig = bsg.buf; j->chg = bch.buf;
    j->tbits = btb.buf; j->tpend = btp.buf;
    if (bel.buf) { j->elab = bel.buf; j->psig = bps.buf; j->pchg = bpc.buf; }
  }
  if (j->cbase[1] == 0) kclose(j, 0);           /* level 0 has nothing left */
  pthread_mutex_init(&j->mu, NULL);
  pthread_cond_init(&j->cv, NULL);
  if (threads > KTMAX) threads = KTMAX;
  PyThreadState *ts = PyEval_SaveThread();
  for (; nth < threads - 1; nth++)
    if (pthread_create(&th[nth], NULL, kthread, j)) break;
  KT = 1;
  kwork(j, &ts, 1);
  KT = 0;
  for (int q = 0; q < nth; q++) pthread_join(th[q], NULL);
  PyEval_RestoreThread(ts);
  pthread_mutex_destroy(&j->mu);
  pthread_cond_destroy(&j->cv);
  seen = j->seen;                   /* (grown with the labels) */
  if (j->why < 0) goto done;
  /* where it stopped: the chunk not admitted (a reason, the deadline), or
     the end of the last level expanded */
  int e, fin = 0;
  Py_ssize_t p, cend;
  if (kwhere(j, j->done, &e, &p, &cend) < 0 && !j->why) {
    fin = 1;                        /* all it was allowed to do */
    e = j->lv;
    p = cend = j->done ? j->pend : end0;
  }
  if (e > 0) { p -= j->lo[e]; cend -= j->lo[e]; }      /* positions in level e's list */
  /* the levels crossed (1..e-1 expanded: their lengths and last states),
     level e's list when e >= 1, its next level's list (made empty if none) */
  Py_ssize_t nl = 0;
  for (Py_ssize_t q = 0; q < NLABELS && q < j->nseen; q++) nl += seen[q];
  if (!(labs = PyTuple_New(nl)) || !(lists = PyTuple_New(e > 0 ? e : 0)) || !(tms = PyTuple_New(e + 1)))
    goto done;
  for (Py_ssize_t q = 0, w = 0; q < NLABELS && q < j->nseen; q++)
    if (seen[q]) {
      PyObject *l = PyList_GET_ITEM(LABELS, q);
      Py_INCREF(l);
      PyTuple_SET_ITEM(labs, w++, l);
    }
  for (int q = 1; q <= e; q++) {    /* (length, last state) of levels 1..e */
    Py_ssize_t len = j->lists[q] ? PyList_GET_SIZE(j->lists[q]) : j->llen[q];
    PyObject *last = j->lists[q] ? (len ? PyList_GET_ITEM(j->lists[q], len - 1) : Py_None) : j->llast[q];
    PyObject *x = Py_BuildValue("(nO)", len, last);
    if (!x) goto done;
    PyTuple_SET_ITEM(lists, q - 1, x);
  }
  for (int q = 1; q <= e + 1; q++) {
    PyObject *tm = j->tn[q] ? PyLong_FromLongLong(j->tmax[q]) : (Py_INCREF(Py_None), Py_None);
    if (!tm) goto done;
    PyTuple_SET_ITEM(tms, q - 1, tm);
  }
  if (!j->lists[e + 1] && !(j->lists[e + 1] = PyList_New(0))) goto done;
  /* (level e's list: None when it is level 0 or expanded, at the end) */
  res = Py_BuildValue("(iniOOOOnOnninO(nnn))", e, p, j->why, e > 0 && j->lists[e] ? j->lists[e] : Py_None,
                      j->lists[e + 1], lists, tms, j->trans, labs, cend, j->n - j->n0, fin, j->ne,
                      KEXC ? KEXC : Py_None, (Py_ssize_t)j->done, j->helped, j->dups);
done:
  if (mine) {                       /* (the interruption handed back, or dropped on an error) */
    Py_CLEAR(KEXC);
    KINTR = 0;
    KBUSY = 0;
  }
  if (j) {
    for (Py_ssize_t q = 2; q <= KMAXLV; q++) Py_XDECREF(j->lists[q]);
    for (Py_ssize_t q = 1; q <= KMAXLV; q++) Py_XDECREF(j->llast[q]);
    Py_XDECREF(j->grave);
    if (j->blk) for (Py_ssize_t q = 0; q < j->nblk; q++) free(j->blk[q]);
    free(j->blk);
  }
  if (j) seen = j->seen;
  free(j); free(seen);
  Py_XDECREF(labs); Py_XDECREF(lists); Py_XDECREF(tms);
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bp);
  Py_buffer *rbs[] = {&bes, &bed, &bdy, &bsg, &bch, &btb, &btp, &bel, &bps, &bpc};
  for (int q = 0; q < 10; q++) if (rbs[q]->obj) PyBuffer_Release(rbs[q]);
  return res;
}
#pragma GCC pop_options
