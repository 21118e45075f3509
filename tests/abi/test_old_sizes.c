/* test_old_sizes.c -- every RBC_*_SIZE_V1_n macro is a size some released header's
 * sizeof gave. An older host passes its sizeof as struct_size; the macro names that
 * size for the library to accept, as the offset of the first field appended after
 * it. A field appended into the old layout's trailing padding (a float after a
 * 4-byte field in a struct holding pointers) makes the macro smaller than that
 * sizeof: the library would then refuse old hosts, or worse, read their padding as
 * the new field. An old sizeof is a multiple of the old layout's alignment: 8 on
 * LP64 where its fields before the offset hold a pointer or a 64-bit integer, else 4
 * (every other field is a 4-byte integer, float or enum). 1.9's rbc_cache_def.
 * frame_rate first went in at offset 44 of a 48-byte struct; this test fails there.
 * Then: each *_init refuses a size no release had with a message that lists every
 * size it accepts, and accepts each of them. */
#include <stdalign.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "rbcloth.h"

#define PTR alignof(void *)
#define U64 alignof(uint64_t)
#define FOUR ((size_t)4)
#define LAYOUT(macro, type, align) {#macro, macro, sizeof(type), align}

int main(void) {
    static const struct {
        const char *name;
        uint32_t size;
        size_t now, align;
    } layouts[] = {
        LAYOUT(RBC_SOLVER_DEF_SIZE_V1_1, rbc_solver_def, FOUR),
        LAYOUT(RBC_SOLVER_DEF_SIZE_V1_2, rbc_solver_def, FOUR),
        LAYOUT(RBC_WORLD_DEF_SIZE_V1_0, rbc_world_def, PTR),    /* alloc_user */
        LAYOUT(RBC_WORLD_DEF_SIZE_V1_1, rbc_world_def, PTR),
        LAYOUT(RBC_CLOTH_DEF_SIZE_V1_0, rbc_cloth_def, PTR),    /* positions */
        LAYOUT(RBC_CLOTH_DEF_SIZE_V1_1, rbc_cloth_def, PTR),
        LAYOUT(RBC_COLLIDER_DEF_SIZE_V1_0, rbc_collider_def, FOUR),
        LAYOUT(RBC_CACHE_DEF_SIZE_V1_0, rbc_cache_def, PTR),    /* path */
        LAYOUT(RBC_CACHE_DEF_SIZE_V1_2, rbc_cache_def, PTR),
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_0, rbc_world_stats, U64), /* step_count */
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_1, rbc_world_stats, U64),
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_2, rbc_world_stats, U64),
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_3, rbc_world_stats, U64),
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_4, rbc_world_stats, U64),
        LAYOUT(RBC_WORLD_STATS_SIZE_V1_5, rbc_world_stats, U64),
        LAYOUT(RBC_MESH_IMPORT_DEF_SIZE_V1_2, rbc_mesh_import_def, PTR), /* mesh_name */
        LAYOUT(RBC_MESH_IMPORT_DEF_SIZE_V1_8, rbc_mesh_import_def, PTR),
        LAYOUT(RBC_MESH_INFO_SIZE_V1_2, rbc_mesh_info, FOUR),
        LAYOUT(RBC_API_V1_SIZE_V1_0, rbc_api_v1, PTR), /* struct_size, then pointers */
        LAYOUT(RBC_API_V1_SIZE_V1_1, rbc_api_v1, PTR),
        LAYOUT(RBC_API_V1_SIZE_V1_2, rbc_api_v1, PTR),
        LAYOUT(RBC_API_V1_SIZE_V1_3, rbc_api_v1, PTR),
        LAYOUT(RBC_API_V1_SIZE_V1_6, rbc_api_v1, PTR),
        LAYOUT(RBC_API_V1_SIZE_V1_8, rbc_api_v1, PTR),
    };
    for (size_t k = 0; k < sizeof layouts / sizeof layouts[0]; ++k) {
        int whole = layouts[k].size % layouts[k].align == 0;
        int older = layouts[k].size < layouts[k].now;
        CHECK(whole);
        CHECK(older);
        if (!whole || !older)
            fprintf(stderr, "  %s is %u: %s (the struct is %zu bytes now, aligned to %zu)\n",
                    layouts[k].name, layouts[k].size,
                    !whole ? "no sizeof of an older layout (a field went into its padding)"
                           : "not smaller than the struct",
                    layouts[k].now, layouts[k].align);
    }
    /* Every struct-size refusal lists every size the library accepts (one table per
     * struct in plugin/defs.c feeds the checks and the messages alike). */
    static const struct {
        const char *name;
        rbc_result (RBC_CALL *init)(void *, uint32_t);
        uint32_t sizes[8];
    } inits[] = {
        {"rbc_world_def_init", (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_world_def_init,
         {sizeof(rbc_world_def), RBC_WORLD_DEF_SIZE_V1_1, RBC_WORLD_DEF_SIZE_V1_0}},
        {"rbc_cloth_def_init", (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_cloth_def_init,
         {sizeof(rbc_cloth_def), RBC_CLOTH_DEF_SIZE_V1_1, RBC_CLOTH_DEF_SIZE_V1_0}},
        {"rbc_collider_def_init",
         (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_collider_def_init,
         {sizeof(rbc_collider_def), RBC_COLLIDER_DEF_SIZE_V1_0}},
        {"rbc_solver_def_init", (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_solver_def_init,
         {sizeof(rbc_solver_def), RBC_SOLVER_DEF_SIZE_V1_2, RBC_SOLVER_DEF_SIZE_V1_1}},
        {"rbc_cache_def_init", (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_cache_def_init,
         {sizeof(rbc_cache_def), RBC_CACHE_DEF_SIZE_V1_2, RBC_CACHE_DEF_SIZE_V1_0}},
        {"rbc_mesh_import_def_init",
         (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_mesh_import_def_init,
         {sizeof(rbc_mesh_import_def), RBC_MESH_IMPORT_DEF_SIZE_V1_8,
          RBC_MESH_IMPORT_DEF_SIZE_V1_2}},
        {"rbc_world_stats_init", (rbc_result (RBC_CALL *)(void *, uint32_t))rbc_world_stats_init,
         {sizeof(rbc_world_stats), RBC_WORLD_STATS_SIZE_V1_5, RBC_WORLD_STATS_SIZE_V1_4,
          RBC_WORLD_STATS_SIZE_V1_3, RBC_WORLD_STATS_SIZE_V1_2, RBC_WORLD_STATS_SIZE_V1_1,
          RBC_WORLD_STATS_SIZE_V1_0}},
    };
    static unsigned char buf[4096];
    for (size_t k = 0; k < sizeof inits / sizeof inits[0]; ++k) {
        CHECK_EQ(inits[k].init(buf, 3), RBC_ERR_INVALID_ARGUMENT);
        const char *msg = rbc_last_error();
        for (int j = 0; j < 8 && inits[k].sizes[j]; ++j) {
            char num[16], end[16]; /* a size is followed by "," or ")" in the list */
            snprintf(num, sizeof num, " %u,", inits[k].sizes[j]);
            snprintf(end, sizeof end, " %u)", inits[k].sizes[j]);
            int listed = strstr(msg, num) != NULL || strstr(msg, end) != NULL;
            CHECK(listed);
            if (!listed) fprintf(stderr, "  %s: \"%s\" lacks%s\n", inits[k].name, msg, num);
            /* and each listed size is accepted */
            CHECK_EQ(inits[k].init(buf, inits[k].sizes[j]), RBC_OK);
        }
    }
    /* rbc_struct_size_for: for every minor up to this header's, the size it gives is
     * one the library accepts (this library accepts every released size), the
     * header's own sizeof for this minor, and it grows with the minor; another major
     * and an unknown kind give 0. */
    for (rbc_struct_kind kind = RBC_STRUCT_WORLD_DEF; kind <= RBC_STRUCT_WORLD_STATS; ++kind) {
        uint32_t prev = 0;
        for (uint32_t minor = 0; minor <= RBC_ABI_VERSION_MINOR; ++minor) {
            uint32_t size = rbc_struct_size_for(kind, (1u << 16) | minor);
            CHECK(size >= prev);
            prev = size;
            if (!size) continue; /* the struct came later */
            /* inits[] holds the kinds in enum order, without the mesh info (no init) */
            if (kind == RBC_STRUCT_MESH_INFO) {
                CHECK(size == sizeof(rbc_mesh_info) || size == RBC_MESH_INFO_SIZE_V1_2);
                continue;
            }
            size_t i = (size_t)kind - 1 - (kind > RBC_STRUCT_MESH_INFO);
            rbc_result r = inits[i].init(buf, size);
            CHECK_EQ(r, RBC_OK);
            if (r) fprintf(stderr, "  %s refuses %u, the size for 1.%u\n", inits[i].name, size, minor);
        }
        CHECK_EQ(rbc_struct_size_for(kind, 2u << 16), 0);
    }
    CHECK_EQ(rbc_struct_size_for(RBC_STRUCT_WORLD_STATS, RBC_ABI_VERSION), sizeof(rbc_world_stats));
    CHECK_EQ(rbc_struct_size_for(RBC_STRUCT_CACHE_DEF, RBC_ABI_VERSION), sizeof(rbc_cache_def));
    CHECK_EQ(rbc_struct_size_for(RBC_STRUCT_CACHE_DEF, (1u << 16) | 8), RBC_CACHE_DEF_SIZE_V1_2);
    CHECK_EQ(rbc_struct_size_for(RBC_STRUCT_WORLD_STATS, (1u << 16) | 4), RBC_WORLD_STATS_SIZE_V1_4);
    CHECK_EQ(rbc_struct_size_for(RBC_STRUCT_SOLVER_DEF, 1u << 16), 0);
    CHECK_EQ(rbc_struct_size_for(99, RBC_ABI_VERSION), 0);
    return check_report("abi_old_sizes");
}
