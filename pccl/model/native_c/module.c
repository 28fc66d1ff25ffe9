/* pccl's native engine: the module's functions Python calls (successors,
   expand, key, fingerprints, violations, ...), its method table and init
   function.  Included by a generated module after reduced.c and
   temporal.c. */
/* the label of buffer entry k: the rule's, or (rule, agent, detail, idx0,
   (0,) * chain length) for a merged transition (reduce.Merger's) */
static PyObject *label_of(Py_ssize_t k) {
  PyObject *l = PyList_GET_ITEM(LABELS, BLAB[k]);
  if (!BCH[k]) { Py_INCREF(l); return l; }
  PyObject *ch = PyTuple_New(BCH[k]);
  if (!ch) return NULL;
  for (Py_ssize_t q = 0; q < BCH[k]; q++) PyTuple_SET_ITEM(ch, q, PyLong_FromLong(0));
  return Py_BuildValue("(OOOiN)", PyTuple_GET_ITEM(l, 0), PyTuple_GET_ITEM(l, 1),
                       PyTuple_GET_ITEM(l, 2), (int)BIDX[k], ch);
}
static PyObject *successors(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  BN = 0; ovf = 0;
  if (rstep(s)) { overflowed(); return NULL; }
  PyObject *out = PyList_New(BN);
  if (!out) return NULL;
  for (Py_ssize_t k = 0; k < BN; k++) {
    PyObject *b = state_bytes(BUF + NS * k);
    PyObject *l = label_of(k);
    if (!b || !l) { Py_XDECREF(b); Py_XDECREF(l); Py_DECREF(out); return NULL; }
    PyList_SET_ITEM(out, k, Py_BuildValue("(NN)", l, b));
  }
  return out;
}
/* expand(states): (successor counts, the successors of all in order, the
   labels met): one call per chunk of a level (want_ids: expand_ids) */
static PyObject *expand_(PyObject *arg, int want_ids) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg), seen = 0, nid = 0, idcap = 0;
  PyObject *ns = PyList_New(n), *flat = PyList_New(0), *labs = NULL;
  int32_t *ids = NULL;
  if (!ns || !flat) goto fail;
  memset(LABSEEN, 0, NLABELS);
  ovf = 0;
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) goto fail;
    BN = 0;
    if (rstep(s)) goto fail;
    for (Py_ssize_t k = 0; k < BN; k++) {
      PyObject *b = state_bytes(BUF + NS * k);
      if (!b) goto fail;
      int r = PyList_Append(flat, b);
      Py_DECREF(b);
      if (r) goto fail;
      LABSEEN[BLAB[k]] = 1;
      if (want_ids) {
        if (nid == idcap) {
          idcap = idcap ? 2 * idcap : 1024;
          int32_t *x = realloc(ids, sizeof(int32_t) * (size_t)idcap);
          if (!x) { PyErr_NoMemory(); goto fail; }
          ids = x;
        }
        ids[nid++] = BLAB[k];
      }
    }
    PyObject *c = PyLong_FromSsize_t(BN);
    if (!c) goto fail;
    PyList_SET_ITEM(ns, i, c);
  }
  for (Py_ssize_t k = 0; k < NLABELS; k++) seen += LABSEEN[k];
  labs = PyTuple_New(seen);
  if (!labs) goto fail;
  for (Py_ssize_t k = 0, w = 0; k < NLABELS; k++)
    if (LABSEEN[k]) {
      PyObject *l = PyList_GET_ITEM(LABELS, k);
      Py_INCREF(l);
      PyTuple_SET_ITEM(labs, w++, l);
    }
  if (want_ids) {
    PyObject *b = PyBytes_FromStringAndSize((const char *)ids, (Py_ssize_t)sizeof(int32_t) * nid);
    free(ids);
    if (!b) { Py_DECREF(ns); Py_DECREF(flat); Py_DECREF(labs); return NULL; }
    return Py_BuildValue("(NNNN)", ns, flat, labs, b);
  }
  return Py_BuildValue("(NNN)", ns, flat, labs);
