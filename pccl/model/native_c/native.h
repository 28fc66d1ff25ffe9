/* pccl's native engine: the fixed C every generated module includes first.

   A module is one translation unit, written by pccl/model/native_gen.py
   (Generator.source) for one program: its header defines the program's
   constants, then it includes the fixed files of this directory in order,
   with the program's own code (its statements, guards, expressions and
   tables; no other function body) between them:

     #define NS ... (the header below)   the program's constants
     #include "native.h"                 this file: values, arithmetic, the
                                         successor buffer, states as bytes
     #include "memo.c"                   memo sites (what Python computes)
     #include "robots.c"                 the shipped blackboxes' outcomes
     agent0() .. agentN-1()              generated: the rules, per agent, per pc
     RHO, AGENT, ENV*, PR*, invariants() generated: rates, the agents' table,
                                         memo sites' slots, the invariants
     #include "step.c"                   the successor function, okexpr()
     the reductions' tables, guard()     generated (native_gen.py reduced_c)
     #include "por.c"                    (under partial-order reduction)
     #include "dead.c"                   the dead-variable reduction
     #include "reduced.c"                merging, symmetry, the reduced step
     #include "temporal.h"               the point classes of interned ids
     tpred(), TPBIT                      generated: the temporal predicates
     #include "temporal.c"               their columns, the graph's SCCs
     #include "module.c"                 the Python-facing functions
     #include "kernel.c"                 the level kernel (explore_levels)

   The header's constants, used here and in the other fixed files:
     NS        slots of the state vector (int64 each)
     NAG       agents
     LQ0       the first slot of the lock queue (NAG slots, -1 unused)
     KEYSKIP   bytes of the vector's start left out of the key (8: the
               clock, under time abstraction; else 0)
     PACK      1 when states are held as int32 slots where they fit
     VMIN      the least int a slot holds (native.py's V_MIN)
     V_TIME, V_PHASE   the slots of the clock and the phase
     PH_DISCRETE, PH_DYNAMIC   the phase's values
     S_RUNNING, S_EXITED, S_STUCK   an agent's statuses (STUCK and above:
               stuck, with its reason)
     AG0, AW   agent j's block: AW slots from AG0 + AW * j (pc, counter,
               lock state, status, then NLOC loc: slots and the allread)
     MOVES, MV whether the program moves; then a robot's position,
               target, obstacles, t0, done, fail, leg start from MV of its block
     NPC, EMPTY_PC, IDLE_PC   the control cells: how many, the top of the
               block and idle
     KEEPN0, DELTA, MAXTICKS, HAS_MAXTICKS   n0, the clock's step, the
               bound of ticks (--max-time)
     L_TA, L_DR   the labels of TIME ADVANCE and DOREACH INVOKE
     FIRST_ONLY, NEV   --events first; the number of events
   MODNAME and INITFN (the module's name, its init function) are defined
   on the compiler's command line's first lines (native_build.py). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>
#include <stdlib.h>
typedef int64_t V;
/* a helper some programs do not call (no atomic, no memo site, ...) */
#define MAYBE_UNUSED __attribute__((unused))
/* per thread: the level kernel (explore_levels) runs the successor code on
   several threads at once, each with its own overflow flag and buffer; KT
   is set while a thread runs it without the GIL (no Python call then) */
static __thread int ovf;
static __thread int KT;
/* the kernel's threads other than the caller's (KHELP) leave a memo miss to
   the calling thread: they give the chunk up (KDEFER), and the calling
   thread, which never waits for them, makes it, taking the GIL for the
   miss itself (no thread then waits for another's Python call) */
static __thread int KHELP, KDEFER;
static PyObject *OverflowExc;
/* ints: VMIN..INT64_MAX (VMIN: the program's header, native.py's V_MIN);
   below VMIN the reserved codes (undefined, the symmetry signature's MSELF
   and MOTHER, dead's DEADV): a result out of range is an overflow (the
   Python engine runs) */
