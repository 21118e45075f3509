/* step_threads.h -- how many of the pool's threads a step runs on when the host left
 * the count to the library (rbc_world_def.thread_count 0; step_threads.c): the
 * pool's size or 1, whichever recent probes measured faster (docs/design/threads.md). */
#ifndef RBC_CORE_STEP_THREADS_H
#define RBC_CORE_STEP_THREADS_H
#include <stdint.h>

#include "solver.h"

/* The threads for the next step. */
uint32_t rbc_step_threads_choose(rbc_solver *s);
/* After a successful step on `used` threads that took ms_per_substep. */
void rbc_step_threads_record(rbc_solver *s, uint32_t used, double ms_per_substep);
#endif
