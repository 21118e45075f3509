/* Coloring and reordering (Sec. 4.2, Fig. 2): on grids and irregular quad meshes
 * every spring joins a red and a black particle, the reordering is a permutation
 * that keeps each color contiguous, springs are unique, and a mesh with an odd
 * cycle (an 11x10 quad torus) is refused. */
#include <string.h>

#include "check.h"
#include "meshes.h"
#include "rbcloth.h"
#include "topology.h"

static rbc_mesh_input input_of(const test_mesh *m) {
    rbc_mesh_input in;
    memset(&in, 0, sizeof in);
    in.vertex_count = m->nv;
    in.positions = m->pos;
    in.quad_count = m->nq;
    in.quads = m->quads;
    in.vertex_mass = 1e-4f;
    in.stiffness = 1000.0f;
    return in;
}

static uint32_t color_of(const rbc_topology *t, uint32_t i) {
    uint32_t c = 0;
    while (i >= t->color_start[c + 1]) c++;
    return c;
}

/* Checks every structural property of a built topology; expect_springs from
 * Euler's formula or the grid's count. */
static void check_topology(const char *name, const test_mesh *m, uint32_t expect_springs) {
    rbc_allocator a = rbc_allocator_default();
    rbc_mesh_input in = input_of(m);
    rbc_topology t;
    char err[256] = "";
    int32_t rc = rbc_topology_build(&in, &a, &t, err, sizeof err);
    CHECK_EQ(rc, RBC_OK);
    if (rc != RBC_OK) {
        fprintf(stderr, "%s: %s\n", name, err);
        return;
    }
    CHECK_EQ(t.n, m->nv);
    CHECK_EQ(t.ns, expect_springs);
    CHECK_EQ(t.ncolors, 2);
    CHECK_EQ(t.color_start[0], 0);
    CHECK_EQ(t.color_start[2], t.n);
    /* Balanced enough to keep both sweeps busy: neither color under a quarter. */
    CHECK(t.color_start[1] >= t.n / 4 && t.n - t.color_start[1] >= t.n / 4);
    /* to_host and to_internal are inverse permutations. */
    int perm_ok = 1;
    for (uint32_t v = 0; v < t.n; ++v) perm_ok &= t.to_host[t.to_internal[v]] == v;
    CHECK(perm_ok);
    /* Every spring joins two colors; rest data follows the permutation. */
    uint32_t same = 0, bad_rest = 0;
    for (uint32_t s = 0; s < t.ns; ++s) {
        same += color_of(&t, t.sa[s]) == color_of(&t, t.sb[s]);
        uint32_t ha = t.to_host[t.sa[s]], hb = t.to_host[t.sb[s]];
        double dx = (double)m->pos[3 * ha] - m->pos[3 * hb],
               dy = (double)m->pos[3 * ha + 1] - m->pos[3 * hb + 1],
               dz = (double)m->pos[3 * ha + 2] - m->pos[3 * hb + 2];
        /* L is the rounded double distance: within half an ulp of a float. */
        bad_rest += fabs(sqrt(dx * dx + dy * dy + dz * dz) - t.rest_len[s]) >
                    6e-8 * t.rest_len[s];
    }
    CHECK_EQ(same, 0);
    CHECK_EQ(bad_rest, 0);
    /* Adjacency: each particle's slots name distinct neighbors of the other color,
     * and ksum is the sum of their stiffness. */
    uint32_t adj_bad = 0;
    for (uint32_t i = 0; i < t.n; ++i) {
        float ks = 0.0f;
        for (uint32_t k = t.adj_start[i]; k < t.adj_start[i + 1]; ++k) {
            adj_bad += color_of(&t, t.adj_nbr[k]) == color_of(&t, i);
            for (uint32_t l = t.adj_start[i]; l < k; ++l) adj_bad += t.adj_nbr[l] == t.adj_nbr[k];
            ks += t.adj_k[k];
        }
        adj_bad += ks != t.ksum[i];
    }
    CHECK_EQ(adj_bad, 0);
    CHECK_EQ(t.adj_start[t.n], 2 * t.ns);
    printf("%s: %u particles, %u springs, colors %u + %u\n", name, t.n, t.ns, t.color_start[1],
           t.n - t.color_start[1]);
    rbc_topology_free(&t, &a);
}

int main(void) {
    test_mesh g = mesh_grid(100, 100, 1.0f / 99.0f);
    check_topology("grid 100x100", &g, 2 * 100 * 99); /* the paper's 19,800 springs */
    mesh_free(&g);

    test_mesh g2 = mesh_grid(7, 3, 0.1f);
    check_topology("grid 7x3", &g2, 7 * 2 + 3 * 6);
    mesh_free(&g2);

    /* Sphere topology: V - E + F = 2. */
    test_mesh cube = mesh_cube(6);
    check_topology("cube surface 6", &cube, cube.nv + cube.nq - 2);
    mesh_free(&cube);

    /* Disk topology: V - E + F = 1. */
    test_mesh split = mesh_split_triangles(12);
    check_topology("split triangles 12", &split, split.nv + split.nq - 1);
    mesh_free(&split);

    /* Torus with even loops: bipartite; V - E + F = 0. */
    test_mesh t10 = mesh_torus(10, 10);
    check_topology("torus 10x10", &t10, t10.nv + t10.nq);
    mesh_free(&t10);

    /* Torus with an odd loop of 11: refused with BAD_MESH and a message. */
    test_mesh t11 = mesh_torus(11, 10);
    rbc_allocator a = rbc_allocator_default();
    rbc_mesh_input in = input_of(&t11);
    rbc_topology t;
    char err[256] = "";
    CHECK_EQ(rbc_topology_build(&in, &a, &t, err, sizeof err), RBC_ERR_BAD_MESH);
    CHECK(strstr(err, "not bipartite") != NULL);
    CHECK(t.n == 0 && t.to_host == NULL); /* nothing half-built is left */
    mesh_free(&t11);

    return check_report("core_coloring");
}
