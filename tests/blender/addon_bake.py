# addon_bake.py -- run inside Blender (blender -b --factory-startup --python-exit-code 1
# --python addon_bake.py -- ZIP CLI WORKDIR MODE): install the add-on zip into the
# fresh user folder that BLENDER_USER_SCRIPTS names, enable it (and import a mesh
# through the shipped library and helper), build a scene and check the bake.
#
#   bake     a pinned 17 x 17 grid, moved and turned (a non-identity matrix_world),
#            over a sphere collider tagged through the add-on's property; the Bake
#            operator; then what Blender shows (the evaluated mesh, through the Mesh
#            Cache modifier the bake added) against `rbcloth run` of the scene JSON
#            the bake wrote. The bake simulates in world space and caches local
#            coordinates rounded to float once, so a state x shows as L = fl(M^-1 x):
#            |L_i - (M^-1 x)_i| <= 2^-24 |L_i|, and M L is within
#            ||M||_inf * 2^-24 * max|L| of x (plus double rounding, 1e-12 m). The rest
#            frame is checked exactly (sample 0 is the mesh's own vertices), and
#            frames 2 and 16 against the CLI's samples 0 and 14 (one step apart is
#            ~1e-2 m, far above the bound: an off-by-one frame mapping fails).
#   moving   the grid at the origin (identity matrix: the cache is the simulated
#            state itself), solved by the game preset with a target strain of 3 %,
#            under a keyframed sphere rising through it: every frame
#            must equal the CLI's exactly (bound 0), so the collider was followed
#            frame by frame with the poses the replay uses.
#            A box turning and rising is followed the same way.
#   cancel   the modal operator's path (invoke needs a window, so its methods are
#            driven headless with stand-in events): 3 timer events, a mouse move
#            passed through, Esc: no file is left in the cache folder and no
#            modifier added; then a modal bake run to its end writes the same bytes
#            as the operator's execute; then a Baker cancelled directly.
#   unsaved  a bake in a .blend never saved: the cache goes to the temporary
#            folder (tempfile.gettempdir()/rbcloth), the modifier names it by its
#            absolute path and plays it (frame 2 is sample 1 exactly).
#   bad      the operator on an Empty, an empty mesh, a mesh with triangles, a
#            missing pin group, a flat box collider, an empty frame range: each an error report (RuntimeError from bpy.ops
#            naming the problem), not a Python traceback, and no file written.
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import time

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1:]
zip_path, cli, work, mode = args
assert "RBCLOTH_LIBRARY" not in os.environ, "the test must use the library the zip ships"
user = os.environ["BLENDER_USER_SCRIPTS"]
shutil.rmtree(user, ignore_errors=True)
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
bpy.ops.preferences.addon_enable(module="rbcloth_blender")
import rbcloth_blender  # noqa: E402

addon_dir = os.path.dirname(rbcloth_blender.__file__)
assert addon_dir.startswith(os.path.realpath(user)) or addon_dir.startswith(user), addon_dir
assert rbcloth_blender.bake.rbcloth.api.path.startswith(addon_dir), \
    rbcloth_blender.bake.rbcloth.api.path
# The helper the library spawns for mesh import runs from the add-on's folder
# (zipfile drops its execute bit; the add-on restores it).
rb = rbcloth_blender.bake.rbcloth
helper = os.path.join(addon_dir, "rbcloth", "rbcloth-import")
assert os.access(helper, os.X_OK), helper
rb.write_obj(os.path.join(work, "quad.obj"), np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2, 3]], np.uint32))
with rb.Mesh(os.path.join(work, "quad.obj")) as m:
    assert m.info()["quad_count"] == 1
os.remove(os.path.join(work, "quad.obj"))
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = 30, 1.0
if mode != "unsaved":
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, "scene.blend"))
cache_dir = os.path.join(work, "rbcloth")


def grid(location=(0, 0, 0), rotation=(0, 0, 0)):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=16, y_subdivisions=16, size=1.0,
                                    location=location, rotation=rotation)
    ob = bpy.context.active_object
    ob.name = "Cloth"
    top = max(v.co.y for v in ob.data.vertices)
    g = ob.vertex_groups.new(name="pins")
    g.add([v.index for v in ob.data.vertices if v.co.y == top], 1.0, 'REPLACE')
    s = ob.rbcloth
    s.pin_group, s.frame_start, s.frame_end = "pins", 1, 31
    s.stiffness, s.vertex_mass = 500.0, 1e-3
    return ob


def sphere(location, radius=0.25):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=location)
    ob = bpy.context.active_object
    ob.rbcloth.collider = 'SPHERE'
    return ob


def bake(ob):
    bpy.context.view_layer.objects.active = ob
    scene.frame_set(7)
    t = time.time()
    r = bpy.ops.rbcloth.bake()
    print("bake: %s in %.2f s" % (r, time.time() - t))
    assert r == {'FINISHED'}, r
    assert scene.frame_current == 7  # the user's frame is left as it was
    files = sorted(os.listdir(cache_dir))
    assert files == ["Cloth.json", "Cloth.pc2"], files
    return os.path.join(cache_dir, "Cloth.json")


