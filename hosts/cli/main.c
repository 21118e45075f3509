/* main.c -- the rbcloth command line: `run`, `batch`, `bench`, `info` and `--help`.
 *
 * The plugin is loaded with dlopen (see plugin.c) and used only through its
 * function table, as any host would. Exit codes: 0 success, 1 runtime failure,
 * 2 usage error.
 */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "batch.h"
#include "bench.h"
#include "plugin.h"
#include "run.h"
#include "scene.h"

enum { EXIT_OK = 0, EXIT_RUNTIME = 1, EXIT_USAGE = 2 };

/* The overview (rbcloth --help) and one page per command (rbcloth COMMAND --help). */
static const char main_usage[] =
    "Usage: rbcloth COMMAND [ARGS]\n"
    "\n"
    "A real-time quad mass-spring cloth solver (librbcloth) on the command line.\n"
    "\n"
    "Commands:\n"
    "  run [SCENE.json]   simulate a scene (default: the built-in hanging cloth) into\n"
    "                     point caches, a PNG still and an HTML player\n"
    "  batch MANIFEST     simulate many meshes or scenes in worker processes\n"
    "  bench NAME         measure: defaults, accuracy, stability, perf, scenes, peers\n"
    "  info               the plugin's path, ABI version and version\n"
    "  help [COMMAND]     this page, or a command's options with their defaults\n"
    "\n"
    "  -h, --help         this page; rbcloth COMMAND --help for a command's options\n"
    "  -V, --version      the versions of this program, the plugin and its ABI\n"
    "\n"
    "The plugin is $RBC_PLUGIN if set, else ../lib/librbcloth.so next to this\n"
    "executable, else librbcloth.so from the library search path.\n"
    "Exit status: 0 success, 1 runtime failure, 2 usage error.\n";

static const char run_usage[] =
    "Usage: rbcloth run [SCENE.json] [OPTIONS]\n"
    "\n"
    "Simulate a scene (samples/scenes/README.md has the format; without SCENE the\n"
    "built-in hanging cloth: the paper's 100 x 100 cloth, 1/60 s frames, 240 frames)\n"
    "and write into DIR: NAME.obj (rest mesh), NAME.pc2 (a point cache of every\n"
    "frame), NAME.json (summary), NAME.png (the last frame, strain as colour) and\n"
    "NAME.html (a player that opens in any browser); with several cloths\n"
    "NAME_CLOTH.obj and NAME_CLOTH.pc2 per cloth. Options win over the scene.\n"
    "SIGINT (Ctrl-C) or SIGTERM stops it at the end of the frame (a second one at\n"
    "once), removing its temporary files (NAME.pc2.tmp ...); the exit status is 1.\n"
    "DIR may not be the output folder of a running batch, nor one of its jobs'.\n"
    "\n"
    "Output:\n"
    "  --out DIR            output directory, created if missing (default: out)\n"
    "  --frames N           frames to simulate, one step of the scene's dt each\n"
    "                       (default: the scene's)\n"
    "  --frame-stats F      also write F, a CSV row per frame: step and collision ms,\n"
    "                       energies, contacts, strain, fail-safe counts\n"
    "  --no-view            write no NAME.png and NAME.html\n"
    "  -q, --quiet          no progress bar and no table of timings\n"
    "\n"
    "The solve (default: the scene's world, else the library's default solve:\n"
    "red-black SOR, 480 substeps a second, 11 iterations each):\n"
    "  --threads N          worker threads; 0 = one per core (default: 0)\n"
    "  --substeps N         substeps per frame, 1..1024; 0 = from --substep-rate\n"
    "                       (default: 0)\n"
    "  --substep-rate HZ    substeps per second when --substeps is 0 (default: 480)\n"
    "  --iterations N       linear iterations per global step, 1..4096 (default: 11)\n"
    "  --nonlinear N        local/global iterations per substep, 1..1024 (default: 1)\n"
    "  --preset NAME        start from a solver preset: cloth (the default solve),\n"
    "                       paper (the paper's RBGS; with --substeps 1 its\n"
    "                       experiment), game_60hz (target mode: RMS strain 0.05\n"
    "                       within 32 substeps x 8 iterations)\n"
    "  --solver NAME        rbgs_sor (default), rbgs, jacobi, jacobi_chebyshev,\n"
    "                       gauss_seidel, rbgs_chebyshev, multicolor_gs, direct\n"
    "  --mode NAME          when the iterations of a global step stop: fixed (the\n"
    "                       count; default), tolerance, budget, target (substeps and\n"
    "                       iterations chosen per frame to reach a strain)\n"
    "  --tolerance X        relative residual for --mode tolerance (default: 1e-3)\n"
    "  --budget-ms X        milliseconds per frame for --mode budget (default: 2)\n"
    "  --target-strain X    RMS relative strain for --mode target (default: 0.05)\n"
    "  --max-substeps N     most substeps per frame, in --mode target and with\n"
    "                       --substeps 0, 1..1024 (default: 32)\n"
    "  --max-iterations N   most linear iterations per global step in the tolerance,\n"
    "                       budget and target modes (default: 1000)\n"
    "  --omega X            SOR factor in (0, 2); 0 = the optimum for each substep\n"
    "                       length (default: 0)\n"
    "  --energy-guard G     when a step adds energy the cloth was not given: clamp\n"
    "                       (scale velocities, log, count; default), fail (error, state\n"
    "                       restored) or off\n"
    "\n"
    "Example: rbcloth run samples/scenes/cloth_on_sphere.json --out out/sphere\n";

