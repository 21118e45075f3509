/* defaults.c -- `rbcloth bench defaults`: what the default solve gives and costs
 * at the time steps hosts pass, beside the alternatives it was chosen from.
 *
 * Two cloths: the paper's (100 x 100 particles 1/99 m apart, pinned at vertices 0 and
 * 99) and a 64 x 48 grid 1/63 m apart (1 m x 0.75 m) pinned at its two corners 0 and
 * 63, both 1e-4 kg per vertex and 1000 N/m, horizontal at rest, falling under
 * gravity. Each is stepped for 4 s of simulated time at dt = 1/240, 1/60 and 1/30 s
 * (960, 240 and 120 frames) with each configuration:
 *
 *   default        rbc_world_def_default() as it is: substeps from the substep rate
 *                  (480 Hz), 11 iterations, solver NULL (RBC_PRESET_CLOTH: red-black
 *                  SOR)
 *   sor_240hz      the same at 240 Hz;  sor_960hz  at 960 Hz
 *   rbgs_480hz     RBGS (RBC_PRESET_PAPER's solver) at the default's counts: what
 *                  SOR adds
 *   paper          the paper's step, and the default before ABI 1.6: RBGS, 1 substep
 *                  of 11 iterations per dt
 *   game_60hz      RBC_PRESET_GAME_60HZ (target mode, RMS strain 0.05, 32 x 8 cap)
 *   sor_target     SOR in the target mode at 0.03 within 32 x 8: the candidate the
 *                  default was measured against
 *   reference      the exact global solve (direct) at 1920 Hz, 4 non-linear
 *                  iterations: close to the converged motion (its strain is the
 *                  cloth's own)
 *
 * Measured per run, by the library's step (stats.step_max_strain every frame, read
 * with skip_measures so the reading costs nothing) and by the host at the end: the
 * largest strain over all frames and the frames with a spring past twice its rest
 * length (strain 1), the steps the strain warning flagged (past 3 times), the
 * largest and RMS strain at the last frame, how far the cloth hangs below its pins
 * then, ms per frame (median, 90th percentile of stats.step_ms) and the substeps and
 * linear iterations per frame. One thread by default: the counts and strains do not
 * depend on it, and times are compared within one run.
 *
 * Outputs: defaults.csv, defaults.md (headed with the command, date, commit and
 * machine), defaults.gp and defaults.png (gnuplot) in DIR.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "fsutil.h"

enum {
    CFG_DEFAULT,
    CFG_SOR_240,
    CFG_SOR_960,
    CFG_RBGS_480,
    CFG_PAPER,
    CFG_GAME,
    CFG_SOR_TARGET,
    CFG_REFERENCE,
    CFG_COUNT
};

static const struct {
    const char *name;
    const char *what;
} configs[CFG_COUNT] = {
    {"default", "the default world (480 Hz, 11 SOR iterations)"},
    {"sor_240hz", "SOR, 240 Hz, 11 iterations"},
    {"sor_960hz", "SOR, 960 Hz, 11 iterations"},
    {"rbgs_480hz", "RBGS at the default's counts"},
    {"paper", "RBGS, 1 substep x 11 (the paper; the default before 1.6)"},
    {"game_60hz", "RBC_PRESET_GAME_60HZ (target 0.05, 32 x 8 cap)"},
    {"sor_target", "SOR, target mode 0.03 within 32 x 8"},
    {"reference", "direct solve, 1920 Hz, 4 non-linear iterations"},
};

typedef struct cloth_case {
    const char *name;
    uint32_t nx, ny;
    double spacing;
    uint32_t pin_count;
    uint32_t pins[2];
} cloth_case;

/* The free grid falls 78 m in the 4 s: how far its mean falls short of (or beyond)
 * the exact Verlet drop g (T^2 + T h) / 2 of its substep h shows what float
 * positions far from the origin cost each solver (fall_error). */