def replay(json_path):
    out = os.path.join(work, "cli")
    r = subprocess.run([cli, "run", json_path, "--out", out, "--no-view"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    data = open(os.path.join(out, "Cloth.pc2"), "rb").read()
    points, samples = struct.unpack("<i", data[16:20])[0], struct.unpack("<i", data[28:32])[0]
    return np.frombuffer(data[32:], "<f4").reshape(samples, points, 3)


def shown(ob, frame):
    scene.frame_set(frame)
    ev = ob.evaluated_get(bpy.context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    co = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    return co.reshape(-1, 3)


def rest(ob):
    co = np.empty(3 * len(ob.data.vertices), np.float32)
    ob.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


if mode == "bake":
    ob = grid(location=(0.1, -0.2, 1.0), rotation=(0.0, 0.0, math.radians(30)))
    ball = sphere((0.1, -0.2, 0.55))
    bpy.ops.mesh.primitive_plane_add(size=3.0, location=(0.1, -0.2, 0.2))
    bpy.context.active_object.rbcloth.collider = 'MESH'
    json_path = bake(ob)
    mod = ob.modifiers[0]
    assert (mod.type, mod.cache_format, mod.frame_start) == ('MESH_CACHE', 'PC2', 1.0)
    assert mod.filepath == "//rbcloth/Cloth.pc2", mod.filepath  # beside the .blend
    scene_json = json.load(open(json_path))
    assert [c["shape"] for c in scene_json["colliders"]] == ["sphere", "mesh"]
    assert not any("keyframes" in c for c in scene_json["colliders"])  # static
    cli_frames = replay(json_path)
    assert cli_frames.shape == (30, len(ob.data.vertices), 3), cli_frames.shape
    M = np.array(ob.matrix_world, np.float64)
    norm = np.abs(M[:3, :3]).sum(axis=1).max()
    assert np.array_equal(shown(ob, 1), rest(ob)), "frame 1 is not the rest pose"
    worst = 0.0
    for frame in (2, 16, 31):
        L = shown(ob, frame).astype(np.float64)
        W = L @ M[:3, :3].T + M[:3, 3]
        x = cli_frames[frame - 2]
        bound = norm * 2.0 ** -24 * np.abs(L).max() + 1e-12
        diff = np.abs(W - x).max()
        print("frame %d: |M L - rbcloth run| = %.3g m, bound %.3g m" % (frame, diff, bound))
        assert diff <= bound, (frame, diff, bound)
        worst = max(worst, diff)
    # The bound is far below what the cloth did: it fell onto the sphere.
    fell = np.abs(cli_frames[-1] - cli_frames[0]).max()
    centre = np.array(ball.matrix_world.translation)
    gap = np.linalg.norm(cli_frames[-1] - centre, axis=1).min() - 0.25
    print("moved %.3f m; nearest vertex %.4f m from the sphere's surface" % (fell, gap))
    assert fell > 0.1 and -0.01 < gap < 0.01
elif mode == "moving":
    ob = grid()
    # The game preset with a target strain of its own: the solve the JSON must name.
    ob.rbcloth.preset, ob.rbcloth.use_target_strain, ob.rbcloth.target_strain = \
        'GAME_60HZ', True, 0.03
    ball = sphere((0.0, 0.0, -0.5), radius=0.2)
    ball.keyframe_insert("location", frame=1)
    ball.location = (0.0, 0.0, 0.4)
    ball.keyframe_insert("location", frame=31)
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0.0, 0.45, -0.9))
    box = bpy.context.active_object
    box.rbcloth.collider, box.rbcloth.friction = 'BOX', 0.4
    box.keyframe_insert("location", frame=1)
    box.keyframe_insert("rotation_euler", frame=1)
    box.location, box.rotation_euler = (0.0, 0.45, -0.5), (0.0, 0.0, math.radians(120))
    box.keyframe_insert("location", frame=31)
    box.keyframe_insert("rotation_euler", frame=31)
    json_path = bake(ob)
    scene_json = json.load(open(json_path))
    assert scene_json["world"]["solver"] == {"preset": "game_60hz", "mode": "target",
                                             "target_strain": float(np.float32(0.03))}
    keys = [c["keyframes"] for c in scene_json["colliders"]]
    assert [len(k) for k in keys] == [31, 31]
    assert keys[1][0]["rotation"] != keys[1][15]["rotation"]  # the box turns
    cli_frames = replay(json_path)
    assert np.array_equal(shown(ob, 1), rest(ob))
    for frame in range(2, 32):
        assert np.array_equal(shown(ob, frame), cli_frames[frame - 2]), frame
    lifted = cli_frames[-1][:, 2].max()
    print("every frame equals rbcloth run exactly; highest vertex at z = %.3f m" % lifted)
    assert lifted > 0.3  # the sphere came up through the cloth's plane and carried it
elif mode == "cancel":
    from types import SimpleNamespace
    Op = rbcloth_blender.RBCLOTH_OT_bake

    class FakeOp:
        """The operator's own methods on a stand-in instance (bpy.ops would need a
        window for invoke's timer)."""
        _timer = None
        _begin, _step, _end, _stop_timer, modal = (
            Op._begin, Op._step, Op._end, Op._stop_timer, Op.modal)

        def __init__(self):
            self.reports = []

        def report(self, kind, message):
            self.reports.append(message)

    ob = grid()
    sphere((0.0, 0.0, -0.5))
    bpy.context.view_layer.objects.active = ob
    ctx = bpy.context
    op = FakeOp()
    assert op._begin(ctx)
    for _ in range(3):
        assert op.modal(ctx, SimpleNamespace(type='TIMER')) == {'RUNNING_MODAL'}
    assert op.modal(ctx, SimpleNamespace(type='MOUSEMOVE')) == {'PASS_THROUGH'}
    assert os.listdir(cache_dir) == ["Cloth.pc2.tmp"]
    assert op.modal(ctx, SimpleNamespace(type='ESC')) == {'CANCELLED'}
    assert os.listdir(cache_dir) == [] and not ob.modifiers, os.listdir(cache_dir)
    assert "cancelled" in op.reports[-1], op.reports
    print("Esc after 3 frames: nothing written (%s)" % op.reports[-1])
    op = FakeOp()
    assert op._begin(ctx)
    events = 1
    while op.modal(ctx, SimpleNamespace(type='TIMER')) == {'RUNNING_MODAL'}:
        events += 1
    assert events == 30 and ob.modifiers[0].type == 'MESH_CACHE', events
    modal_bytes = open(os.path.join(cache_dir, "Cloth.pc2"), "rb").read()
    assert bake(ob) and open(os.path.join(cache_dir, "Cloth.pc2"), "rb").read() == modal_bytes
    assert len(ob.modifiers) == 1  # the second bake reused the modifier
    print("a modal bake of 30 timer events wrote what execute writes")
    for f in os.listdir(cache_dir):
        os.remove(os.path.join(cache_dir, f))
    path = os.path.join(cache_dir, "Cloth.pc2")
    b = rbcloth_blender.bake.Baker(scene, ob, path)
    assert os.listdir(cache_dir) == ["Cloth.pc2.tmp"]  # written while baking
    for _ in range(3):
        assert b.step()
    b.cancel()
    assert os.listdir(cache_dir) == [], os.listdir(cache_dir)
    print("cancelled after 3 frames: nothing left in", cache_dir)
elif mode == "unsaved":
    import tempfile
    tempfile.tempdir = os.path.join(work, "tmp")
    ob = grid()
    bpy.context.view_layer.objects.active = ob
    assert bpy.ops.rbcloth.bake() == {'FINISHED'}
    pc2 = os.path.join(work, "tmp", "rbcloth", "Cloth.pc2")
    assert sorted(os.listdir(os.path.dirname(pc2))) == ["Cloth.json", "Cloth.pc2"]
    assert ob.modifiers[0].filepath == pc2, ob.modifiers[0].filepath
    data = open(pc2, "rb").read()
    n = len(ob.data.vertices)
    sample1 = np.frombuffer(data[32 + n * 12: 32 + 2 * n * 12], "<f4").reshape(n, 3)
    assert np.array_equal(shown(ob, 2), sample1) and not np.array_equal(sample1, rest(ob))
    print("unsaved .blend: cache in", os.path.dirname(pc2))
elif mode == "bad":
    def refused(ob, expect):
        bpy.context.view_layer.objects.active = ob
        try:
            bpy.ops.rbcloth.bake()
        except RuntimeError as e:
            msg = str(e)
            print("refused: %s" % msg.strip())
            assert "Traceback" not in msg and expect in msg and "rbcloth:" in msg, msg
        else:
            raise AssertionError("bake of %s was not refused" % ob.name)
        assert not os.path.exists(cache_dir) or os.listdir(cache_dir) == []
    empty = bpy.data.objects.new("Empty", None)
    scene.collection.objects.link(empty)
    refused(empty, "is not a mesh")
    nothing = bpy.data.objects.new("Nothing", bpy.data.meshes.new("Nothing"))
    scene.collection.objects.link(nothing)
    refused(nothing, "nothing to simulate")
    bpy.ops.mesh.primitive_cone_add()
    refused(bpy.context.active_object, "32 triangles and 1 n-gons")
    ob = grid()
    ob.rbcloth.pin_group = "nope"
    refused(ob, "no vertex group 'nope'")
    ob.rbcloth.pin_group = "pins"
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 0, -1))
    flat = bpy.context.active_object
    flat.rbcloth.collider = 'BOX'
    refused(ob, "box collider 'Plane' is flat")
    flat.rbcloth.collider = 'NONE'
    ob.rbcloth.frame_end = 1
    refused(ob, "frame range 1-1 has no step")
else:
    sys.exit("unknown mode %s" % mode)
print("addon_bake %s: ok" % mode)
