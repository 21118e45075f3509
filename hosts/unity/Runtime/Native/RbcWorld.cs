// RbcWorld.cs -- the safe managed layer over RbcNative, modelled on the Python
// binding (hosts/python/rbcloth): every failing call throws RbcException, objects
// own their ids, arrays are checked against the counts C will read before anything
// reaches C. Callbacks are static methods (IL2CPP can only hand those to C) whose
// delegates live in static fields; they find their world's handlers through a
// GCHandle passed as the library's `user` pointer.
using System;
using System.Runtime.InteropServices;

namespace RbCloth.Native
{
    /// <summary>The library's messages (on the thread running the step).</summary>
    public delegate void RbcLogHandler(int level, string message);

    /// <summary>The host's collision code, once per substep after the solver and the
    /// built-in colliders. It may move vertices through cloths[i].positions. Return
    /// false (or throw) to fail the step with RBC_ERR_CALLBACK; the world is then as
    /// it was before the step.</summary>
    public unsafe delegate bool RbcCollisionHandler(float dt, rbc_collision_cloth* cloths, uint count);

    /// <summary>What a world is made with: Def starts as rbc_world_def_init's
    /// defaults (change fields as needed); Solver, when HasSolver, is passed as the
    /// def's solver (else the library's default solve, RBC_PRESET_CLOTH).</summary>
    public sealed class RbcWorldSettings
    {
        public rbc_world_def Def;
        public rbc_solver_def Solver;
        public bool HasSolver;
        public RbcLogHandler Log;
        /// <summary>Optional job system (ABI 1.10); null = the world's own threads.</summary>
        public IRbcJobSystem Jobs;

        public unsafe RbcWorldSettings()
        {
            Def = RbcDefs.WorldDef();
            Solver = RbcDefs.SolverPreset(RbcNative.RBC_PRESET_CLOTH);
        }

        public unsafe void SetGravity(float x, float y, float z)
        {
            fixed (float* g = Def.gravity) { g[0] = x; g[1] = y; g[2] = z; }
        }
    }

    /// <summary>Defs filled by the library's *_def_init. A library older than this
    /// binding refuses the binding's sizeof as an unknown size: the older released
    /// sizes are tried, as the Python binding does, and the fields past the size
    /// taken keep their zeros (the library never reads them).</summary>
    public static unsafe class RbcDefs
    {
        public static readonly uint WorldDefSize = (uint)Marshal.SizeOf(typeof(rbc_world_def));
        /// <summary>RBC_WORLD_DEF_SIZE_V1_6: the 1.6-1.9 size, before enqueue_task.</summary>
        public static readonly uint WorldDefSizeV1_6 = (uint)Marshal.OffsetOf(typeof(rbc_world_def), "enqueue_task");
        public static readonly uint ClothDefSize = (uint)Marshal.SizeOf(typeof(rbc_cloth_def));
        public static readonly uint ColliderDefSize = (uint)Marshal.SizeOf(typeof(rbc_collider_def));
        public static readonly uint SolverDefSize = (uint)Marshal.SizeOf(typeof(rbc_solver_def));
        public static readonly uint StatsSize = (uint)Marshal.SizeOf(typeof(rbc_world_stats));
        public static readonly uint VertexOutputSize = (uint)Marshal.SizeOf(typeof(rbc_vertex_output));

        public static rbc_world_def WorldDef()
        {
            var d = new rbc_world_def();
            int r = RbcNative.rbc_world_def_init(&d, WorldDefSize);
            if (r == RbcNative.RBC_ERR_INVALID_ARGUMENT)
            {
                d = new rbc_world_def();
                if (RbcNative.rbc_world_def_init(&d, WorldDefSizeV1_6) == RbcNative.RBC_OK) return d;
            }
            RbcException.Check(r);
            return d;
        }

        public static rbc_cloth_def ClothDef()
        {
            var d = new rbc_cloth_def();
            RbcException.Check(RbcNative.rbc_cloth_def_init(&d, ClothDefSize));
            return d;
        }

        public static rbc_collider_def ColliderDef(int shape)
        {
            var d = new rbc_collider_def();
            RbcException.Check(RbcNative.rbc_collider_def_init(&d, ColliderDefSize));
            d.shape = shape;
            return d;
        }

        public static rbc_solver_def SolverPreset(int preset)
        {
            var d = new rbc_solver_def();
            RbcException.Check(RbcNative.rbc_solver_def_preset(&d, SolverDefSize, preset));
            return d;
        }
    }

