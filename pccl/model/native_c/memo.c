/* pccl's native engine: the memo sites (Generator.case_memo, env_site):
   a hash table from (site, the values of the slots the site reads) to its
   successors' labels and the values of the slots it writes, filled by
   NativeModel._miss.  Included by a generated module after native.h. */
#include <pthread.h>
static PyObject *MISS, *LABELS;
static unsigned char *LABSEEN;
static Py_ssize_t NLABELS;
/* per label its agent (-1: none): labels grow on memo misses.  The level
   kernel's threads read it while another thread's miss adds labels, so it
   is never moved: a larger one is made, filled and published, the old one
   left as it is (the labels are hundreds at most) */
static int *LABAG;
static Py_ssize_t LABCAP;
static int labels_grown(void) {
  Py_ssize_t nl = PyList_GET_SIZE(LABELS), cap = LABCAP;
  unsigned char *x = realloc(LABSEEN, nl + 1);
  if (!x) { PyErr_NoMemory(); return -1; }
  LABSEEN = x;
  int *y = LABAG;
  if (nl + 1 > cap) {
    cap = cap ? 2 * cap : 256;
    while (cap < nl + 1) cap *= 2;
    if (!(y = malloc(sizeof(int) * cap))) { PyErr_NoMemory(); return -1; }
    if (NLABELS) memcpy(y, LABAG, sizeof(int) * NLABELS);
  }
  for (Py_ssize_t k = NLABELS; k < nl; k++) {
    LABSEEN[k] = 0;
    PyObject *a = PyTuple_GetItem(PyList_GET_ITEM(LABELS, k), 1);
    if (!a) { if (y != LABAG) free(y); return -1; }
    y[k] = a == Py_None ? -1 : (int)PyLong_AsLong(a);
  }
  __atomic_store_n(&LABAG, y, __ATOMIC_RELEASE);
  LABCAP = cap;
  __atomic_store_n(&NLABELS, nl, __ATOMIC_RELEASE);
  return 0;
}
/* the arena: per entry [klen, vlen, key..., value...]; value = [n, then n
   times (label, the written slots' values)] */
