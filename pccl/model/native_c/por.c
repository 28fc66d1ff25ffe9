/* pccl's native engine: partial-order reduction's per-state test
   (reduce.Por.footprint / eligible / movable / successors,
   independence.may_wait), over the tables the generated module defines
   before it includes this file (native_gen.py Generator.por_c: PCLS, PSR,
   PSW, PRR, PRW, PENDS, PWRITER, PEMPTY, PSPENT, EVR, EVW, the C_* classes;
   guard(), the program's guards per agent). */
/* the events agent j at the top of its block selects next (local guards):
   their footprint */
static void evfp(int j, const V *s, uint64_t *r, uint64_t *w) {
  *r = GUARDR; *w = 0;
#if GUARDS_LOCAL
  for (int e = 0; e < NEV; e++)
    if (guard(j, e, s)) { *r |= EVR[e]; *w |= EVW[e]; if (FIRST_ONLY) return; }
#else
  (void)j; (void)s;
#endif
}
/* what running agent j may still do before the next TIME ADVANCE
   (Por.footprint): at the top of its block with local guards, the events
   enabled now; else the rest of its k cell, plus every event body if its
   counter allows another EVENT SELECT (Independence.footprint) */
static void ind_footprint(const V *b, int j, uint64_t *r, uint64_t *w) {
  V pc = b[0];
  *r = PRR[pc]; *w = PRW[pc];
  if (b[1] + (PENDS[pc] ? 2 * RHO[j] : RHO[j]) <= KEEPN0) { *r |= EVR_ALL; *w |= EVW_ALL; }
}
static void footprint(const V *s, int j, uint64_t *r, uint64_t *w) {
  const V *b = s + AG0 + AW * j;
  if (GUARDS_LOCAL && b[0] == TOP_PC && b[1] + 2 * RHO[j] > KEEPN0) {
    if (b[1] + RHO[j] > KEEPN0) { *r = 0; *w = 0; return; }
    evfp(j, s, r, w);
    return;
  }
  ind_footprint(b, j, r, w);
}
static int may_wait(const V *s, int j) {
  const V *b = s + AG0 + AW * j;
  if (b[1] + RHO[j] > KEEPN0) return 0;
  if (b[2] == L_REQUEST) return 1;
  uint64_t r, w;
  ind_footprint(b, j, &r, &w);
  return (w & LQ_BIT) != 0;
}
/* whether agent i's next step (i running, an execution left) is
   independent of all the others can do in this time step (Por.eligible) */
static int eligible(const V *s, int i) {
  const V *ag = s + AG0 + AW * i;
  V pc = ag[VA_PC];
  if ((uint64_t)pc >= NPC) return 0;
  int cls = PCLS[pc];
  if (cls == C_LOCAL) return 1;
  if (cls == C_NEVER) return 0;
  if (cls == C_EXECUTE) return s[LQ0] == i;
  if (cls == C_REQUEST && ag[VA_LCK] == L_LOCK) return 1;
  if (cls == C_RELEASE) {
    for (int j = 0; j < NAG; j++)
      if (j != i && s[AG0 + AW * j + 3] == S_RUNNING && may_wait(s, j)) return 0;
    return 1;
  }
  uint64_t r = PSR[pc], w = PSW[pc];
  if (!(r | w)) return 1;
  for (int j = 0; j < NAG; j++)
    if (j != i && s[AG0 + AW * j + 3] == S_RUNNING) {
      uint64_t fr, fw;
      footprint(s, j, &fr, &fw);
      if ((w & (fr | fw)) || (r & fw)) return 0;
    }
  return 1;
}
/* whether merging may run agent i's next step (Por.movable): 0 no, 1 a
   step the stall signature does not see, 2 one that writes its data */
static MAYBE_UNUSED int movable(const V *s, int i) {   /* merging's */
  const V *ag = s + AG0 + AW * i;
  V pc = ag[VA_PC];
  if ((uint64_t)pc >= NPC) return 0;
  int cls = PCLS[pc];
  if (cls == C_EXECUTE) return s[LQ0] == i;
  if (cls == C_REQUEST && ag[VA_LCK] == L_LOCK) return 1;
  if (cls == C_ACCESS) { if (PEMPTY[pc]) return 0; }
  else if (cls != C_REQUEST && cls != C_RELEASE) return 0;
  if (!eligible(s, i)) return 0;
  return (cls != C_ACCESS || PWRITER[pc]) ? 2 : 1;
}
/* rstep's ample set (Por.successors): the first agent with an execution
   left whose next step is independent of what the others can still do;
   else the first spent agent whose next step is a plain statement of its
   own (Independence.spent_local).  An agent's successors are the ample set
   when they all keep it running: 1 (its successors in the buffer from b0),
   0 none found (the buffer as it was), -1 an error */
static inline int ample_try(const V *s, Py_ssize_t b0, int i) {
  if (AGENT[i](s)) return -1;
  int all = BN > b0;
  for (Py_ssize_t k = b0; k < BN && all; k++) all = BUF[NS * k + AG0 + AW * i + 3] == S_RUNNING;
  if (all) return 1;
  BN = b0;
  return 0;
}
static inline int ample(const V *s, Py_ssize_t b0) {
  for (int i = 0; i < NAG; i++) {
    const V *b = s + AG0 + AW * i;
    if (b[3] == S_RUNNING && b[1] <= KEEPN0 - RHO[i] && eligible(s, i)) {
      int a = ample_try(s, b0, i);
      if (a) return a;
    }
  }
  for (int i = 0; i < NAG; i++) {
    const V *b = s + AG0 + AW * i;
    if (b[3] == S_RUNNING && b[1] > KEEPN0 - RHO[i] && (uint64_t)b[0] < NPC && PSPENT[b[0]]) {
      int a = ample_try(s, b0, i);
      if (a) return a;
    }
  }
  return 0;
}