fail:
  free(ids);
  Py_XDECREF(ns); Py_XDECREF(flat);
  overflowed();
  return NULL;
}
static PyObject *expand(PyObject *Py_UNUSED(self), PyObject *arg) { return expand_(arg, 0); }
/* expand_ids(states): expand(states) and a fourth bytes object, each
   successor's label number (int32, into the label list; the frozen-team
   check's per-transition events) */
static PyObject *expand_ids(PyObject *Py_UNUSED(self), PyObject *arg) { return expand_(arg, 1); }

/* key(state): the state's identity: the canonical vector (symmetry), without
   the clock under time abstraction */
static PyObject *key(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  V c[NS];
  canon(s, c);
  return PyBytes_FromStringAndSize((const char *)c + KEYSKIP, sizeof(V) * NS - KEYSKIP);
}
/* xxhash's XXH3_128bits (setup() passes its address; NULL when the xxhash
   module does not export it) */
typedef struct { uint64_t lo, hi; } H128;
typedef H128 (*xxh128_fn)(const void *, size_t);
static xxh128_fn XXH;
/* the stall signature's hash (pccl/model/stall.py's fields): xxh3 of the
   signature's slots gathered, else a slot-by-slot mix (equal signatures
   give equal hashes either way; only equality is read) */
static inline void gather(const V *s, const int *slots, int nslots, V *g) {
  for (int q = 0; q < nslots; q++) g[q] = s[slots[q]];
}
static int64_t slothash(const V *s, const int *slots, int nslots) {
  if (XXH) {
    V g[NSIGSLOTS > NPSIGSLOTS ? NSIGSLOTS : NPSIGSLOTS];
    gather(s, slots, nslots, g);
    H128 x = XXH(g, sizeof(V) * (size_t)nslots);
    return (int64_t)(x.lo ^ x.hi);
  }
  uint64_t h = 0x9E3779B97F4A7C15ULL;
  for (int q = 0; q < nslots; q++) {
    uint64_t z = (uint64_t)s[slots[q]] + 0x9E3779B97F4A7C15ULL * (uint64_t)(q + 1);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    h = (h ^ (z ^ (z >> 31))) * 0x100000001B3ULL;
    h ^= h >> 29;
  }
  return (int64_t)h;
}
static int64_t sighash(const V *s) { return slothash(s, SIGSLOTS, NSIGSLOTS); }
/* the frozen-team check's progress signature (pccl/model/frozen.py): the
   stall signature's slots without the lock queue, the env and the doReach
   flags */
static int64_t psighash(const V *s) { return slothash(s, PSIGSLOTS, NPSIGSLOTS); }
/* packed(state): the state's bytes in the form the explorer holds (state_bytes) */
static PyObject *packed(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  return s ? state_bytes(s) : NULL;
}
/* unpacked(state): the state's int64 vector, as bytes (arg_state) */
static PyObject *unpacked(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  return s ? PyBytes_FromStringAndSize((const char *)s, sizeof(V) * NS) : NULL;
}
/* sig(state): the stall signature's hash */
static PyObject *sig(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  return PyLong_FromLongLong((long long)sighash(s));
}
/* progsig(state): the progress signature itself, what psighash hashes (the
   slots PSIGSLOTS, generated: pccl/model/frozen.py's fields), as bytes:
   the frozen-team check's re-exploration compares them for equality, no
   hash between (frozen.py _explore) */