    public sealed unsafe class RbcWorld : IDisposable
    {
        /// <summary>The handlers a world's callbacks reach through their GCHandle. Kept
        /// apart from the world so that the handle does not keep the world alive.</summary>
        sealed class Hooks
        {
            public RbcLogHandler Log;
            public RbcCollisionHandler Collision;
            public IRbcJobSystem Jobs;
            public Exception Pending; // a handler's exception, rethrown by the step
        }

        uint id;
        readonly Hooks hooks = new Hooks();
        GCHandle hooksHandle;

        public uint Id { get { return id; } }
        public bool IsDisposed { get { return id == 0; } }

        public RbcWorld() : this(new RbcWorldSettings()) { }

        public RbcWorld(RbcWorldSettings settings)
        {
            if (settings == null) throw new ArgumentNullException("settings");
            hooks.Log = settings.Log;
            hooks.Jobs = settings.Jobs;
            hooksHandle = GCHandle.Alloc(hooks);
            IntPtr user = GCHandle.ToIntPtr(hooksHandle);
            rbc_world_def d = settings.Def;
            rbc_solver_def solver = settings.Solver;
            d.solver = settings.HasSolver ? (IntPtr)(&solver) : IntPtr.Zero;
            if (settings.Log != null)
            {
                d.log = s_logPtr;
                d.log_user = user;
            }
            if (settings.Jobs != null)
            {
                if (d.struct_size < RbcDefs.WorldDefSize)
                {
                    hooksHandle.Free();
                    throw new RbcException(RbcNative.RBC_ERR_UNSUPPORTED,
                        "the loaded library (ABI " + AbiString() + ") has no enqueue_task/finish_task");
                }
                d.enqueue_task = s_enqueuePtr;
                d.finish_task = s_finishPtr;
                d.task_user = user;
            }
            uint w;
            int r = RbcNative.rbc_world_create(&d, out w);
            if (r != RbcNative.RBC_OK)
            {
                string msg = RbcNative.LastError();
                hooksHandle.Free();
                throw new RbcException(r, msg);
            }
            id = w;
        }

        ~RbcWorld() { Release(); }

        public void Dispose()
        {
            Release();
            GC.SuppressFinalize(this);
        }

        void Release()
        {
            if (id != 0)
            {
                uint w = id;
                id = 0;
                RbcNative.rbc_world_destroy(w); // waits for a step in flight
            }
            if (hooksHandle.IsAllocated) hooksHandle.Free();
        }

        public static string AbiString()
        {
            uint v = RbcNative.rbc_abi_version();
            return (v >> 16) + "." + (v & 0xFFFF);
        }

        public static string Version { get { return RbcNative.Str(RbcNative.rbc_version_string()); } }

        internal uint LiveId
        {
            get
            {
                if (id == 0) throw new ObjectDisposedException("RbcWorld");
                return id;
            }
        }

        // A step's failure carries the handler's exception, if one caused it.
        void CheckStep(int r)
        {
            if (r == RbcNative.RBC_OK) { hooks.Pending = null; return; }
            string msg = RbcNative.LastError();
            Exception inner = hooks.Pending;
            hooks.Pending = null;
            throw new RbcException(r, msg, inner);
        }

        // --- stepping ---
        public void Step(float dt) { CheckStep(RbcNative.rbc_world_step(LiveId, dt)); }

        /// <summary>Start a step on the world's step thread (1.10); until StepWait every
        /// other call on the world throws RBC_ERR_BUSY.</summary>
        public void StepBegin(float dt) { RbcException.Check(RbcNative.rbc_world_step_begin(LiveId, dt)); }

        /// <summary>Wait for the step StepBegin started; throws its failure.</summary>
        public void StepWait() { CheckStep(RbcNative.rbc_world_step_wait(LiveId)); }

        public void SetIterations(uint substeps, uint nonlinear, uint linear)
        {
            RbcException.Check(RbcNative.rbc_world_set_iterations(LiveId, substeps, nonlinear, linear));
        }

        public void SetGravity(float x, float y, float z)
        {
            float* g = stackalloc float[3];
            g[0] = x; g[1] = y; g[2] = z;
            RbcException.Check(RbcNative.rbc_world_set_gravity(LiveId, g));
        }

        public void SetWind(float vx, float vy, float vz, float drag, float lift)
        {
            float* v = stackalloc float[3];
            v[0] = vx; v[1] = vy; v[2] = vz;
            RbcException.Check(RbcNative.rbc_world_set_wind(LiveId, v, drag, lift));
        }

        public void SetSolver(rbc_solver_def def)
        {
            RbcException.Check(RbcNative.rbc_world_set_solver(LiveId, &def));
        }