static V *MA;
static size_t MA_N, MA_CAP;
static size_t *MSLOT, MSLOT_CAP, MEMO_N, MEMO_MISS, MEMO_HIT;
static void memo_clear(void) {
  free(MA); free(MSLOT);
  MA = NULL; MSLOT = NULL; MA_N = MA_CAP = MSLOT_CAP = MEMO_N = MEMO_MISS = MEMO_HIT = 0;
}
static uint64_t mhash(const V *k, int n) {
  uint64_t h = 0x9E3779B97F4A7C15ULL ^ (uint64_t)n;
  for (int q = 0; q < n; q++) { h ^= (uint64_t)k[q]; h *= 0xBF58476D1CE4E5B9ULL; h ^= h >> 31; }
  return h;
}
static const V *memo_find(const V *key, int kl) {
  if (!MSLOT_CAP) return NULL;
  size_t sl = mhash(key, kl) & (MSLOT_CAP - 1);
  for (;;) {
    size_t o = MSLOT[sl];
    if (!o) return NULL;
    const V *e = MA + (o - 1);
    if (e[0] == kl && !memcmp(e + 2, key, sizeof(V) * kl)) return e + 2 + kl;
    sl = (sl + 1) & (MSLOT_CAP - 1);
  }
}
static int memo_rehash(void) {
  size_t cap = MSLOT_CAP ? 2 * MSLOT_CAP : 4096;
  size_t *t = calloc(cap, sizeof(size_t));
  if (!t) { PyErr_NoMemory(); return -1; }
  for (size_t o = 0; o < MA_N; ) {
    const V *e = MA + o;
    size_t sl = mhash(e + 2, (int)e[0]) & (cap - 1);
    while (t[sl]) sl = (sl + 1) & (cap - 1);
    t[sl] = o + 1;
    o += 2 + e[0] + e[1];
  }
  free(MSLOT); MSLOT = t; MSLOT_CAP = cap;
  return 0;
}
static const V *memo_put(const V *key, int kl, const V *val, Py_ssize_t vl) {
  if (2 * (MEMO_N + 1) > MSLOT_CAP && memo_rehash()) return NULL;
  size_t need = MA_N + 2 + kl + vl;
  if (need > MA_CAP) {
    size_t cap = MA_CAP ? MA_CAP : 65536;
    while (cap < need) cap *= 2;
    V *a = realloc(MA, sizeof(V) * cap);
    if (!a) { PyErr_NoMemory(); return NULL; }
    MA = a; MA_CAP = cap;
  }
  V *e = MA + MA_N;
  e[0] = kl; e[1] = vl;
  memcpy(e + 2, key, sizeof(V) * kl);
  memcpy(e + 2 + kl, val, sizeof(V) * vl);
  size_t sl = mhash(key, kl) & (MSLOT_CAP - 1);
  while (MSLOT[sl]) sl = (sl + 1) & (MSLOT_CAP - 1);
  MSLOT[sl] = MA_N + 1;
  MA_N = need; MEMO_N++;
  return e + 2 + kl;
}
/* a miss: MISS(site, state) -> (value as int64 bytes, the label list grew) */
/* wl: the lock to hold alone while inserting (the level kernel's), or NULL */
static const V *memo_miss(const V *s, const V *key, int kl, pthread_rwlock_t *wl) {
  MEMO_MISS++;
  PyObject *st = state_bytes(s);
  if (!st) return NULL;
  PyObject *r = PyObject_CallFunction(MISS, "nN", (Py_ssize_t)key[0], st);
  if (!r) return NULL;
  PyObject *val = PyTuple_GetItem(r, 0);
  if (!val || !PyBytes_Check(val)) {
    Py_DECREF(r);
    if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "memo miss: not bytes");
    return NULL;
  }
  if (wl) pthread_rwlock_wrlock(wl);
  const V *out = PyList_GET_SIZE(LABELS) > NLABELS && labels_grown() ? NULL
      : memo_put(key, kl, (const V *)PyBytes_AS_STRING(val),
                 PyBytes_GET_SIZE(val) / (Py_ssize_t)sizeof(V));
  if (wl) pthread_rwlock_unlock(wl);
  Py_DECREF(r);
  return out;
}
static int EMIT(int lab, const V *t);
#define MEMO_KMAX (NS + 1)
/* the level kernel's threads (KT) share the memo: a reader holds MLOCK
   shared while it reads an entry (an insertion may move the arena).  A
   miss, one at a time (MMISS), calls Python with the GIL taken (the kernel
   runs without it) while the others go on reading, and holds MLOCK alone
   only to insert its entry.  Lock order: MMISS, the GIL, MLOCK; the thread
   admitting (the GIL held) takes none of them.  An error in the miss is
   left to the explorer's batches, which expand the chunk again holding the
   GIL and raise it. */
static pthread_rwlock_t MLOCK;
static pthread_mutex_t MMISS = PTHREAD_MUTEX_INITIALIZER;
static int MLOCK_READY;
/* an interruption (KeyboardInterrupt: Ctrl-C, SIGTERM) raised in a miss's
   Python code: kept for explore_levels to hand back with its figures, and
   KINTR stops the kernel's threads */
static PyObject *KEXC;
static int KINTR;
static void memo_lock_init(void) {       /* (before the kernel's threads start) */
  if (MLOCK_READY) return;
  pthread_rwlockattr_t at;
  pthread_rwlockattr_init(&at);
#ifdef __GLIBC__                          /* a waiting insertion goes before new readers */
  pthread_rwlockattr_setkind_np(&at, PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP);
#endif
  pthread_rwlock_init(&MLOCK, &at);
  pthread_rwlockattr_destroy(&at);
  MLOCK_READY = 1;
}
/* in the kernel, MLOCK not held: the entry of key, filled if missing;
   returns with MLOCK held shared (NULL: an error, MLOCK not held) */
