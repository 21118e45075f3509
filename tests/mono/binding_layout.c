/* binding_layout.c -- prints sizeof and every field's offset of the structs the C# binding
 * (hosts/unity/Runtime/Native/RbcStructs.cs) declares, as the C compiler lays them
 * out from abi/rbcloth.h. BindingTest.cs compares them with Marshal.SizeOf and
 * Marshal.OffsetOf, so a field the binding misses, misorders or mistypes fails the
 * mono_binding test instead of corrupting memory. One "struct field offset" line
 * per field, one "struct - size" line per struct. */
#include <stddef.h>
#include <stdio.h>

#include "rbcloth.h"

#define S(T) printf(#T " - %zu\n", sizeof(T))
#define F(T, f) printf(#T " " #f " %zu\n", offsetof(T, f))

int main(void) {
    S(rbc_world_def);
    F(rbc_world_def, struct_size); F(rbc_world_def, gravity); F(rbc_world_def, substeps);
    F(rbc_world_def, nonlinear_iterations); F(rbc_world_def, linear_iterations);
    F(rbc_world_def, backend); F(rbc_world_def, thread_count); F(rbc_world_def, log_level);
    F(rbc_world_def, alloc); F(rbc_world_def, free); F(rbc_world_def, alloc_user);
    F(rbc_world_def, log); F(rbc_world_def, log_user); F(rbc_world_def, solver);
    F(rbc_world_def, substep_rate); F(rbc_world_def, strain_warning);
    F(rbc_world_def, enqueue_task); F(rbc_world_def, finish_task); F(rbc_world_def, task_user);

    S(rbc_cloth_def);
    F(rbc_cloth_def, struct_size); F(rbc_cloth_def, vertex_count); F(rbc_cloth_def, positions);
    F(rbc_cloth_def, quad_count); F(rbc_cloth_def, quads); F(rbc_cloth_def, spring_count);
    F(rbc_cloth_def, springs); F(rbc_cloth_def, masses); F(rbc_cloth_def, density);
    F(rbc_cloth_def, vertex_mass); F(rbc_cloth_def, stiffness); F(rbc_cloth_def, damping);
    F(rbc_cloth_def, pin_count); F(rbc_cloth_def, pins); F(rbc_cloth_def, shear_stiffness);
    F(rbc_cloth_def, bend_stiffness); F(rbc_cloth_def, thickness); F(rbc_cloth_def, friction);
    F(rbc_cloth_def, collision_flags); F(rbc_cloth_def, tear_strain);

    S(rbc_collider_def);
    F(rbc_collider_def, struct_size); F(rbc_collider_def, shape); F(rbc_collider_def, radius);
    F(rbc_collider_def, thickness); F(rbc_collider_def, position); F(rbc_collider_def, rotation);
    F(rbc_collider_def, friction); F(rbc_collider_def, half_extents);
    F(rbc_collider_def, mesh_positions); F(rbc_collider_def, mesh_vertex_count);
    F(rbc_collider_def, mesh_triangles); F(rbc_collider_def, mesh_triangle_count);

    S(rbc_solver_def);
    F(rbc_solver_def, struct_size); F(rbc_solver_def, solver); F(rbc_solver_def, omega);
    F(rbc_solver_def, rho); F(rbc_solver_def, chebyshev_delay); F(rbc_solver_def, mode);
    F(rbc_solver_def, tolerance); F(rbc_solver_def, budget_ms);
    F(rbc_solver_def, max_linear_iterations); F(rbc_solver_def, energy_guard);
    F(rbc_solver_def, target_strain); F(rbc_solver_def, max_substeps);

    S(rbc_world_stats);
    F(rbc_world_stats, struct_size); F(rbc_world_stats, cloth_count);
    F(rbc_world_stats, collider_count); F(rbc_world_stats, particle_count);
    F(rbc_world_stats, spring_count); F(rbc_world_stats, color_count);
    F(rbc_world_stats, thread_count); F(rbc_world_stats, backend); F(rbc_world_stats, step_count);
    F(rbc_world_stats, substeps); F(rbc_world_stats, nonlinear_iterations);
    F(rbc_world_stats, linear_iterations); F(rbc_world_stats, reserved0);
    F(rbc_world_stats, step_ms); F(rbc_world_stats, integrate_ms); F(rbc_world_stats, local_ms);
    F(rbc_world_stats, global_ms); F(rbc_world_stats, collide_ms);
    F(rbc_world_stats, callback_ms); F(rbc_world_stats, other_ms); F(rbc_world_stats, error_eq7);
    F(rbc_world_stats, max_strain); F(rbc_world_stats, solver); F(rbc_world_stats, iteration_mode);
    F(rbc_world_stats, linear_residual); F(rbc_world_stats, pd_objective);
    F(rbc_world_stats, spectral_radius); F(rbc_world_stats, omega);
    F(rbc_world_stats, kinetic_energy); F(rbc_world_stats, potential_energy);
    F(rbc_world_stats, energy_budget); F(rbc_world_stats, energy_removed);
    F(rbc_world_stats, energy_clamped_steps); F(rbc_world_stats, memory_bytes);
    F(rbc_world_stats, skip_measures); F(rbc_world_stats, reserved1);
    F(rbc_world_stats, collider_contacts); F(rbc_world_stats, cloth_contacts);
    F(rbc_world_stats, torn_springs); F(rbc_world_stats, strain_rms);
    F(rbc_world_stats, target_reached); F(rbc_world_stats, target_met);
    F(rbc_world_stats, next_substeps); F(rbc_world_stats, target_missed_steps);
    F(rbc_world_stats, target_capped_steps); F(rbc_world_stats, cloth_contact_frozen);
    F(rbc_world_stats, cloth_contact_capped); F(rbc_world_stats, step_max_strain);
    F(rbc_world_stats, strain_warning_steps);

    S(rbc_vertex_output);
    F(rbc_vertex_output, struct_size); F(rbc_vertex_output, cloth); F(rbc_vertex_output, buffer);
    F(rbc_vertex_output, buffer_size); F(rbc_vertex_output, stride);
    F(rbc_vertex_output, position_offset); F(rbc_vertex_output, normal_offset);
    F(rbc_vertex_output, triangle_revision);

    S(rbc_collision_cloth);
    F(rbc_collision_cloth, cloth); F(rbc_collision_cloth, vertex_count);
    F(rbc_collision_cloth, positions); F(rbc_collision_cloth, previous_positions);
    return 0;
}