static const char batch_usage[] =
    "Usage: rbcloth batch MANIFEST.json [OPTIONS]\n"
    "       rbcloth batch MESHDIR --template T.json [OPTIONS]\n"
    "\n"
    "Simulate every job of a manifest (mesh files read with assimp, or scenes) in\n"
    "worker processes. DIR/JOB/ holds JOB.obj (rest mesh), the caches asked for (pc2,\n"
    "mdd, objseq: frames/JOB_0001.obj ..), JOB.png and JOB.html; DIR/index.html shows\n"
    "every job's still. Finished jobs are skipped on a rerun, even with DIR spelled\n"
    "another way; SIGINT/SIGTERM stop it without half-written files (workers still\n"
    "running after --term-grace are killed; a second signal kills them at once); it\n"
    "closes with DIR/batch_report.json and .md. One batch at a time per DIR: a second\n"
    "is refused (DIR/.rbcloth-batch.lock names the holder). Workers die with the batch.\n"
    "Folder mode: every mesh file in MESHDIR (.obj .ply .off .stl .dae .gltf .glb .fbx\n"
    ".3ds ...) is a job named after its file, with T's settings (the keys of a\n"
    "manifest's \"defaults\"). Formats: docs/formats.md.\n"
    "\n"
    "  -j, --jobs N         worker processes, 1..256 (default: 2)\n"
    "  --out DIR            output directory (default: out/batch)\n"
    "  --job-timeout S      kill a job still running after S seconds, import included,\n"
    "                       and record it failed; a job's \"timeout\" key wins; 0 = no\n"
    "                       limit (default: 0)\n"
    "  --term-grace S       seconds from SIGINT/SIGTERM to the SIGKILL of workers still\n"
    "                       running (default: 5)\n"
    "  --template T.json    settings of every job in folder mode\n"
    "  --only I             run job I only (0-based, manifest or file-name order) and\n"
    "                       write no report: one Slurm array task\n"
    "  --report-only        run nothing; build the report from the results in DIR\n"
    "                       (the Slurm merge step; samples/slurm/)\n"
    "  --count              print the number of jobs and exit\n"
    "  -q, --quiet          no progress lines\n"
    "\n"
    "Exit status: 0 all jobs ok; 1 a job failed or timed out, the batch was stopped\n"
    "by a signal, DIR is held by another batch, or the batch could not run; 2 usage.\n";