static PyObject *progsig(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  V g[NPSIGSLOTS + 1];
  gather(s, PSIGSLOTS, NPSIGSLOTS, g);
  return PyBytes_FromStringAndSize((const char *)g, sizeof(V) * NPSIGSLOTS);
}
/* the hash fn of each state of a list, as int64s in one bytes object */
static PyObject *hash_each(PyObject *arg, int64_t (*fn)(const V *)) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyBytes_FromStringAndSize(NULL, n * (Py_ssize_t)sizeof(int64_t));
  if (!out) return NULL;
  int64_t *o = (int64_t *)PyBytes_AS_STRING(out);
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) { Py_DECREF(out); return NULL; }
    o[i] = fn(s);
  }
  return out;
}
/* sigs(states): sig of each state of a list */
static PyObject *sigs(PyObject *Py_UNUSED(self), PyObject *arg) { return hash_each(arg, sighash); }
/* psigs(states): the progress signature's hash (psighash) of each state of a list */
static PyObject *psigs(PyObject *Py_UNUSED(self), PyObject *arg) { return hash_each(arg, psighash); }
/* reach_back(src, dst, can, sweeps): marks in can (bytes 0/1, writable) every
   state with a transition into a marked one, until nothing changes: the
   transitions src[e] -> dst[e] (uint32s, sorted by source) are swept from the
   last to the first, so a breadth-first graph (most transitions lead to a
   later state) settles in a few sweeps.  Returns the sweeps made, or -1 when
   the last of at most `sweeps` still changed something (not settled: can
   holds a part of the answer).  The graph analysis' backward reachability
   (pccl/search/liveness.py Graph.can_reach) */
static PyObject *reach_back(PyObject *Py_UNUSED(self), PyObject *args) {
  Py_buffer bs, bd, bc;
  int most;
  if (!PyArg_ParseTuple(args, "y*y*w*i", &bs, &bd, &bc, &most)) return NULL;
  if (bs.len != bd.len || bs.itemsize != 4 || bd.itemsize != 4) {
    PyBuffer_Release(&bs); PyBuffer_Release(&bd); PyBuffer_Release(&bc);
    PyErr_SetString(PyExc_ValueError, "two uint32 arrays of one length");
    return NULL;
  }
  const uint32_t *src = (const uint32_t *)bs.buf, *dst = (const uint32_t *)bd.buf;
  unsigned char *can = (unsigned char *)bc.buf;
  Py_ssize_t m = bs.len / 4, lim = bc.len;
  int sweeps = 0, changed = 1, bad = 0;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t e = 0; e < m; e++)
    if (src[e] >= (uint64_t)lim || dst[e] >= (uint64_t)lim) { bad = 1; break; }
  while (!bad && changed && sweeps < most) {
    changed = 0;
    sweeps++;
    for (Py_ssize_t e = m - 1; e >= 0; e--)
      if (can[dst[e]] && !can[src[e]]) { can[src[e]] = 1; changed = 1; }
  }
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bd); PyBuffer_Release(&bc);
  if (bad) { PyErr_SetString(PyExc_ValueError, "a state number out of range"); return NULL; }
  return PyLong_FromLong(changed ? -1 : sweeps);
}
/* The fingerprint table's index (pccl/search/explorer.py FingerprintTable:
   linear probing of uint32 state numbers, keyed by the fingerprint's second
   word, 0xFFFFFFFF empty) probed and filled in C, the arrays numpy's.
   table_lookup(slots, fps, q, out, mask): out[i] = the state number of
   fingerprint q[i] (two uint64s), or -1.  table_place(slots, fps, idx, mask):
   index the state numbers idx (uint32s, distinct, absent). */
