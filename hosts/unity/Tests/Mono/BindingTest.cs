// BindingTest.cs -- the mono_binding test (tests/mono/CMakeLists.txt): the C# binding
// of hosts/unity/Runtime/Native under Mono, against the built librbcloth.
//   BindingTest.exe LAYOUT_FILE
// LAYOUT_FILE is what tests/mono/binding_layout.c prints (the C compiler's sizeof and
// offsetof); without it (Unity's test runner, BindingTests.cs) the layout check is
// left out.
// Checks: the struct layouts; a hanging cloth stepped from C# (1 and 2 threads
// bitwise equal, pins held, the cloth falls, finite, strain bounded); refused input
// (codes, names, messages) leaves a world that still steps; stale handles; the log
// and collision callbacks; and the ABI 1.10 calls (read_vertices, triangles,
// transform, split step, C# job systems). Exit 0 when everything holds, 1 when a
// check fails (each failure on stderr); a library without the 1.10 entry points is
// a failure (the binding is built for ABI 1.10).
using System;
using System.Collections.Generic;
using System.IO;
using System.Runtime.InteropServices;
using RbCloth.Native;

public static unsafe class BindingTest
{
    static int failures;
    static readonly string[] Names = {
        "", "RBC_ERR_INVALID_ARGUMENT", "RBC_ERR_OUT_OF_MEMORY", "RBC_ERR_UNSUPPORTED",
        "RBC_ERR_BACKEND_UNAVAILABLE", "RBC_ERR_BAD_MESH", "RBC_ERR_IO", "RBC_ERR_UNSTABLE",
        "RBC_ERR_STALE_HANDLE", "RBC_ERR_CALLBACK", "RBC_ERR_CAPACITY", "RBC_ERR_BUSY" };

    static void Check(bool ok, string what)
    {
        if (ok) return;
        failures++;
        Console.Error.WriteLine("mono_binding: FAILED: " + what);
    }

    // The scene: N x N vertices `Spacing` apart in the plane y = 0, vertex (i, j) at
    // (i h, 0, j h) with index j N + i; the two corners of row j = 0 pinned.
    const int N = 20;
    const float Spacing = 0.05f;
    const float Dt = 1f / 60f;
    const int Steps = 120;
    static readonly uint[] Pins = { 0, N - 1 };

    static float[] GridPositions()
    {
        var p = new float[3 * N * N];
        for (int j = 0; j < N; ++j)
            for (int i = 0; i < N; ++i)
            {
                int v = j * N + i;
                p[3 * v] = i * Spacing;
                p[3 * v + 1] = 0f;
                p[3 * v + 2] = j * Spacing;
            }
        return p;
    }

    static uint[] GridQuads()
    {
        var q = new List<uint>();
        for (int j = 0; j + 1 < N; ++j)
            for (int i = 0; i + 1 < N; ++i)
            {
                uint a = (uint)(j * N + i);
                q.Add(a); q.Add(a + 1); q.Add(a + 1 + N); q.Add(a + N);
            }
        return q.ToArray();
    }

    static RbcWorld MakeWorld(uint threads, IRbcJobSystem jobs = null, RbcLogHandler log = null,
                              int logLevel = RbcNative.RBC_LOG_WARNING, float strainWarning = -1)
    {
        var s = new RbcWorldSettings();
        s.Def.thread_count = threads;
        s.Def.log_level = logLevel;
        if (strainWarning >= 0) s.Def.strain_warning = strainWarning;
        s.Log = log;
        s.Jobs = jobs;
        return new RbcWorld(s);
    }

    static RbcCloth MakeCloth(RbcWorld w) { return w.CreateCloth(GridPositions(), GridQuads(), Pins); }

    static float[] Run(RbcWorld w, RbcCloth c, bool split = false)
    {
        for (int k = 0; k < Steps; ++k)
        {
            if (split) { w.StepBegin(Dt); w.StepWait(); }
            else w.Step(Dt);
        }
        return c.ReadPositions();
    }

    static bool BitwiseEqual(float[] a, float[] b)
    {
        if (a.Length != b.Length) return false;
        for (int k = 0; k < a.Length; ++k)
            if (BitConverter.ToInt32(BitConverter.GetBytes(a[k]), 0) !=
                BitConverter.ToInt32(BitConverter.GetBytes(b[k]), 0)) return false;
        return true;
    }

