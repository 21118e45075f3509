// RbcStructs.cs -- the structs of abi/rbcloth.h (ABI 1.10) as blittable C# structs.
// Field names, order and types follow the header one for one so that
// Marshal.OffsetOf can be checked against the C compiler's offsetof (the
// mono_binding test does, with Tests/Mono/layout.c). uint32_t is uint, int32_t enums
// are int, size_t is UIntPtr, pointers (data and functions) are IntPtr, float[n]
// are fixed buffers. No UnityEngine dependency: compiled with mcs and tested under
// Mono. Layouts are those of 64-bit targets (the only ones tested).
using System;
using System.Runtime.InteropServices;

namespace RbCloth.Native
{
    [StructLayout(LayoutKind.Sequential)]
    public unsafe struct rbc_world_def
    {
        public uint struct_size;
        public fixed float gravity[3];
        public uint substeps;
        public uint nonlinear_iterations;
        public uint linear_iterations;
        public int backend;
        public uint thread_count;
        public int log_level;
        public IntPtr alloc;        // rbc_alloc_fn
        public IntPtr free;         // rbc_free_fn
        public IntPtr alloc_user;
        public IntPtr log;          // rbc_log_fn
        public IntPtr log_user;
        public IntPtr solver;       // const rbc_solver_def* (1.1)
        public float substep_rate;  // 1.6
        public float strain_warning;
        public IntPtr enqueue_task; // rbc_enqueue_task_fn (1.10)
        public IntPtr finish_task;  // rbc_finish_task_fn (1.10)
        public IntPtr task_user;
    }

    [StructLayout(LayoutKind.Sequential)]
    public struct rbc_cloth_def
    {
        public uint struct_size;
        public uint vertex_count;
        public IntPtr positions;    // const float*
        public uint quad_count;
        public IntPtr quads;        // const uint32_t*
        public uint spring_count;
        public IntPtr springs;      // const uint32_t*
        public IntPtr masses;       // const float*
        public float density;
        public float vertex_mass;
        public float stiffness;
        public float damping;
        public uint pin_count;
        public IntPtr pins;         // const uint32_t*
        public float shear_stiffness; // 1.1
        public float bend_stiffness;
        public float thickness;     // 1.3
        public float friction;
        public uint collision_flags;
        public float tear_strain;
    }

    [StructLayout(LayoutKind.Sequential)]
    public unsafe struct rbc_collider_def
    {
        public uint struct_size;
        public int shape;
        public float radius;
        public float thickness;
        public fixed float position[3];
        public fixed float rotation[4];   // x y z w
        public float friction;            // 1.3
        public fixed float half_extents[3];
        public IntPtr mesh_positions;     // const float*
        public uint mesh_vertex_count;
        public IntPtr mesh_triangles;     // const uint32_t*
        public uint mesh_triangle_count;
    }

    [StructLayout(LayoutKind.Sequential)]
    public struct rbc_solver_def
    {
        public uint struct_size;
        public int solver;
        public float omega;
        public float rho;
        public uint chebyshev_delay;
        public int mode;
        public float tolerance;
        public float budget_ms;
        public uint max_linear_iterations;
        public int energy_guard;     // 1.2
        public float target_strain;  // 1.4
        public uint max_substeps;
    }

    [StructLayout(LayoutKind.Sequential)]
    public struct rbc_world_stats
    {
        public uint struct_size;
        public uint cloth_count;
        public uint collider_count;
        public uint particle_count;
        public uint spring_count;
        public uint color_count;
        public uint thread_count;
        public int backend;
        public ulong step_count;
        public uint substeps;
        public uint nonlinear_iterations;
        public uint linear_iterations;
        public uint reserved0;
        public double step_ms;
        public double integrate_ms;
        public double local_ms;
        public double global_ms;
        public double collide_ms;
        public double callback_ms;
        public double other_ms;
        public double error_eq7;
        public double max_strain;
        public int solver;           // 1.1
        public int iteration_mode;
        public double linear_residual;
        public double pd_objective;
        public double spectral_radius;
        public double omega;
        public double kinetic_energy; // 1.2
        public double potential_energy;
        public double energy_budget;
        public double energy_removed;
        public ulong energy_clamped_steps;
        public ulong memory_bytes;
        public uint skip_measures;
        public uint reserved1;
        public uint collider_contacts; // 1.3
        public uint cloth_contacts;
        public ulong torn_springs;
        public double strain_rms;      // 1.4
        public double target_reached;
        public uint target_met;
        public uint next_substeps;
        public ulong target_missed_steps;
        public ulong target_capped_steps;
        public uint cloth_contact_frozen; // 1.5
        public uint cloth_contact_capped;
        public double step_max_strain;    // 1.6
        public ulong strain_warning_steps;
    }

    /// <summary>One cloth's destination in rbc_world_read_vertices (1.10).</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct rbc_vertex_output
    {
        public uint struct_size;
        public uint cloth;
        public IntPtr buffer;        // void*
        public UIntPtr buffer_size;  // size_t
        public uint stride;
        public uint position_offset;
        public uint normal_offset;
        public uint triangle_revision; // out
    }

    /// <summary>One cloth as the collision callback sees it.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public unsafe struct rbc_collision_cloth
    {
        public uint cloth;
        public uint vertex_count;
        public float* positions;           // writable: the callback may move vertices
        public float* previous_positions;  // read only
    }
}
