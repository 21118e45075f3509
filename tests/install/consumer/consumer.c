/* consumer.c -- a host built against an installed rbcloth: linked with -lrbcloth (by
 * find_package, pkg-config or add_subdirectory), not dlopen'd. It checks that the
 * library it runs is the major it was built for, drops a free quad for 10 steps
 * (each vertex falls g t^2 / 2, as the substeps discretise it), and imports a mesh
 * file through the installed helper. Exit 0 on success. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "rbcloth.h"

int main(int argc, char **argv) {
    uint32_t v = rbc_abi_version();
    if ((v >> 16) != RBC_ABI_VERSION_MAJOR || (v & 0xFFFF) < RBC_ABI_VERSION_MINOR) {
        fprintf(stderr, "consumer: built for ABI %d.%d, the library is %u.%u\n",
                RBC_ABI_VERSION_MAJOR, RBC_ABI_VERSION_MINOR, v >> 16, v & 0xFFFF);
        return 1;
    }
    float pos[4 * 3] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
    const uint32_t quad[4] = {0, 1, 2, 3};
    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = 0;
    rbc_cloth_def cd = rbc_cloth_def_default();
    cd.vertex_count = 4;
    cd.positions = pos;
    cd.quad_count = 1;
    cd.quads = quad;
    rbc_cloth_id c = 0;
    if (rbc_world_create(&wd, &w) || rbc_cloth_create(w, &cd, &c)) {
        fprintf(stderr, "consumer: %s\n", rbc_last_error());
        return 1;
    }
    for (int k = 0; k < 10; ++k)
        if (rbc_world_step(w, 0.01f)) {
            fprintf(stderr, "consumer: step: %s\n", rbc_last_error());
            return 1;
        }
    float out[12];
    rbc_cloth_read_positions(w, c, out, 12, NULL);
    /* 0.1 s of free fall: 4.9 cm. The default 480 Hz substeps make 50 of 2 ms, after
     * which the integration has fallen g h^2 n (n + 1) / 2, (n + 1) / n = 2 % further
     * than g t^2 / 2: the fall must lie within [exact, 1.03 exact]. */
    double fall = -out[1], exact = 0.5 * 9.81 * 0.1 * 0.1;
    rbc_world_destroy(w);
    if (!(fall >= exact && fall <= 1.03 * exact)) {
        fprintf(stderr, "consumer: fell %g m in 0.1 s, not %g\n", fall, exact);
        return 1;
    }
    if (argc > 1) { /* a mesh through the installed helper (../libexec/rbcloth) */
        rbc_mesh_id m = 0;
        if (rbc_mesh_import(argv[1], NULL, &m)) {
            fprintf(stderr, "consumer: import: %s\n", rbc_last_error());
            return 1;
        }
        rbc_mesh_destroy(m);
    }
    printf("consumer: ABI %u.%u, fell %.4f m (exact %.4f)%s\n", v >> 16, v & 0xFFFF, fall, exact,
           argc > 1 ? ", imported the mesh" : "");
    return 0;
}