static const cloth_case cloths[] = {
    {"paper_cloth_100x100", 100, 100, 1.0 / 99.0, 2, {0, 99}},
    {"grid_64x48", 64, 48, 1.0 / 63.0, 2, {0, 63}},
    {"free_64x48", 64, 48, 1.0 / 63.0, 0, {0, 0}},
};
enum { CLOTH_COUNT = sizeof cloths / sizeof cloths[0] };

static const struct {
    const char *name;
    double dt;
} steps[] = {{"1/240", 1.0 / 240.0}, {"1/60", 1.0 / 60.0}, {"1/30", 1.0 / 30.0}};
enum { STEP_COUNT = sizeof steps / sizeof steps[0] };

typedef struct run_row {
    int ok;
    char error[160];
    uint32_t frames;
    double max_strain;         /* over all frames (stats.step_max_strain) */
    uint32_t frames_over_2x;   /* frames with a spring past twice its length */
    uint64_t warnings;         /* stats.strain_warning_steps: past 3 times */
    double final_max, final_rms;
    double sag;                /* lowest point below the pins at the end, m */
    double fall_error;         /* free cloths: mean drop / exact Verlet drop - 1 */
    double ms_median, ms_p90;
    double substeps_mean, linear_mean;
    uint64_t clamped;
} run_row;

/* defaults.csv: a line per cloth, time step and configuration (a run_row). */
static const char csv_header[] =
    "cloth,dt,config,frames,ok,max_strain,frames_over_2x,strain_warnings,final_max_strain,"
    "final_rms_strain,ms_median,ms_p90,substeps_mean,linear_per_frame,sag_m,fall_error,"
    "energy_clamped,error";

/* The world of configuration `cfg`, with one cloth from `m`. */
static rbc_result make_world(const rbc_api_v1 *api, int cfg, uint32_t threads,
                             const bench_mesh *m, rbc_world_id *world, rbc_cloth_id *cloth) {
    rbc_world_def wd;
    rbc_solver_def sd;
    rbc_result r = api->world_def_init(&wd, (uint32_t)sizeof wd);
    if (r != RBC_OK) return r;
    wd.thread_count = threads;
    if (cfg != CFG_DEFAULT && cfg != CFG_SOR_240 && cfg != CFG_SOR_960) {
        rbc_preset preset = cfg == CFG_GAME ? RBC_PRESET_GAME_60HZ
                            : cfg == CFG_SOR_TARGET ? RBC_PRESET_CLOTH
                                                    : RBC_PRESET_PAPER;
        if ((r = api->solver_def_preset(&sd, (uint32_t)sizeof sd, preset)) != RBC_OK) return r;
        wd.solver = &sd;
    }
    switch (cfg) {
    case CFG_SOR_240: wd.substep_rate = 240.0f; break;
    case CFG_SOR_960: wd.substep_rate = 960.0f; break;
    case CFG_PAPER: wd.substeps = 1; break;
    case CFG_SOR_TARGET:
        sd.mode = RBC_ITERATE_TARGET;
        sd.target_strain = 0.03f;
        sd.max_substeps = 32;
        sd.max_linear_iterations = 8;
        break;
    case CFG_REFERENCE:
        sd.solver = RBC_SOLVER_DIRECT;
        sd.max_substeps = 64;
        wd.substep_rate = 1920.0f;
        wd.nonlinear_iterations = 4;
        break;
    default: break;
    }
    if ((r = api->world_create(&wd, world)) != RBC_OK) return r;
    rbc_cloth_def cd;
    if ((r = bench_cloth_def(api, m, &cd)) == RBC_OK) r = api->cloth_create(*world, &cd, cloth);
    if (r != RBC_OK) {
        api->world_destroy(*world);
        *world = 0;
    }
    return r;
}

