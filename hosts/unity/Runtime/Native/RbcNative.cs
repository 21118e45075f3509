// RbcNative.cs -- P/Invoke declarations of librbcloth's C ABI (abi/rbcloth.h, 1.10).
// The library is "rbcloth": librbcloth.so on Linux/Android, rbcloth.dll on Windows,
// librbcloth.dylib on macOS (Unity resolves it from the package's Plugins folder;
// Mono from LD_LIBRARY_PATH). Pointer arguments are unsafe pointers so a host can
// pass a NativeArray's GetUnsafePtr() or a pinned array without a copy; the
// managed layer (RbcWorld, RbcCloth, RbcCollider) adds array overloads.
// Borrowed strings (rbc_last_error, rbc_result_string, rbc_version_string) are
// IntPtr: a `string` return would make the marshaller free library memory (the
// header's note; tests/mono/Strings.cs).
using System;
using System.Runtime.InteropServices;

#if !UNITY_5_3_OR_NEWER
namespace AOT
{
    /// <summary>What Unity's IL2CPP looks for on a static method handed to native
    /// code as a function pointer (Unity defines it in UnityEngine; this copy lets
    /// the binding compile and run outside Unity, where Mono ignores it).</summary>
    [AttributeUsage(AttributeTargets.Method)]
    public sealed class MonoPInvokeCallbackAttribute : Attribute
    {
        public MonoPInvokeCallbackAttribute(Type type) { Type = type; }
        public Type Type { get; private set; }
    }
}
#endif

namespace RbCloth.Native
{
    // Callback signatures (RBC_CALL is cdecl everywhere, __cdecl on Windows).
    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate void rbc_log_fn(IntPtr user, int level, IntPtr message);

    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public unsafe delegate int rbc_collision_fn(IntPtr user, uint world, float dt,
                                                rbc_collision_cloth* cloths, uint cloth_count);

    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate void rbc_task_fn(uint begin, uint end, uint worker, IntPtr task_context);

    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate IntPtr rbc_enqueue_task_fn(IntPtr task, uint item_count, uint min_range,
                                               IntPtr task_context, IntPtr user);

