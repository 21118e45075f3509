/* batch.h -- `rbcloth batch`: many simulations from a manifest, in parallel. */
#ifndef RBC_CLI_BATCH_H
#define RBC_CLI_BATCH_H

#include "plugin.h"

typedef struct cli_batch_options {
    /// A manifest JSON, or a folder of mesh files (folder mode, with template_path).
    const char *manifest_path;
    /// Folder mode: a JSON object of job settings (the keys of a manifest's
    /// "defaults", or a manifest whose "defaults" is used) applied to every mesh.
    const char *template_path;
    /// Run only job INDEX (0-based, in manifest or sorted folder order) and write no
    /// report: one Slurm array task. -1 = every job.
    long only;
    /// Run nothing: build the report from the results already in out_dir.
    int report_only;
    /// Run nothing: print the number of jobs (to size a Slurm array).
    int count_only;
    /// Output directory (created like mkdir -p); one folder per job inside.
    const char *out_dir;
    /// Worker processes (one fork per job).
    long jobs;
    /// Seconds a job may run (import included) before its worker is killed and the job
    /// fails ("timed out"); 0 = no limit. A job's manifest key "timeout" wins.
    double job_timeout;
    /// Seconds between the SIGTERM forwarded to the workers at SIGINT/SIGTERM and the
    /// SIGKILL of those still running (a worker checks only between frames).
    double term_grace;
    /// No progress bar (the per-job lines are still printed).
    int quiet;
} cli_batch_options;

/// Run the manifest. Returns 0 when every job succeeded (or was already done), 1
/// when any failed or the run was interrupted (the failures listed on stderr), or
/// when another rbcloth batch holds the output folder.
int cli_batch(const cli_plugin *plugin, const cli_batch_options *options);

#endif
