# roundtrip_check.py -- run inside Blender (blender -b --factory-startup
# --python-exit-code 1 --python roundtrip_check.py -- BATCH_DIR FORMAT FILE): the
# round trip of issue 19 in real Blender. The user imports their own FILE with
# Blender's importer for FORMAT (obj, fbx, dae, gltf) and applies the cache
# `rbcloth batch` made from that same file (BATCH_DIR/FORMAT/FORMAT.pc2, the file's
# vertex order, the default) with the Mesh Cache modifier; every vertex must then be
# where the simulation put it, at the first, a middle and the last frame, and the
# MDD must play the same frames in the modifier's TIME mode.
#
# The simulation's own positions come from the same job run with "cache_order":
# "simulation" (BATCH_DIR/FORMAT_sim/: its OBJ and PC2 in the simulation's order).
# Which simulated vertex a Blender vertex is, is found here, independently of the
# library's map: by nearest rest position, after the axis change each importer makes
# (below). The bound is float rounding: 4 units in the last place of the largest
# coordinate (the cache is rounded to float once, the FBX's and Collada's rotations
# are floats, and the transform back to the file's coordinates rounds once more).
#
# Axes: rbcloth simulates what assimp gives, y-up. Blender's OBJ importer keeps the
# file's y-up coordinates in the mesh (the object gets the rotation), so the mesh's
# coordinates are the simulation's. Its FBX and Collada importers keep the mesh in
# the z-up coordinates Blender exported (assimp applies the file's axis and unit
# transforms, so rbcloth's are y-up), and its glTF importer converts glTF's y-up to
# z-up inside the mesh: for those three, simulation = (x, z, -y) of the mesh's. A
# glTF cache is in the file's y-up coordinates, so the modifier converts it: its
# Forward +Z, Up -Y settings do (found by trying all 24 in Blender 3.4; the README
# tells users).
import array
import math
import struct
import sys

import bpy
import numpy

args = sys.argv[sys.argv.index("--") + 1:]
batch_dir, fmt, path = args[0], args[1], args[2]
failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL: " + msg)


def read_pc2(p):
    data = open(p, "rb").read()
    if data[:12] != b"POINTCACHE2\0":
        sys.exit("not a PC2 file: %s" % p)
    points, = struct.unpack("<i", data[16:20])
    samples, = struct.unpack("<i", data[28:32])
    a = numpy.frombuffer(data, dtype="<f4", offset=32, count=samples * points * 3)
    return a.reshape(samples, points, 3).astype(numpy.float64)


def read_obj_v(p):
    return numpy.array([[float(t) for t in line.split()[1:4]]
                        for line in open(p) if line.startswith("v ")])


bpy.ops.wm.read_factory_settings(use_empty=True)
if fmt == "obj":
    bpy.ops.wm.obj_import(filepath=path)
elif fmt == "fbx":
    bpy.ops.import_scene.fbx(filepath=path)
elif fmt == "dae":
    bpy.ops.wm.collada_import(filepath=path)
elif fmt == "gltf":
    # Debian's Blender 3.4 glTF importer still uses numpy.bool, which Debian's numpy
    # 1.24 removed (AttributeError: module 'numpy' has no attribute 'bool'); the
    # alias it meant is the builtin bool.
    if not hasattr(numpy, "bool"):
        numpy.bool = bool
    bpy.ops.import_scene.gltf(filepath=path)
else:
    sys.exit("unknown format " + fmt)
meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
if len(meshes) != 1:
    sys.exit("Blender's importer made %d mesh objects" % len(meshes))
ob = meshes[0]


def to_sim(co):
    co = numpy.asarray(co, dtype=numpy.float64)
    if fmt == "obj":
        return co
    return numpy.stack([co[..., 0], co[..., 2], -co[..., 1]], axis=-1)


