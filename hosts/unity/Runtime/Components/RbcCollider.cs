// RbcCollider.cs -- the cloth's view of this object's SphereCollider, CapsuleCollider
// or BoxCollider: created once from its size (world space: the transform's scale
// applied), moved to the transform before every step. A size changed later needs
// the component disabled and enabled again.
// NOT compiled here (no Unity in the repository's build): see README.md.
using RbCloth.Native;
using UnityEngine;

namespace RbCloth
{
    public sealed class RbcCollider : MonoBehaviour
    {
        [Tooltip("The world; empty = the first RbcClothWorld in the scene")]
        public RbcClothWorld world;
        [Tooltip("metres kept between cloth and the surface")] public float thickness = 0f;
        public float friction = 0f;

        Native.RbcCollider native;
        Vector3 center;          // the Unity collider's centre, local space
        Quaternion axis = Quaternion.identity; // capsule: the library's y axis to Unity's direction
        bool started;

        void Start()
        {
            started = true;
            OnEnable();
        }

        void OnEnable()
        {
            if (!started) return; // Start creates it: every world's Awake has run by then
            if (world == null) world = FindObjectOfType<RbcClothWorld>();
            if (world == null || world.World == null)
            {
                Debug.LogError("RbcCollider: no RbcClothWorld in the scene", this);
                enabled = false;
                return;
            }
            rbc_collider_def def;
            Vector3 s = transform.lossyScale;
            float maxScale = Mathf.Max(Mathf.Abs(s.x), Mathf.Abs(s.y), Mathf.Abs(s.z));
            var sphere = GetComponent<SphereCollider>();
            var capsule = GetComponent<CapsuleCollider>();
            var box = GetComponent<BoxCollider>();
            if (sphere != null)
            {
                def = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_SPHERE);
                def.radius = sphere.radius * maxScale;
                center = sphere.center;
            }
            else if (capsule != null)
            {
                // Unity scales a capsule's radius by the larger of the two scales
                // across its axis and its height by the scale along it.
                int d = capsule.direction;
                float along = Mathf.Abs(d == 0 ? s.x : d == 1 ? s.y : s.z);
                float across = d == 0 ? Mathf.Max(Mathf.Abs(s.y), Mathf.Abs(s.z))
                             : d == 1 ? Mathf.Max(Mathf.Abs(s.x), Mathf.Abs(s.z))
                             : Mathf.Max(Mathf.Abs(s.x), Mathf.Abs(s.y));
                def = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_CAPSULE);
                def.radius = capsule.radius * across;
                unsafe
                {
                    // The library's capsule runs along its frame's y; its half length
                    // is the segment's, without the caps. Must be > 0.
                    def.half_extents[1] = Mathf.Max(1e-4f, capsule.height * along * 0.5f - def.radius);
                }
                axis = Quaternion.FromToRotation(Vector3.up,
                    d == 0 ? Vector3.right : d == 1 ? Vector3.up : Vector3.forward);
                center = capsule.center;
            }
            else if (box != null)
            {
                def = RbcDefs.ColliderDef(RbcNative.RBC_SHAPE_BOX);
                Vector3 h = Vector3.Scale(box.size, s) * 0.5f;
                unsafe
                {
                    def.half_extents[0] = Mathf.Abs(h.x);
                    def.half_extents[1] = Mathf.Abs(h.y);
                    def.half_extents[2] = Mathf.Abs(h.z);
                }
                center = box.center;
            }
            else
            {
                Debug.LogError("RbcCollider: needs a SphereCollider, CapsuleCollider or BoxCollider", this);
                enabled = false;
                return;
            }
            def.thickness = thickness;
            def.friction = friction;
            native = world.World.CreateCollider(def);
            Sync();
            world.Register(this);
        }

        /// <summary>Move the library's collider to the transform (called by the world
        /// before each step). Unity's quaternions are x y z w, as the library's.</summary>
        internal void Sync()
        {
            if (native == null) return;
            Vector3 p = transform.TransformPoint(center);
            Quaternion q = transform.rotation * axis;
            native.SetTransform(p.x, p.y, p.z, q.x, q.y, q.z, q.w);
        }

        void OnDisable()
        {
            if (world != null) world.Unregister(this);
            if (native != null && world != null && world.World != null && !world.World.IsDisposed)
                native.Destroy();
            native = null;
        }
    }
}
