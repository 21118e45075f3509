// RbcClothMesh.cs -- a cloth from this object's MeshFilter mesh, simulated in world
// space and written back into the mesh (local space) every frame.
// NOT compiled here (no Unity in the repository's build): see README.md.
//
//  - Vertices: Unity splits a vertex at UV seams and hard edges; copies at the same
//    local position are welded into one cloth vertex (else the cloth would come
//    apart at the seams), and every Unity vertex follows its cloth vertex.
//  - Faces: a mesh with quad topology is taken as it is; triangles are paired into
//    quads across shared edges of opposite direction (Unity's triangle pairs of a
//    quad: (a b c)(a c d) and the like). A triangle left without a partner becomes
//    three springs (its vertices get no normal from the library: they keep the
//    mesh's own).
//  - Pins: vertices whose colour has red > 0.5 (pinsFromVertexColors), and the
//    Unity vertex indices in pinnedVertices. A pin follows this transform: its
//    target is set to the transform of its rest position before each step.
//  - Output: rbc_world_read_vertices into a NativeArray (position and normal
//    interleaved, stride 24) without a copy, then world -> local and
//    Mesh.SetVertices / SetNormals.
using System.Collections.Generic;
using RbCloth.Native;
using Unity.Collections;
using Unity.Collections.LowLevel.Unsafe;
using UnityEngine;

namespace RbCloth
{
    [RequireComponent(typeof(MeshFilter))]
    public sealed class RbcClothMesh : MonoBehaviour
    {
        [Tooltip("The world; empty = the first RbcClothWorld in the scene")]
        public RbcClothWorld world;
        public bool pinsFromVertexColors = true;
        [Tooltip("Unity vertex indices to pin, besides the red ones")]
        public int[] pinnedVertices = new int[0];
        [Tooltip("kg/m^2; 0 = every vertex has vertexMass")]
        public float density = 0.2f;
        public float vertexMass = 1e-4f;
        [Tooltip("N/m")] public float stiffness = 1000f;
        [Tooltip("N/m, 0 = none")] public float shearStiffness = 0f;
        [Tooltip("N/m, 0 = none")] public float bendStiffness = 0f;
        [Tooltip("1/s")] public float damping = 0f;
        [Tooltip("metres kept from collider surfaces")] public float thickness = 0f;
        public float friction = 0f;

        Native.RbcCloth cloth;
        Mesh mesh;
        int[] unityToCloth;           // Unity vertex -> cloth vertex
        uint[] pins;                  // cloth vertices pinned
        Vector3[] pinRestLocal;       // their rest positions, local space
        Vector3[] meshNormals;        // the mesh's own normals, for vertices without a face
        NativeArray<float> readback;  // cloth vertices: position, normal (world space)
        NativeArray<Vector3> outPositions, outNormals;

        public Native.RbcCloth Cloth { get { return cloth; } }

        void Start()
        {
            if (world == null) world = FindObjectOfType<RbcClothWorld>();
            if (world == null || world.World == null)
            {
                Debug.LogError("RbcClothMesh: no RbcClothWorld in the scene", this);
                enabled = false;
                return;
            }
            mesh = GetComponent<MeshFilter>().mesh; // an instance: the asset stays as it was
            mesh.MarkDynamic();
            Create();
            world.Register(this);
        }

        void Create()
        {
            Vector3[] local = mesh.vertices;
            meshNormals = mesh.normals;
            int n = local.Length;

            // Weld copies at one position.
            unityToCloth = new int[n];
            var first = new Dictionary<Vector3, int>();
            var clothLocal = new List<Vector3>();
            for (int u = 0; u < n; ++u)
            {
                int c;
                if (!first.TryGetValue(local[u], out c))
                {
                    c = clothLocal.Count;
                    first.Add(local[u], c);
                    clothLocal.Add(local[u]);
                }
                unityToCloth[u] = c;
            }

            var quads = new List<uint>();
            var springs = new List<uint>();
            for (int sub = 0; sub < mesh.subMeshCount; ++sub)
            {
                int[] idx = mesh.GetIndices(sub);
                MeshTopology topo = mesh.GetTopology(sub);
                if (topo == MeshTopology.Quads)
                    for (int k = 0; k < idx.Length; ++k) quads.Add((uint)unityToCloth[idx[k]]);
                else if (topo == MeshTopology.Triangles)
                    PairTriangles(idx, quads, springs);
            }

            var pinSet = new SortedSet<int>();
            if (pinsFromVertexColors)
            {
                Color[] colors = mesh.colors;
                for (int u = 0; u < colors.Length; ++u)
                    if (colors[u].r > 0.5f) pinSet.Add(unityToCloth[u]);
            }
            foreach (int u in pinnedVertices)
                if (u >= 0 && u < n) pinSet.Add(unityToCloth[u]);
            pins = new uint[pinSet.Count];
            pinRestLocal = new Vector3[pinSet.Count];
            int p = 0;
            foreach (int c in pinSet) { pins[p] = (uint)c; pinRestLocal[p] = clothLocal[c]; ++p; }

            Matrix4x4 toWorld = transform.localToWorldMatrix;
            var xyz = new float[3 * clothLocal.Count];
            for (int c = 0; c < clothLocal.Count; ++c)
            {
                Vector3 w = toWorld.MultiplyPoint3x4(clothLocal[c]);
                xyz[3 * c] = w.x; xyz[3 * c + 1] = w.y; xyz[3 * c + 2] = w.z;
            }

            rbc_cloth_def def = RbcDefs.ClothDef();
            def.density = density;
            def.vertex_mass = vertexMass;
            def.stiffness = stiffness;
            def.shear_stiffness = shearStiffness;
            def.bend_stiffness = bendStiffness;
            def.damping = damping;
            def.thickness = thickness;
            def.friction = friction;
            cloth = world.World.CreateCloth(xyz, quads.ToArray(), pins, springs.ToArray(), def);

            readback = new NativeArray<float>(6 * cloth.VertexCount, Allocator.Persistent);
            outPositions = new NativeArray<Vector3>(n, Allocator.Persistent);
            outNormals = new NativeArray<Vector3>(n, Allocator.Persistent);
        }

