/* fuzz_cloth.c -- bytes -> an rbc_cloth_def -> rbc_cloth_create in a small world, a
 * few steps, readback, cut, destroy; through the public ABI (linked to librbcloth).
 *
 * The input is read as a stream of numbers (fuzz_common.h; what runs out reads 0):
 *   byte 0    flags: 1 two threads, 2 a collider, 4 grid positions, 8 grid quads,
 *             16 per-vertex masses, 32 an odd struct_size, 64 a cut, 128 1/60 s steps
 *   then      the world (substeps, iterations, preset, solver, mode, guard), the
 *             collider, the cloth (vertex count <= 256, positions, quads <= 256,
 *             springs <= 32, pins <= 8, masses, density, stiffness, damping, shear,
 *             bend, thickness, friction, collision flags, tearing), steps (1-3, dt)
 * Promises checked (a broken one aborts): every call returns RBC_OK or a documented
 * error code with a non-empty rbc_last_error(); a refused create leaves the world's
 * cloth count as it was, an accepted one adds one and the cloth has the def's vertex
 * count; positions read back are finite after any step (OK or not); quads, springs
 * and colors read back within their counts and ranges; destroy brings the count back;
 * nothing is printed to stdout. Sizes are capped so an input runs in milliseconds. */
#include <math.h>

#include "fuzz_common.h"

enum { MAX_VERTICES = 256, MAX_QUADS = 256, MAX_SPRINGS = 32, MAX_PINS = 8 };

