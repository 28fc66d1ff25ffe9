/* pccl's native engine: what tcols() (the temporal properties' per-state
   columns, temporal.c) reads, included by a generated module before the
   properties' predicates (tpred(), native_expr.py ExprC.temporal_c).

   TPOINT: per interned id (positions, targets: NativeModel's table) its
   point class + 2 (0: not known yet, 1: None, k + 2: the k-th distinct
   (x, y) of a point), set by Python as it interns a value (pcls_set, the
   GIL held) before any state holds the id; the level kernel's threads read
   it.  An id beyond TPOINT_CAP (a stable 31-bit id of forked workers) has
   no class: tcols() then leaves the column to Python. */
#define TPOINT_CAP 65536
static int32_t TPOINT[TPOINT_CAP];
/* the class of interned id v: -1 None, k >= 0 a point, -2 not known */
static inline int pcls(V v) {
  if (v < 0 || v >= TPOINT_CAP) return -2;
  return __atomic_load_n(&TPOINT[v], __ATOMIC_ACQUIRE) - 2;
}
