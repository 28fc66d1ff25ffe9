/* pccl's native engine: the temporal properties' graph (issue 46), included
   by a generated module after its tpred() (the properties' state
   predicates, NTP of them, the n-th setting bit TPBIT[n] of the columns)
   and TPEND (1: the program moves and a robot under way arrives, fairly),
   before module.c, whose method table lists TEMPORAL_METHODS.

   tcols(s, &bits, &pend): the graph recorder's per-state columns of the
   temporal properties (bit 2k for property k's P and 2k + 1 for its Q),
   and the robots whose doReach is under way (search_view.arrival_pending,
   by the classes of the interned position ids, TPOINT: temporal.h).
   Returns 1 when Python must decide a column (a predicate met an undefined
   value, an overflow, a division by zero; a position id without a class).

   tcolumns(states): the graph recorder's columns of a list of states
   (pccl/search/liveness.py StateColumns): (bits, pend, unsure) as bytes,
   uint64 per state the properties' P/Q bits and the robots under way, and
   int64 the positions whose columns Python must compute (tcols() said so).

   pcls_set(id, cls): the point class of an interned id (temporal.h).

   scc(fptr, fdst, allowed, nodes, comp): Tarjan's strongly connected
   components, iterative, of the subgraph of the CSR graph (fptr: uint32 or
   int64 offsets, fdst: uint32 targets) induced by `allowed` (a byte per
   state), for the roots `nodes` (int64) in order, edges in CSR order: the
   very numbering of liveness.py Graph.sccs (a component's id is the order
   in which it is completed).  Writes comp (int64 per state, -1 outside);
   returns the per-component "has a cycle" flags as bytes. */
