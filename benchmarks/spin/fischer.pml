/* Fischer's protocol (programs/fischer.pccl) as a Promela model whose state
 * space is exactly pccl's unreduced one (`pccl explore programs/fischer.pccl
 * --set k=K --set d=D -n N --reduce none --no-timelock --no-stall`):
 * one d_step per rule application of docs/language.md §11 (EVENT SELECT,
 * IDLE, STATEMENT, COUNTER ADVANCE, LOCK REQUEST, ATOMIC WAIT, ATOMIC
 * EXECUTION, LOCK RELEASE, TIME ADVANCE, DOREACH INVOKE), n0 = 1, ρ = 1,
 * time abstracted (the clock is not in the state).
 *
 * The state is pccl's configuration: per agent its k cell (pc, numbered
 * below), counter, lock state and locals (status is always running: the
 * program cannot get stuck or exit; the position never changes), the
 * shared variables, the lock queue and the transition phase.  K, D and N
 * come from `spin -DK=.. -DD=.. -DN=..`; benchmarks/spin.py writes
 * fischer_gen.pml next to this file: INIT (one option per initial state,
 * so the unique pre-initial state has one transition to each of pccl's
 * initial states) and ALLSPENT (TIME ADVANCE's guard for N agents).
 * Compile with `spin -o2` so that write-only `cstime` stays in the state.
 */

/* phases */
#define DISC 0
#define DYN  1
#define PRE  2
/* lock states */
#define IDLE 0
#define REQ  1
#define LOCK 2

/* pcs: the k cells of one agent.  EMPTY: the top of the event block;
 * END: endEventBlock; the others: the statement at the head of k. */
#define EMPTY     0
#define END       1
#define S_IF      2   /* Start: if (reqid != -1)      */
#define S_C1      3   /*   c1 = 0                     */
#define S_START   4   /*   start = false              */
#define S_WAIT    5   /*   wait = true                */
#define W_IF      6   /* Wait: if (c1 < waitTime)     */
#define W_INC     7   /*   c1 = c1 + 1                */
#define W_C1      8   /*   c1 = 0                     */
#define W_WAIT    9   /*   wait = false               */
#define W_ASSIGN 10   /*   assign = true              */
#define A_ATOMIC 11   /* Assign: atomic:              */
#define A_ACQ    12   /*   (lock requested)           */
#define A_BODY   13   /*   reqid = id                 */
#define A_AEND   14   /*   atomicEnd                  */
#define A_DELAY  15   /*   delay = true               */
#define A_ASSIGN 16   /*   assign = false             */
#define D_IF     17   /* Delay: if (c2 < d)           */
#define D_INC    18   /*   c2 = c2 + 1                */
#define D_C2     19   /*   c2 = 0                     */
#define D_DELAY  20   /*   delay = false              */
#define D_IF2    21   /*   if (reqid != id)           */
#define D_C1     22   /*     c1 = 0                   */
#define D_WAIT   23   /*     wait = true              */
#define D_INCS   24   /*   else inCs = true           */
#define I_IF     25   /* InCs: if (c3 < 3)            */
#define I_INC    26   /*   c3 = c3 + 1                */
#define I_C3     27   /*   c3 = 0                     */
#define I_INCS   28   /*   inCs = false               */
#define I_START  29   /*   start = true               */
#define I_ATOMIC 30   /*   atomic:                    */
#define I_ACQ    31   /*   (lock requested)           */
#define I_BODY   32   /*   reqid = -1                 */
#define I_AEND   33   /*   atomicEnd                  */

/* the configuration */
byte phase = PRE;
byte lq[N];              /* lock queue: agent ids, unused slots 0 */
byte lqn = 0;
short reqid = -1;        /* shared; k and d are constants */
byte pc[N] = EMPTY;
byte cnt[N] = 0;
byte lst[N] = IDLE;
byte id[N];
byte waitTime[N];
bool start[N] = true;
bool assign[N] = false;
bool delay[N] = false;
bool wait[N] = false;
bool inCs[N] = false;
byte c1[N] = 0;
byte c2[N] = 0;
byte cstime[N];
byte c3[N] = 0;
byte t_j, t_w;           /* scratch: always 0 between steps (BFS forbids hidden) */

#include "fischer_gen.pml"

#define R(g, body) :: d_step { phase == DISC && g -> body }
#define GO(p) pc[i] = p
#define STMT(p, body) R(pc[i] == p, body)
/* the atomic block at pc A (request pc A+1, body pc A+2) */
#define ATOMIC(A) \
  R(pc[i] == A && lst[i] == IDLE, lst[i] = REQ; lq[lqn] = i; lqn++; GO(A + 1)) \
  R(pc[i] == A && lst[i] == LOCK, GO(A + 2)) \
  R(pc[i] == A + 1 && lst[i] == REQ && lqn > 0 && lq[0] == i, lst[i] = LOCK; GO(A + 2)) \
  R(pc[i] == A + 1 && lst[i] == REQ && !(lqn > 0 && lq[0] == i) && cnt[i] == 0, cnt[i] = 1)