static void run_one(const rbc_api_v1 *api, int cfg, const bench_mesh *m, double dt,
                    uint32_t frames, uint32_t threads, run_row *row) {
    memset(row, 0, sizeof *row);
    rbc_world_id world;
    rbc_cloth_id cloth;
    rbc_result r = make_world(api, cfg, threads, m, &world, &cloth);
    if (r != RBC_OK) {
        snprintf(row->error, sizeof row->error, "%s", bench_result_text(api, r, row->error, sizeof row->error));
        return;
    }
    double *ms = malloc(sizeof(double) * (frames ? frames : 1));
    float *xyz = malloc(sizeof(float) * 3 * m->n);
    if (!ms || !xyz) {
        snprintf(row->error, sizeof row->error, "out of memory");
        free(ms);
        free(xyz);
        api->world_destroy(world);
        return;
    }
    uint64_t substeps = 0, linear = 0;
    uint32_t done = 0;
    for (; done < frames; ++done) {
        r = api->world_step(world, (float)dt);
        if (r != RBC_OK) {
            bench_result_text(api, r, row->error, sizeof row->error);
            break;
        }
        rbc_world_stats st;
        memset(&st, 0, sizeof st);
        st.struct_size = sizeof st;
        st.skip_measures = 1;
        api->world_get_stats(world, &st);
        ms[done] = st.step_ms;
        substeps += st.substeps;
        linear += st.linear_iterations;
        if (st.step_max_strain > row->max_strain) row->max_strain = st.step_max_strain;
        row->frames_over_2x += st.step_max_strain > 1.0;
        row->warnings = st.strain_warning_steps;
        row->clamped = st.energy_clamped_steps;
    }
    row->frames = done;
    row->ok = done == frames;
    if (done > 0) {
        rbc_world_stats st;
        bench_stats(api, world, &st);
        row->final_max = st.max_strain;
        row->final_rms = st.strain_rms;
        api->cloth_read_positions(world, cloth, xyz, 3 * (size_t)m->n, NULL);
        double low = 0.0, mean = 0.0;
        for (uint32_t i = 0; i < m->n; ++i) {
            if (-(double)xyz[3 * i + 1] > low) low = -(double)xyz[3 * i + 1];
            mean -= (double)xyz[3 * i + 1] / m->n;
        }
        row->sag = low;
        row->fall_error = NAN;
        /* The closed form needs a constant substep: not the target modes. */
        if (m->pin_count == 0 && done == frames && cfg != CFG_GAME && cfg != CFG_SOR_TARGET) {
            /* Verlet from rest with a constant substep h falls g h^2 n (n + 1) / 2
             * after n substeps: g (T^2 + T h) / 2. */
            double T = dt * done, h = st.substeps ? dt / st.substeps : dt;
            row->fall_error = mean / (9.81 * (T * T + T * h) / 2.0) - 1.0;
        }
        bench_median_p90(ms, done, &row->ms_median, &row->ms_p90);
        row->substeps_mean = (double)substeps / done;
        row->linear_mean = (double)linear / done;
    }
    free(ms);
    free(xyz);
    api->world_destroy(world);
}

static int write_plot(const char *dir) {
    FILE *f = bench_open(dir, "defaults.gp");
    if (!f) return -1;
    fprintf(f, "# Generated by `rbcloth bench defaults`; run `gnuplot defaults.gp` here.\n");
    fprintf(f, "set terminal pngcairo size 1500,480 font ',10' noenhanced\n"
               "set output 'defaults.png'\n"
               "set datafile separator ','\n"
               "set multiplot layout 1,%d\n"
               "set logscale xy\n"
               "set xlabel 'ms per frame (median, 1 thread)'\n"
               "set ylabel 'largest strain over the run'\n"
               "set key top right font ',8'\n"
               "set grid\n", CLOTH_COUNT);
    for (int c = 0; c < CLOTH_COUNT; ++c) {
        fprintf(f, "set title '%s: every dt (1/240, 1/60, 1/30 s)'\n", cloths[c].name);
        fprintf(f, "plot ");
        for (int k = 0; k < CFG_COUNT; ++k)
            fprintf(f, "%s'defaults.csv' using ((strcol(1) eq '%s' && strcol(3) eq '%s' && "
                       "$6 > 0) ? $11 : 1/0):6 with points pt %d ps 1.5 title '%s'",
                    k ? ", " : "", cloths[c].name, configs[k].name, k + 1, configs[k].name);
        fprintf(f, "\n");
    }
    fprintf(f, "unset multiplot\n");
    return bench_close(f, dir, "defaults.gp");
}

