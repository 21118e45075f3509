"""The bake: a Blender mesh object simulated with rbcloth (no bpy UI here).

Coordinates: the cloth is simulated in world space (the object's matrix_world at
the first frame applied to its vertices, Blender's z up, gravity -Z) and the cache
holds the object's local coordinates (inverse matrix, in double, rounded to float
once), which the Mesh Cache modifier plays with its default axes. The cloth is the
mesh's own vertices in Blender's order, so the cache needs no map; every face must
be a quad (the scene format has no springs for triangles, and a bake that the
scene JSON cannot replay exactly would not be honest), anything else is refused.

Frames: sample k of the cache is the state k steps after the first frame (sample
0 is the rest pose), the PC2 header's start frame is the first frame, and the
modifier's frame_start is the first frame: frame f shows the state after f - start
steps of 1/fps s each.

Colliders: objects whose rbcloth.collider is SPHERE (radius half the largest of
dimensions, centred on the origin), BOX (half_extents half the dimensions, centred on
the origin) or MESH (the evaluated mesh triangulated, in the object's frame with its
scale applied), posed by matrix_world (translation and rotation; scale and
deformation as at the first frame). Animated ones are followed: before the step
into frame f the collider is moved to its pose at f, as rbc_scene_apply_frame does
for a scene's keyframes, so `rbcloth run` of the written scene JSON replays the bake
exactly (poses are rounded as the scene loader rounds them).
"""
import json
import math
import os

import numpy as np

from . import rbcloth

GRAVITY = (0.0, 0.0, -9.81)


class BakeError(Exception):
    """A setting or an object the bake refuses; the message is the report."""


def _f(x):
    return float(np.float32(x))


def loader_quaternion(q):
    """The float32 quaternion samples/scene.c's read_quaternion makes of q (x y z w):
    normalised in double, then rounded; the same operations in the same order."""
    x, y, z, w = (float(v) for v in q)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return np.array([x / norm, y / norm, z / norm, w / norm], np.float32)


def matrix_np(m):
    return np.array([[m[i][j] for j in range(4)] for i in range(4)], np.float64)


def pose(ob):
    """(position float32[3], rotation x y z w as the doubles Blender gives)."""
    loc, rot, _scale = ob.matrix_world.decompose()
    return (np.array(loc, np.float32), [float(rot.x), float(rot.y), float(rot.z), float(rot.w)])


def cloth_mesh(ob, pin_group):
    """(local positions float32 (n, 3), quads uint32 (m, 4), pins uint32) of a mesh
    object's own mesh, refusing what cannot be a cloth."""
    if ob is None or ob.type != 'MESH':
        raise BakeError("rbcloth: the active object%s is not a mesh"
                        % ("" if ob is None else " '%s' (%s)" % (ob.name, ob.type.lower())))
    me = ob.data
    n, faces = len(me.vertices), len(me.polygons)
    if n == 0 or faces == 0:
        raise BakeError("rbcloth: mesh '%s' has %d vertices and %d faces: nothing to simulate"
                        % (ob.name, n, faces))
    totals = np.empty(faces, np.int32)
    me.polygons.foreach_get("loop_total", totals)
    if np.any(totals != 4):
        tris, ngons = int(np.sum(totals == 3)), int(np.sum(totals > 4))
        raise BakeError("rbcloth: mesh '%s' has %d triangles and %d n-gons among %d faces; "
                        "only quads are simulated (the scene JSON has no springs to replay "
                        "them): make it all quads (e.g. Tris to Quads, or a quad grid)"
                        % (ob.name, tris, ngons, faces))
    co = np.empty(3 * n, np.float32)
    me.vertices.foreach_get("co", co)
    loops = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", loops)
    starts = np.empty(faces, np.int32)
    me.polygons.foreach_get("loop_start", starts)
    quads = loops[starts[:, None] + np.arange(4)[None, :]].astype(np.uint32)
    pins = np.zeros(0, np.uint32)
    if pin_group:
        g = ob.vertex_groups.get(pin_group)
        if g is None:
            raise BakeError("rbcloth: '%s' has no vertex group '%s'" % (ob.name, pin_group))
        pins = np.array([v.index for v in me.vertices
                         if any(e.group == g.index and e.weight > 0.0 for e in v.groups)],
                        np.uint32)
    return co.reshape(n, 3), quads, pins


def collider_shape(ob):
    """The collider def fields (without its pose) and the scene JSON's keys."""
    kind = ob.rbcloth.collider
    friction = _f(ob.rbcloth.friction)
    dims = [_f(d) for d in ob.dimensions]
    if kind == 'SPHERE':
        r = _f(max(dims) / 2.0)
        if not r > 0:
            raise BakeError("rbcloth: sphere collider '%s' has no size" % ob.name)
        return {"shape": "sphere", "radius": r}, {"radius": r}, friction
    if kind == 'BOX':
        h = [_f(d / 2.0) for d in dims]
        if not min(h) > 0:
            raise BakeError("rbcloth: box collider '%s' is flat (dimensions %s)" % (ob.name, dims))
        return {"shape": "box", "half_extents": h}, {"half_extents": h}, friction
    if ob.type != 'MESH':
        raise BakeError("rbcloth: mesh collider '%s' is not a mesh" % ob.name)
    me = ob.data
    me.calc_loop_triangles()
    if not me.loop_triangles:
        raise BakeError("rbcloth: mesh collider '%s' has no faces" % ob.name)
    co = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", co)
    scale = np.array(ob.matrix_world.decompose()[2], np.float64)
    v = (co.reshape(-1, 3).astype(np.float64) * scale).astype(np.float32)
    t = np.empty(3 * len(me.loop_triangles), np.int32)
    me.loop_triangles.foreach_get("vertices", t)
    t = t.reshape(-1, 3).astype(np.uint32)
    return ({"shape": "mesh", "vertices": v.tolist(), "triangles": t.tolist()},
            {"vertices": v, "triangles": t}, friction)