        // Greedy pairing, first come first served: each triangle takes the first
        // unpaired triangle across one of its edges that runs the other way there
        // (the same winding), giving the quad (p0 p1 q p2) for triangles (p0 p1 p2)
        // and (p2 p1 q).
        void PairTriangles(int[] idx, List<uint> quads, List<uint> springs)
        {
            int t = idx.Length / 3;
            var edges = new Dictionary<long, int>(); // directed edge (a, b) -> triangle
            var tri = new int[3 * t];
            for (int k = 0; k < 3 * t; ++k) tri[k] = unityToCloth[idx[k]];
            for (int k = 0; k < t; ++k)
                for (int e = 0; e < 3; ++e)
                    edges[Key(tri[3 * k + e], tri[3 * k + (e + 1) % 3])] = k;
            var paired = new bool[t];
            for (int k = 0; k < t; ++k)
            {
                if (paired[k]) continue;
                for (int e = 0; e < 3 && !paired[k]; ++e)
                {
                    int a = tri[3 * k + e], b = tri[3 * k + (e + 1) % 3], opp = tri[3 * k + (e + 2) % 3];
                    int other;
                    if (!edges.TryGetValue(Key(b, a), out other) || other == k || paired[other]) continue;
                    int q = -1;
                    for (int f = 0; f < 3; ++f)
                    {
                        int v = tri[3 * other + f];
                        if (v != a && v != b) q = v;
                    }
                    if (q < 0 || q == opp) continue;
                    // Triangle k is (opp a b); the other is (b a q): the quad opp a q b.
                    quads.Add((uint)opp); quads.Add((uint)a); quads.Add((uint)q); quads.Add((uint)b);
                    paired[k] = paired[other] = true;
                }
            }
            int left = 0;
            for (int k = 0; k < t; ++k)
            {
                if (paired[k]) continue;
                ++left;
                for (int e = 0; e < 3; ++e)
                {
                    springs.Add((uint)tri[3 * k + e]);
                    springs.Add((uint)tri[3 * k + (e + 1) % 3]);
                }
            }
            if (left > 0)
                Debug.LogWarning("RbcClothMesh: " + left + " of " + t + " triangles found no partner for a quad; " +
                                 "their edges are springs", this);
        }

        static long Key(int a, int b) { return ((long)a << 32) | (uint)b; }

        /// <summary>Pins follow the transform (called by the world before each step).</summary>
        internal void SyncPins()
        {
            if (cloth == null) return;
            Matrix4x4 toWorld = transform.localToWorldMatrix;
            for (int k = 0; k < pins.Length; ++k)
            {
                Vector3 w = toWorld.MultiplyPoint3x4(pinRestLocal[k]);
                cloth.SetPin(pins[k], w.x, w.y, w.z);
            }
        }

        /// <summary>The cloth's vertices into the mesh (called by the world while idle).</summary>
        internal unsafe void WriteMesh()
        {
            if (cloth == null) return;
            cloth.ReadVertices(NativeArrayUnsafeUtility.GetUnsafePtr(readback), 4L * readback.Length, 24, 0, 12);
            Matrix4x4 toLocal = transform.worldToLocalMatrix;
            // Normals go back with the transpose of local -> world (inverse transpose
            // of world -> local); a mirroring transform turned the winding, and so
            // the library's normals, around.
            Matrix4x4 normalToLocal = transform.localToWorldMatrix.transpose;
            float flip = transform.localToWorldMatrix.determinant < 0f ? -1f : 1f;
            float* r = (float*)NativeArrayUnsafeUtility.GetUnsafeReadOnlyPtr(readback);
            for (int u = 0; u < unityToCloth.Length; ++u)
            {
                float* v = r + 6 * unityToCloth[u];
                outPositions[u] = toLocal.MultiplyPoint3x4(new Vector3(v[0], v[1], v[2]));
                var nw = new Vector3(v[3], v[4], v[5]);
                outNormals[u] = nw == Vector3.zero && meshNormals.Length > u
                    ? meshNormals[u]
                    : (normalToLocal.MultiplyVector(nw) * flip).normalized;
            }
            mesh.SetVertices(outPositions);
            mesh.SetNormals(outNormals);
            mesh.RecalculateBounds();
        }

        void OnDestroy()
        {
            if (world != null) world.Unregister(this);
            // The world's own OnDestroy destroys its cloths; only a live world is asked.
            if (cloth != null && world != null && world.World != null && !world.World.IsDisposed)
                cloth.Destroy();
            cloth = null;
            if (readback.IsCreated) readback.Dispose();
            if (outPositions.IsCreated) outPositions.Dispose();
            if (outNormals.IsCreated) outNormals.Dispose();
        }
    }
}