#define TEMPTY 0xFFFFFFFFu
static PyObject *table_lookup(PyObject *Py_UNUSED(self), PyObject *args) {
  Py_buffer bs, bf, bq, bo;
  unsigned long long mask;
  if (!PyArg_ParseTuple(args, "y*y*y*w*K", &bs, &bf, &bq, &bo, &mask)) return NULL;
  const uint32_t *slots = (const uint32_t *)bs.buf;
  const uint64_t *fps = (const uint64_t *)bf.buf, *q = (const uint64_t *)bq.buf;
  int64_t *out = (int64_t *)bo.buf;
  Py_ssize_t k = bq.len / 16, nf = bf.len / 16;
  int bad = (Py_ssize_t)(bo.len / 8) < k || (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t i = 0; i < k && !bad; i++) {
    if (i + 8 < k) __builtin_prefetch(&slots[q[2 * (i + 8) + 1] & mask]);
    uint64_t lo = q[2 * i], hi = q[2 * i + 1];
    size_t pos = hi & mask;
    for (;;) {
      uint32_t e = slots[pos];
      if (e == TEMPTY) { out[i] = -1; break; }
      if ((Py_ssize_t)e >= nf) { bad = 1; break; }
      if (fps[2 * (size_t)e + 1] == hi && fps[2 * (size_t)e] == lo) { out[i] = e; break; }
      pos = (pos + 1) & mask;
    }
  }
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bq); PyBuffer_Release(&bo);
  if (bad) { PyErr_SetString(PyExc_ValueError, "table arrays of the wrong size"); return NULL; }
  Py_RETURN_NONE;
}
static PyObject *table_place(PyObject *Py_UNUSED(self), PyObject *args) {
  Py_buffer bs, bf, bi;
  unsigned long long mask;
  if (!PyArg_ParseTuple(args, "w*y*y*K", &bs, &bf, &bi, &mask)) return NULL;
  uint32_t *slots = (uint32_t *)bs.buf;
  const uint64_t *fps = (const uint64_t *)bf.buf;
  const uint32_t *idx = (const uint32_t *)bi.buf;
  Py_ssize_t k = bi.len / 4, nf = bf.len / 16;
  int bad = (Py_ssize_t)(bs.len / 4) <= (Py_ssize_t)mask;
  Py_BEGIN_ALLOW_THREADS
  for (Py_ssize_t i = 0; i < k && !bad; i++) {
    if ((Py_ssize_t)idx[i] >= nf) { bad = 1; break; }
    size_t pos = fps[2 * (size_t)idx[i] + 1] & mask;
    while (slots[pos] != TEMPTY) pos = (pos + 1) & mask;
    slots[pos] = idx[i];
  }
  Py_END_ALLOW_THREADS
  PyBuffer_Release(&bs); PyBuffer_Release(&bf); PyBuffer_Release(&bi);
  if (bad) { PyErr_SetString(PyExc_ValueError, "table arrays of the wrong size"); return NULL; }
  Py_RETURN_NONE;
}
/* 1 into a dynamic state (a TIME ADVANCE), else 0: the graph's time cost */
static inline unsigned char phase_cost(const V *s) {
  return s[V_PHASE] != PH_DISCRETE;
}
/* phases(states): per state 1 if it is dynamic (after TIME ADVANCE), as bytes */
static PyObject *phases(PyObject *Py_UNUSED(self), PyObject *arg) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyBytes_FromStringAndSize(NULL, n);
  if (!out) return NULL;
  char *o = PyBytes_AS_STRING(out);
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) { Py_DECREF(out); return NULL; }
    o[i] = phase_cost(s);
  }
  return out;
}
/* fingerprints(states): (the 16-byte fingerprints of their keys, in order,
   as one bytes object; the positions, ascending, of each key's first
   occurrence, as int64s; per state the position of its key's first
   occurrence, as int64s).  A fingerprint is pccl.search.fingerprint's: xxh3_128 of
   marshal version 2 of the key (a bytes object: 's', its length as a
   little-endian int32, its bytes), in xxhash's canonical (big-endian) form */
/* fingerprint_of(t, out): state t's fingerprint as the table holds it, two
   words whose bytes are the canonical form */
