/* api.c -- versions and the function table that dlopen hosts resolve with one
 * symbol (OpenFX's OfxGetPlugin idea). Entries are only ever appended. */
#include <stddef.h>

#include "rbcloth.h"

#ifndef RBC_VERSION_STRING
#define RBC_VERSION_STRING "0.0.0"
#endif

RBC_API uint32_t RBC_CALL rbc_abi_version(void) { return RBC_ABI_VERSION; }

RBC_API const char *RBC_CALL rbc_version_string(void) { return RBC_VERSION_STRING; }

static const rbc_api_v1 g_api_v1 = {
    sizeof(rbc_api_v1),
    RBC_ABI_VERSION,
    rbc_abi_version,
    rbc_version_string,
    rbc_result_string,
    rbc_last_error,
    rbc_world_def_init,
    rbc_cloth_def_init,
    rbc_collider_def_init,
    rbc_cache_def_init,
    rbc_world_create,
    rbc_world_destroy,
    rbc_world_step,
    rbc_world_set_iterations,
    rbc_world_set_gravity,
    rbc_world_get_stats,
    rbc_world_set_collision_callback,
    rbc_cloth_create,
    rbc_cloth_destroy,
    rbc_cloth_get_vertex_count,
    rbc_cloth_get_topology,
    rbc_cloth_read_positions,
    rbc_cloth_set_pin,
    rbc_collider_create,
    rbc_collider_set_transform,
    rbc_collider_destroy,
    rbc_write_obj,
    rbc_cache_create,
    rbc_cache_write_frame,
    rbc_cache_finish,
    rbc_cache_destroy,
    rbc_solver_def_init,
    rbc_world_set_solver,
    rbc_world_get_solver,
    rbc_cloth_get_colors,
    rbc_cloth_get_state,
    rbc_cloth_set_state,
    rbc_mesh_import_def_init,
    rbc_mesh_import,
    rbc_mesh_destroy,
    rbc_mesh_get_info,
    rbc_mesh_get_positions,
    rbc_mesh_get_quads,
    rbc_mesh_get_springs,
    rbc_mesh_get_pins,
    rbc_cloth_create_from_mesh,
    rbc_world_set_contact_callback,
    rbc_world_pick,
    rbc_cloth_attach,
    rbc_cloth_cut,
    rbc_cloth_get_quads,
    rbc_cloth_get_springs,
    rbc_world_set_wind,
    rbc_mesh_get_triangles,
    rbc_solver_def_preset,
    rbc_world_stats_init,
    rbc_mesh_get_file_map,
    rbc_mesh_to_file_positions,
    rbc_mesh_write_file_obj,
    rbc_vertex_output_init,
    rbc_world_read_vertices,
    rbc_cloth_get_triangles,
    rbc_cloth_transform,
    rbc_world_step_begin,
    rbc_world_step_wait,
};

RBC_API const void *RBC_CALL rbc_get_api(uint32_t abi_major) {
    return abi_major == RBC_ABI_VERSION_MAJOR ? &g_api_v1 : NULL;
}