        public rbc_solver_def GetSolver()
        {
            var d = new rbc_solver_def { struct_size = RbcDefs.SolverDefSize };
            RbcException.Check(RbcNative.rbc_world_get_solver(LiveId, &d));
            return d;
        }

        public rbc_world_stats GetStats(bool skipMeasures = false)
        {
            var s = new rbc_world_stats();
            RbcException.Check(RbcNative.rbc_world_stats_init(&s, RbcDefs.StatsSize));
            s.skip_measures = skipMeasures ? 1u : 0u;
            RbcException.Check(RbcNative.rbc_world_get_stats(LiveId, &s));
            return s;
        }

        /// <summary>Install (or with null remove) the collision handler.</summary>
        public void SetCollisionHandler(RbcCollisionHandler handler)
        {
            uint w = LiveId;
            int r = handler == null
                ? RbcNative.rbc_world_set_collision_callback(w, IntPtr.Zero, IntPtr.Zero)
                : RbcNative.rbc_world_set_collision_callback(w, s_collisionPtr, GCHandle.ToIntPtr(hooksHandle));
            RbcException.Check(r);
            hooks.Collision = handler;
        }

        /// <summary>The vertex nearest the ray within radius, or false.</summary>
        public bool Pick(float[] origin, float[] dir, float maxDistance, float radius,
                         out uint cloth, out uint vertex, out float t)
        {
            RbcArrays.Need(origin, 3, "origin");
            RbcArrays.Need(dir, 3, "dir");
            fixed (float* o = origin)
            fixed (float* d = dir)
                RbcException.Check(RbcNative.rbc_world_pick(LiveId, o, d, maxDistance, radius,
                                                            out cloth, out vertex, out t));
            return cloth != 0;
        }

        // --- cloths and colliders ---
        /// <summary>A cloth from positions (3 floats per vertex), quads (4 indices
        /// each), optional pins (vertex indices) and springs (2 indices each); the
        /// other fields from `settings` (RbcDefs.ClothDef() when omitted).</summary>
        public RbcCloth CreateCloth(float[] positions, uint[] quads, uint[] pins = null,
                                    uint[] springs = null, rbc_cloth_def? settings = null)
        {
            if (positions == null || positions.Length == 0 || positions.Length % 3 != 0)
                throw new ArgumentException("positions: 3 floats per vertex, at least one vertex");
            if (quads == null) quads = new uint[0];
            if (quads.Length % 4 != 0) throw new ArgumentException("quads: 4 indices per quad");
            if (springs != null && springs.Length % 2 != 0)
                throw new ArgumentException("springs: 2 indices per spring");
            rbc_cloth_def d = settings.HasValue ? settings.Value : RbcDefs.ClothDef();
            fixed (float* p = positions)
            fixed (uint* q = quads)
            fixed (uint* pn = pins)
            fixed (uint* s = springs)
            {
                d.vertex_count = (uint)(positions.Length / 3);
                d.positions = (IntPtr)p;
                d.quad_count = (uint)(quads.Length / 4);
                d.quads = (IntPtr)q;
                d.pin_count = pins == null ? 0u : (uint)pins.Length;
                d.pins = (IntPtr)pn;
                d.spring_count = springs == null ? 0u : (uint)(springs.Length / 2);
                d.springs = (IntPtr)s;
                if (d.masses != IntPtr.Zero)
                    throw new ArgumentException("settings.masses: pass masses through CreateCloth(ref def)");
                return CreateCloth(ref d);
            }
        }

        /// <summary>A cloth from a def whose pointers the caller has set (and keeps
        /// valid for this call: the library copies every array).</summary>
        public RbcCloth CreateCloth(ref rbc_cloth_def def)
        {
            uint c;
            fixed (rbc_cloth_def* d = &def)
                RbcException.Check(RbcNative.rbc_cloth_create(LiveId, d, out c));
            return new RbcCloth(this, c);
        }

        public RbcCollider CreateCollider(rbc_collider_def def)
        {
            uint c;
            RbcException.Check(RbcNative.rbc_collider_create(LiveId, &def, out c));
            return new RbcCollider(this, c);
        }

        public RbcCollider CreateSphere(float radius, float x, float y, float z)
        {
            var d = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_SPHERE);
            d.radius = radius;
            d.position[0] = x; d.position[1] = y; d.position[2] = z;
            return CreateCollider(d);
        }