    [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
    public delegate void rbc_finish_task_fn(IntPtr handle, IntPtr user);

    public static unsafe class RbcNative
    {
        const string Lib = "rbcloth";

        // --- constants (the header's enums) ---
        public const uint ABI_VERSION_MAJOR = 1;
        public const uint ABI_VERSION_MINOR = 10;

        public const int RBC_OK = 0;
        public const int RBC_ERR_INVALID_ARGUMENT = -1;
        public const int RBC_ERR_OUT_OF_MEMORY = -2;
        public const int RBC_ERR_UNSUPPORTED = -3;
        public const int RBC_ERR_BACKEND_UNAVAILABLE = -4;
        public const int RBC_ERR_BAD_MESH = -5;
        public const int RBC_ERR_IO = -6;
        public const int RBC_ERR_UNSTABLE = -7;
        public const int RBC_ERR_STALE_HANDLE = -8;
        public const int RBC_ERR_CALLBACK = -9;
        public const int RBC_ERR_CAPACITY = -10;
        public const int RBC_ERR_BUSY = -11;

        public const int RBC_BACKEND_AUTO = 0, RBC_BACKEND_CPU = 1, RBC_BACKEND_CUDA = 2;
        public const int RBC_LOG_ERROR = 0, RBC_LOG_WARNING = 1, RBC_LOG_INFO = 2, RBC_LOG_DEBUG = 3;
        public const int RBC_SHAPE_PLANE = 1, RBC_SHAPE_SPHERE = 2, RBC_SHAPE_CAPSULE = 3,
                         RBC_SHAPE_BOX = 4, RBC_SHAPE_TRIANGLE_MESH = 5;
        public const int RBC_SOLVER_RBGS = 0, RBC_SOLVER_JACOBI = 1, RBC_SOLVER_JACOBI_CHEBYSHEV = 2,
                         RBC_SOLVER_GAUSS_SEIDEL = 3, RBC_SOLVER_RBGS_SOR = 4,
                         RBC_SOLVER_RBGS_CHEBYSHEV = 5, RBC_SOLVER_MULTICOLOR_GS = 6,
                         RBC_SOLVER_DIRECT = 7;
        public const int RBC_ITERATE_FIXED = 0, RBC_ITERATE_TOLERANCE = 1, RBC_ITERATE_BUDGET = 2,
                         RBC_ITERATE_TARGET = 3;
        public const int RBC_ENERGY_GUARD_OFF = 0, RBC_ENERGY_GUARD_CLAMP = 1,
                         RBC_ENERGY_GUARD_FAIL = 2;
        public const int RBC_PRESET_PAPER = 0, RBC_PRESET_GAME_60HZ = 1, RBC_PRESET_CLOTH = 2;
        public const uint RBC_CLOTH_COLLIDE_SELF = 1, RBC_CLOTH_COLLIDE_CLOTHS = 2;
        public const uint RBC_NO_ATTRIBUTE = 0xFFFFFFFFu;
        public const uint RBC_TRANSFORM_KEEP_VELOCITY = 0, RBC_TRANSFORM_RESET_VELOCITY = 1;

        // --- versions and messages ---
        [DllImport(Lib)] public static extern uint rbc_abi_version();
        [DllImport(Lib)] public static extern IntPtr rbc_version_string();
        [DllImport(Lib)] public static extern IntPtr rbc_result_string(int result);
        [DllImport(Lib)] public static extern IntPtr rbc_last_error();

        // --- defs ---
        [DllImport(Lib)] public static extern int rbc_world_def_init(rbc_world_def* def, uint struct_size);
        [DllImport(Lib)] public static extern int rbc_cloth_def_init(rbc_cloth_def* def, uint struct_size);
        [DllImport(Lib)] public static extern int rbc_collider_def_init(rbc_collider_def* def, uint struct_size);
        [DllImport(Lib)] public static extern int rbc_solver_def_init(rbc_solver_def* def, uint struct_size);
        [DllImport(Lib)] public static extern int rbc_solver_def_preset(rbc_solver_def* def, uint struct_size, int preset);
        [DllImport(Lib)] public static extern int rbc_world_stats_init(rbc_world_stats* stats, uint struct_size);

        // --- worlds ---
        [DllImport(Lib)] public static extern int rbc_world_create(rbc_world_def* def, out uint out_world);
        [DllImport(Lib)] public static extern int rbc_world_destroy(uint world);
        [DllImport(Lib)] public static extern int rbc_world_step(uint world, float dt);
        [DllImport(Lib)] public static extern int rbc_world_set_iterations(uint world, uint substeps,
            uint nonlinear_iterations, uint linear_iterations);
        [DllImport(Lib)] public static extern int rbc_world_set_gravity(uint world, float* gravity);
        [DllImport(Lib)] public static extern int rbc_world_get_stats(uint world, rbc_world_stats* stats);
        [DllImport(Lib)] public static extern int rbc_world_set_collision_callback(uint world, IntPtr fn, IntPtr user);
        [DllImport(Lib)] public static extern int rbc_world_set_solver(uint world, rbc_solver_def* def);
        [DllImport(Lib)] public static extern int rbc_world_get_solver(uint world, rbc_solver_def* def);
        [DllImport(Lib)] public static extern int rbc_world_set_wind(uint world, float* velocity, float drag, float lift);
        [DllImport(Lib)] public static extern int rbc_world_pick(uint world, float* origin, float* dir,
            float max_distance, float radius, out uint out_cloth, out uint out_vertex, out float out_t);

        // --- cloths ---
        [DllImport(Lib)] public static extern int rbc_cloth_create(uint world, rbc_cloth_def* def, out uint out_cloth);
        [DllImport(Lib)] public static extern int rbc_cloth_destroy(uint world, uint cloth);
        [DllImport(Lib)] public static extern int rbc_cloth_get_vertex_count(uint world, uint cloth, out uint out_count);
        [DllImport(Lib)] public static extern int rbc_cloth_get_topology(uint world, uint cloth,
            out uint out_spring_count, out uint out_color_count);
        [DllImport(Lib)] public static extern int rbc_cloth_read_positions(uint world, uint cloth, float* xyz,
            UIntPtr capacity, out UIntPtr out_written);
        [DllImport(Lib)] public static extern int rbc_cloth_set_pin(uint world, uint cloth, uint vertex, float* target);
        [DllImport(Lib)] public static extern int rbc_cloth_get_state(uint world, uint cloth, float* positions,
            float* previous, UIntPtr capacity);
        [DllImport(Lib)] public static extern int rbc_cloth_set_state(uint world, uint cloth, float* positions,
            float* previous);
        [DllImport(Lib)] public static extern int rbc_cloth_attach(uint world, uint cloth, uint vertex,
            uint collider, float* local);
        [DllImport(Lib)] public static extern int rbc_cloth_cut(uint world, uint cloth, uint* pairs,
            uint pair_count, out uint out_cut);
        [DllImport(Lib)] public static extern int rbc_cloth_get_quads(uint world, uint cloth, uint* quads,
            UIntPtr capacity, out UIntPtr out_count);
        [DllImport(Lib)] public static extern int rbc_cloth_get_springs(uint world, uint cloth, uint* pairs,
            UIntPtr capacity, out UIntPtr out_count);

        // --- colliders ---
        [DllImport(Lib)] public static extern int rbc_collider_create(uint world, rbc_collider_def* def, out uint out_collider);
        [DllImport(Lib)] public static extern int rbc_collider_set_transform(uint world, uint collider,
            float* position, float* rotation);
        [DllImport(Lib)] public static extern int rbc_collider_destroy(uint world, uint collider);

        // --- 1.10: a game loop ---
        [DllImport(Lib)] public static extern int rbc_vertex_output_init(rbc_vertex_output* output, uint struct_size);
        [DllImport(Lib)] public static extern int rbc_world_read_vertices(uint world, rbc_vertex_output* outputs, uint count);
        [DllImport(Lib)] public static extern int rbc_cloth_get_triangles(uint world, uint cloth, uint* triangles,
            UIntPtr capacity, out UIntPtr out_count, out uint out_revision);
        [DllImport(Lib)] public static extern int rbc_cloth_transform(uint world, uint cloth, float* translation,
            float* rotation, uint flags);
        [DllImport(Lib)] public static extern int rbc_world_step_begin(uint world, float dt);
        [DllImport(Lib)] public static extern int rbc_world_step_wait(uint world);

        /// <summary>A borrowed C string (UTF-8 from the library; ASCII in practice) as
        /// a managed copy; "" for NULL.</summary>
        public static string Str(IntPtr p)
        {
            return p == IntPtr.Zero ? "" : (Marshal.PtrToStringAnsi(p) ?? "");
        }

        public static string ResultName(int result) { return Str(rbc_result_string(result)); }
        public static string LastError() { return Str(rbc_last_error()); }
    }
}