int cli_bench_defaults(const cli_plugin *plugin, const cli_bench_options *o) {
    if (bench_require_minor(plugin, "defaults", 6)) return 1;
    const rbc_api_v1 *api = plugin->api;
    const char *dir = o->out_dir;
    uint32_t threads = o->threads >= 0 ? (uint32_t)o->threads : 1;
    /* 4 s of simulated time per run; --quick: 0.5 s, the default and the paper only. */
    double seconds = o->quick ? 0.5 : 4.0;
    if (o->frames > 0) seconds = -1.0;
    if (fs_mkdir_p_or_say(dir)) return 1;
    FILE *csv = bench_open_csv(dir, "defaults.csv", csv_header);
    if (!csv) return 1;
    static run_row rows[CLOTH_COUNT][STEP_COUNT][CFG_COUNT];
    int failed = 0;
    for (int c = 0; c < CLOTH_COUNT; ++c) {
        bench_mesh m;
        if (bench_mesh_grid(&m, cloths[c].nx, cloths[c].ny, cloths[c].spacing, 0, 0.0) ||
            !(m.pins = malloc(2 * sizeof(uint32_t)))) {
            fprintf(stderr, "rbcloth: bench defaults: out of memory\n");
            fclose(csv);
            bench_mesh_free(&m);
            return 1;
        }
        m.pins[0] = cloths[c].pins[0];
        m.pins[1] = cloths[c].pins[1];
        m.pin_count = cloths[c].pin_count;
        for (int d = 0; d < STEP_COUNT; ++d)
            for (int k = 0; k < CFG_COUNT; ++k) {
                run_row *row = &rows[c][d][k];
                if (o->quick && (d != 1 || (k != CFG_DEFAULT && k != CFG_PAPER))) {
                    row->frames = 0;
                    continue;
                }
                uint32_t frames = seconds > 0.0 ? (uint32_t)lround(seconds / steps[d].dt)
                                                : (uint32_t)o->frames;
                run_one(api, k, &m, steps[d].dt, frames, threads, row);
                failed |= !row->ok;
                fprintf(csv, "%s,%s,%s,%u,%d,%.6g,%u,%llu,%.6g,%.6g,%.5f,%.5f,%.3f,%.2f,%.4f,%.6g,%llu,%s\n",
                        cloths[c].name, steps[d].name, configs[k].name, row->frames, row->ok,
                        row->max_strain, row->frames_over_2x,
                        (unsigned long long)row->warnings, row->final_max, row->final_rms,
                        row->ms_median, row->ms_p90, row->substeps_mean, row->linear_mean,
                        row->sag, row->fall_error, (unsigned long long)row->clamped, row->error);
                fflush(csv);
                printf("%-20s dt %-5s %-11s max strain %7.3f (%3u frames over 2x), final %6.3f "
                       "(RMS %.4f), %7.3f ms/frame%s%s\n",
                       cloths[c].name, steps[d].name, configs[k].name, row->max_strain,
                       row->frames_over_2x, row->final_max, row->final_rms, row->ms_median,
                       row->ok ? "" : ", FAILED: ", row->error);
                fflush(stdout);
            }
        bench_mesh_free(&m);
    }
    if (bench_close(csv, dir, "defaults.csv")) return 1;

    FILE *md = bench_open(dir, "defaults.md");
    if (!md) return 1;
    fprintf(md, "# The default solve at 1/240, 1/60 and 1/30 s\n\n");
    bench_write_provenance(md, "defaults", o);
    fprintf(md, "Each cloth falls from horizontal, pinned at two corners (the free grid: "
                "none), for %.1f s of simulated time (1e-4 kg per vertex, 1000 N/m), %u "
                "thread(s). *largest*: the "
                "largest relative strain of any spring in any frame (1 = a spring at twice "
                "its rest length; the library's strain warning fires past 2); *>2x*: frames "
                "with a spring past twice its length; *end*: the largest strain at the last "
                "frame; *ms*: median ms per frame (stats.step_ms). `reference` is the exact "
                "global solve at 1920 substeps a second with 4 local/global iterations: its "
                "strain is the cloth's own, what a converged solve shows. For the free grid "
                "*fall* is how far its mean drop is from the exact Verlet drop of its "
                "substep length, g (T^2 + T h) / 2 (78 m after 4 s): what float positions "
                "far from the origin cost each solver (at 78 m a float position moves in "
                "steps of 7.6e-6 m, and the gravity a substep adds, g h^2, is 4.3e-5 m at "
                "480 Hz and 2.7e-6 m at 1920 Hz).\n\n",
            seconds > 0.0 ? seconds : (double)o->frames * steps[1].dt, threads);
    for (int c = 0; c < CLOTH_COUNT; ++c) {
        fprintf(md, "## %s (%u particles)\n\n", cloths[c].name, cloths[c].nx * cloths[c].ny);
        const int free_fall = cloths[c].pin_count == 0;
        fprintf(md, "| configuration |");
        for (int d = 0; d < STEP_COUNT; ++d)
            fprintf(md, free_fall ? " dt %s: largest / fall | ms |" : " dt %s: largest / >2x / end | ms |",
                    steps[d].name);
        fprintf(md, "\n|---|");
        for (int d = 0; d < STEP_COUNT; ++d) fprintf(md, "---:|---:|");
        fprintf(md, "\n");
        for (int k = 0; k < CFG_COUNT; ++k) {
            int any = 0;
            for (int d = 0; d < STEP_COUNT; ++d) any |= rows[c][d][k].frames > 0;
            if (!any) continue;
            fprintf(md, "| `%s`: %s |", configs[k].name, configs[k].what);
            for (int d = 0; d < STEP_COUNT; ++d) {
                const run_row *row = &rows[c][d][k];
                if (!row->frames && !row->error[0]) {
                    fprintf(md, " | |");
                    continue;
                }
                if (!row->ok)
                    fprintf(md, " failed at frame %u: %s | |", row->frames + 1, row->error);
                else if (free_fall && isnan(row->fall_error))
                    fprintf(md, " %.2f / (substeps vary) | %.3f |", row->max_strain, row->ms_median);
                else if (free_fall)
                    fprintf(md, " %.2f / %+.2f %% | %.3f |", row->max_strain, 100.0 * row->fall_error,
                            row->ms_median);
                else
                    fprintf(md, " %.2f / %u / %.2f | %.3f |", row->max_strain, row->frames_over_2x,
                            row->final_max, row->ms_median);
            }
            fprintf(md, "\n");
        }
        fprintf(md, "\n");
    }
    fprintf(md, "![Largest strain against ms per frame, every configuration and dt](defaults.png)"
                "\n\nEvery figure of every run (RMS strain, sag, p90 ms, substeps and linear "
                "iterations per frame, energy guard clamps) is in `defaults.csv`; the plot "
                "(`defaults.png`, from `defaults.gp`) needs gnuplot.\n");
    if (bench_close(md, dir, "defaults.md")) return 1;
    if (write_plot(dir)) return 1;
    if (!bench_have_gnuplot()) {
        printf("Plot skipped: gnuplot is not on PATH (Debian: apt-get install gnuplot-nox); "
               "run `gnuplot defaults.gp` in %s.\n",
               dir);
    } else if (bench_run_gnuplot(dir, "defaults.gp") != 0) {
        fprintf(stderr, "rbcloth: bench defaults: gnuplot %s/defaults.gp failed\n", dir);
        return 1;
    }
    printf("Wrote defaults.csv, defaults.md and defaults.gp%s in %s\n",
           bench_have_gnuplot() ? ", defaults.png" : "", dir);
    return failed ? 1 : 0;
}
