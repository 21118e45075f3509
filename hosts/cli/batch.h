/* batch.h -- `rbcloth batch`: many simulations from a manifest, in parallel. */
#ifndef RBC_CLI_BATCH_H
#define RBC_CLI_BATCH_H

#include "plugin.h"

typedef struct cli_batch_options {
    const char *manifest_path;
    /// Output directory (created like mkdir -p); one folder per job inside.
    const char *out_dir;
    /// Worker processes (one fork per job).
    long jobs;
    /// No progress bar (the per-job lines are still printed).
    int quiet;
} cli_batch_options;

/// Run the manifest. Returns 0 when every job succeeded (or was already done), 1
/// when any failed or the run was interrupted (the failures listed on stderr).
int cli_batch(const cli_plugin *plugin, const cli_batch_options *options);

#endif