static void RBC_CALL quiet_log(void *user, rbc_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static uint32_t cloth_count(rbc_world_id world) {
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = (uint32_t)sizeof st;
    st.skip_measures = 1;
    rbc_result r = rbc_world_get_stats(world, &st);
    FUZZ_CHECK(r == RBC_OK, "rbc_world_get_stats: %s (%s)", rbc_result_string(r),
               rbc_last_error());
    return st.cloth_count;
}

static void check(rbc_result r, const char *call) {
    if (r != RBC_OK) fuzz_check_error(r, call);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    fuzz_capture_stdout();
    fuzz_reader in = {data, size};
    uint32_t flags = fuzz_u8(&in);

    /* The world: small counts, any solver and mode. */
    rbc_solver_def solver;
    check(rbc_solver_def_preset(&solver, (uint32_t)sizeof solver, (rbc_preset)(fuzz_u8(&in) % 3)),
          "rbc_solver_def_preset");
    uint32_t s = fuzz_u8(&in);
    if (s < 240) {
        solver.solver = (rbc_solver_kind)(s % 8);
        solver.mode = (rbc_iteration_mode)(fuzz_u8(&in) % 4);
        solver.energy_guard = (rbc_energy_guard)(fuzz_u8(&in) % 3);
    } else { /* out of range, to be refused */
        solver.solver = (rbc_solver_kind)(int32_t)fuzz_u32(&in);
    }
    if (solver.mode == RBC_ITERATE_TOLERANCE) solver.tolerance = fabsf(fuzz_float(&in));
    if (solver.mode == RBC_ITERATE_TARGET) solver.target_strain = fuzz_float(&in);
    if (solver.mode == RBC_ITERATE_BUDGET) solver.budget_ms = 0.5f;
    if (solver.max_substeps > 8) solver.max_substeps = 8;
    if (solver.max_linear_iterations > 64) solver.max_linear_iterations = 64;

    rbc_world_def wd;
    check(rbc_world_def_init(&wd, (uint32_t)sizeof wd), "rbc_world_def_init");
    wd.thread_count = 1 + (flags & 1);
    wd.substeps = fuzz_u8(&in) % 5; /* 0: from the substep rate, capped at 8 above */
    wd.linear_iterations = 1 + fuzz_u8(&in) % 16;
    wd.nonlinear_iterations = 1 + fuzz_u8(&in) % 2;
    wd.solver = &solver;
    wd.log = quiet_log;
    wd.log_level = RBC_LOG_DEBUG;
    rbc_world_id world = 0;
    rbc_result r = rbc_world_create(&wd, &world);
    if (r != RBC_OK) {
        fuzz_check_error(r, "rbc_world_create");
        fuzz_note("world refused: %s: %s", rbc_result_string(r), rbc_last_error());
        fuzz_check_stdout("rbc_world_create");
        return 0;
    }

    if (flags & 2) {
        rbc_collider_def cd;
        check(rbc_collider_def_init(&cd, (uint32_t)sizeof cd), "rbc_collider_def_init");
        cd.shape = (rbc_shape)(1 + fuzz_u8(&in) % 4);
        cd.radius = fuzz_float(&in);
        cd.thickness = fabsf(fuzz_float(&in)) * 0.01f;
        for (int k = 0; k < 3; k++) cd.position[k] = fuzz_float(&in);
        for (int k = 0; k < 3; k++) cd.half_extents[k] = fuzz_float(&in);
        cd.friction = fuzz_float(&in);
        rbc_collider_id col = 0;
        check(rbc_collider_create(world, &cd, &col), "rbc_collider_create");
    }

    /* The cloth. */
    uint32_t nv, cols;
    if (flags & 4) {
        cols = 1 + fuzz_u8(&in) % 16;
        nv = cols * (1 + fuzz_u8(&in) % 16);
    } else {
        nv = fuzz_u8(&in);
        cols = 1;
    }
    static float positions[3 * MAX_VERTICES];
    static uint32_t quads[4 * MAX_QUADS], springs[2 * MAX_SPRINGS], pins[MAX_PINS];
    static float masses[MAX_VERTICES];
    for (uint32_t i = 0; i < nv && i < MAX_VERTICES; i++) {
        if (flags & 4) {
            float jitter = (float)((int)fuzz_u8(&in) - 128) * 1e-4f;
            positions[3 * i] = 0.1f * (float)(i % cols) + jitter;
            positions[3 * i + 1] = 0.0f;
            positions[3 * i + 2] = 0.1f * (float)(i / cols);
        } else {
            for (int k = 0; k < 3; k++) positions[3 * i + k] = fuzz_float(&in);
        }
    }
    uint32_t nq = 0;
    if ((flags & 8) && cols > 1) {
        uint32_t rows = nv / cols;
        for (uint32_t y = 0; y + 1 < rows && nq < MAX_QUADS; y++)
            for (uint32_t x = 0; x + 1 < cols && nq < MAX_QUADS; x++, nq++) {
                quads[4 * nq] = y * cols + x;
                quads[4 * nq + 1] = y * cols + x + 1;
                quads[4 * nq + 2] = (y + 1) * cols + x + 1;
                quads[4 * nq + 3] = (y + 1) * cols + x;
            }
        /* a few entries replaced from the input */
        uint32_t edits = fuzz_u8(&in) % 4;
        for (uint32_t e = 0; e < edits && nq; e++) {
            uint32_t at = fuzz_u16(&in) % (4 * nq);
            quads[at] = fuzz_u16(&in) % (nv + 2);
        }
    } else {
        nq = fuzz_u8(&in) % 33;
        for (uint32_t i = 0; i < 4 * nq; i++) quads[i] = fuzz_u16(&in) % (nv + 2);
    }
    uint32_t ns = fuzz_u8(&in) % (MAX_SPRINGS + 1);
    for (uint32_t i = 0; i < 2 * ns; i++) springs[i] = fuzz_u16(&in) % (nv + 2);
    uint32_t np = fuzz_u8(&in) % (MAX_PINS + 1);
    for (uint32_t i = 0; i < np; i++) pins[i] = fuzz_u16(&in) % (nv + 1);
    if (flags & 16)
        for (uint32_t i = 0; i < nv && i < MAX_VERTICES; i++) masses[i] = fuzz_float(&in);

    rbc_cloth_def def;
    check(rbc_cloth_def_init(&def, (uint32_t)sizeof def), "rbc_cloth_def_init");
    def.vertex_count = nv;
    def.positions = positions;
    def.quad_count = nq;
    def.quads = quads;
    def.spring_count = ns;
    def.springs = ns ? springs : NULL;
    def.pin_count = np;
    def.pins = np ? pins : NULL;
    def.masses = (flags & 16) ? masses : NULL;
    uint32_t which = fuzz_u8(&in);
    if (which & 1) def.density = fuzz_float(&in);
    if (which & 2) def.vertex_mass = fuzz_float(&in);
    if (which & 4) def.stiffness = fuzz_float(&in);
    if (which & 8) def.damping = fuzz_float(&in);
    if (which & 16) def.shear_stiffness = fuzz_float(&in);
    if (which & 32) def.bend_stiffness = fuzz_float(&in);
    if (which & 64) {
        def.thickness = fuzz_float(&in) * 0.01f;
        def.friction = fuzz_float(&in);
        def.collision_flags = fuzz_u8(&in) % 5;
    }
    if (which & 128) def.tear_strain = fuzz_float(&in);
    if (flags & 32) {
        static const uint32_t sizes[] = {RBC_CLOTH_DEF_SIZE_V1_0, RBC_CLOTH_DEF_SIZE_V1_1, 0, 4,
                                         (uint32_t)sizeof def + 4, 1u << 31};
        def.struct_size = sizes[fuzz_u8(&in) % (sizeof sizes / sizeof sizes[0])];
    }
    if (nv > MAX_VERTICES) def.vertex_count = MAX_VERTICES;

    uint32_t before = cloth_count(world);
    rbc_cloth_id cloth = 0;
    r = rbc_cloth_create(world, &def, &cloth);
    if (r != RBC_OK) {
        fuzz_check_error(r, "rbc_cloth_create");
        fuzz_note("cloth refused: %s: %s", rbc_result_string(r), rbc_last_error());
        FUZZ_CHECK(cloth_count(world) == before,
                   "a refused rbc_cloth_create (%s) changed the cloth count from %u to %u",
                   rbc_result_string(r), before, cloth_count(world));
    } else {
        FUZZ_CHECK(cloth_count(world) == before + 1, "rbc_cloth_create: cloth count %u -> %u",
                   before, cloth_count(world));
        uint32_t vc = 0;
        check(rbc_cloth_get_vertex_count(world, cloth, &vc), "rbc_cloth_get_vertex_count");
        FUZZ_CHECK(vc == def.vertex_count, "vertex count %u, def had %u", vc, def.vertex_count);

        fuzz_note("cloth of %u vertices, %u quads made", vc, def.quad_count);
        uint32_t steps = 1 + fuzz_u8(&in) % 3;
        float dt = (flags & 128) ? 1.0f / 60.0f : fuzz_float(&in);
        for (uint32_t k = 0; k < steps; k++) {
            r = rbc_world_step(world, dt);
            if (r != RBC_OK) fuzz_check_error(r, "rbc_world_step");
            fuzz_note("step %u: %s", k, rbc_result_string(r));
            static float xyz[3 * MAX_VERTICES];
            size_t written = 0;
            check(rbc_cloth_read_positions(world, cloth, xyz, 3 * MAX_VERTICES, &written),
                  "rbc_cloth_read_positions");
            FUZZ_CHECK(written == 3 * (size_t)vc, "read %zu floats of %u vertices", written, vc);
            for (size_t i = 0; i < written; i++)
                FUZZ_CHECK(isfinite(xyz[i]), "position %zu is %g after step %u (%s)", i / 3,
                           (double)xyz[i], k, rbc_result_string(r));
        }
        size_t count = 0;
        check(rbc_cloth_get_quads(world, cloth, NULL, 0, &count), "rbc_cloth_get_quads");
        FUZZ_CHECK(count <= 4 * (size_t)def.quad_count && count % 4 == 0, "%zu quad indices of %u quads",
                   count, def.quad_count);
        static uint32_t back[4 * MAX_QUADS + 8 * MAX_VERTICES];
        if (count <= sizeof back / sizeof back[0]) {
            check(rbc_cloth_get_quads(world, cloth, back, count, &count), "rbc_cloth_get_quads");
            for (size_t i = 0; i < count; i++)
                FUZZ_CHECK(back[i] < vc, "quad index %u of %u vertices", back[i], vc);
        }
        check(rbc_cloth_get_springs(world, cloth, NULL, 0, &count), "rbc_cloth_get_springs");
        if (count <= sizeof back / sizeof back[0]) {
            check(rbc_cloth_get_springs(world, cloth, back, count, &count), "rbc_cloth_get_springs");
            for (size_t i = 0; i < count; i++)
                FUZZ_CHECK(back[i] < vc, "spring index %u of %u vertices", back[i], vc);
        }
        uint32_t ncolors = 0, sizes[64];
        check(rbc_cloth_get_colors(world, cloth, sizes, 64, &ncolors), "rbc_cloth_get_colors");
        FUZZ_CHECK(ncolors <= 64, "%u colors", ncolors);
        if (flags & 64) {
            uint32_t pairs[8];
            for (int k = 0; k < 8; k++) pairs[k] = fuzz_u16(&in) % (vc + 1);
            uint32_t cut = 0;
            check(rbc_cloth_cut(world, cloth, pairs, 4, &cut), "rbc_cloth_cut");
            r = rbc_world_step(world, 1.0f / 60.0f);
            if (r != RBC_OK) fuzz_check_error(r, "rbc_world_step after a cut");
        }
        check(rbc_cloth_destroy(world, cloth), "rbc_cloth_destroy");
        FUZZ_CHECK(cloth_count(world) == before, "rbc_cloth_destroy: cloth count %u, expected %u",
                   cloth_count(world), before);
    }
    check(rbc_world_destroy(world), "rbc_world_destroy");
    fuzz_check_stdout("the cloth target");
    return 0;
}
