// RbcCloth.cs, with RbcCollider -- a cloth and a collider of an RbcWorld, named by
// their ids; every method goes through the world. Destroying the world destroys
// them; a destroyed one's id is refused by the library as RBC_ERR_STALE_HANDLE (never
// dereferenced), which is what a call after Destroy throws.
using System;

namespace RbCloth.Native
{
    public sealed unsafe class RbcCloth
    {
        public RbcWorld World { get; private set; }
        public uint Id { get; private set; }
        /// <summary>Vertices, as created (cuts and tears keep every vertex).</summary>
        public int VertexCount { get; private set; }

        internal RbcCloth(RbcWorld world, uint id)
        {
            World = world;
            Id = id;
            uint n;
            RbcException.Check(RbcNative.rbc_cloth_get_vertex_count(world.LiveId, id, out n));
            VertexCount = (int)n;
        }

        public void Destroy() { RbcException.Check(RbcNative.rbc_cloth_destroy(World.LiveId, Id)); }

        /// <summary>Positions (3 floats per vertex, creation order) into xyz, which
        /// holds `capacity` floats (at least 3 * VertexCount).</summary>
        public void ReadPositions(float* xyz, int capacity)
        {
            UIntPtr written;
            RbcException.Check(RbcNative.rbc_cloth_read_positions(World.LiveId, Id, xyz,
                                                                  (UIntPtr)capacity, out written));
        }

        public void ReadPositions(float[] xyz)
        {
            RbcArrays.Need(xyz, 3 * VertexCount, "xyz");
            fixed (float* p = xyz) ReadPositions(p, xyz.Length);
        }

        public float[] ReadPositions()
        {
            var xyz = new float[3 * VertexCount];
            ReadPositions(xyz);
            return xyz;
        }

        /// <summary>Positions and previous positions into buffers of `capacity` floats
        /// each (either may be null).</summary>
        public void GetState(float* positions, float* previous, int capacity)
        {
            RbcException.Check(RbcNative.rbc_cloth_get_state(World.LiveId, Id, positions, previous,
                                                             (UIntPtr)capacity));
        }

        /// <summary>Replace the state from buffers of 3 * VertexCount floats (previous
        /// null = at rest).</summary>
        public void SetState(float* positions, float* previous)
        {
            RbcException.Check(RbcNative.rbc_cloth_set_state(World.LiveId, Id, positions, previous));
        }

        /// <summary>Positions and previous positions (either may be null).</summary>
        public void GetState(float[] positions, float[] previous)
        {
            int n = 3 * VertexCount;
            if (positions != null) RbcArrays.Need(positions, n, "positions");
            if (previous != null) RbcArrays.Need(previous, n, "previous");
            fixed (float* p = positions)
            fixed (float* q = previous)
                RbcException.Check(RbcNative.rbc_cloth_get_state(World.LiveId, Id, p, q, (UIntPtr)n));
        }

        /// <summary>Replace the state; previous null = at rest.</summary>
        public void SetState(float[] positions, float[] previous = null)
        {
            RbcArrays.Need(positions, 3 * VertexCount, "positions");
            if (previous != null) RbcArrays.Need(previous, 3 * VertexCount, "previous");
            fixed (float* p = positions)
            fixed (float* q = previous)
                RbcException.Check(RbcNative.rbc_cloth_set_state(World.LiveId, Id, p, q));
        }

        /// <summary>Pin a vertex at (x, y, z), reached over the next step's substeps.</summary>
        public void SetPin(uint vertex, float x, float y, float z)
        {
            float* t = stackalloc float[3];
            t[0] = x; t[1] = y; t[2] = z;
            RbcException.Check(RbcNative.rbc_cloth_set_pin(World.LiveId, Id, vertex, t));
        }

        public void ReleasePin(uint vertex)
        {
            RbcException.Check(RbcNative.rbc_cloth_set_pin(World.LiveId, Id, vertex, null));
        }

        /// <summary>Pin a vertex to a collider's frame where it is now.</summary>
        public void Attach(uint vertex, RbcCollider collider)
        {
            RbcException.Check(RbcNative.rbc_cloth_attach(World.LiveId, Id, vertex, collider.Id, null));
        }

        /// <summary>Cut the springs joining vertex pairs (2 indices each); returns the count cut.</summary>
        public uint Cut(uint[] pairs)
        {
            if (pairs == null || pairs.Length % 2 != 0) throw new ArgumentException("pairs: 2 indices each");
            uint cut;
            fixed (uint* p = pairs)
                RbcException.Check(RbcNative.rbc_cloth_cut(World.LiveId, Id, p, (uint)(pairs.Length / 2), out cut));
            return cut;
        }

        public uint[] GetQuads()
        {
            UIntPtr n;
            uint w = World.LiveId;
            RbcException.Check(RbcNative.rbc_cloth_get_quads(w, Id, null, UIntPtr.Zero, out n));
            var q = new uint[(int)n];
            fixed (uint* p = q) RbcException.Check(RbcNative.rbc_cloth_get_quads(w, Id, p, n, out n));
            return q;
        }

