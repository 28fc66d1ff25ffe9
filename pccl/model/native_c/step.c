/* pccl's native engine: the successor function step() around the agents'
   rules, and the state check okexpr(), over what the generated module
   defines before it includes this file (native_gen.py Generator.source):
   agent0() .. agentN-1() (the rules of semantics/rules.py per pc) in the
   table AGENT, the rates RHO, the agents' blocks (AG0, AW), KEEPN0, the
   clock (DELTA, MAXTICKS, HAS_MAXTICKS), the labels L_TA and L_DR, and
   invariants() (the program's invariants); for a program that moves, the
   memo site of DOREACH INVOKE (ENV_SITE, ENVR, ENVW: the blackbox's
   outcomes, memo.c). */
/* the successors of s, emitted into OUT; -1 on an error (ovf or Python's) */
static int step(const V *s) {
  if (s[V_PHASE] == PH_DISCRETE) {
    for (int i = 0; i < NAG; i++)
      if (s[AG0 + AW * i + 3] == S_RUNNING && AGENT[i](s)) return -1;
    /* TIME ADVANCE: some agent running, none with an execution left, the
       bound of ticks not reached */
    int running = 0, blocked = 0;
    for (int i = 0; i < NAG; i++) {
      const V *b = s + AG0 + AW * i;
      running |= b[3] == S_RUNNING;
      blocked |= b[3] != S_EXITED && b[1] <= KEEPN0 - RHO[i];
    }
#if HAS_MAXTICKS
    int ticks = s[V_TIME] / DELTA + 1 <= MAXTICKS;
#else
    int ticks = 1;
#endif
    if (running && !blocked && ticks) {
      V t[NS]; memcpy(t, s, sizeof t);
      t[V_TIME] = ADD(s[V_TIME], DELTA); t[V_PHASE] = PH_DYNAMIC;
      if (EMIT(L_TA, t)) return -1;
    }
  } else {
    /* DOREACH INVOKE */
#if MOVES
    if (memo_site(s, ENV_SITE, ENVR, NENVR, ENVW, NENVW)) return -1;
#else
    /* positions, reach cells and env are constant (not in the vector) */
    V t[NS]; memcpy(t, s, sizeof t);
    t[V_PHASE] = PH_DISCRETE;
    for (int j = 0; j < NAG; j++) t[AG0 + 1 + AW * j] = 0;
    if (EMIT(L_DR, t)) return -1;
#endif
  }
  return ovf ? -1 : 0;
}
/* no agent stuck, the lock's holder not exited, every invariant holds */
static inline int okexpr(const V *s) {
  for (int i = 0; i < NAG; i++)
    if (s[AG0 + AW * i + 3] >= S_STUCK) return 0;
  for (int i = 0; i < NAG; i++)
    if (s[LQ0] == i && s[AG0 + AW * i + 3] == S_EXITED) return 0;
  return invariants(s);
}