static const char bench_usage[] =
    "Usage: rbcloth bench NAME [OPTIONS]\n"
    "\n"
    "Benches print figures and write CSV, Markdown and PNG plots (gnuplot) into DIR;\n"
    "docs/results/ holds one page per bench from the command it names.\n"
    "\n"
    "  defaults     the default solve against the presets on the paper's cloth and a\n"
    "               64 x 48 grid at 1/240, 1/60 and 1/30 s: largest and RMS strain,\n"
    "               ms per frame (defaults.csv, defaults.md; about 2 minutes)\n"
    "  accuracy     the paper's convergence experiments (Figs. 3, 4) for every\n"
    "               solver: Eq. 7 per frame at 11 iterations and within 2 ms, a\n"
    "               budget sweep, the PD objective gap (about 5 minutes)\n"
    "  stability    every solver over stiffness, dt, mass ratio, size, degenerate\n"
    "               springs, stretch, pins and a moving sphere (about 1 minute)\n"
    "  perf         ms per frame and stage, updates per second, setup time and\n"
    "               memory on 1K .. 1M particle grids, 1 and N threads\n"
    "  scenes       the paper's scenes (samples/scenes) beside its GTX 970 figures\n"
    "  peers        solver x substeps x iterations on the paper's cloth for 500\n"
    "               frames: the Pareto front of ms per frame against Eq. 7 beside\n"
    "               published peer figures (a few minutes; --quick: seconds)\n"
    "  pool         ms per step on 1 thread, the default count and every core, on\n"
    "               an idle machine and with one busy loop per core (about 30 s)\n"
    "\n"
    "  --out DIR            output directory (default: out/bench)\n"
    "  --frames N           frames per run (default: the bench's; accuracy 240,\n"
    "                       stability 200, peers 500, scenes the scene's)\n"
    "  --threads N          worker threads of every world; 0 = one per core (perf,\n"
    "                       scenes: 1 thread and N, default 2; peers, defaults: 1)\n"
    "  --quick              fewer frames, budgets and cases (the tests' smoke runs;\n"
    "                       scenes: without the crumpled cloth)\n"
    "  --backend cpu|cuda   perf: the worlds' backend (cuda: 10K .. 4M particles;\n"
    "                       refused where no CUDA device is)\n"
    "  --setup-only N       perf: only the set-up (cloth creation) of the 1M grid and\n"
    "                       the 1M irregular mesh, N times each, interleaved; prints\n"
    "                       each time and the medians, writes nothing\n"
    "  --irregular          perf: only the grid-against-irregular comparison (the\n"
    "                       irregular meshes and the grids of their sizes)\n";

static const char info_usage[] =
    "Usage: rbcloth info\n"
    "\n"
    "Print the plugin's path and how it was found, its ABI version beside this\n"
    "program's, and its release version.\n";

/* Names a command line may give, for "did you mean" (rbc_scene_nearest). */
static const char *const command_names[] = {"run", "batch", "bench", "info", "help", NULL};
static const char *const bench_names[] = {"defaults", "accuracy", "stability", "perf",
                                          "scenes", "peers", "pool", NULL};
static const char *const run_option_names[] = {
    "--out", "--frames", "--frame-stats", "--no-view", "--quiet", "--threads", "--substeps",
    "--substep-rate", "--iterations", "--nonlinear", "--preset", "--solver", "--mode",
    "--tolerance", "--budget-ms", "--target-strain", "--max-substeps", "--max-iterations",
    "--omega", "--energy-guard", "--help", NULL};
static const char *const batch_option_names[] = {"--jobs", "--out", "--template", "--only",
                                                 "--report-only", "--count", "--quiet",
                                                 "--job-timeout", "--term-grace", "--help",
                                                 NULL};
static const char *const bench_option_names[] = {"--out", "--frames", "--threads", "--quick",
                                                 "--backend", "--setup-only", "--irregular",
                                                 "--help", NULL};

