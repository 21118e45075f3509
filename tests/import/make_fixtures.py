# make_fixtures.py -- regenerates tests/import/file_vertices/ (the fixtures of the
# import_file_vertices_* tests) with Blender:
#   blender -b --factory-startup --python tests/import/make_fixtures.py -- OUTDIR
# A 22 x 22 vertex grid ("ClothGrid", object "Cloth", moved, turned and scaled so
# that a node transform would show) with a UV seam down one column (so assimp splits
# those vertices) and its vertices in a shuffled order (so that no reader could pass
# by emitting them in grid order), and a 4-vertex plane ("PatchMesh", object
# "Patch"), exported with the default settings of
#   bpy.ops.export_scene.fbx    -> grid.fbx  (binary FBX 7.4)
#   bpy.ops.wm.collada_export   -> grid.dae
# and written out as text:
#   grid_vertices.txt   each mesh's vertices as Blender holds them when exporting
#                       (mesh.vertices[i].co, mesh-local): "mesh NAME COUNT", then
#                       "x y z" lines (repr of the float32 values as Python floats)
#   grid_fbx_reimport.txt, grid_dae_reimport.txt
#                       the same for the meshes Blender's own importers make from
#                       the two files (bpy.ops.import_scene.fbx, wm.collada_import)
#   grid_info.txt       Blender version and the scene's unit settings
import bmesh
import bpy
import os
import sys

out = sys.argv[sys.argv.index("--") + 1]
os.makedirs(out, exist_ok=True)


def write_meshes(path, objs):
    with open(path, "w") as f:
        for ob in sorted(objs, key=lambda o: o.data.name):
            me = ob.data
            f.write("mesh %s %d\n" % (me.name, len(me.vertices)))
            for v in me.vertices:
                f.write("%r %r %r\n" % (v.co.x, v.co.y, v.co.z))


bpy.ops.wm.read_factory_settings(use_empty=True)
for n in (22, 21):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=n, y_subdivisions=n, size=2.0)
    grid = bpy.context.active_object
    if len(grid.data.vertices) == 22 * 22:
        break
    bpy.data.objects.remove(grid)
assert len(grid.data.vertices) == 484, len(grid.data.vertices)
grid.name = "Cloth"
grid.data.name = "ClothGrid"
grid.location = (1.0, 2.0, 3.0)
grid.rotation_euler = (0.3, 0.2, 0.1)
grid.scale = (1.5, 1.5, 1.5)

# A seam along the column x = 0 (between columns 10 and 11 there is none at 0 with
# 22 columns, so take the column nearest x = 0).
me = grid.data
xs = sorted({round(v.co.x, 6) for v in me.vertices})
xseam = xs[len(xs) // 2]
bm = bmesh.new()
bm.from_mesh(me)
for e in bm.edges:
    a, b = e.verts
    if abs(a.co.x - xseam) < 1e-6 and abs(b.co.x - xseam) < 1e-6:
        e.seam = True
bm.to_mesh(me)
bm.free()
bpy.context.view_layer.objects.active = grid
grid.select_set(True)
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.select_all(action="SELECT")
bpy.ops.uv.unwrap(method="ANGLE_BASED", margin=0.02)
bpy.ops.mesh.sort_elements(type="RANDOMIZE", elements={"VERT"}, seed=7)
bpy.ops.object.mode_set(mode="OBJECT")

bpy.ops.mesh.primitive_plane_add(size=0.5, location=(-3.0, 0.0, 0.25))
patch = bpy.context.active_object
patch.name = "Patch"
patch.data.name = "PatchMesh"

objs = [grid, patch]
write_meshes(os.path.join(out, "grid_vertices.txt"), objs)
us = bpy.context.scene.unit_settings
with open(os.path.join(out, "grid_info.txt"), "w") as f:
    f.write("blender %s\n" % bpy.app.version_string)
    f.write("unit_system %s scale_length %r\n" % (us.system, us.scale_length))

bpy.ops.object.select_all(action="DESELECT")
bpy.ops.export_scene.fbx(filepath=os.path.join(out, "grid.fbx"))
bpy.ops.wm.collada_export(filepath=os.path.join(out, "grid.dae"))

for kind, path in (("fbx", "grid.fbx"), ("dae", "grid.dae")):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if kind == "fbx":
        bpy.ops.import_scene.fbx(filepath=os.path.join(out, path))
    else:
        bpy.ops.wm.collada_import(filepath=os.path.join(out, path))
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    write_meshes(os.path.join(out, "grid_%s_reimport.txt" % kind), meshes)
print("make_fixtures: wrote", out)