        /// <summary>A capsule along its frame's y axis: radius, half length of the axis.</summary>
        public RbcCollider CreateCapsule(float radius, float halfLength)
        {
            var d = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_CAPSULE);
            d.radius = radius;
            d.half_extents[1] = halfLength;
            return CreateCollider(d);
        }

        public RbcCollider CreateBox(float hx, float hy, float hz)
        {
            var d = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_BOX);
            d.half_extents[0] = hx; d.half_extents[1] = hy; d.half_extents[2] = hz;
            return CreateCollider(d);
        }

        /// <summary>The plane y = 0 of its frame (cloth kept on +y).</summary>
        public RbcCollider CreatePlane() { return CreateCollider(RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_PLANE)); }

        /// <summary>Vertices of several cloths into host buffers (1.10): every entry is
        /// checked before any buffer is written.</summary>
        public void ReadVertices(rbc_vertex_output* outputs, uint count)
        {
            RbcException.Check(RbcNative.rbc_world_read_vertices(LiveId, outputs, count));
        }

        public void ReadVertices(rbc_vertex_output[] outputs)
        {
            fixed (rbc_vertex_output* o = outputs)
                ReadVertices(o, outputs == null ? 0u : (uint)outputs.Length);
        }

        // --- callbacks: static, [MonoPInvokeCallback] for IL2CPP, delegates kept alive
        // in static fields for as long as the process (C holds their pointers) ---
        static readonly rbc_log_fn s_log = LogThunk;
        static readonly IntPtr s_logPtr = Marshal.GetFunctionPointerForDelegate(s_log);
        static readonly rbc_collision_fn s_collision = CollisionThunk;
        static readonly IntPtr s_collisionPtr = Marshal.GetFunctionPointerForDelegate(s_collision);
        static readonly rbc_enqueue_task_fn s_enqueue = EnqueueThunk;
        static readonly IntPtr s_enqueuePtr = Marshal.GetFunctionPointerForDelegate(s_enqueue);
        static readonly rbc_finish_task_fn s_finish = FinishThunk;
        static readonly IntPtr s_finishPtr = Marshal.GetFunctionPointerForDelegate(s_finish);

        static Hooks HooksOf(IntPtr user) { return (Hooks)GCHandle.FromIntPtr(user).Target; }

        [AOT.MonoPInvokeCallback(typeof(rbc_log_fn))]
        static void LogThunk(IntPtr user, int level, IntPtr message)
        {
            try
            {
                var h = HooksOf(user);
                if (h.Log != null) h.Log(level, RbcNative.Str(message));
            }
            catch (Exception) { } // an exception must not unwind into C; a log has no failure path
        }

        [AOT.MonoPInvokeCallback(typeof(rbc_collision_fn))]
        static int CollisionThunk(IntPtr user, uint world, float dt, rbc_collision_cloth* cloths, uint count)
        {
            Hooks h = null;
            try
            {
                h = HooksOf(user);
                return h.Collision != null && h.Collision(dt, cloths, count) ? 0 : 1;
            }
            catch (Exception e)
            {
                if (h != null) h.Pending = e;
                return 1; // RBC_ERR_CALLBACK, world restored; the step rethrows e as inner
            }
        }

        [AOT.MonoPInvokeCallback(typeof(rbc_enqueue_task_fn))]
        static IntPtr EnqueueThunk(IntPtr task, uint itemCount, uint minRange, IntPtr context, IntPtr user)
        {
            // There is no failure path back into the library, and after a throw it is
            // unknown which ranges were handed out (running them again, or returning
            // while they run, would corrupt the step): a job system that throws ends
            // the process with its exception.
            try
            {
                object handle = HooksOf(user).Jobs.Enqueue(new RbcTask(RbcTask.DelegateFor(task), context),
                                                           itemCount, minRange);
                return handle == null ? IntPtr.Zero : GCHandle.ToIntPtr(GCHandle.Alloc(handle));
            }
            catch (Exception e)
            {
                Environment.FailFast("rbcloth: IRbcJobSystem.Enqueue threw", e);
                return IntPtr.Zero;
            }
        }

        [AOT.MonoPInvokeCallback(typeof(rbc_finish_task_fn))]
        static void FinishThunk(IntPtr handle, IntPtr user)
        {
            if (handle == IntPtr.Zero) return;
            GCHandle g = GCHandle.FromIntPtr(handle);
            try { HooksOf(user).Jobs.Finish(g.Target); }
            catch (Exception e) { Environment.FailFast("rbcloth: IRbcJobSystem.Finish threw", e); }
            g.Free();
        }
    }

    static class RbcArrays
    {
        public static void Need(Array a, int n, string what)
        {
            if (a == null || a.Length < n)
                throw new ArgumentException(what + ": " + n + " values expected");
        }
    }
}
