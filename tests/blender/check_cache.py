# check_cache.py -- run inside Blender (blender -b --python-exit-code 1 --python
# check_cache.py -- OBJ PC2 IMPORTER FRAME_START): bring `rbcloth run`'s rest mesh
# and point cache into Blender the way the README says, and compare what Blender
# shows with the cache.
#
#   IMPORTER     new (wm.obj_import, Blender's default since 3.3) or legacy
#                (import_scene.obj with split_mode OFF, which keeps the file's
#                vertex order)
#   FRAME_START  the Mesh Cache modifier's frame_start: frame f shows sample
#                f - FRAME_START. Sample k is the state after k + 1 steps (frame 0
#                is the OBJ's rest pose), so 1 puts every state on its frame; with
#                Blender's default 0, frame f shows the state after f + 1 steps, one
#                step late (the test checks both, each exactly).
#
# Every other setting is the modifier's default: format PC2, time mode FRAME, play
# mode SCENE, forward +Y, up +Z (the importer's rotation of the object turns rbcloth's
# y-up into Blender's z-up; the cache is in the mesh's own coordinates). Exact
# equality is expected: the modifier copies the cache's floats into the mesh.
# Exit status 0 when every checked frame matches, 1 otherwise (a Python error too).
import array
import struct
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
obj_path, pc2_path, importer, frame_start = args[0], args[1], args[2], float(args[3])
bpy.ops.wm.read_factory_settings(use_empty=True)
if importer == "new":
    bpy.ops.wm.obj_import(filepath=obj_path)
else:
    bpy.ops.import_scene.obj(filepath=obj_path, split_mode="OFF")
ob = bpy.context.selected_objects[0]
mod = ob.modifiers.new("rbcloth", "MESH_CACHE")
mod.cache_format = "PC2"
mod.filepath = pc2_path
mod.frame_start = frame_start

data = open(pc2_path, "rb").read()
if data[:12] != b"POINTCACHE2\0":
    sys.exit("not a PC2 file: %s" % pc2_path)
points, = struct.unpack("<i", data[16:20])
samples, = struct.unpack("<i", data[28:32])
if len(ob.data.vertices) != points:
    sys.exit("the imported mesh has %d vertices, the cache %d" % (len(ob.data.vertices), points))
scene = bpy.context.scene
worst_all = 0.0
first = int(frame_start)
for frame in sorted({first, first + 1, first + samples // 2, first + samples - 1}):
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = ob.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    k = frame - first
    sample = array.array("f")
    sample.frombytes(data[32 + k * points * 12: 32 + (k + 1) * points * 12])
    worst = max(abs(mesh.vertices[i].co[c] - sample[3 * i + c])
                for i in range(points) for c in range(3))
    evaluated.to_mesh_clear()
    print("frame %d: largest |Blender - sample %d| = %g m" % (frame, k, worst))
    worst_all = max(worst_all, worst)
print("importer %s, frame_start %g: %s" % (importer, frame_start,
      "exact" if worst_all == 0.0 else "off by up to %g m" % worst_all))
sys.exit(0 if worst_all == 0.0 else 1)