/* "rbcloth: unknown WHAT 'ARG'WHERE[; did you mean 'X'?]", exit code 2. */
static int unknown(const char *what, const char *arg, const char *where,
                   const char *const *choices, const char *help) {
    const char *eq = strchr(arg, '=');
    char name[128];
    snprintf(name, sizeof name, "%.*s", eq ? (int)(eq - arg) : (int)strlen(arg), arg);
    const char *near = rbc_scene_nearest(name, choices);
    fprintf(stderr, "rbcloth: unknown %s '%s'%s", what, name, where);
    if (near) fprintf(stderr, "; did you mean '%s'?", near);
    fprintf(stderr, "\nTry 'rbcloth %s'.\n", help);
    return 2;
}

/* The help page a usage error points to: "--help", or "run --help" once the command
 * is known. */
static const char *help_hint = "--help";

static int usage_error(const char *fmt, const char *arg) {
    fputs("rbcloth: ", stderr);
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\nTry 'rbcloth %s'.\n", help_hint);
    return EXIT_USAGE;
}

/* A string option "--name value" or "--name=value": 1 and *out set (the value, or
 * NULL if missing) when arg names it, advancing *i past a separate value; 0 if arg
 * is another option. */
static int string_option(const char *arg, const char *name, int argc, char **argv, int *i,
                         const char **out) {
    const char *eq = strchr(arg, '=');
    size_t name_len = eq ? (size_t)(eq - arg) : strlen(arg);
    if (name_len != strlen(name) || strncmp(arg, name, name_len) != 0) return 0;
    *out = eq ? eq + 1 : (*i + 1 < argc ? argv[++*i] : NULL);
    return 1;
}

/* Load the plugin (plugin.h) for a command: 0, or 1 after "rbcloth: why" on stderr. */
static int open_plugin(cli_plugin *plugin) {
    char err[4096 + 512];
    if (cli_plugin_open(plugin, err, sizeof err) == 0)
        return 0;
    fprintf(stderr, "rbcloth: %s\n", err);
    return 1;
}

static int is_help(const char *arg) {
    return strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0;
}

/* Any argument -h or --help: 1 after `page` on stdout, else 0. */
static int help_asked(int argc, char **argv, const char *page) {
    for (int i = 0; i < argc; ++i)
        if (is_help(argv[i])) {
            fputs(page, stdout);
            return 1;
        }
    return 0;
}

/* Whether arg (name_len characters before any '=') names the option `name`; if so,
 * *value is its text: after the '=' (already there), else the next argument (*i
 * advanced past it), else NULL. */
static int names_option(const char *arg, size_t name_len, const char *name, const char **value,
                        int argc, char **argv, int *i) {
    if (name_len != strlen(name) || strncmp(arg, name, name_len) != 0)
        return 0;
    if (!*value && *i + 1 < argc)
        *value = argv[++*i];
    return 1;
}

/* A decimal integer in [min, max], the whole string. */
static int parse_long(const char *text, long min, long max, long *out) {
    if (!text || !text[0])
        return -1;
    char *end;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (errno || *end || v < min || v > max)
        return -1;
    *out = v;
    return 0;
}

/* A number of seconds in [0, 1e7] for option `name` into *out; EXIT_USAGE after
 * saying why, else EXIT_OK. */
static int parse_seconds(const char *name, const char *text, double *out) {
    char *end = NULL;
    double v = text && text[0] ? strtod(text, &end) : -1.0;
    if (!text || !text[0] || *end || !(v >= 0.0) || v > 1e7) {
        fprintf(stderr, "rbcloth: %s needs a number of seconds in [0, 1e7], got '%s'\n", name,
                text ? text : "");
        fprintf(stderr, "Try 'rbcloth %s'.\n", help_hint);
        return EXIT_USAGE;
    }
    *out = v;
    return EXIT_OK;
}

typedef struct int_option {
    const char *name;
    long min, max;
    long *target;
} int_option;

/* If arg (of name_len characters before any '=') names one of ints, parse its value
 * (after '=' or the next argument) into the target: *matched = 1. Returns EXIT_USAGE
 * after printing why on a bad value, else EXIT_OK. */
