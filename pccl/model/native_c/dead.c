/* pccl's native engine: the dead-variable reduction (dead.py DeadVars), over
   the tables the generated module defines before it includes this file
   (native_gen.py Generator.dead_c: DEADPC, LIVEEV, DCOND, DKEEP, DALL, DGR,
   DTOP, ...; guard(), the program's guards per agent, under DLOCAL).

   dead_bits(s, d): per agent j the mask d[j] of its dead values (bit q: loc:
   slot q; bit NLOC: its reach, when it has arrived or failed); nonzero when
   some value is dead.  dead_apply(s, d): those values set to DEADV (the
   reach: target, t0, flags), before the key. */
#if DEAD
static int dead_bits(const V *s, uint64_t *d) {
  uint64_t any = 0;
  for (int j = 0; j < NAG; j++) {
    const V *b = s + AG0 + AW * j;
    int row = 0;          /* the row of the tables: which conditions hold */
    for (int k = 0; k < NDCOND; k++) row |= (b[4 + DCOND[k]] == 1) << k;
    if (b[3] != S_RUNNING) d[j] = b[3] == S_EXITED ? DALL & ~DKEEP : 0;
    else if (b[0] == EMPTY_PC || b[0] == IDLE_PC) {
#if DLOCAL
      /* at the top of its block: what the events it may select next read */
      int o = ovf;
      uint64_t ev = 0, live = DGR;
      for (int e = 0; e < NEV; e++)
        if (guard(j, e, s)) { ev |= 1ULL << e; if (FIRST_ONLY) break; }
      if (ovf && !o) { ovf = 0; ev = DEVALL; }
      for (int e = 0; e < NEV; e++) if (ev >> e & 1) live |= LIVEEV[e * DROWS + row];
      d[j] = DALL & ~(live | DKEEP);
#else
      d[j] = DALL & ~(DTOP | DKEEP);
#endif
    } else d[j] = (uint64_t)b[0] < NPC ? DEADPC[b[0] * DROWS + row] : 0;
#if MOVES
    /* a reach is masked only where the robot has arrived or failed */
    if (!(b[MV + 4] || b[MV + 5])) d[j] &= ~(1ULL << NLOC);
#endif
    any |= d[j];
  }
  return any != 0;
}
static void dead_apply(V *s, const uint64_t *d) {
  for (int j = 0; j < NAG; j++) {
    uint64_t x = d[j];
    if (!x) continue;
    V *b = s + AG0 + AW * j;
#if MOVES
    if (x >> NLOC & 1) { b[MV + 1] = DEADV; b[MV + 3] = DEADV; b[MV + 4] = DEADV; b[MV + 5] = DEADV; }
#endif
    x &= ~(1ULL << NLOC);
    while (x) { b[4 + __builtin_ctzll(x)] = DEADV; x &= x - 1; }
  }
}
#endif
