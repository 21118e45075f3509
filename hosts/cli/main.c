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

static const char usage_text[] =
    "Usage: rbcloth COMMAND [ARGS]\n"
    "\n"
    "A real-time quad mass-spring cloth solver (librbcloth) on the command line.\n"
    "\n"
    "Commands:\n"
    "  run [SCENE.json] [OPTIONS]  simulate a scene (the built-in 100 x 100 hanging\n"
    "                              cloth when SCENE is omitted) and write into DIR:\n"
    "                              NAME.obj (rest mesh), NAME.pc2 (point cache of every\n"
    "                              frame) and NAME.json (summary); with several cloths\n"
    "                              NAME_CLOTH.obj and NAME_CLOTH.pc2 per cloth\n"
    "  batch MANIFEST.json [-j N] [--out DIR] [--quiet]\n"
    "                              simulate every job of a manifest (mesh files read\n"
    "                              with assimp, or scenes) in N worker processes:\n"
    "                              DIR/JOB/ holds JOB.obj (rest mesh) and the caches\n"
    "                              asked for (pc2, mdd, objseq: frames/JOB_0001.obj..);\n"
    "                              finished jobs are skipped on a rerun; SIGINT/SIGTERM\n"
    "                              stop it without half-written files; closes with\n"
    "                              DIR/batch_report.json and .md (default -j 2, DIR\n"
    "                              out/batch); exit 1 if any job failed\n"
    "  batch MESHDIR --template T.json [-j N] [--out DIR] [--quiet]\n"
    "                              folder mode: every mesh file in MESHDIR (.obj .ply\n"
    "                              .off .stl .dae .gltf .glb .fbx .3ds ...) is a job\n"
    "                              named after its file, with T's settings (the keys\n"
    "                              of a manifest's \"defaults\": frames, dt, solver,\n"
    "                              pins, colliders, outputs ...)\n"
    "    --only I                  run job I only (0-based, manifest or file-name\n"
    "                              order) and write no report: one Slurm array task\n"
    "    --report-only             run nothing; build DIR/batch_report.json and .md\n"
    "                              from the results in DIR (the Slurm merge step)\n"
    "    --count                   print the number of jobs and exit\n"
    "                              (samples/slurm/ runs a batch as a Slurm job array)\n"
    "  bench accuracy [OPTIONS]    the paper's convergence experiments (Figs. 3, 4)\n"
    "                              for every solver: Eq. 7 per frame at 11 iterations\n"
    "                              and within 2 ms, a budget sweep, the PD objective\n"
    "                              gap; CSVs, pareto.md and PNG plots (gnuplot) in DIR\n"
    "  bench stability [OPTIONS]   a stability map of every solver over stiffness, dt,\n"
    "                              mass ratio, size, degenerate springs, stretch, pins\n"
    "                              and a moving sphere: stability.csv, stability.md\n"
    "  bench perf [OPTIONS]        what a frame costs: ms per frame and per stage,\n"
    "                              particle updates/s, setup time and memory of RBGS\n"
    "                              on 1K .. 1M particle grids with 1 and N threads, an\n"
    "                              irregular quad mesh against the grid, Jacobi and\n"
    "                              serial Gauss-Seidel at equal iterations: perf.csv,\n"
    "                              perf.md, perf_scaling.png\n"
    "  bench scenes [OPTIONS]      the paper's scenes (samples/scenes: cloth on a chair,\n"
    "                              four layers and a sphere, funnel, cannonballs and\n"
    "                              tearing; two reference scenes) with 1 and N threads,\n"
    "                              collisions included: ms per step and substep (median,\n"
    "                              p90), stages, contacts, torn springs, penetration,\n"
    "                              beside the paper's GTX 970 figures: scenes.csv,\n"
    "                              scenes.md, scenes.png (scenes from $RBC_SCENES_DIR,\n"
    "                              else ./samples/scenes, else the source tree's)\n"
    "  bench peers [OPTIONS]       rbcloth on the peer scene of FIELD-NOTES (the default\n"
    "                              scene, 500 frames, 1 thread): solver x substeps x\n"
    "                              non-linear x linear iterations (SOR omega, Chebyshev\n"
    "                              rho, energy guard), the Pareto front of ms per frame\n"
    "                              against Eq. 7 beside the peers' figures: peers.csv,\n"
    "                              peers.md, peers.png (a few minutes; --quick: seconds)\n"
    "  info                        print the plugin's path, ABI version and version\n"
    "\n"
    "Options of run:\n"
    "  --out DIR         output directory, created if missing (default: out)\n"
    "  --frames N        frames to simulate (one step of the scene's dt each)\n"
    "  --threads N       worker threads; 0 = one per core\n"
    "  --substeps N      substeps per frame (1..1024)\n"
    "  --iterations N    linear iterations per non-linear iteration (1..4096)\n"
    "  --nonlinear N     non-linear (local/global) iterations per substep (1..1024)\n"
    "  --solver NAME     global solver: rbgs (default), jacobi, jacobi_chebyshev,\n"
    "                    gauss_seidel, rbgs_sor, rbgs_chebyshev, multicolor_gs, direct\n"
    "  --mode NAME       when linear iterations stop: fixed (the count), tolerance\n"
    "                    (relative residual), budget (milliseconds per frame), target\n"
    "                    (substeps and iterations chosen per frame to reach a strain)\n"
    "  --target-strain X RMS relative strain for --mode target (default 0.05)\n"
    "  --max-substeps N  most substeps per frame in --mode target (1..1024, default 16)\n"
    "  --max-iterations N  most linear iterations per non-linear iteration in the\n"
    "                    tolerance, budget and target modes (default 1000)\n"
    "  --preset NAME     solver preset applied before the options: default, game_60hz\n"
    "                    (target mode, strain 0.05, 32 substeps x 8 iterations at most)\n"
    "  --tolerance X     relative residual for --mode tolerance (default 1e-3)\n"
    "  --budget-ms X     milliseconds per frame for --mode budget (default 2)\n"
    "  --omega X         SOR factor for rbgs_sor, in (0, 2); 0 = optimal (default)\n"
    "  --energy-guard G  when a step adds energy the cloth was not given: clamp\n"
    "                    (default: scale velocities, log, count), fail (error, state\n"
    "                    restored) or off\n"
    "  --frame-stats F   write F, a CSV of every frame: step and collision ms,\n"
    "                    kinetic, potential and guard energies, contacts, strain,\n"
    "                    vertices the cloth contact fail-safe froze or capped\n"
    "  --quiet           no progress bar and no table of timings\n"
    "\n"
    "Options of bench:\n"
    "  --out DIR         output directory, created if missing (default: out/bench)\n"
    "  --frames N        frames per run (accuracy: default 240; stability: 200;\n"
    "                    perf: 200 up to 10K particles, fewer above, 20 at 1M;\n"
    "                    scenes: the scene's, measured after 2 warm-up frames;\n"
    "                    peers: 500, --quick 60)\n"
    "  --threads N       worker threads of every world; 0 = one per core (perf,\n"
    "                    scenes: measure 1 thread and N threads, default N = 2;\n"
    "                    peers: default 1)\n"
    "  --quick           fewer frames, budgets and cases (a smoke run, for tests;\n"
    "                    perf: only cloths up to 10K particles)\n"
    "\n"
    "  -h, --help        show this help\n"
    "\n"
    "The plugin is $RBC_PLUGIN if set, else ../lib/librbcloth.so next to this\n"
    "executable, else librbcloth.so from the library search path.\n"
    "Exit status: 0 success, 1 runtime failure, 2 usage error.\n";

