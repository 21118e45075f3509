/* test_conformance.c -- a host that loads the plugin the way engines and FFIs do:
 * dlopen() the file named in argv[1], resolve the single symbol rbc_get_api, and
 * do everything else through the rbc_api_v1 function table.
 *
 * This program does not link librbcloth (it includes rbcloth.h for the types
 * only; no function of the header is called by name), and checks at run time
 * that the library was not already loaded before its dlopen (RTLD_NOLOAD).
 *
 * Checked: rbc_get_api(1) is non-NULL, its struct_size covers this header's
 * rbc_api_v1 and its abi_version has major 1 (and agrees with abi_version_fn);
 * every entry is non-NULL; rbc_get_api(0) and rbc_get_api(2) are NULL; a 10 x 10
 * cloth hanging from two pins runs 50 steps through the table with all
 * positions finite and the pins exactly in place; everything is destroyed.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "rbcloth.h"

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s path/to/librbcloth.so\n", argv[0]);
        return 2;
    }
    /* Not loaded yet: this program must not have linked the library. */
    void *pre = dlopen(argv[1], RTLD_NOW | RTLD_NOLOAD);
    CHECK(pre == NULL);
    if (pre) {
        fprintf(stderr, "  %s was already loaded: the conformance test must not link it\n", argv[1]);
        dlclose(pre);
    }

    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen(%s): %s\n", argv[1], dlerror());
        CHECK(lib != NULL);
        return check_report("abi_conformance");
    }
    /* dlsym returns void *; convert through a union to the function pointer
     * type (ISO C has no direct conversion, POSIX guarantees it works). */
    union { void *obj; rbc_get_api_fn fn; } sym;
    sym.obj = dlsym(lib, "rbc_get_api");
    CHECK(sym.obj != NULL);
    if (!sym.obj) {
        fprintf(stderr, "dlsym(rbc_get_api): %s\n", dlerror());
        dlclose(lib);
        return check_report("abi_conformance");
    }
    rbc_get_api_fn get_api = sym.fn;

    CHECK(get_api(0) == NULL);
    CHECK(get_api(2) == NULL);
    CHECK(get_api(0xFFFFFFFFu) == NULL);
    const rbc_api_v1 *api = (const rbc_api_v1 *)get_api(1);
    CHECK(api != NULL);
    if (!api) {
        dlclose(lib);
        return check_report("abi_conformance");
    }
    /* The same static table every time. */
    CHECK(get_api(1) == (const void *)api);
    CHECK(api->struct_size >= sizeof(rbc_api_v1));
    CHECK_EQ(api->abi_version >> 16, 1);
    CHECK_EQ(api->abi_version >> 16, RBC_ABI_VERSION_MAJOR);
    CHECK(api->abi_version >= (uint32_t)RBC_ABI_VERSION); /* minor may only grow */
    if (api->struct_size < sizeof(rbc_api_v1)) {
        fprintf(stderr, "  table struct_size %u < %zu: refusing to call through it\n",
                api->struct_size, sizeof(rbc_api_v1));
        dlclose(lib);
        return check_report("abi_conformance");
    }

    /* Every entry of this header's table is present. */
    {
        const size_t first = offsetof(rbc_api_v1, abi_version_fn);
        const size_t n = (sizeof(rbc_api_v1) - first) / sizeof(void (*)(void));
        int missing = 0;
        for (size_t k = 0; k < n; k++) {
            void (*fp)(void);
            memcpy(&fp, (const char *)api + first + k * sizeof fp, sizeof fp);
            if (!fp) {
                missing++;
                fprintf(stderr, "  table entry %zu is NULL\n", k);
            }
        }
        CHECK_EQ(missing, 0);
        if (missing) {
            dlclose(lib);
            return check_report("abi_conformance");
        }
    }
    CHECK_EQ(api->abi_version_fn(), api->abi_version);
    CHECK(api->version_string() != NULL && api->version_string()[0] != '\0');
    CHECK(api->result_string(RBC_ERR_BAD_MESH) != NULL &&
          strcmp(api->result_string(RBC_ERR_BAD_MESH), "RBC_ERR_BAD_MESH") == 0);
    CHECK(api->last_error() != NULL);
    /* The *_def_init entries write exactly the host's struct_size bytes: a marker
     * placed right after the def survives, and struct_size is set. */
    {
        union { rbc_world_def d; unsigned char b[sizeof(rbc_world_def) + 16]; } uw;
        union { rbc_cloth_def d; unsigned char b[sizeof(rbc_cloth_def) + 16]; } uc;
        union { rbc_collider_def d; unsigned char b[sizeof(rbc_collider_def) + 16]; } uk;
        union { rbc_cache_def d; unsigned char b[sizeof(rbc_cache_def) + 16]; } uh;
        memset(&uw, 0xCD, sizeof uw);
        memset(&uc, 0xCD, sizeof uc);
        memset(&uk, 0xCD, sizeof uk);
        memset(&uh, 0xCD, sizeof uh);
        CHECK_EQ(api->world_def_init(&uw.d, sizeof(rbc_world_def)), RBC_OK);
        CHECK_EQ(api->cloth_def_init(&uc.d, sizeof(rbc_cloth_def)), RBC_OK);
        CHECK_EQ(api->collider_def_init(&uk.d, sizeof(rbc_collider_def)), RBC_OK);
        CHECK_EQ(api->cache_def_init(&uh.d, sizeof(rbc_cache_def)), RBC_OK);
        CHECK_EQ(uw.d.struct_size, sizeof(rbc_world_def));
        CHECK_EQ(uc.d.struct_size, sizeof(rbc_cloth_def));
        CHECK_EQ(uk.d.struct_size, sizeof(rbc_collider_def));
        CHECK_EQ(uh.d.struct_size, sizeof(rbc_cache_def));
        int overrun = 0;
        for (size_t k = sizeof(rbc_world_def); k < sizeof uw; k++) overrun |= uw.b[k] != 0xCD;
        for (size_t k = sizeof(rbc_cloth_def); k < sizeof uc; k++) overrun |= uc.b[k] != 0xCD;
        for (size_t k = sizeof(rbc_collider_def); k < sizeof uk; k++) overrun |= uk.b[k] != 0xCD;
        for (size_t k = sizeof(rbc_cache_def); k < sizeof uh; k++) overrun |= uh.b[k] != 0xCD;
        CHECK(!overrun);
        /* Documented defaults, spot-checked. */
        /* 1.6: substeps 0 = from the substep rate, 480 Hz. */
        CHECK(uw.d.gravity[1] == -9.81f && uw.d.substeps == 0 && uw.d.substep_rate == 480.0f &&
              uw.d.linear_iterations == 11);
        CHECK(uc.d.stiffness == 1000.0f && uc.d.vertex_mass == 1e-4f && uc.d.damping == 0.0f);
        CHECK(uk.d.shape == RBC_SHAPE_PLANE && uk.d.radius == 0.5f && uk.d.rotation[3] == 1.0f);
        CHECK(uh.d.format == RBC_CACHE_PC2 && uh.d.sample_rate == 1.0f);
    }

    /* A 10 x 10 cloth, 0.1 m spacing, horizontal at y = 1, pinned at the corners
     * 0 and 9 of its first row, plus a sphere below it; 50 frames of 1/60 s. */
    enum { NX = 10, NY = 10, NV = NX * NY, NQ = (NX - 1) * (NY - 1) };
    static float pos[3 * NV];
    static uint32_t quads[4 * NQ];
    for (uint32_t j = 0; j < NY; j++)
        for (uint32_t i = 0; i < NX; i++) {
            uint32_t v = i + NX * j;
            pos[3 * v + 0] = 0.1f * (float)i;
            pos[3 * v + 1] = 1.0f;
            pos[3 * v + 2] = 0.1f * (float)j;
        }
    for (uint32_t j = 0; j + 1 < NY; j++)
        for (uint32_t i = 0; i + 1 < NX; i++) {
            uint32_t q = i + (NX - 1) * j;
            quads[4 * q + 0] = i + NX * j;
            quads[4 * q + 1] = i + 1 + NX * j;
            quads[4 * q + 2] = i + 1 + NX * (j + 1);
            quads[4 * q + 3] = i + NX * (j + 1);
        }
    const uint32_t pins[2] = {0, NX - 1};

    rbc_world_def wd;
    CHECK_EQ(api->world_def_init(&wd, sizeof wd), RBC_OK);
    rbc_world_id w = 0;
    CHECK_EQ(api->world_create(&wd, &w), RBC_OK);
    rbc_cloth_def cd;
    CHECK_EQ(api->cloth_def_init(&cd, sizeof cd), RBC_OK);
    cd.vertex_count = NV;
    cd.positions = pos;
    cd.quad_count = NQ;
    cd.quads = quads;
    cd.pin_count = 2;
    cd.pins = pins;
    rbc_cloth_id c = 0;
    CHECK_EQ(api->cloth_create(w, &cd, &c), RBC_OK);
    rbc_collider_def kd;
    CHECK_EQ(api->collider_def_init(&kd, sizeof kd), RBC_OK);
    kd.shape = RBC_SHAPE_SPHERE;
    kd.radius = 0.2f;
    kd.position[0] = 0.45f;
    kd.position[1] = 0.3f;
    kd.position[2] = 0.45f;
    rbc_collider_id k = 0;
    CHECK_EQ(api->collider_create(w, &kd, &k), RBC_OK);

    uint32_t nv = 0, ns = 0, ncol = 0;
    CHECK_EQ(api->cloth_get_vertex_count(w, c, &nv), RBC_OK);
    CHECK_EQ(nv, NV);
    CHECK_EQ(api->cloth_get_topology(w, c, &ns, &ncol), RBC_OK);
    CHECK_EQ(ns, NY * (NX - 1) + NX * (NY - 1));
    CHECK_EQ(ncol, 2);
    const float g[3] = {0.0f, -9.81f, 0.0f};
    CHECK_EQ(api->world_set_gravity(w, g), RBC_OK);
    CHECK_EQ(api->world_set_iterations(w, 2, 1, 11), RBC_OK);

    int step_fail = 0;
    for (int s = 0; s < 50; s++)
        if (api->world_step(w, 1.0f / 60.0f) != RBC_OK) step_fail++;
    CHECK_EQ(step_fail, 0);

    static float out[3 * NV];
    size_t need = 0, written = 0;
    CHECK_EQ(api->cloth_read_positions(w, c, NULL, 0, &need), RBC_OK);
    CHECK_EQ(need, 3 * NV);
    CHECK_EQ(api->cloth_read_positions(w, c, out, 3 * NV, &written), RBC_OK);
    CHECK_EQ(written, 3 * NV);
    int finite = 1;
    float ymin = INFINITY;
    for (int v = 0; v < 3 * NV; v++)
        if (!isfinite(out[v])) finite = 0;
    for (int v = 0; v < NV; v++) ymin = fminf(ymin, out[3 * v + 1]);
    CHECK(finite);
    /* Pins are written positions: exactly in place. */
    CHECK(memcmp(out + 3 * pins[0], pos + 3 * pins[0], 3 * sizeof(float)) == 0);
    CHECK(memcmp(out + 3 * pins[1], pos + 3 * pins[1], 3 * sizeof(float)) == 0);
    /* The cloth did move (hangs below its start). */
    CHECK(ymin < 0.9f);

    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    CHECK_EQ(api->world_get_stats(w, &st), RBC_OK);
    CHECK_EQ(st.step_count, 50);
    CHECK_EQ(st.particle_count, NV);

    /* An error through the table sets the table's last_error. */
    CHECK_EQ(api->world_step(w, -1.0f), RBC_ERR_INVALID_ARGUMENT);
    CHECK(api->last_error()[0] != '\0');

    CHECK_EQ(api->collider_destroy(w, k), RBC_OK);
    CHECK_EQ(api->cloth_destroy(w, c), RBC_OK);
    CHECK_EQ(api->world_destroy(w), RBC_OK);
    CHECK_EQ(api->world_step(w, 1.0f / 60.0f), RBC_ERR_STALE_HANDLE);

    CHECK_EQ(dlclose(lib), 0);
    return check_report("abi_conformance");
}
