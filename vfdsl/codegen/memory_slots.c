/* vfdsl: one memory slot per caller.
 *
 * Replaces the exported @PREFIX@, @PREFIX@_checkout and @PREFIX@_release of a generated file (see
 * build.py), and makes every solver inside it (casadi_fK with a memory pool) use the slot of the
 * exported call that is running on this thread, instead of checking a memory out of one shared pool
 * per call. A slot holds each solver's persistent DAQP workspace and warm start, so callers that hold
 * different slots share nothing and may run in parallel; the answers of one slot do not depend on
 * what other slots do.
 *
 *   @PREFIX@_checkout()    a free slot (-1 when all VFDSL_MAX_SLOTS are taken), under a mutex;
 *   @PREFIX@_release(s)    frees slot s's solver memory and returns the slot to the pool;
 *   @PREFIX@(..., s)       one evaluation on slot s: returns VFDSL_BAD_SLOT for a slot that is not
 *                          checked out, VFDSL_SLOT_BUSY (without touching anything) when another
 *                          thread is inside an evaluation on the same slot.
 */
#include <pthread.h>
#include <string.h>

#define VFDSL_BAD_SLOT 2
#define VFDSL_SLOT_BUSY 3

static pthread_mutex_t vfdsl_slots_lock = PTHREAD_MUTEX_INITIALIZER;
static int vfdsl_slot_taken[VFDSL_MAX_SLOTS];
static int vfdsl_slot_busy[VFDSL_MAX_SLOTS];
static int vfdsl_slots_ready = 0;              /* slots [0, ready) have initialised solver memory */
static _Thread_local int vfdsl_slot = -1;      /* the slot of the evaluation running on this thread */

static int vfdsl_current_slot(void) {
  return vfdsl_slot;
}

static void vfdsl_slot_init(int s) {
@INIT_SLOT@
}

static void vfdsl_slot_free(int s) {
@FREE_SLOT@
}

CASADI_SYMBOL_EXPORT int @PREFIX@_checkout(void) {
  int s, found = -1;
  pthread_mutex_lock(&vfdsl_slots_lock);
  for (s=0; s<VFDSL_MAX_SLOTS; ++s) {
    if (!__atomic_load_n(&vfdsl_slot_taken[s], __ATOMIC_ACQUIRE)) { found = s; break; }
  }
  if (found>=0) {
    for (; vfdsl_slots_ready<=found; ++vfdsl_slots_ready) vfdsl_slot_init(vfdsl_slots_ready);
    __atomic_store_n(&vfdsl_slot_taken[found], 1, __ATOMIC_RELEASE);
  }
  pthread_mutex_unlock(&vfdsl_slots_lock);
  return found;
}

CASADI_SYMBOL_EXPORT void @PREFIX@_release(int mem) {
  if (mem<0 || mem>=VFDSL_MAX_SLOTS) return;
  pthread_mutex_lock(&vfdsl_slots_lock);
  if (vfdsl_slot_taken[mem] && !__atomic_load_n(&vfdsl_slot_busy[mem], __ATOMIC_ACQUIRE)) {
    vfdsl_slot_free(mem);      /* a later checkout of this slot starts cold, like a new one */
    vfdsl_slot_init(mem);
    __atomic_store_n(&vfdsl_slot_taken[mem], 0, __ATOMIC_RELEASE);
  }
  pthread_mutex_unlock(&vfdsl_slots_lock);
}

CASADI_SYMBOL_EXPORT int @PREFIX@(const casadi_real** arg, casadi_real** res, casadi_int* iw,
                                  casadi_real* w, int mem) {
  int flag;
  if (mem<0 || mem>=VFDSL_MAX_SLOTS || !__atomic_load_n(&vfdsl_slot_taken[mem], __ATOMIC_ACQUIRE)) {
    return VFDSL_BAD_SLOT;
  }
  if (__atomic_exchange_n(&vfdsl_slot_busy[mem], 1, __ATOMIC_ACQUIRE)) return VFDSL_SLOT_BUSY;
  vfdsl_slot = mem;
  flag = casadi_f0(arg, res, iw, w, mem);
  vfdsl_slot = -1;
  __atomic_store_n(&vfdsl_slot_busy[mem], 0, __ATOMIC_RELEASE);
  return flag;
}