rest_local = numpy.array([v.co[:] for v in ob.data.vertices], dtype=numpy.float64)
sim_rest = read_obj_v("%s/%s_sim/%s_sim.obj" % (batch_dir, fmt, fmt))
sim = read_pc2("%s/%s_sim/%s_sim.pc2" % (batch_dir, fmt, fmt))
file_pc2 = "%s/%s/%s.pc2" % (batch_dir, fmt, fmt)
points, = struct.unpack("<i", open(file_pc2, "rb").read()[16:20])
print("%s: Blender's importer made %d vertices; the file-order cache has %d, the simulation %d"
      % (fmt, len(rest_local), points, len(sim_rest)))
if points != len(rest_local):
    fail("the cache has %d points, the mesh Blender imports %d vertices" % (points, len(rest_local)))
    sys.exit(1)

tol = 4.0 * 2.0 ** -23 * max(1.0, float(numpy.abs(sim).max()), float(numpy.abs(sim_rest).max()))
rest_sim = to_sim(rest_local)
d2 = ((rest_sim[:, None, :] - sim_rest[None, :, :]) ** 2).sum(axis=2)
match = d2.argmin(axis=1)
rest_err = float(numpy.sqrt(d2[numpy.arange(len(match)), match]).max())
print("%s: rest: every Blender vertex within %.3g m of a simulated vertex (bound %.3g)"
      % (fmt, rest_err, tol))
if rest_err > tol:
    fail("rest positions do not match the simulation's: %.3g m > %.3g" % (rest_err, tol))

edges = [tuple(e.vertices) for e in ob.data.edges]
rest_len = numpy.array([numpy.linalg.norm(rest_local[a] - rest_local[b]) for a, b in edges])
scene = bpy.context.scene
frames = [1, sim.shape[0] // 2, sim.shape[0]]


def check(mode):
    worst_all = 0.0
    for frame in frames:
        scene.frame_set(frame)
        dg = bpy.context.evaluated_depsgraph_get()
        ev = ob.evaluated_get(dg)
        me = ev.to_mesh()
        co = numpy.array([v.co[:] for v in me.vertices], dtype=numpy.float64)
        ev.to_mesh_clear()
        got = to_sim(co)
        want = sim[frame - 1][match]  # frame f shows the state after f steps
        worst = float(numpy.abs(got - want).max())
        moved = float(numpy.abs(want - sim_rest[match]).max())
        print("%s %s frame %d: largest |Blender - simulation| = %.3g m (bound %.3g; the cloth "
              "moved up to %.3g m)" % (fmt, mode, frame, worst, tol, moved))
        if worst > tol:
            fail("%s frame %d: %.3g m > %.3g" % (mode, frame, worst, tol))
        if frame == 1:
            # The symptom, counted: at frame 1 the cloth has hardly moved, so an
            # edge 10 % off its rest length is a scrambled vertex (later, quad
            # diagonals of a triangulated import may shear that far).
            lens = numpy.array([numpy.linalg.norm(co[a] - co[b]) for a, b in edges])
            off = int((numpy.abs(lens / rest_len - 1.0) > 0.10).sum())
            print("%s %s frame 1: %d of %d edges more than 10 %% off their rest length"
                  % (fmt, mode, off, len(edges)))
            if off:
                fail("%s frame 1: %d edges more than 10 %% off" % (mode, off))
        if frame == frames[-1] and moved < 100 * tol:
            fail("the cloth hardly moved (%.3g m): the check would not see a wrong order" % moved)
        worst_all = max(worst_all, worst)
    return worst_all


mod = ob.modifiers.new("rbcloth", "MESH_CACHE")
mod.cache_format = "PC2"
mod.filepath = file_pc2
mod.frame_start = 1.0
if fmt == "gltf":
    mod.forward_axis = "POS_Z"
    mod.up_axis = "NEG_Y"
check("PC2")
# MDD in TIME mode at the simulation's 60 frames per second: the times are seconds.
mod.cache_format = "MDD"
mod.filepath = "%s/%s/%s.mdd" % (batch_dir, fmt, fmt)
mod.time_mode = "TIME"
mod.frame_start = 0.0
scene.render.fps = 60
scene.render.fps_base = 1.0
check("MDD")
if failures:
    print("%s: %d failures" % (fmt, len(failures)))
    sys.exit(1)
print("%s: the cache lands on Blender's own import of the file" % fmt)