static int usage_error(const char *fmt, const char *arg) {
    fputs("rbcloth: ", stderr);
    fprintf(stderr, fmt, arg);
    fputs("\nTry 'rbcloth --help'.\n", stderr);
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

static int is_help(const char *arg) {
    return strcmp(arg, "-h") == 0 || strcmp(arg, "--help") == 0;
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
        if (name_len != strlen(ints[k].name) || strncmp(arg, ints[k].name, name_len) != 0)
            continue;
        *matched = 1;
        if (!*value && *i + 1 < argc)
            *value = argv[++*i];
        if (parse_long(*value, ints[k].min, ints[k].max, ints[k].target)) {
            fprintf(stderr, "rbcloth: %s needs an integer in [%ld, %ld], got '%s'\n",
                    ints[k].name, ints[k].min, ints[k].max, *value ? *value : "");
            fputs("Try 'rbcloth --help'.\n", stderr);
            return EXIT_USAGE;
        }
    }
    return EXIT_OK;
}

static int parse_run_args(int argc, char **argv, cli_run_options *o) {
    int_option ints[] = {
        {"--frames", 1, 10000000, &o->frames},
        {"--threads", 0, 1024, &o->threads},
        {"--substeps", 1, 1024, &o->substeps},
        {"--iterations", 1, 4096, &o->iterations},
        {"--nonlinear", 1, 1024, &o->nonlinear},
        {"--max-substeps", 1, 1024, &o->max_substeps},
        {"--max-iterations", 1, 100000, &o->max_linear},
    };
    struct {
        const char *name;
        double *target;
    } reals[] = {{"--tolerance", &o->tolerance}, {"--budget-ms", &o->budget_ms},
                 {"--omega", &o->omega}, {"--target-strain", &o->target_strain}};
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
            if (name_len != strlen(reals[k].name) || strncmp(arg, reals[k].name, name_len) != 0)
                continue;
            matched = 1;
            if (!value && i + 1 < argc)
                value = argv[++i];
            char *end = NULL;
            double v = value ? strtod(value, &end) : -1.0;
            if (!value || !value[0] || *end || !(v >= 0.0) || v > 1e9) {
                fprintf(stderr, "rbcloth: %s needs a number >= 0, got '%s'\n", reals[k].name,
                        value ? value : "");
                fputs("Try 'rbcloth --help'.\n", stderr);
                return EXIT_USAGE;
            }
            *reals[k].target = v;
        }
        for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
            if (name_len != strlen(names[k].name) || strncmp(arg, names[k].name, name_len) != 0)
                continue;
            matched = 1;
            if (!value && i + 1 < argc)
                value = argv[++i];
            int found = 0;
            for (int c = 0; value && names[k].choices[c]; ++c)
                found |= strcmp(value, names[k].choices[c]) == 0;
            if (!found) {
                fprintf(stderr, "rbcloth: %s needs one of:", names[k].name);
                for (int c = 0; names[k].choices[c]; ++c) fprintf(stderr, " %s", names[k].choices[c]);
                fprintf(stderr, "; got '%s'\n", value ? value : "");
                fputs("Try 'rbcloth --help'.\n", stderr);
                return EXIT_USAGE;
            }
            *names[k].target = value;
        }
        if (take_int_option(ints, sizeof ints / sizeof ints[0], arg, name_len, &value, argc, argv,
                            &i, &matched))
            return EXIT_USAGE;
        if (!matched)
            return usage_error("unknown option '%s' for run", arg);
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
        .quiet = 0,
    };
    for (int i = 0; i < argc; ++i) {
        if (is_help(argv[i])) {
            fputs(usage_text, stdout);
            return EXIT_OK;
        }
    }
    int rc = parse_run_args(argc, argv, &options);
    if (rc != EXIT_OK)
        return rc;

    cli_plugin plugin;
    char err[4096 + 512];
    if (cli_plugin_open(&plugin, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return EXIT_RUNTIME;
    }
    rc = cli_run(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int command_batch(int argc, char **argv) {
    cli_batch_options options = {.manifest_path = NULL, .out_dir = "out/batch", .jobs = 2,
                                 .quiet = 0, .only = -1};
    int_option ints[] = {{"-j", 1, 256, &options.jobs},
                         {"--jobs", 1, 256, &options.jobs},
                         {"--only", 0, 100000000, &options.only}};
    for (int i = 0; i < argc; ++i) {
        const char *arg = argv[i];
        if (is_help(arg)) {
            fputs(usage_text, stdout);
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
        if (take_int_option(ints, sizeof ints / sizeof ints[0], arg, name_len, &value, argc, argv,
                            &i, &matched))
            return EXIT_USAGE;
        if (!matched)
            return usage_error("unknown option '%s' for batch", arg);
    }
    if (!options.manifest_path)
        return usage_error("%s", "batch needs a manifest file or a folder of meshes");
    if (options.report_only + options.count_only + (options.only >= 0) > 1)
        return usage_error("%s", "--only, --report-only and --count exclude each other");
    cli_plugin plugin;
    char err[4096 + 512];
    if (cli_plugin_open(&plugin, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return EXIT_RUNTIME;
    }
    int rc = cli_batch(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int parse_bench_args(int argc, char **argv, cli_bench_options *o) {
    int_option ints[] = {
        {"--frames", 1, 1000000, &o->frames},
        {"--threads", 0, 1024, &o->threads},
    };
    for (int i = 0; i < argc; ++i) {
        const char *arg = argv[i];
        if (strcmp(arg, "--quick") == 0) {
            o->quick = 1;
            continue;
        }
        if (arg[0] != '-')
            return usage_error("bench takes no file arguments, got '%s'", arg);
        const char *eq = strchr(arg, '=');
        size_t name_len = eq ? (size_t)(eq - arg) : strlen(arg);
        const char *value = eq ? eq + 1 : NULL;
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
            return usage_error("unknown option '%s' for bench", arg);
    }
    return EXIT_OK;
}

static int command_bench(int argc, char **argv) {
    cli_bench_options options = {
        .out_dir = "out/bench",
        .frames = -1,
        .threads = -1,
        .quick = 0,
    };
    for (int i = 0; i < argc; ++i) {
        if (is_help(argv[i])) {
            fputs(usage_text, stdout);
            return EXIT_OK;
        }
    }
    if (argc < 1)
        return usage_error("%s",
                           "bench needs 'accuracy', 'stability', 'perf', 'scenes' or 'peers'");
    typedef int (*bench_fn)(const cli_plugin *, const cli_bench_options *);
    static const struct {
        const char *name;
        bench_fn run;
    } benches[] = {{"accuracy", cli_bench_accuracy},
                   {"stability", cli_bench_stability},
                   {"perf", cli_bench_perf},
                   {"scenes", cli_bench_scenes},
                   {"peers", cli_bench_peers}};
    const char *which = argv[0];
    bench_fn run = NULL;
    for (size_t k = 0; k < sizeof benches / sizeof benches[0]; ++k)
        if (strcmp(which, benches[k].name) == 0)
            run = benches[k].run;
    if (!run)
        return usage_error("unknown bench '%s' (accuracy, stability, perf, scenes or peers)",
                           which);
    int rc = parse_bench_args(argc - 1, argv + 1, &options);
    if (rc != EXIT_OK)
        return rc;

    cli_plugin plugin;
    char err[4096 + 512];
    if (cli_plugin_open(&plugin, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return EXIT_RUNTIME;
    }
    rc = run(&plugin, &options);
    cli_plugin_close(&plugin);
    return rc;
}

static int command_info(int argc, char **argv) {
    if (argc > 0)
        return is_help(argv[0]) ? (fputs(usage_text, stdout), EXIT_OK)
                                : usage_error("info takes no arguments, got '%s'", argv[0]);
    cli_plugin plugin;
    char err[4096 + 512];
    if (cli_plugin_open(&plugin, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return EXIT_RUNTIME;
    }
    const rbc_api_v1 *api = plugin.api;
    uint32_t abi = api->abi_version_fn();
    printf("plugin:  %s (found by %s)\n", plugin.path, plugin.found_by);
    printf("ABI:     %u.%u (this host: %d.%d)\n", abi >> 16, abi & 0xFFFFu, RBC_ABI_VERSION_MAJOR,
           RBC_ABI_VERSION_MINOR);
    printf("version: %s\n", api->version_string());
    cli_plugin_close(&plugin);
    return EXIT_OK;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fputs(usage_text, stderr);
        return EXIT_USAGE;
    }
    const char *command = argv[1];
    if (is_help(command) || strcmp(command, "help") == 0) {
        fputs(usage_text, stdout);
        return EXIT_OK;
    }
    if (strcmp(command, "run") == 0)
        return command_run(argc - 2, argv + 2);
    if (strcmp(command, "batch") == 0)
        return command_batch(argc - 2, argv + 2);
    if (strcmp(command, "bench") == 0)
        return command_bench(argc - 2, argv + 2);
    if (strcmp(command, "info") == 0)
        return command_info(argc - 2, argv + 2);
    return usage_error("unknown command '%s'", command);
}
