/* pccl's native engine: partial-order reduction's per-state test
   (reduce.Por.footprint / eligible / movable, independence.may_wait), over
   the tables the generated module defines before it includes this file
   (Generator.por_c: PCLS, PSR, PSW, PRR, PRW, PENDS, PWRITER, PEMPTY,
   PSPENT, the C_* classes, evfp()). */
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
