// RbcClothWorld.cs -- the scene's cloth world. Simulation space is Unity's world
// space (colliders and cloths in world coordinates, gravity along -y).
// NOT compiled here (no Unity in the repository's build): see README.md.
//
// Two ways to step, chosen by `stepping`:
//  - FixedUpdate: colliders and pins are synced, then rbc_world_step(fixedDeltaTime),
//    in FixedUpdate; the meshes are written in LateUpdate. Simple, blocking.
//  - Split: LateUpdate syncs colliders and pins (after animation has moved them) and
//    starts the step (rbc_world_step_begin, on the world's step thread) with this
//    frame's deltaTime; the next frame's Update waits for it (rbc_world_step_wait)
//    and writes the meshes. The step runs while Unity renders. Anything that needs
//    the world in between goes through World, which waits first, so no call ever
//    meets RBC_ERR_BUSY.
using System.Collections.Generic;
using RbCloth.Native;
using UnityEngine;

namespace RbCloth
{
    [DefaultExecutionOrder(1000)] // after the scripts that move colliders and pins
    [DisallowMultipleComponent]
    public sealed class RbcClothWorld : MonoBehaviour
    {
        public enum Stepping { FixedUpdate, Split }

        public Stepping stepping = Stepping.FixedUpdate;
        [Tooltip("Worker threads including the stepping one; 0 = the library chooses")]
        public int threadCount = 0;
        public Vector3 gravity = new Vector3(0f, -9.81f, 0f);
        [Tooltip("Substeps per second of simulated time (the library's default 480)")]
        public float substepRate = 480f;
        [Tooltip("Unity's console gets the library's warnings and errors")]
        public bool logToConsole = true;

        RbcWorld world;
        bool stepInFlight;
        readonly List<RbcClothMesh> meshes = new List<RbcClothMesh>();
        readonly List<RbcCollider> colliders = new List<RbcCollider>();

        /// <summary>The world, idle: a step started by the split mode is waited for
        /// first. Null before Awake and after OnDestroy.</summary>
        public RbcWorld World
        {
            get
            {
                WaitForStep();
                return world;
            }
        }

        void Awake()
        {
            var s = new RbcWorldSettings();
            s.SetGravity(gravity.x, gravity.y, gravity.z);
            s.Def.thread_count = (uint)Mathf.Max(0, threadCount);
            s.Def.substep_rate = substepRate;
            if (logToConsole)
            {
                // Called on the stepping thread: Debug.Log is thread-safe.
                s.Log = (level, message) =>
                {
                    if (level <= RbcNative.RBC_LOG_ERROR) Debug.LogError("rbcloth: " + message);
                    else Debug.LogWarning("rbcloth: " + message);
                };
            }
            world = new RbcWorld(s);
        }

        void OnDestroy()
        {
            if (world == null) return;
            WaitForStep();
            world.Dispose(); // destroys every cloth and collider in it
            world = null;
        }

        internal void Register(RbcClothMesh m) { meshes.Add(m); }
        internal void Unregister(RbcClothMesh m) { meshes.Remove(m); }
        internal void Register(RbcCollider c) { colliders.Add(c); }
        internal void Unregister(RbcCollider c) { colliders.Remove(c); }

        void WaitForStep()
        {
            if (!stepInFlight) return;
            stepInFlight = false;
            world.StepWait(); // throws the step's failure, if any
        }

        void SyncInputs()
        {
            for (int k = 0; k < colliders.Count; ++k) colliders[k].Sync();
            for (int k = 0; k < meshes.Count; ++k) meshes[k].SyncPins();
        }

        void WriteMeshes()
        {
            for (int k = 0; k < meshes.Count; ++k) meshes[k].WriteMesh();
        }

        void FixedUpdate()
        {
            if (stepping != Stepping.FixedUpdate || world == null) return;
            SyncInputs();
            world.Step(Time.fixedDeltaTime);
        }

        void Update()
        {
            if (stepping != Stepping.Split || world == null) return;
            WaitForStep();
            WriteMeshes();
        }

        void LateUpdate()
        {
            if (world == null) return;
            if (stepping == Stepping.FixedUpdate)
            {
                WriteMeshes();
                return;
            }
            float dt = Time.deltaTime;
            if (dt <= 0f) return; // paused (timeScale 0): the library refuses dt <= 0
            WaitForStep();
            SyncInputs();
            world.StepBegin(dt);
            stepInFlight = true;
        }
    }
}