static void fingerprint_of(const V *t, uint64_t *out) {
  size_t klen = sizeof(V) * NS - KEYSKIP;
  unsigned char buf[5 + sizeof(V) * NS];
  buf[0] = 's';
  buf[1] = klen & 255; buf[2] = (klen >> 8) & 255; buf[3] = (klen >> 16) & 255; buf[4] = (klen >> 24) & 255;
  V c[NS];
  canon(t, c);
  memcpy(buf + 5, (const char *)c + KEYSKIP, klen);
  H128 h = XXH(buf, 5 + klen);
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
  out[0] = h.hi; out[1] = h.lo;
#else
  out[0] = __builtin_bswap64(h.hi); out[1] = __builtin_bswap64(h.lo);
#endif
}
static PyObject *fingerprints_(PyObject *arg, int want_sigs) {
  if (!PyList_Check(arg) || !XXH) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg), m = 0;
  PyObject *sgs = want_sigs ? PyBytes_FromStringAndSize(NULL, 8 * n) : NULL;
  if (want_sigs && !sgs) return NULL;
  int64_t *sg = sgs ? (int64_t *)PyBytes_AS_STRING(sgs) : NULL;
  size_t size = 16;
  while (size < 2 * (size_t)n) size <<= 1;
  uint32_t *tab = calloc(size, sizeof(uint32_t));
  PyObject *blob = PyBytes_FromStringAndSize(NULL, 16 * n);
  PyObject *first = PyBytes_FromStringAndSize(NULL, 8 * n);
  PyObject *occ = PyBytes_FromStringAndSize(NULL, 8 * n);
  if (!tab || !blob || !first || !occ) goto fail;
  unsigned char *out = (unsigned char *)PyBytes_AS_STRING(blob);
  int64_t *fo = (int64_t *)PyBytes_AS_STRING(first);
  int64_t *oc = (int64_t *)PyBytes_AS_STRING(occ);
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) goto fail;
    if (sg) sg[i] = sighash(s);       /* while the state is in the cache */
    uint64_t f[2];
    fingerprint_of(s, f);
    memcpy(out + 16 * i, f, 16);
    size_t slot = (size_t)(f[0] ^ f[1]) & (size - 1);
    for (;;) {
      uint32_t e = tab[slot];
      if (!e) { tab[slot] = (uint32_t)i + 1; fo[m++] = i; oc[i] = i; break; }
      if (!memcmp(out + 16 * (e - 1), out + 16 * i, 16)) { oc[i] = e - 1; break; }
      slot = (slot + 1) & (size - 1);
    }
  }
  free(tab);
  if (_PyBytes_Resize(&first, 8 * m)) { Py_DECREF(blob); Py_DECREF(occ); Py_XDECREF(sgs); return NULL; }
  if (sgs) return Py_BuildValue("(NNNN)", blob, first, occ, sgs);
  return Py_BuildValue("(NNN)", blob, first, occ);
fail:
  free(tab);
  Py_XDECREF(blob); Py_XDECREF(first); Py_XDECREF(occ); Py_XDECREF(sgs);
  return NULL;
}
static PyObject *fingerprints(PyObject *Py_UNUSED(self), PyObject *arg) {
  return fingerprints_(arg, 0);
}
/* fingerprints_sigs(states): fingerprints(states) and a fourth bytes object,
   sig of each state (int64s), computed in the same pass */
static PyObject *fingerprints_sigs(PyObject *Py_UNUSED(self), PyObject *arg) {
  return fingerprints_(arg, 1);
}
/* no agent stuck, the lock's holder has not exited, every invariant holds
   (okexpr: step.c) */
static inline int okstate(const V *s) {
  ovf = 0;
  int r = okexpr(s);
  return ovf ? 0 : r;
}
static PyObject *ok(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  int r = okstate(s);
  if (PyErr_Occurred()) return NULL;
  return PyBool_FromLong(r);
}
/* violations(state): [] when okstate, else SLOWVIOL(state) (the Python
   model's own violations of the decoded configuration) */
static PyObject *SLOWVIOL;
static PyObject *violations(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  if (okstate(s)) return PyList_New(0);
  if (PyErr_Occurred()) return NULL;        /* (a property memo site's miss raised) */
  return PyObject_CallOneArg(SLOWVIOL, arg);
}
/* suspects(states): the positions, ascending, of the states of a list that
   okstate does not pass (violations(state) may be non-empty only there):
   one call for a batch instead of one per state */
