/* timings.c -- per-frame stage times from rbc_world_stats, and their median and mean. */
#include "timings.h"

#include <stdlib.h>
#include <string.h>

const char *const cli_stage_names[CLI_STAGE_COUNT] = {
    "step", "integrate", "local", "global", "collide", "callback", "other",
};

int cli_timings_init(cli_timings *t, uint32_t capacity) {
    memset(t, 0, sizeof *t);
    for (int s = 0; s < CLI_STAGE_COUNT; ++s) {
        t->ms[s] = malloc((capacity ? capacity : 1) * sizeof *t->ms[s]);
        if (!t->ms[s])
            return -1;
    }
    t->scratch = malloc((capacity ? capacity : 1) * sizeof *t->scratch);
    if (!t->scratch)
        return -1;
    t->capacity = capacity;
    return 0;
}

void cli_timings_add(cli_timings *t, const rbc_world_stats *stats) {
    if (t->count >= t->capacity)
        return;
    const double values[CLI_STAGE_COUNT] = {
        stats->step_ms,   stats->integrate_ms, stats->local_ms, stats->global_ms,
        stats->collide_ms, stats->callback_ms, stats->other_ms,
    };
    for (int s = 0; s < CLI_STAGE_COUNT; ++s)
        t->ms[s][t->count] = values[s];
    t->count++;
}

static int compare_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

void cli_timings_summary(const cli_timings *t, cli_stage stage, double *median, double *mean) {
    *median = *mean = 0.0;
    if (t->count == 0)
        return;
    double sum = 0.0;
    for (uint32_t i = 0; i < t->count; ++i)
        sum += t->ms[stage][i];
    *mean = sum / t->count;

    double *sorted = t->scratch;
    memcpy(sorted, t->ms[stage], t->count * sizeof *sorted);
    qsort(sorted, t->count, sizeof *sorted, compare_double);
    uint32_t mid = t->count / 2;
    *median = t->count % 2 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
}

void cli_timings_free(cli_timings *t) {
    for (int s = 0; s < CLI_STAGE_COUNT; ++s)
        free(t->ms[s]);
    free(t->scratch);
    memset(t, 0, sizeof *t);
}