    static float MinY(float[] p)
    {
        float m = float.PositiveInfinity;
        for (int v = 0; v < p.Length / 3; ++v) m = Math.Min(m, p[3 * v + 1]);
        return m;
    }

    static RbcException Expect(Action a, int code, string what, params string[] substrings)
    {
        try { a(); }
        catch (RbcException e)
        {
            Check(e.Result == code, what + ": code " + e.Result + " (" + e.ResultName + "), expected " + code);
            Check(e.ResultName == Names[-code], what + ": name " + e.ResultName + ", expected " + Names[-code]);
            foreach (string s in substrings)
                Check(e.LibraryMessage.Contains(s), what + ": message \"" + e.LibraryMessage +
                      "\" lacks \"" + s + "\"");
            Console.WriteLine("mono_binding: " + what + " -> " + e.Message);
            return e;
        }
        Check(false, what + ": no RbcException");
        return null;
    }

    // --- the struct layouts against the C compiler's ---
    static readonly Dictionary<string, Type> Structs = new Dictionary<string, Type> {
        { "rbc_world_def", typeof(rbc_world_def) }, { "rbc_cloth_def", typeof(rbc_cloth_def) },
        { "rbc_collider_def", typeof(rbc_collider_def) }, { "rbc_solver_def", typeof(rbc_solver_def) },
        { "rbc_world_stats", typeof(rbc_world_stats) }, { "rbc_vertex_output", typeof(rbc_vertex_output) },
        { "rbc_collision_cloth", typeof(rbc_collision_cloth) } };

    static void CheckLayouts(string file)
    {
        var seen = new Dictionary<string, int>();
        foreach (string line in File.ReadAllLines(file))
        {
            string[] f = line.Split(' ');
            if (f.Length != 3) continue;
            Type t;
            if (!Structs.TryGetValue(f[0], out t)) { Check(false, "layout: unknown struct " + f[0]); continue; }
            long want = long.Parse(f[2]);
            if (f[1] == "-")
            {
                Check(Marshal.SizeOf(t) == want, "layout: sizeof " + f[0] + " C " + want + ", C# " + Marshal.SizeOf(t));
                continue;
            }
            seen[f[0]] = seen.ContainsKey(f[0]) ? seen[f[0]] + 1 : 1;
            long got = -1;
            try { got = (long)Marshal.OffsetOf(t, f[1]); } catch (ArgumentException) { }
            Check(got == want, "layout: " + f[0] + "." + f[1] + " at " + want + " in C, " + got + " in C#");
        }
        // Every C# field is one the C side listed: none extra, none missed.
        foreach (var kv in Structs)
        {
            int fields = kv.Value.GetFields().Length;
            int listed = seen.ContainsKey(kv.Key) ? seen[kv.Key] : 0;
            Check(fields == listed, "layout: " + kv.Key + " has " + fields + " C# fields, C lists " + listed);
        }
    }

    static int Main(string[] args)
    {
        if (args.Length != 1) { Console.Error.WriteLine("usage: BindingTest.exe LAYOUT_FILE"); return 2; }
        try { return Run(args[0]); }
        catch (Exception e)
        {
            Console.Error.WriteLine("mono_binding: FAILED: unexpected " + e);
            return 1;
        }
    }