static int take_int_option(const int_option *ints, size_t n, const char *arg, size_t name_len,
                           const char **value, int argc, char **argv, int *i, int *matched) {
    for (size_t k = 0; k < n; ++k) {
        if (!names_option(arg, name_len, ints[k].name, value, argc, argv, i))
            continue;
        *matched = 1;
        if (parse_long(*value, ints[k].min, ints[k].max, ints[k].target)) {
            fprintf(stderr, "rbcloth: %s needs an integer in [%ld, %ld], got '%s'\n",
                    ints[k].name, ints[k].min, ints[k].max, *value ? *value : "");
            fprintf(stderr, "Try 'rbcloth %s'.\n", help_hint);
            return EXIT_USAGE;
        }
    }
    return EXIT_OK;
}

static int parse_run_args(int argc, char **argv, cli_run_options *o) {
    int_option ints[] = {
        {"--frames", 1, 10000000, &o->frames},
        {"--threads", 0, 1024, &o->threads},
        {"--substeps", 0, 1024, &o->substeps},
        {"--iterations", 1, 4096, &o->iterations},
        {"--nonlinear", 1, 1024, &o->nonlinear},
        {"--max-substeps", 1, 1024, &o->max_substeps},
        {"--max-iterations", 1, 100000, &o->max_linear},
    };
    struct {
        const char *name;
        double *target;
    } reals[] = {{"--tolerance", &o->tolerance}, {"--budget-ms", &o->budget_ms},
                 {"--omega", &o->omega}, {"--target-strain", &o->target_strain},
                 {"--substep-rate", &o->substep_rate}};
    struct {
        const char *name;
        const char *const *choices;
        const char **target;
    } names[] = {{"--solver", rbc_scene_solver_names, &o->solver},
                 {"--mode", rbc_scene_mode_names, &o->mode},
                 {"--energy-guard", rbc_scene_energy_guard_names, &o->energy_guard},
                 {"--preset", rbc_scene_preset_names, &o->preset}};
    for (int i = 0; i < argc; ++i) {
        const char *arg = argv[i];
        if (strcmp(arg, "--quiet") == 0 || strcmp(arg, "-q") == 0) {
            o->quiet = 1;
            continue;
        }
        if (strcmp(arg, "--no-view") == 0) {
            o->no_view = 1;
            continue;
        }
        if (arg[0] != '-') {
            if (o->scene_path)
                return usage_error("run takes one scene file, got a second: '%s'", arg);
            o->scene_path = arg;
            continue;
        }
        /* "--name value" or "--name=value" */
        const char *eq = strchr(arg, '=');
        size_t name_len = eq ? (size_t)(eq - arg) : strlen(arg);
        const char *value = eq ? eq + 1 : NULL;
        int matched = 0;
        if (string_option(arg, "--out", argc, argv, &i, &value)) {
            if (!value || !value[0])
                return usage_error("%s needs a directory", "--out");
            o->out_dir = value;
            continue;
        }
        if (string_option(arg, "--frame-stats", argc, argv, &i, &value)) {
            if (!value || !value[0])
                return usage_error("%s needs a file name", "--frame-stats");
            o->frame_stats = value;
            continue;
        }
        for (size_t k = 0; k < sizeof reals / sizeof reals[0]; ++k) {
            if (!names_option(arg, name_len, reals[k].name, &value, argc, argv, &i))
                continue;
            matched = 1;
            char *end = NULL;
            double v = value ? strtod(value, &end) : -1.0;
            if (!value || !value[0] || *end || !(v >= 0.0) || v > 1e9) {
                fprintf(stderr, "rbcloth: %s needs a number >= 0, got '%s'\n", reals[k].name,
                        value ? value : "");
                fprintf(stderr, "Try 'rbcloth %s'.\n", help_hint);
                return EXIT_USAGE;
            }
            *reals[k].target = v;
        }
        for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
            if (!names_option(arg, name_len, names[k].name, &value, argc, argv, &i))
                continue;
            matched = 1;
            int found = 0;
            for (int c = 0; value && names[k].choices[c]; ++c)
                found |= strcmp(value, names[k].choices[c]) == 0;
            if (!found) {
                fprintf(stderr, "rbcloth: %s needs one of:", names[k].name);
                for (int c = 0; names[k].choices[c]; ++c) fprintf(stderr, " %s", names[k].choices[c]);
                fprintf(stderr, "; got '%s'", value ? value : "");
                const char *near = value ? rbc_scene_nearest(value, names[k].choices) : NULL;
                if (near) fprintf(stderr, "; did you mean '%s'?", near);
                fprintf(stderr, "\nTry 'rbcloth %s'.\n", help_hint);
                return EXIT_USAGE;
            }
            *names[k].target = value;
        }
        if (take_int_option(ints, sizeof ints / sizeof ints[0], arg, name_len, &value, argc, argv,
                            &i, &matched))
            return EXIT_USAGE;
        if (!matched)
            return unknown("option", arg, " for run", run_option_names, help_hint);
    }
    return EXIT_OK;
}