static const V *memo_miss_kernel(const V *s, const V *key, int kl) {
  pthread_mutex_lock(&MMISS);
  pthread_rwlock_rdlock(&MLOCK);
  const V *val = memo_find(key, kl);      /* (another thread's miss may have filled it) */
  if (val) { pthread_mutex_unlock(&MMISS); return val; }
  pthread_rwlock_unlock(&MLOCK);
  PyGILState_STATE g = PyGILState_Ensure();
  KT = 0;
  int ok = memo_miss(s, key, kl, &MLOCK) != NULL;   /* (the entry is found again below) */
  if (!ok && !KEXC && PyErr_ExceptionMatches(PyExc_BaseException)
      && !PyErr_ExceptionMatches(PyExc_Exception)) {
    PyObject *et, *ev, *tb;
    PyErr_Fetch(&et, &ev, &tb);
    PyErr_NormalizeException(&et, &ev, &tb);
    if (tb && ev) PyException_SetTraceback(ev, tb);
    Py_XDECREF(et); Py_XDECREF(tb);
    KEXC = ev;
    __atomic_store_n(&KINTR, 1, __ATOMIC_RELEASE);
  }
  if (!ok) PyErr_Clear();
  KT = 1;
  PyGILState_Release(g);
  if (ok) {
    pthread_rwlock_rdlock(&MLOCK);
    val = memo_find(key, kl);
  }
  pthread_mutex_unlock(&MMISS);
  return val;
}
/* robots.c: a miss of DOREACH INVOKE's site made in C (NULL with ROBOTS_PY
   set: Python makes it) */
static const V *robots_fill(const V *s, int k, const V *key, int kl, int kt);
static __thread int ROBOTS_PY;
/* the successors of site k in state s: each a copy of s with the written
   slots W_ set (the rule's own label); unused in a program without memo sites */
static MAYBE_UNUSED int memo_site(const V *s, int k, const int *R_, int nr, const int *W_, int nw) {
  V key[MEMO_KMAX];
  key[0] = k;
  for (int q = 0; q < nr; q++) key[1 + q] = s[R_[q]];
  int kt = KT;
  if (kt) pthread_rwlock_rdlock(&MLOCK);
  const V *val = memo_find(key, nr + 1);
  if (val) {
    if (kt) __atomic_fetch_add(&MEMO_HIT, 1, __ATOMIC_RELAXED);
    else MEMO_HIT++;
  } else if (!kt) {
    if (!(val = robots_fill(s, k, key, nr + 1, 0))) {
      if (!ROBOTS_PY) { PyErr_NoMemory(); ovf = 1; return -1; }
      if (!(val = memo_miss(s, key, nr + 1, NULL))) { ovf = 1; return -1; }
    }
  } else {
    pthread_rwlock_unlock(&MLOCK);
    if (!(val = robots_fill(s, k, key, nr + 1, 1))) {  /* (MLOCK held shared when made) */
      if (!ROBOTS_PY) { ovf = 1; return -1; }   /* (no memory: the batches raise it) */
      if (KHELP) { KDEFER = 1; return -1; }     /* (the calling thread's to fill) */
      if (!(val = memo_miss_kernel(s, key, nr + 1))) { ovf = 1; return -1; }
    }
  }
  V n = val[0];
  const V *p = val + 1;
  int r = 0;
  for (V c = 0; c < n && !r; c++, p += 1 + nw) {
    V t[NS];
    memcpy(t, s, sizeof t);
    for (int q = 0; q < nw; q++) t[W_[q]] = p[1 + q];
    r = EMIT((int)p[0], t);
  }
  if (kt) pthread_rwlock_unlock(&MLOCK);
  return r ? -1 : 0;
}
/* the value of property memo site k in state s (Generator.pmemo): an int
   the site's Python predicate gave for the values of the slots R_ it reads.
   Undefined (the predicate raised, or gave what a slot does not hold), a
   miss another thread must fill (KDEFER) or an error set ovf: okstate then
   fails, and the Python model's violations decide the state */
static MAYBE_UNUSED V memo_value(const V *s, int k, const int *R_, int nr) {
  V key[MEMO_KMAX];
  key[0] = k;
  for (int q = 0; q < nr; q++) key[1 + q] = s[R_[q]];
  int kt = KT;
  if (kt) pthread_rwlock_rdlock(&MLOCK);
  const V *val = memo_find(key, nr + 1);
  if (val) {
    if (kt) __atomic_fetch_add(&MEMO_HIT, 1, __ATOMIC_RELAXED);
    else MEMO_HIT++;
  } else if (!kt) {
    if (!(val = memo_miss(s, key, nr + 1, NULL))) { ovf = 1; return 0; }
  } else {
    pthread_rwlock_unlock(&MLOCK);
    if (KHELP) { KDEFER = 1; ovf = 1; return 0; }     /* (the calling thread's to fill) */
    if (!(val = memo_miss_kernel(s, key, nr + 1))) { ovf = 1; return 0; }
  }
  V v = val[0];
  if (kt) pthread_rwlock_unlock(&MLOCK);
  if (v == INT64_MIN) ovf = 1;
  return v;
}
