/* timings.h -- per-frame stage times from rbc_world_stats, and their median and mean. */
#ifndef RBC_CLI_TIMINGS_H
#define RBC_CLI_TIMINGS_H

#include <stdint.h>

#include "rbcloth.h"

/// The stages of rbc_world_stats, in the order they are reported.
typedef enum cli_stage {
    CLI_STAGE_STEP,
    CLI_STAGE_INTEGRATE,
    CLI_STAGE_LOCAL,
    CLI_STAGE_GLOBAL,
    CLI_STAGE_COLLIDE,
    CLI_STAGE_CALLBACK,
    CLI_STAGE_OTHER,
    CLI_STAGE_COUNT
} cli_stage;

/// "step", "integrate", ... as used in the summary JSON and the table.
extern const char *const cli_stage_names[CLI_STAGE_COUNT];

typedef struct cli_timings {
    uint32_t count;
    uint32_t capacity;
    /// ms[stage][frame], milliseconds.
    double *ms[CLI_STAGE_COUNT];
    /// Room to sort one stage for its median.
    double *scratch;
} cli_timings;

/// Room for `capacity` frames. Returns 0, or -1 when out of memory (then *t is
/// safe to free).
int cli_timings_init(cli_timings *t, uint32_t capacity);

/// Record the stage times of the last step (ignored once full).
void cli_timings_add(cli_timings *t, const rbc_world_stats *stats);

/// Median and mean of one stage over the recorded frames (0 when none).
void cli_timings_summary(const cli_timings *t, cli_stage stage, double *median, double *mean);

void cli_timings_free(cli_timings *t);

#endif