    /// <summary>Every check; layoutFile null leaves out the layout check. Returns the
    /// exit status (0, or 1 when a check failed).</summary>
    public static int Run(string layoutFile)
    {
        failures = 0;
        Console.WriteLine("mono_binding: library " + RbcWorld.Version + ", ABI " + RbcWorld.AbiString());
        Check((RbcNative.rbc_abi_version() >> 16) == RbcNative.ABI_VERSION_MAJOR, "ABI major");
        if (layoutFile != null) CheckLayouts(layoutFile);

        // (1) the hanging cloth at 1 and 2 threads.
        float[] start = GridPositions();
        float[] p1, p2;
        using (var w1 = MakeWorld(1))
        using (var w2 = MakeWorld(2))
        {
            p1 = Run(w1, MakeCloth(w1));
            p2 = Run(w2, MakeCloth(w2));
            var st = w1.GetStats();
            Check(st.step_count == Steps, "stats.step_count " + st.step_count);
            Check(st.particle_count == N * N, "stats.particle_count " + st.particle_count);
            // The default solve (RBC_PRESET_CLOTH) keeps this cloth's springs well
            // inside the library's strain warning (2: three times their length).
            Check(st.step_max_strain < 2.0 && st.strain_warning_steps == 0,
                  "strain: step_max_strain " + st.step_max_strain + ", warnings " + st.strain_warning_steps);
            Console.WriteLine("mono_binding: hanging cloth: min y " + MinY(p1) + " m, max strain " + st.step_max_strain +
                              ", substeps per step " + st.substeps);
        }
        Check(BitwiseEqual(p1, p2), "1 and 2 threads: positions differ");
        bool finite = true;
        foreach (float x in p1) finite &= !float.IsNaN(x) && !float.IsInfinity(x);
        Check(finite, "a position is not finite");
        foreach (uint v in Pins)
            for (int k = 0; k < 3; ++k)
                Check(Math.Abs(p1[3 * v + k] - start[3 * v + k]) <= 1e-6f,
                      "pin " + v + " moved: " + p1[3 * v + k] + " vs " + start[3 * v + k]);
        // 2 s of free fall would be 19.6 m; hanging from the row j = 0 the far row is
        // up to 0.95 m below it. Below -0.3 m: it fell, and well past a sag.
        Check(MinY(p1) < -0.3f, "the cloth did not fall: min y " + MinY(p1));
        // No vertex gets farther from a pin than the cloth's diagonal stretched by the
        // strain the warning allows (3 x): a bound that catches an exploding solve.
        float diag = (float)Math.Sqrt(2) * (N - 1) * Spacing;
        for (int v = 0; v < N * N; ++v)
        {
            float dx = p1[3 * v], dy = p1[3 * v + 1], dz = p1[3 * v + 2];
            Check(Math.Sqrt(dx * dx + dy * dy + dz * dz) <= 3 * diag, "vertex " + v + " too far from pin 0");
        }

        // (2) refused input; the world steps on.
        using (var w = MakeWorld(1))
        {
            var c = MakeCloth(w);
            uint[] bad = GridQuads();
            bad[4 * 7 + 2] = N * N + 5; // quad 7, corner 2: an index past the vertices
            Expect(() => w.CreateCloth(GridPositions(), bad, Pins), RbcNative.RBC_ERR_BAD_MESH,
                   "quad index out of range", "quad 7", (N * N + 5).ToString());
            Expect(() => w.Step(-1f), RbcNative.RBC_ERR_INVALID_ARGUMENT, "dt = -1", "dt");
            Expect(() => RbcException.Check(RbcNative.rbc_world_set_gravity(w.Id, null)),
                   RbcNative.RBC_ERR_INVALID_ARGUMENT, "gravity NULL", "gravity");
            Expect(() => w.CreateCloth(GridPositions(), GridQuads(), new uint[] { N * N }),
                   RbcNative.RBC_ERR_INVALID_ARGUMENT, "pin out of range", (N * N).ToString());
            Check(w.GetStats().cloth_count == 1, "a refused cloth was created");
            // C would read 3 * VertexCount floats: a shorter array is refused before the call.
            try { c.SetState(new float[3 * N * N - 1]); Check(false, "a short state array was passed to C"); }
            catch (ArgumentException) { }

            // State round trip through the pointer forms: a moved state reads back as set.
            var moved = GridPositions();
            for (int k = 1; k < moved.Length; k += 3) moved[k] = -0.01f;
            fixed (float* mp = moved) c.SetState(mp, null);
            var got = new float[moved.Length];
            var prev = new float[moved.Length];
            fixed (float* gp = got) fixed (float* pp = prev) c.GetState(gp, pp, got.Length);
            bool asSet = true;
            for (int v = 0; v < N * N; ++v)
                if (v != Pins[0] && v != Pins[1])
                    for (int k = 0; k < 3; ++k) asSet &= got[3 * v + k] == moved[3 * v + k] && prev[3 * v + k] == moved[3 * v + k];
            Check(asSet, "set_state/get_state: the state does not read back as set");
            w.Step(Dt);
            float[] p = c.ReadPositions();
            Check(MinY(p) < 0f, "after refused calls the world did not step: min y " + MinY(p));

            // (4) stale handles: a destroyed cloth's and collider's ids, a destroyed world's.
            var col = w.CreateSphere(0.1f, 0.5f, -1f, 0.5f);
            uint staleCloth = c.Id;
            c.Destroy();
            Expect(() => c.ReadPositions(), RbcNative.RBC_ERR_STALE_HANDLE, "destroyed cloth", "cloth");
            Expect(() => c.Destroy(), RbcNative.RBC_ERR_STALE_HANDLE, "cloth destroyed twice", "cloth");
            col.Destroy();
            Expect(() => col.SetTransform(0, 0, 0, 0, 0, 0, 1), RbcNative.RBC_ERR_STALE_HANDLE,
                   "destroyed collider", "collider");
            var c2 = MakeCloth(w); // may reuse the slot: the generation must tell them apart
            Check(c2.Id != staleCloth, "a new cloth got the destroyed cloth's id " + staleCloth);
            uint n;
            Check(RbcNative.rbc_cloth_get_vertex_count(w.Id, staleCloth, out n) == RbcNative.RBC_ERR_STALE_HANDLE,
                  "the destroyed cloth's id is not stale after a new cloth");
            w.Step(Dt);
            uint wid = w.Id;
            w.Dispose();
            Check(RbcNative.rbc_world_step(wid, Dt) == RbcNative.RBC_ERR_STALE_HANDLE, "a destroyed world's id steps");
            try { w.Step(Dt); Check(false, "a disposed RbcWorld steps"); }
            catch (ObjectDisposedException) { }
        }

        // (3) callbacks: the log gets the strain warning (strain_warning 1e-6 makes the
        // first step's sag exceed it); the collision callback runs once per substep
        // and its floor at y = -0.1 holds.
        var logged = new List<string>();
        using (var w = MakeWorld(1, null, (level, msg) => { if (level == RbcNative.RBC_LOG_WARNING) logged.Add(msg); },
                                 RbcNative.RBC_LOG_WARNING, 1e-6f))
        {
            MakeCloth(w);
            w.Step(Dt);
            Check(logged.Count >= 1 && logged[0].Contains("strain"),
                  "log: " + logged.Count + " warnings" + (logged.Count > 0 ? ", first \"" + logged[0] + "\"" : ""));
            if (logged.Count > 0) Console.WriteLine("mono_binding: log: " + logged[0]);
            Check(w.GetStats().strain_warning_steps == 1, "strain_warning_steps after one step");
        }
        using (var w = MakeWorld(1))
        {
            var c = MakeCloth(w);
            int calls = 0;
            uint seenCloth = 0, seenCount = 0;
            const float Floor = -0.1f;
            w.SetCollisionHandler((dt, cloths, count) =>
            {
                calls++;
                seenCloth = cloths[0].cloth;
                seenCount = cloths[0].vertex_count;
                for (uint k = 0; k < count; ++k)
                    for (uint v = 0; v < cloths[k].vertex_count; ++v)
                        if (cloths[k].positions[3 * v + 1] < Floor) cloths[k].positions[3 * v + 1] = Floor;
                return true;
            });
            uint substeps = 0;
            for (int k = 0; k < Steps; ++k)
            {
                int before = calls;
                w.Step(Dt);
                substeps = w.GetStats(true).substeps;
                Check(calls - before == (int)substeps,
                      "step " + k + ": " + (calls - before) + " collision calls, " + substeps + " substeps");
                if (calls - before != (int)substeps) break;
            }
            Check(seenCloth == c.Id && seenCount == N * N, "collision callback saw cloth " + seenCloth + " of " + seenCount);
            float[] p = c.ReadPositions();
            Check(MinY(p) >= Floor, "the callback's floor did not hold: min y " + MinY(p));
            Check(MinY(p) <= Floor + 1e-3f, "the cloth did not reach the floor: min y " + MinY(p));
            Console.WriteLine("mono_binding: collision: " + calls + " calls over " + Steps + " steps (" + substeps +
                              " substeps each), min y " + MinY(p));

            // A handler that refuses or throws fails the step and leaves the world as it was.
            w.SetCollisionHandler((dt, cloths, count) => false);
            Expect(() => w.Step(Dt), RbcNative.RBC_ERR_CALLBACK, "handler returns false");
            Check(BitwiseEqual(p, c.ReadPositions()), "a refused step changed positions");
            w.SetCollisionHandler((dt, cloths, count) => { throw new InvalidOperationException("from C#"); });
            var e = Expect(() => w.Step(Dt), RbcNative.RBC_ERR_CALLBACK, "handler throws");
            Check(e != null && e.InnerException is InvalidOperationException, "the handler's exception is not the inner one");
            w.SetCollisionHandler(null);
            w.Step(Dt);
            Check(MinY(c.ReadPositions()) < Floor, "without the handler the cloth does not go below the floor");
        }

        // (5) ABI 1.10.
        bool have110 = true;
        try { var o = new rbc_vertex_output(); RbcNative.rbc_vertex_output_init(&o, RbcDefs.VertexOutputSize); }
        catch (EntryPointNotFoundException) { have110 = false; }
        if (have110) Check110(p1);
        else Check(false, "the library has no rbc_vertex_output_init: it is older than ABI 1.10, which this binding is for");

        if (failures > 0) { Console.Error.WriteLine("mono_binding: " + failures + " checks failed"); return 1; }
        Console.WriteLine("mono_binding: all checks hold");
        return 0;
    }