static int tcols(const V *s, uint64_t *bits, uint64_t *pend) {
  int saved = ovf, unsure = 0;
  uint64_t b = 0, pm = 0;
  for (int n = 0; n < NTP; n++) {
    ovf = 0;
    V x = tpred(n, s);
    if (ovf) unsure = 1;
    else if (x) b |= 1ULL << TPBIT[n];
  }
#if TPEND
  for (int i = 0; i < NAG; i++) {
    const V *o = s + AG0 + AW * i + MV;
    if (!o[4] && !o[5]) {
      int ct = pcls(o[1]);
      if (ct != -1) {
        int cp = pcls(o[0]);
        if (ct < -1 || cp < -1) unsure = 1;
        else if (ct != cp) pm |= 1ULL << i;
      }
    }
  }
#endif
  ovf = saved;
  *bits = b; *pend = pm;
  return unsure;
}
static PyObject *tcolumns(PyObject *Py_UNUSED(self), PyObject *arg) {
  if (!PyList_Check(arg)) { PyErr_SetString(PyExc_TypeError, "a list of states"); return NULL; }
  Py_ssize_t n = PyList_GET_SIZE(arg), nu = 0;
  PyObject *bo = PyBytes_FromStringAndSize(NULL, 8 * n), *po = PyBytes_FromStringAndSize(NULL, 8 * n);
  int64_t *un = malloc(8 * (n ? n : 1));
  if (!bo || !po || !un) { Py_XDECREF(bo); Py_XDECREF(po); free(un); return PyErr_NoMemory(); }
  uint64_t *b = (uint64_t *)PyBytes_AS_STRING(bo), *p = (uint64_t *)PyBytes_AS_STRING(po);
  for (Py_ssize_t i = 0; i < n; i++) {
    V sb[NS]; const V *s = arg_state(PyList_GET_ITEM(arg, i), sb);
    if (!s) { Py_DECREF(bo); Py_DECREF(po); free(un); return NULL; }
    if (tcols(s, b + i, p + i)) un[nu++] = i;
  }
  PyObject *uo = PyBytes_FromStringAndSize((const char *)un, 8 * nu);
  free(un);
  if (!uo) { Py_DECREF(bo); Py_DECREF(po); return NULL; }
  return Py_BuildValue("(NNN)", bo, po, uo);
}
static PyObject *pcls_set(PyObject *Py_UNUSED(self), PyObject *args) {
  long long id;
  int cls;
  if (!PyArg_ParseTuple(args, "Li", &id, &cls)) return NULL;
  if (id >= 0 && id < TPOINT_CAP && cls >= -1) __atomic_store_n(&TPOINT[id], cls + 2, __ATOMIC_RELEASE);
  Py_RETURN_NONE;
}
static PyObject *scc(PyObject *Py_UNUSED(self), PyObject *args) {
  Py_buffer bp, bd, ba, bn, bc;
  if (!PyArg_ParseTuple(args, "y*y*y*y*w*", &bp, &bd, &ba, &bn, &bc)) return NULL;
  Py_ssize_t n = ba.len, m = bd.len / 4, nn = bn.len / 8;
  int wide = bp.itemsize == 8 || bp.len == 8 * (n + 1);
  const uint32_t *p32 = bp.buf, *dst = bd.buf;
  const int64_t *p64 = bp.buf, *nodes = bn.buf;
  const unsigned char *allowed = ba.buf;
  int64_t *comp = bc.buf;
  PyObject *res = NULL;
  int64_t *index = NULL, *low = NULL, *stack = NULL, *wv = NULL, *we = NULL;
  unsigned char *onst = NULL, *cyc = NULL;
  Py_ssize_t ncomp = 0, ccap = 1024;
  int bad = bd.itemsize != 4 || bn.itemsize != 8 || bc.len != 8 * n
            || bp.len != (wide ? 8 : 4) * (n + 1);
  if (bad) { PyErr_SetString(PyExc_ValueError, "scc: arrays of the wrong size"); goto done; }
  index = malloc(8 * (n + 1)); low = malloc(8 * (n + 1)); stack = malloc(8 * (n + 1));
  wv = malloc(8 * (n + 1)); we = malloc(8 * (n + 1)); onst = calloc(n + 1, 1); cyc = malloc(ccap);
  if (!index || !low || !stack || !wv || !we || !onst || !cyc) { PyErr_NoMemory(); goto done; }
  Py_BEGIN_ALLOW_THREADS
#define PTR(v) (wide ? p64[v] : (int64_t)p32[v])
  for (Py_ssize_t v = 0; v < n; v++) { index[v] = -1; comp[v] = -1; }
  int64_t counter = 0, sp = 0;
  for (Py_ssize_t r = 0; r < nn && !bad; r++) {
    int64_t root = nodes[r];
    if (root < 0 || root >= n) { bad = 1; break; }
    if (index[root] >= 0) continue;
    Py_ssize_t wp = 0;
    wv[wp] = root; we[wp++] = PTR(root);
    index[root] = low[root] = counter++;
    stack[sp++] = root; onst[root] = 1;
    while (wp) {
      int64_t v = wv[wp - 1], e = we[wp - 1], end = PTR(v + 1);
      int descended = 0;
      if (end > m) { bad = 1; break; }
      while (e < end) {
        int64_t w = dst[e++];
        if (w >= n) { bad = 1; break; }
        if (!allowed[w]) continue;
        if (index[w] < 0) {
          we[wp - 1] = e;
          index[w] = low[w] = counter++;
          stack[sp++] = w; onst[w] = 1;
          wv[wp] = w; we[wp++] = PTR(w);
          descended = 1;
          break;
        }
        if (onst[w] && index[w] < low[v]) low[v] = index[w];
      }
      if (bad) break;
      if (descended) continue;
      wp--;
      if (wp && low[v] < low[wv[wp - 1]]) low[wv[wp - 1]] = low[v];
      if (low[v] == index[v]) {
        int64_t size = 0, w;
        do { w = stack[--sp]; onst[w] = 0; comp[w] = ncomp; size++; } while (w != v);
        unsigned char c = size > 1;
        if (!c) for (int64_t f = PTR(v); f < PTR(v + 1); f++) if (dst[f] == v) { c = 1; break; }
        if (ncomp == ccap) {
          unsigned char *x = realloc(cyc, 2 * ccap);
          if (!x) { bad = 2; break; }
          cyc = x; ccap *= 2;
        }
        cyc[ncomp++] = c;
      }
    }
  }
#undef PTR
  Py_END_ALLOW_THREADS
  if (bad == 2) PyErr_NoMemory();
  else if (bad) PyErr_SetString(PyExc_ValueError, "scc: a state number out of range");
  else res = PyBytes_FromStringAndSize((const char *)cyc, ncomp);
done:
  free(index); free(low); free(stack); free(wv); free(we); free(onst); free(cyc);
  PyBuffer_Release(&bp); PyBuffer_Release(&bd); PyBuffer_Release(&ba); PyBuffer_Release(&bn);
  PyBuffer_Release(&bc);
  return res;
}
#define TEMPORAL_METHODS \
  {"tcolumns", tcolumns, METH_O, "the temporal properties' columns of a list of states"}, \
  {"pcls_set", pcls_set, METH_VARARGS, "the point class of an interned id"}, \
  {"scc", scc, METH_VARARGS, "strongly connected components of a CSR graph"},