static int command_run(int argc, char **argv) {
    cli_run_options options = {
        .scene_path = NULL,
        .out_dir = "out",
        .frames = -1,
        .threads = -1,
        .substeps = -1,
        .iterations = -1,
        .nonlinear = -1,
        .solver = NULL,
        .mode = NULL,
        .energy_guard = NULL,
        .tolerance = -1.0,
        .budget_ms = -1.0,
        .omega = -1.0,
        .preset = NULL,
        .target_strain = -1.0,
        .max_substeps = -1,
        .max_linear = -1,
        .substep_rate = -1.0,
        .quiet = 0,
    };
    help_hint = "run --help";
    if (help_asked(argc, argv, run_usage))
        return EXIT_OK;
    int rc = parse_run_args(argc, argv, &options);
    if (rc != EXIT_OK)
        return rc;

    cli_plugin plugin;
    if (open_plugin(&plugin))
        return EXIT_RUNTIME;
    rc = cli_run(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int command_batch(int argc, char **argv) {
    cli_batch_options options = {.manifest_path = NULL, .out_dir = "out/batch", .jobs = 2,
                                 .quiet = 0, .only = -1, .job_timeout = 0.0, .term_grace = 5.0};
    struct {
        const char *name;
        double *target;
    } reals[] = {{"--job-timeout", &options.job_timeout}, {"--term-grace", &options.term_grace}};
    int_option ints[] = {{"-j", 1, 256, &options.jobs},
                         {"--jobs", 1, 256, &options.jobs},
                         {"--only", 0, 100000000, &options.only}};
    help_hint = "batch --help";
    for (int i = 0; i < argc; ++i) {
        const char *arg = argv[i];
        if (is_help(arg)) {
            fputs(batch_usage, stdout);
            return EXIT_OK;
        }
        if (strcmp(arg, "--quiet") == 0 || strcmp(arg, "-q") == 0) {
            options.quiet = 1;
            continue;
        }
        if (strcmp(arg, "--report-only") == 0) {
            options.report_only = 1;
            continue;
        }
        if (strcmp(arg, "--count") == 0) {
            options.count_only = 1;
            continue;
        }
        if (arg[0] != '-') {
            if (options.manifest_path)
                return usage_error("batch takes one manifest, got a second: '%s'", arg);
            options.manifest_path = arg;
            continue;
        }
        const char *eq = strchr(arg, '=');
        size_t name_len = eq ? (size_t)(eq - arg) : strlen(arg);
        const char *value = eq ? eq + 1 : NULL;
        if (string_option(arg, "--out", argc, argv, &i, &value)) {
            if (!value || !value[0])
                return usage_error("%s needs a directory", "--out");
            options.out_dir = value;
            continue;
        }
        if (string_option(arg, "--template", argc, argv, &i, &value)) {
            if (!value || !value[0])
                return usage_error("%s needs a JSON file", "--template");
            options.template_path = value;
            continue;
        }
        /* -jN as well as -j N */
        if (strncmp(arg, "-j", 2) == 0 && arg[2] >= '0' && arg[2] <= '9') {
            value = arg + 2;
            name_len = 2;
        }
        int matched = 0;
        for (size_t k = 0; k < sizeof reals / sizeof reals[0]; ++k) {
            if (!names_option(arg, name_len, reals[k].name, &value, argc, argv, &i))
                continue;
            matched = 1;
            if (parse_seconds(reals[k].name, value, reals[k].target))
                return EXIT_USAGE;
        }
        if (!matched && take_int_option(ints, sizeof ints / sizeof ints[0], arg, name_len, &value,
                                        argc, argv, &i, &matched))
            return EXIT_USAGE;
        if (!matched)
            return unknown("option", arg, " for batch", batch_option_names, help_hint);
    }
    if (!options.manifest_path)
        return usage_error("%s", "batch needs a manifest file or a folder of meshes");
    if (options.report_only + options.count_only + (options.only >= 0) > 1)
        return usage_error("%s", "--only, --report-only and --count exclude each other");
    cli_plugin plugin;
    if (open_plugin(&plugin))
        return EXIT_RUNTIME;
    int rc = cli_batch(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int parse_bench_args(int argc, char **argv, cli_bench_options *o) {
    int_option ints[] = {
        {"--frames", 1, 1000000, &o->frames},
        {"--threads", 0, 1024, &o->threads},
        {"--setup-only", 1, 1000, &o->setup_only},
    };
    for (int i = 0; i < argc; ++i) {
        const char *arg = argv[i];
        if (strcmp(arg, "--quick") == 0) {
            o->quick = 1;
            continue;
        }
        if (strcmp(arg, "--irregular") == 0) {
            o->irregular_only = 1;
            continue;
        }
        if (arg[0] != '-')
            return usage_error("bench takes no file arguments, got '%s'", arg);
        const char *eq = strchr(arg, '=');
        size_t name_len = eq ? (size_t)(eq - arg) : strlen(arg);
        const char *value = eq ? eq + 1 : NULL;
        if (string_option(arg, "--backend", argc, argv, &i, &value)) {
            if (value && !strcmp(value, "cpu"))
                o->backend = RBC_BACKEND_CPU;
            else if (value && !strcmp(value, "cuda"))
                o->backend = RBC_BACKEND_CUDA;
            else
                return usage_error("--backend is 'cpu' or 'cuda', not '%s'", value ? value : "");
            continue;
        }
        if (string_option(arg, "--out", argc, argv, &i, &value)) {
            if (!value || !value[0])
                return usage_error("%s needs a directory", "--out");
            o->out_dir = value;
            continue;
        }
        int matched = 0;
        if (take_int_option(ints, sizeof ints / sizeof ints[0], arg, name_len, &value, argc, argv,
                            &i, &matched))
            return EXIT_USAGE;
        if (!matched)
            return unknown("option", arg, " for bench", bench_option_names, help_hint);
    }
    return EXIT_OK;
}

static int command_bench(int argc, char **argv) {
    cli_bench_options options = {
        .out_dir = "out/bench",
        .frames = -1,
        .threads = -1,
        .quick = 0,
        .backend = RBC_BACKEND_CPU,
        .setup_only = 0,
    };
    help_hint = "bench --help";
    if (help_asked(argc, argv, bench_usage))
        return EXIT_OK;
    if (argc < 1)
        return usage_error("%s", "bench needs a name: 'defaults', 'accuracy', 'stability', "
                                 "'perf', 'scenes', 'peers' or 'pool'");
    typedef int (*bench_fn)(const cli_plugin *, const cli_bench_options *);
    static const struct {
        const char *name;
        bench_fn run;
    } benches[] = {{"defaults", cli_bench_defaults},
                   {"accuracy", cli_bench_accuracy},
                   {"stability", cli_bench_stability},
                   {"perf", cli_bench_perf},
                   {"scenes", cli_bench_scenes},
                   {"peers", cli_bench_peers},
                   {"pool", cli_bench_pool}};
    const char *which = argv[0];
    bench_fn run = NULL;
    for (size_t k = 0; k < sizeof benches / sizeof benches[0]; ++k)
        if (strcmp(which, benches[k].name) == 0)
            run = benches[k].run;
    if (!run)
        return unknown("bench", which, "", bench_names, help_hint);
    int rc = parse_bench_args(argc - 1, argv + 1, &options);
    if (rc != EXIT_OK)
        return rc;
    if (options.backend != RBC_BACKEND_CPU && run != cli_bench_perf)
        return usage_error("%s", "only bench perf takes --backend");
    if (options.setup_only && run != cli_bench_perf)
        return usage_error("%s", "only bench perf takes --setup-only");

    cli_plugin plugin;
    if (open_plugin(&plugin))
        return EXIT_RUNTIME;
    rc = run(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int command_info(int argc, char **argv) {
    help_hint = "info --help";
    if (argc > 0)
        return is_help(argv[0]) ? (fputs(info_usage, stdout), EXIT_OK)
                                : usage_error("info takes no arguments, got '%s'", argv[0]);
    cli_plugin plugin;
    if (open_plugin(&plugin))
        return EXIT_RUNTIME;
    const rbc_api_v1 *api = plugin.api;
    uint32_t abi = api->abi_version_fn();
    printf("plugin:  %s (found by %s)\n", plugin.path, plugin.found_by);
    printf("ABI:     %u.%u (this host: %d.%d)\n", abi >> 16, abi & 0xFFFFu, RBC_ABI_VERSION_MAJOR,
           RBC_ABI_VERSION_MINOR);
    printf("version: %s\n", api->version_string());
    cli_plugin_close(&plugin);
    return EXIT_OK;
}

/* rbcloth --version: this program's version and ABI, and the plugin's if it loads. */
static int command_version(void) {
    printf("rbcloth %s (built against ABI %d.%d)\n", RBC_CLI_VERSION, RBC_ABI_VERSION_MAJOR,
           RBC_ABI_VERSION_MINOR);
    cli_plugin plugin;
    if (open_plugin(&plugin))
        return EXIT_RUNTIME;
    uint32_t abi = plugin.api->abi_version_fn();
    printf("librbcloth %s, ABI %u.%u (%s)\n", plugin.api->version_string(), abi >> 16,
           abi & 0xFFFFu, plugin.path);
    cli_plugin_close(&plugin);
    return EXIT_OK;
}

/* rbcloth help [COMMAND]. */
static int command_help(int argc, char **argv) {
    if (argc < 1) {
        fputs(main_usage, stdout);
        return EXIT_OK;
    }
    static const struct {
        const char *name;
        const char *text;
    } pages[] = {{"run", run_usage}, {"batch", batch_usage}, {"bench", bench_usage},
                 {"info", info_usage}, {"help", main_usage}};
    for (size_t k = 0; k < sizeof pages / sizeof pages[0]; ++k)
        if (strcmp(argv[0], pages[k].name) == 0) {
            fputs(pages[k].text, stdout);
            return EXIT_OK;
        }
    return unknown("command", argv[0], "", command_names, "--help");
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fputs(main_usage, stderr);
        return EXIT_USAGE;
    }
    const char *command = argv[1];
    if (is_help(command)) {
        fputs(main_usage, stdout);
        return EXIT_OK;
    }
    if (strcmp(command, "--version") == 0 || strcmp(command, "-V") == 0 ||
        strcmp(command, "version") == 0)
        return command_version();
    if (strcmp(command, "help") == 0)
        return command_help(argc - 2, argv + 2);
    if (strcmp(command, "run") == 0)
        return command_run(argc - 2, argv + 2);
    if (strcmp(command, "batch") == 0)
        return command_batch(argc - 2, argv + 2);
    if (strcmp(command, "bench") == 0)
        return command_bench(argc - 2, argv + 2);
    if (strcmp(command, "info") == 0)
        return command_info(argc - 2, argv + 2);
    return unknown("command", command, "", command_names, "--help");
}