class Baker:
    """One bake, stepped by the operator: start (everything checked, the cache
    opened on "<path>.tmp"), step() per frame, then finish() or cancel(). Cancelled
    or failed, nothing is written: the cache is destroyed (its .tmp removed) and
    the scene JSON, kept in memory, never written."""

    def __init__(self, scene, ob, cache_path):
        s = ob.rbcloth
        self.scene, self.ob, self.path = scene, ob, cache_path
        self.start, self.end = s.frame_start, s.frame_end
        self.user_frame = scene.frame_current
        if self.end <= self.start:
            raise BakeError("rbcloth: frame range %d-%d has no step" % (self.start, self.end))
        rest_local, quads, pins = cloth_mesh(ob, s.pin_group)
        self.dt = _f(scene.render.fps_base / scene.render.fps)
        self.frames = self.end - self.start
        scene.frame_set(self.start)
        M = matrix_np(ob.matrix_world)
        self.M = M
        self.Minv = np.linalg.inv(M)
        world = (rest_local.astype(np.float64) @ M[:3, :3].T + M[:3, 3]).astype(np.float32)
        colliders = [o for o in scene.objects if o is not ob and o.rbcloth.collider != 'NONE']
        # Poses at every frame of the range (frame_set moves the animation).
        poses = {o.name: [] for o in colliders}
        for f in range(self.start, self.end + 1):
            scene.frame_set(f)
            for o in colliders:
                poses[o.name].append(pose(o))
        scene.frame_set(self.start)  # shapes and scales are taken at the first frame
        cloth_keys = dict(vertex_mass=_f(s.vertex_mass), stiffness=_f(s.stiffness),
                          damping=_f(s.damping), thickness=_f(s.thickness),
                          friction=_f(s.friction))
        solver = {"preset": s.preset.lower()}
        if s.use_target_strain:
            solver.update(mode="target", target_strain=_f(s.target_strain))
        name = "".join(c if c.isalnum() or c in "_.-" else "_" for c in ob.name)[:64]
        self.json = {
            "name": name.lstrip(".") or "cloth",
            "description": "baked by the rbcloth Blender add-on from object '%s', frames %d-%d"
                           % (ob.name, self.start, self.end),
            "frames": self.frames, "dt": self.dt,
            "world": {"gravity": list(GRAVITY), "solver": solver},
            "cloths": [dict({"name": "cloth", "vertices": world.tolist(),
                             "quads": quads.tolist(), "pins": pins.tolist()}, **cloth_keys)],
            "colliders": []}
        self.world = rbcloth.World(gravity=GRAVITY, preset=s.preset.lower(),
                                   target_strain=cloth_target(s))
        self.moving = []
        try:
            self.cloth = self.world.cloth(world, quads, pins=pins, **cloth_keys)
            for o in colliders:
                keys, fields, friction = collider_shape(o)
                seq = poses[o.name]
                p0, q0 = seq[0]
                entry = dict(keys, friction=friction, position=p0.tolist(), rotation=q0)
                c = self.world.collider(keys["shape"], position=p0, rotation=loader_quaternion(q0),
                                        friction=friction, **fields)
                if any(not np.array_equal(p, p0) or q != q0 for p, q in seq):
                    entry["keyframes"] = [{"time": self.dt * k, "position": p.tolist(),
                                           "rotation": q} for k, (p, q) in enumerate(seq)]
                    self.moving.append((c, [(p, loader_quaternion(q)) for p, q in seq]))
                self.json["colliders"].append(entry)
            self.cache = rbcloth.Cache(self.path, len(rest_local), format="pc2",
                                       start_frame=self.start, sample_rate=1)
        except (rbcloth.Error, BakeError) as e:
            self.world.close()
            scene.frame_set(self.user_frame)
            raise e if isinstance(e, BakeError) else BakeError("rbcloth: %s" % e)
        scene.frame_set(self.user_frame)  # the bake leaves the user's frame as it was
        try:
            self.cache.write(rest_local)  # sample 0: the rest pose, exactly the mesh's
        except rbcloth.Error as e:
            self.cancel()
            raise BakeError("rbcloth: %s" % e)
        self.k = 0

    def step(self):
        """Simulate one frame and write it; True while frames remain."""
        for c, seq in self.moving:
            p, q = seq[self.k + 1]
            c.set_transform(p, q)
        self.world.step(self.dt)
        x = self.cloth.positions().astype(np.float64)
        local = (x @ self.Minv[:3, :3].T + self.Minv[:3, 3]).astype(np.float32)
        self.cache.write(local)
        self.k += 1
        return self.k < self.frames

    def finish(self):
        """Put the cache in place, then the scene JSON beside it (NAME.json)."""
        self.cache.finish()
        self.world.close()
        json_path = os.path.splitext(self.path)[0] + ".json"
        tmp = json_path + ".tmp"
        with open(tmp, "w") as f:
            json.dump(self.json, f)
        os.replace(tmp, json_path)
        return json_path

    def cancel(self):
        self.cache.destroy()
        self.world.close()


def cloth_target(s):
    return _f(s.target_strain) if s.use_target_strain else None