        public uint[] GetSprings()
        {
            UIntPtr n;
            uint w = World.LiveId;
            RbcException.Check(RbcNative.rbc_cloth_get_springs(w, Id, null, UIntPtr.Zero, out n));
            var s = new uint[(int)n];
            fixed (uint* p = s) RbcException.Check(RbcNative.rbc_cloth_get_springs(w, Id, p, n, out n));
            return s;
        }

        /// <summary>Triangle index buffer (3 per triangle; two per quad a b c d: a b c,
        /// a c d) and its revision, which changes when a tear or cut removes a face (1.10).</summary>
        public uint[] GetTriangles(out uint revision)
        {
            UIntPtr n;
            uint w = World.LiveId;
            RbcException.Check(RbcNative.rbc_cloth_get_triangles(w, Id, null, UIntPtr.Zero, out n, out revision));
            var t = new uint[(int)n];
            fixed (uint* p = t)
                RbcException.Check(RbcNative.rbc_cloth_get_triangles(w, Id, p, n, out n, out revision));
            return t;
        }

        /// <summary>Triangles into a caller buffer of `capacity` uint values; returns
        /// the count written (uint values) (1.10).</summary>
        public int GetTriangles(uint* triangles, int capacity, out uint revision)
        {
            UIntPtr n;
            RbcException.Check(RbcNative.rbc_cloth_get_triangles(World.LiveId, Id, triangles,
                                                                 (UIntPtr)capacity, out n, out revision));
            return (int)n;
        }

        /// <summary>Move the whole cloth rigidly, p -> R p + t (rotation a unit
        /// quaternion x y z w), previous positions and pins too (1.10).</summary>
        public void Transform(float tx, float ty, float tz, float qx, float qy, float qz, float qw,
                              bool resetVelocity = false)
        {
            float* t = stackalloc float[3];
            float* q = stackalloc float[4];
            t[0] = tx; t[1] = ty; t[2] = tz;
            q[0] = qx; q[1] = qy; q[2] = qz; q[3] = qw;
            RbcException.Check(RbcNative.rbc_cloth_transform(World.LiveId, Id, t, q,
                resetVelocity ? RbcNative.RBC_TRANSFORM_RESET_VELOCITY : RbcNative.RBC_TRANSFORM_KEEP_VELOCITY));
        }

        /// <summary>A vertex output for this cloth (rbc_vertex_output_init's defaults
        /// with the cloth, buffer and layout set), for RbcWorld.ReadVertices (1.10).
        /// normalOffset RBC_NO_ATTRIBUTE skips normals.</summary>
        public rbc_vertex_output Output(void* buffer, long bufferSize, uint stride,
                                        uint positionOffset, uint normalOffset)
        {
            var o = new rbc_vertex_output();
            RbcException.Check(RbcNative.rbc_vertex_output_init(&o, RbcDefs.VertexOutputSize));
            o.cloth = Id;
            o.buffer = (IntPtr)buffer;
            o.buffer_size = (UIntPtr)(ulong)bufferSize;
            o.stride = stride;
            o.position_offset = positionOffset;
            o.normal_offset = normalOffset;
            return o;
        }

        /// <summary>This cloth's vertices into a buffer at a stride (1.10); returns the
        /// triangle revision at this read.</summary>
        public uint ReadVertices(void* buffer, long bufferSize, uint stride, uint positionOffset,
                                 uint normalOffset)
        {
            rbc_vertex_output o = Output(buffer, bufferSize, stride, positionOffset, normalOffset);
            World.ReadVertices(&o, 1);
            return o.triangle_revision;
        }

        /// <summary>ReadVertices into a float array: stride and offsets in bytes.</summary>
        public uint ReadVertices(float[] buffer, uint stride, uint positionOffset, uint normalOffset)
        {
            if (buffer == null) throw new ArgumentNullException("buffer");
            fixed (float* p = buffer)
                return ReadVertices(p, 4L * buffer.Length, stride, positionOffset, normalOffset);
        }
    }

    public sealed unsafe class RbcCollider
    {
        public RbcWorld World { get; private set; }
        public uint Id { get; private set; }

        internal RbcCollider(RbcWorld world, uint id) { World = world; Id = id; }

        /// <summary>Move the collider: position (metres) and unit quaternion x y z w.</summary>
        public void SetTransform(float px, float py, float pz, float qx, float qy, float qz, float qw)
        {
            float* p = stackalloc float[3];
            float* q = stackalloc float[4];
            p[0] = px; p[1] = py; p[2] = pz;
            q[0] = qx; q[1] = qy; q[2] = qz; q[3] = qw;
            RbcException.Check(RbcNative.rbc_collider_set_transform(World.LiveId, Id, p, q));
        }

        public void Destroy() { RbcException.Check(RbcNative.rbc_collider_destroy(World.LiveId, Id)); }
    }
}