    static void Check110(float[] reference)
    {
        // The expected normal of the flat sheet from the quad winding: (c - a) x (d - b).
        float[] s = GridPositions();
        uint[] q = GridQuads();
        float[] e1 = new float[3], e2 = new float[3];
        for (int k = 0; k < 3; ++k) { e1[k] = s[3 * q[2] + k] - s[3 * q[0] + k]; e2[k] = s[3 * q[3] + k] - s[3 * q[1] + k]; }
        float ny = e1[2] * e2[0] - e1[0] * e2[2]; // the y component; x and z are 0 in the plane y = 0
        float sign = Math.Sign(ny);

        using (var w = MakeWorld(1))
        {
            var c = MakeCloth(w);
            const int Floats = 6; // stride 24: position, normal
            var buf = new float[Floats * N * N];
            uint rev = c.ReadVertices(buf, 24, 0, 12);
            Check(rev == 1, "triangle revision of a new cloth " + rev);
            for (int v = 0; v < N * N; ++v)
            {
                // Normalised in float: within a few ulps of 1 (1e-6 is 16 of them).
                bool ok = Math.Abs(buf[Floats * v + 3]) <= 1e-6f && Math.Abs(buf[Floats * v + 4] - sign) <= 1e-6f &&
                          Math.Abs(buf[Floats * v + 5]) <= 1e-6f;
                if (!ok)
                {
                    Check(false, "flat sheet: normal of vertex " + v + " is (" + buf[Floats * v + 3] + ", " +
                          buf[Floats * v + 4] + ", " + buf[Floats * v + 5] + "), expected (0, " + sign + ", 0)");
                    break;
                }
            }
            for (int k = 0; k < Steps; ++k) w.Step(Dt);
            rev = c.ReadVertices(buf, 24, 0, 12);
            float[] pos = c.ReadPositions();
            Check(BitwiseEqual(pos, reference), "the 1.10 world's run differs from the first one");
            bool same = true, unit = true;
            for (int v = 0; v < N * N; ++v)
            {
                for (int k = 0; k < 3; ++k) same &= buf[Floats * v + k] == pos[3 * v + k];
                double nx = buf[Floats * v + 3], nyy = buf[Floats * v + 4], nz = buf[Floats * v + 5];
                unit &= Math.Abs(Math.Sqrt(nx * nx + nyy * nyy + nz * nz) - 1) <= 1e-5;
            }
            Check(same, "read_vertices positions differ from read_positions");
            Check(unit, "a normal of the hanging cloth is not unit length (1e-5)");

            // Several outputs in one call, positions only, packed: the same positions.
            var packed = new float[3 * N * N];
            fixed (float* pp = packed)
            {
                var outs = new[] { c.Output(pp, 4L * packed.Length, 12, 0, RbcNative.RBC_NO_ATTRIBUTE) };
                w.ReadVertices(outs);
            }
            Check(BitwiseEqual(packed, pos), "packed read_vertices differs from read_positions");
            // A buffer one byte short is refused, naming the entry, and nothing is written.
            var small = new float[6 * N * N];
            fixed (float* sp = small)
            {
                var outs = new[] { c.Output(sp, 24L * N * N - 1, 24, 0, 12) };
                Expect(() => w.ReadVertices(outs), RbcNative.RBC_ERR_INVALID_ARGUMENT, "read_vertices buffer too small", "0");
            }
            bool untouched = true;
            foreach (float x in small) untouched &= x == 0f;
            Check(untouched, "a refused read_vertices wrote the buffer");

            uint trev;
            uint[] tris = c.GetTriangles(out trev);
            Check(tris.Length == 3 * 2 * (q.Length / 4) && trev == 1,
                  "triangles: " + tris.Length + " indices, revision " + trev);
            if (tris.Length >= 6)
                Check(tris[0] == q[0] && tris[1] == q[1] && tris[2] == q[2] && tris[3] == q[0] && tris[4] == q[2] &&
                      tris[5] == q[3], "the first quad's triangles are not (a b c) (a c d)");
            c.Cut(new uint[] { q[0], q[1] });
            c.GetTriangles(out trev);
            Check(trev == 2, "revision after a cut " + trev);

            // A rigid move by (1, 2, 3): every position moves by it (float rounding of p + t).
            float[] before = c.ReadPositions();
            c.Transform(1, 2, 3, 0, 0, 0, 1);
            float[] after = c.ReadPositions();
            bool moved = true;
            for (int v = 0; v < N * N; ++v)
                for (int k = 0; k < 3; ++k) moved &= Math.Abs(after[3 * v + k] - (before[3 * v + k] + 1 + k)) <= 1e-5f;
            Check(moved, "cloth_transform did not move every vertex by (1, 2, 3)");
        }

        // The split step: bitwise the same as rbc_world_step; calls in between are BUSY.
        using (var w = MakeWorld(2))
        {
            var c = MakeCloth(w);
            float[] p = Run(w, c, true);
            Check(BitwiseEqual(p, reference), "step_begin/step_wait positions differ from rbc_world_step's");
            w.StepBegin(Dt);
            Expect(() => c.ReadPositions(), RbcNative.RBC_ERR_BUSY, "read while stepping");
            Expect(() => w.Step(Dt), RbcNative.RBC_ERR_BUSY, "step while stepping");
            w.StepWait();
            w.StepWait(); // none running: RBC_OK at once
            c.ReadPositions();

            // After step_begin the callbacks run on the world's step thread, a thread
            // Mono has never seen: the reverse P/Invoke must attach it and work there.
            int main = System.Threading.Thread.CurrentThread.ManagedThreadId, calls = 0, foreign = 0;
            w.SetCollisionHandler((dt, cloths, count) =>
            {
                calls++;
                if (System.Threading.Thread.CurrentThread.ManagedThreadId != main) foreign++;
                return true;
            });
            for (int k = 0; k < 10; ++k) { w.StepBegin(Dt); w.StepWait(); }
            uint sub = w.GetStats(true).substeps;
            Check(calls == 10 * (int)sub && foreign == calls,
                  "split step callbacks: " + calls + " calls (" + foreign + " off the main thread), expected " + 10 * sub);
        }

        // Task callbacks: C# job systems give bitwise the world's own pool's result.
        var pool = new RbcThreadPoolJobs(1);
        using (var w = MakeWorld(2, pool))
        {
            float[] p = Run(w, MakeCloth(w));
            Check(BitwiseEqual(p, reference), "ThreadPool jobs: positions differ from the built-in pool's");
            Check(pool.EnqueuedTasks > 0, "ThreadPool jobs: enqueue_task was never called");
            Console.WriteLine("mono_binding: ThreadPool jobs: " + pool.EnqueuedTasks + " tasks, " + pool.RangesRun + " ranges");
        }
        var pool4 = new RbcThreadPoolJobs(3);
        using (var w = MakeWorld(4, pool4))
        using (var wb = MakeWorld(4))
        {
            float[] p = Run(w, MakeCloth(w));
            Check(BitwiseEqual(p, Run(wb, MakeCloth(wb))), "ThreadPool jobs at 4 threads: differ from the built-in pool's");
            Check(BitwiseEqual(p, reference), "4 threads differ from 1");
            Check(pool4.EnqueuedTasks > 0, "ThreadPool jobs at 4 threads: enqueue_task was never called");
        }
        var inline = new RbcInlineJobs();
        using (var w = MakeWorld(2, inline))
        {
            float[] p = Run(w, MakeCloth(w), true);
            Check(BitwiseEqual(p, reference), "inline jobs with the split step: positions differ");
            Check(inline.EnqueuedTasks > 0, "inline jobs: enqueue_task was never called");
        }
    }
}