static inline V ADD(V a, V b) { V r; if (__builtin_add_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }
static inline V SUB(V a, V b) { V r; if (__builtin_sub_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }
static inline V MUL(V a, V b) { V r; if (__builtin_mul_overflow(a, b, &r) || r < VMIN) ovf = 1; return r; }
static inline V NEG(V a) { if (a < -INT64_MAX || -a < VMIN) { ovf = 1; return 0; } return -a; }
static inline V DIV(V a, V b) {
  if (b == 0 || (a == INT64_MIN && b == -1)) { ovf = 1; return 0; }
  V r = a / b; if (r < VMIN) ovf = 1; return r;
}
static inline V MOD(V a, V b) { if (b == 0 || (a == INT64_MIN && b == -1)) { ovf = 1; return 0; } return a % b; }
static inline V AIX(V j) { if (j < 0 || j >= NAG) { ovf = 1; return 0; } return j; }
static inline V U(V a) { if (a == INT64_MIN) ovf = 1; return a; }
static MAYBE_UNUSED void lq_append(V *t, V i) { for (int k = 0; k < NAG; k++) if (t[LQ0 + k] < 0) { t[LQ0 + k] = i; return; } }
static MAYBE_UNUSED void lq_remove(V *t, V i) {
  int w = 0;
  for (int k = 0; k < NAG; k++) if (t[LQ0 + k] >= 0 && t[LQ0 + k] != i) t[LQ0 + w++] = t[LQ0 + k];
  for (; w < NAG; w++) t[LQ0 + w] = -1;
}
/* the successor buffer: step() and rstep() append each successor's vector,
   its label, its place in the unmerged relation and its merged chain length */
static __thread V *BUF;
static __thread int32_t *BLAB, *BIDX, *BCH;
static __thread Py_ssize_t BN, BCAP;
static int grow(void) {
  Py_ssize_t cap = BCAP ? 2 * BCAP : 1024;
  V *b = realloc(BUF, sizeof(V) * NS * cap);
  if (!b) { if (!KT) PyErr_NoMemory(); return -1; }
  BUF = b;
  int32_t *x[3] = {BLAB, BIDX, BCH};
  for (int q = 0; q < 3; q++) {
    int32_t *y = realloc(x[q], sizeof(int32_t) * cap);
    if (!y) { if (!KT) PyErr_NoMemory(); return -1; }
    x[q] = y;
  }
  BLAB = x[0]; BIDX = x[1]; BCH = x[2];
  BCAP = cap;
  return 0;
}
static inline int EMIT(int lab, const V *t) {
  if (BN == BCAP && grow()) return -1;
  memcpy(BUF + NS * BN, t, sizeof(V) * NS);
  BLAB[BN] = lab; BIDX[BN] = 0; BCH[BN] = 0;
  BN++;
  return 0;
}
/* A state as Python holds it (NativeModel.pack's form): int32 slots when
   every slot fits (undefined, INT64_MIN, as INT32_MIN), else int64.  Half
   the bytes, and a 64-slot state then fits CPython's small-object
   allocator instead of malloc.  The slots' values, not the bytes, are the
   state: fingerprints, keys and memo keys read the int64 vector. */
static PyObject *state_bytes(const V *t) {
  int fit = PACK;
  for (int q = 0; q < NS; q++) fit &= (t[q] == INT64_MIN) | ((t[q] > INT32_MIN) & (t[q] <= INT32_MAX));
  if (!fit) return PyBytes_FromStringAndSize((const char *)t, sizeof(V) * NS);
  PyObject *b = PyBytes_FromStringAndSize(NULL, sizeof(int32_t) * NS);
  if (!b) return NULL;
  int32_t *p = (int32_t *)PyBytes_AS_STRING(b);
  for (int q = 0; q < NS; q++) p[q] = t[q] == INT64_MIN ? INT32_MIN : (int32_t)t[q];
  return b;
}
/* the int64 vector of state arg: in place, or unpacked into buf; NULL
   when it is not a state of this model, without a Python error (the level
   kernel's threads call it without the GIL) */
static const V *raw_state(PyObject *arg, V *buf) {
  if (!PyBytes_Check(arg)) return NULL;
  Py_ssize_t n = PyBytes_GET_SIZE(arg);
  if (PACK && n == (Py_ssize_t)(sizeof(int32_t) * NS)) {
    const int32_t *p = (const int32_t *)PyBytes_AS_STRING(arg);
    for (int q = 0; q < NS; q++) buf[q] = p[q] == INT32_MIN ? INT64_MIN : (V)p[q];
    return buf;
  }
  return n == (Py_ssize_t)(sizeof(V) * NS) ? (const V *)PyBytes_AS_STRING(arg) : NULL;
}
/* ... with the Python error */
static const V *arg_state(PyObject *arg, V *buf) {
  const V *s = raw_state(arg, buf);
  if (!s) PyErr_SetString(PyExc_TypeError, "not a native state of this model");
  return s;
}
/* the Python error of an overflow met (ovf) when no other error is set */
static void overflowed(void) {
  if (ovf && !PyErr_Occurred())
    PyErr_SetString(OverflowExc, "an int beyond 64 bits, a division by zero or an undefined value");
}