/* LOCK RELEASE at pc E, then pc P: drop i from the lock queue */
#define RELEASE(E, P) \
  R(pc[i] == E && lst[i] == LOCK, \
    lst[i] = IDLE; t_w = 0; t_j = 0; \
    do :: t_j < lqn -> if :: lq[t_j] != i -> lq[t_w] = lq[t_j]; t_w++ :: else fi; t_j++ \
       :: else -> break od; \
    t_j = t_w; do :: t_j < lqn -> lq[t_j] = 0; t_j++ :: else -> break od; \
    lqn = t_w; t_j = 0; t_w = 0; GO(P))

active [N] proctype agent() {
  byte i = _pid;
  do
  /* EVENT SELECT: k empty, counter + 1 <= n0 (= 1) */
  R(pc[i] == EMPTY && cnt[i] == 0 && start[i], GO(S_IF))
  R(pc[i] == EMPTY && cnt[i] == 0 && wait[i], GO(W_IF))
  R(pc[i] == EMPTY && cnt[i] == 0 && assign[i], GO(A_ATOMIC))
  R(pc[i] == EMPTY && cnt[i] == 0 && delay[i], GO(D_IF))
  R(pc[i] == EMPTY && cnt[i] == 0 && inCs[i], GO(I_IF))
  /* IDLE: no guard holds */
  R(pc[i] == EMPTY && cnt[i] == 0 && !(start[i] || wait[i] || assign[i] || delay[i] || inCs[i]),
    GO(END))
  /* COUNTER ADVANCE */
  R(pc[i] == END && cnt[i] == 0, GO(EMPTY); cnt[i] = 1)
  /* STATEMENT */
  STMT(S_IF, if :: reqid != -1 -> GO(S_C1) :: else -> GO(S_START) fi)
  STMT(S_C1, c1[i] = 0; GO(END))
  STMT(S_START, start[i] = false; GO(S_WAIT))
  STMT(S_WAIT, wait[i] = true; GO(END))
  STMT(W_IF, if :: c1[i] < waitTime[i] -> GO(W_INC) :: else -> GO(W_C1) fi)
  STMT(W_INC, c1[i] = c1[i] + 1; GO(END))
  STMT(W_C1, c1[i] = 0; GO(W_WAIT))
  STMT(W_WAIT, wait[i] = false; GO(W_ASSIGN))
  STMT(W_ASSIGN, assign[i] = true; GO(END))
  ATOMIC(A_ATOMIC)
  STMT(A_BODY, reqid = id[i]; GO(A_AEND))
  RELEASE(A_AEND, A_DELAY)
  STMT(A_DELAY, delay[i] = true; GO(A_ASSIGN))
  STMT(A_ASSIGN, assign[i] = false; GO(END))
  STMT(D_IF, if :: c2[i] < D -> GO(D_INC) :: else -> GO(D_C2) fi)
  STMT(D_INC, c2[i] = c2[i] + 1; GO(END))
  STMT(D_C2, c2[i] = 0; GO(D_DELAY))
  STMT(D_DELAY, delay[i] = false; GO(D_IF2))
  STMT(D_IF2, if :: reqid != id[i] -> GO(D_C1) :: else -> GO(D_INCS) fi)
  STMT(D_C1, c1[i] = 0; GO(D_WAIT))
  STMT(D_WAIT, wait[i] = true; GO(END))
  STMT(D_INCS, inCs[i] = true; GO(END))
  STMT(I_IF, if :: c3[i] < 3 -> GO(I_INC) :: else -> GO(I_C3) fi)
  STMT(I_INC, c3[i] = c3[i] + 1; GO(END))
  STMT(I_C3, c3[i] = 0; GO(I_INCS))
  STMT(I_INCS, inCs[i] = false; GO(I_START))
  STMT(I_START, start[i] = true; GO(I_ATOMIC))
  ATOMIC(I_ATOMIC)
  STMT(I_BODY, reqid = -1; GO(I_AEND))
  RELEASE(I_AEND, END)
  od
}

active proctype clock() {
  INIT;
  do
  /* TIME ADVANCE: every agent's counter spent */
  :: d_step { phase == DISC && ALLSPENT -> phase = DYN }
  /* DOREACH INVOKE (no doReach: positions stay): counters reset */
  :: d_step { phase == DYN -> t_j = 0; do :: t_j < N -> cnt[t_j] = 0; t_j++ :: else -> break od;
                              t_j = 0; phase = DISC }
  od
}
