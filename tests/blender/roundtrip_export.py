# roundtrip_export.py -- run inside Blender (blender -b --factory-startup --python
# roundtrip_export.py -- OUTDIR): the user's side of a DCC round trip. Builds a
# 22 x 22 curtain (484 vertices, 441 quads, 1 m square, level at 2 m in Blender's XY
# plane; pinned along one edge it swings down by a metre, so a vertex out of place
# shows) whose UV map has a seam down the middle (so every format that stores UVs per
# vertex has to split the seam's vertices), exports it with Blender's own exporters
# as OBJ, FBX, Collada and glTF (binary), and writes OUTDIR/manifest.json: each file
# simulated twice by `rbcloth batch`, once with the caches in the file's vertex order
# (the default) and once in the simulation's order (the reference the check reads).
import json
import os
import sys

import bmesh
import bpy

out = sys.argv[sys.argv.index("--") + 1]
os.makedirs(out, exist_ok=True)
bpy.ops.wm.read_factory_settings(use_empty=True)
n = 22
verts = [(i / (n - 1) - 0.5, 0.5 - j / (n - 1), 2.0) for j in range(n) for i in range(n)]
faces = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)
         for j in range(n - 1) for i in range(n - 1)]
me = bpy.data.meshes.new("curtain")
me.from_pydata(verts, [], faces)
ob = bpy.data.objects.new("curtain", me)
bpy.context.scene.collection.objects.link(ob)
bpy.context.view_layer.objects.active = ob
ob.select_set(True)
bpy.ops.object.mode_set(mode="EDIT")
bm = bmesh.from_edit_mesh(me)
seam_x = verts[n // 2][0]
for e in bm.edges:
    a, b = e.verts
    if abs(a.co.x - seam_x) < 1e-6 and abs(b.co.x - seam_x) < 1e-6:
        e.seam = True
bmesh.update_edit_mesh(me)
bpy.ops.mesh.select_all(action="SELECT")
bpy.ops.uv.unwrap()
bpy.ops.object.mode_set(mode="OBJECT")
seams = sum(e.use_seam for e in me.edges)
if seams != n - 1:
    sys.exit("expected %d seam edges, made %d" % (n - 1, seams))

bpy.ops.wm.obj_export(filepath=os.path.join(out, "curtain.obj"), export_selected_objects=True)
bpy.ops.export_scene.fbx(filepath=os.path.join(out, "curtain.fbx"), use_selection=True)
bpy.ops.wm.collada_export(filepath=os.path.join(out, "curtain.dae"), selected=True)
bpy.ops.export_scene.gltf(filepath=os.path.join(out, "curtain.glb"), use_selection=True)

# The edge at x = 0.5 is pinned: x is x in every file's simulation (each importer
# turns Blender's z-up into rbcloth's y-up about the x axis, see roundtrip_check.py).
manifest = {
    "description": "Blender's curtain in four formats, caches in the file's order and in "
                   "the simulation's (tests/blender/roundtrip_export.py)",
    "defaults": {"frames": 24, "dt": 1 / 60, "outputs": ["pc2", "mdd"],
                 "pins": {"top_axis": "x", "top_tolerance": 0.001}},
    "jobs": [],
}
for fmt, ext in (("obj", "obj"), ("fbx", "fbx"), ("dae", "dae"), ("gltf", "glb")):
    manifest["jobs"].append({"name": fmt, "mesh": "curtain." + ext})
    manifest["jobs"].append({"name": fmt + "_sim", "mesh": "curtain." + ext,
                             "cache_order": "simulation"})
with open(os.path.join(out, "manifest.json"), "w") as f:
    json.dump(manifest, f, indent=1)
print("exported the curtain (%d vertices, %d seam edges) to %s" % (len(me.vertices), seams, out))