static PyObject *suspects(PyObject *Py_UNUSED(self), PyObject *arg) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg);
  PyObject *out = PyList_New(0);
  if (!out) return NULL;
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) { Py_DECREF(out); return NULL; }
    if (!okstate(s)) {
      if (PyErr_Occurred()) { Py_DECREF(out); return NULL; }
      PyObject *j = PyLong_FromSsize_t(i);
      if (!j || PyList_Append(out, j)) { Py_XDECREF(j); Py_DECREF(out); return NULL; }
      Py_DECREF(j);
    }
  }
  return out;
}
static PyObject *memo_stats(PyObject *Py_UNUSED(self), PyObject *Py_UNUSED(unused)) {
  return Py_BuildValue("(nnn)", (Py_ssize_t)MEMO_N, (Py_ssize_t)MEMO_MISS, (Py_ssize_t)MEMO_HIT);
}
static PyObject *clock_(PyObject *Py_UNUSED(self), PyObject *arg) {
  V sb[NS]; const V *s = arg_state(arg, sb);
  if (!s) return NULL;
  return PyLong_FromLongLong(s[V_TIME]);
}
/* max_clock(states): the largest time of a list of states (None: empty) */
static PyObject *max_clock(PyObject *Py_UNUSED(self), PyObject *arg) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg);
  if (!n) Py_RETURN_NONE;
  long long m = 0;
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) return NULL;
    if (!i || s[V_TIME] > m) m = s[V_TIME];
  }
  return PyLong_FromLongLong(m);
}
static PyObject *setup(PyObject *Py_UNUSED(self), PyObject *args) {
  PyObject *labels, *exc, *slow, *miss;
  unsigned long long xxh;
  if (!PyArg_ParseTuple(args, "O!OOKO", &PyList_Type, &labels, &exc, &slow, &xxh, &miss))
    return NULL;
  Py_XDECREF(LABELS); Py_XDECREF(OverflowExc); Py_XDECREF(SLOWVIOL); Py_XDECREF(MISS);
  Py_INCREF(labels); Py_INCREF(exc); Py_INCREF(slow); Py_INCREF(miss);
  LABELS = labels; OverflowExc = exc; SLOWVIOL = slow; MISS = miss;
  memo_clear();
  NLABELS = 0;
  if (labels_grown()) return NULL;
  XXH = (xxh128_fn)(uintptr_t)xxh;
  Py_RETURN_NONE;
}
static PyObject *explore_levels(PyObject *self, PyObject *args);   /* kernel.c */
static PyMethodDef methods[] = {
  {"successors", successors, METH_O, "labelled successors of a state"},
  {"ok", ok, METH_O, "no stuck agent, the lock fine, every invariant holds"},
  {"expand", expand, METH_O, "successor counts, flat successors and labels of a list of states"},
  {"fingerprints", fingerprints, METH_O, "fingerprints and first occurrences of a list of states"},
  {"fingerprints_sigs", fingerprints_sigs, METH_O, "fingerprints, first occurrences and stall signatures"},
  {"reach_back", reach_back, METH_VARARGS, "backward reachability over a transition list"},
  {"table_lookup", table_lookup, METH_VARARGS, "the fingerprint table's lookups"},
  {"table_place", table_place, METH_VARARGS, "the fingerprint table's index filled"},
  {"violations", violations, METH_O, "[] or the Python model's violations"},
  {"suspects", suspects, METH_O, "the positions of the states okstate does not pass"},
  {"clock", clock_, METH_O, "the state's time"},
  {"max_clock", max_clock, METH_O, "the largest time of a list of states"},
  {"key", key, METH_O, "the state's identity (canonical under symmetry)"},
  {"sig", sig, METH_O, "the stall signature's hash"},
  {"progsig", progsig, METH_O, "the progress signature's slots"},
  {"sigs", sigs, METH_O, "the stall signatures' hashes of a list of states, as int64s"},
  {"psigs", psigs, METH_O, "the progress signatures' hashes of a list of states, as int64s"},
  {"expand_ids", expand_ids, METH_O, "expand, and each successor's label number (int32s)"},
  {"packed", packed, METH_O, "a state's bytes in the form the explorer holds"},
  {"unpacked", unpacked, METH_O, "a state's int64 vector, as bytes"},
  {"phases", phases, METH_O, "1 per dynamic state"},
  {"setup", setup, METH_VARARGS, "labels and the overflow exception"},
  {"memo_stats", memo_stats, METH_NOARGS, "(entries, misses, hits) of the memo"},
  {"explore_levels", explore_levels, METH_VARARGS, "levels expanded and admitted, on threads"},
  TEMPORAL_METHODS                  /* temporal.c */
  ROBOTS_METHODS
  {NULL, NULL, 0, NULL}
};
static struct PyModuleDef mod = {PyModuleDef_HEAD_INIT, MODNAME, NULL, -1, methods, NULL, NULL, NULL, NULL};
PyMODINIT_FUNC INITFN(void) { return PyModule_Create(&mod); }
