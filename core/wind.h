/* wind.h -- wind and drag on the quads (wind.c; rbc_world_set_wind). */
#ifndef RBC_CORE_WIND_H
#define RBC_CORE_WIND_H
#include "solver.h"

/* Add h^2 F / m to the prediction (y and p) of every free corner of every quad, and
 * the wind's work to the energy guard's budget. Thread 0, after the prediction. */
void rbc_wind_apply(rbc_solver *s, float h);
#endif
