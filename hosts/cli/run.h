/* run.h -- `rbcloth run`: simulate a scene and write its mesh, cache and summary. */
#ifndef RBC_CLI_RUN_H
#define RBC_CLI_RUN_H

#include "plugin.h"

typedef struct cli_run_options {
    /// Scene file, or NULL for the built-in default scene.
    const char *scene_path;
    /// Output directory (created like mkdir -p).
    const char *out_dir;
    /// Overrides of the scene; -1 = keep the scene's value.
    long frames;
    long threads;
    long substeps;
    /// Linear (Red-Black Gauss-Seidel) iterations per non-linear iteration.
    long iterations;
    /// Non-linear (local/global) iterations per substep.
    long nonlinear;
    /// Global solver and iteration mode by name (rbc_scene_solver_names,
    /// rbc_scene_mode_names), or NULL to keep the scene's.
    const char *solver;
    const char *mode;
    /// Energy guard by name (rbc_scene_energy_guard_names), or NULL for the scene's.
    const char *energy_guard;
    /// Mode parameters and SOR omega; < 0 = keep the scene's.
    double tolerance, budget_ms, omega;
    /// A solver preset by name ("paper", "game_60hz", "cloth": rbc_solver_def_preset),
    /// applied to the scene's solver before the options above; NULL = none.
    const char *preset;
    /// --mode target: the RMS relative strain to reach (< 0 = the scene's), and the
    /// caps max_substeps and max_linear_iterations (-1 = the scene's).
    double target_strain;
    long max_substeps, max_linear;
    /// A CSV file of per-frame figures (time, energies, contacts, strain), or NULL.
    const char *frame_stats;
    /// Substeps per second when the substeps are 0 (< 0 = the scene's).
    double substep_rate;
    /// 1: write no PNG still and no HTML player.
    int no_view;
    /// No progress bar and no table on stdout.
    int quiet;
} cli_run_options;

/// Run the scene. Returns the process exit code: 0, or 1 after printing the reason
/// on stderr.
int cli_run(const cli_plugin *plugin, const cli_run_options *options);

#endif
