"""rbcloth for Blender: bake a quad mesh as rbcloth cloth into a PC2 point cache.

Properties editor > Physics > rbcloth: on a mesh object, the pin vertex group, the
solver preset or a target strain, the frame range, the cache path (beside the
.blend, `//rbcloth/NAME.pc2`), and Bake. Any object can be tagged as a sphere, box
or mesh collider in the same panel; animated colliders are followed per frame.
The bake adds a Mesh Cache modifier that plays the cache exactly, and writes the
scene as rbcloth scene JSON beside it (`rbcloth run NAME.json` replays the bake).

The solver is the rbcloth binding and librbcloth.so shipped inside this add-on's
folder (rbcloth/), with the rbcloth-import helper beside the library.
"""
bl_info = {
    "name": "rbcloth",
    "author": "rbcloth",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Physics > rbcloth",
    "description": "Bake quad cloth with the rbcloth solver into a PC2 cache",
    "category": "Physics",
}

import os
import stat
import tempfile

import bpy

_here = os.path.dirname(os.path.abspath(__file__))
# Blender's add-on installer extracts the zip with zipfile, which drops the execute
# bit: give it back to the import helper the library spawns.
_helper = os.path.join(_here, "rbcloth", "rbcloth-import")
if os.path.exists(_helper) and not os.access(_helper, os.X_OK):
    os.chmod(_helper, os.stat(_helper).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)

from . import bake  # noqa: E402 (loads the binding and the library)



class RbclothSettings(bpy.types.PropertyGroup):
    collider: bpy.props.EnumProperty(
        name="Collider", default='NONE',
        items=[('NONE', "None", "Not a collider"),
               ('SPHERE', "Sphere", "A sphere of half the largest dimension around the origin"),
               ('BOX', "Box", "A box of the object's dimensions around its origin"),
               ('MESH', "Mesh", "The object's mesh, triangulated")])
    pin_group: bpy.props.StringProperty(name="Pin group",
                                        description="Vertices of this group (weight > 0) are pinned")
    preset: bpy.props.EnumProperty(
        name="Preset", default='CLOTH',
        items=[('CLOTH', "Cloth", "The default solve: red-black SOR, 480 substeps a second"),
               ('GAME_60HZ', "Game 60 Hz", "Target strain 5 % within 32 substeps x 8 iterations"),
               ('PAPER', "Paper", "The paper's fixed 11 RBGS iterations (far from converged)")])
    use_target_strain: bpy.props.BoolProperty(name="Target strain", default=False)
    target_strain: bpy.props.FloatProperty(name="Strain", default=0.05, min=1e-6, max=10.0,
                                           description="RMS relative strain each frame reaches")
    frame_start: bpy.props.IntProperty(name="Start", default=1, min=0)
    frame_end: bpy.props.IntProperty(name="End", default=120, min=1)
    stiffness: bpy.props.FloatProperty(name="Stiffness", default=1000.0, min=1e-3)
    vertex_mass: bpy.props.FloatProperty(name="Vertex mass", default=1e-3, min=1e-9,
                                         precision=6)
    damping: bpy.props.FloatProperty(name="Damping", default=0.0, min=0.0)
    thickness: bpy.props.FloatProperty(name="Thickness", default=0.0, min=0.0, precision=4)
    friction: bpy.props.FloatProperty(name="Friction", default=0.0, min=0.0)
    cache_path: bpy.props.StringProperty(name="Cache", subtype='FILE_PATH', default="",
                                         description="PC2 file; empty: //rbcloth/OBJECT.pc2")


def cache_path(ob):
    """Absolute path of the object's cache, and a note when the .blend is unsaved
    (then `//` has no folder: the cache goes to the temporary folder)."""
    p = ob.rbcloth.cache_path or "//rbcloth/%s.pc2" % bpy.path.clean_name(ob.name)
    if p.startswith("//") and not bpy.data.filepath:
        d = os.path.join(tempfile.gettempdir(), "rbcloth")
        return os.path.join(d, p[2:].replace("rbcloth/", "", 1)), (
            "the .blend is not saved: the cache went to %s" % d)
    return os.path.abspath(bpy.path.abspath(p)), None


def add_modifier(ob, path, start):
    """A Mesh Cache modifier that plays the cache exactly: PC2, frame mode, frame
    f shows sample f - start, default axes (the cache is in local coordinates), first
    in the stack (it replaces the mesh's own vertices, in their order)."""
    mod = ob.modifiers.get("rbcloth") or ob.modifiers.new("rbcloth", 'MESH_CACHE')
    mod.cache_format = 'PC2'
    mod.filepath = bpy.path.relpath(path) if bpy.data.filepath else path
    mod.time_mode = 'FRAME'
    mod.play_mode = 'SCENE'
    mod.frame_start = start
    mod.frame_scale = 1.0
    mod.forward_axis = 'POS_Y'
    mod.up_axis = 'POS_Z'
    mod.deform_mode = 'OVERWRITE'
    mod.factor = 1.0
    while ob.modifiers[0] != mod:
        bpy.ops.object.modifier_move_up({"object": ob}, modifier=mod.name)
    return mod


class RBCLOTH_OT_bake(bpy.types.Operator):
    """Simulate the active mesh with rbcloth and write its PC2 cache (Esc cancels:
    nothing is written)"""
    bl_idname = "rbcloth.bake"
    bl_label = "Bake rbcloth"
    bl_options = {'REGISTER'}

    _timer = None

    def _begin(self, context):
        ob = context.active_object
        try:
            path, note = cache_path(ob) if ob is not None else (None, None)
            if path:
                os.makedirs(os.path.dirname(path), exist_ok=True)
            self.baker = bake.Baker(context.scene, ob, path)
        except bake.BakeError as e:
            self.report({'ERROR'}, str(e))
            return False
        except OSError as e:
            self.report({'ERROR'}, "rbcloth: cannot write the cache: %s" % e)
            return False
        self.path, self.note = path, note
        context.window_manager.progress_begin(0, self.baker.frames)
        return True

    def _step(self, context):
        try:
            more = self.baker.step()
        except bake.rbcloth.Error as e:
            self._end(context, cancel=True)
            self.report({'ERROR'}, "rbcloth: frame %d: %s" % (self.baker.start + self.baker.k + 1, e))
            return None
        context.window_manager.progress_update(self.baker.k)
        return more

    def _end(self, context, cancel):
        context.window_manager.progress_end()
        if cancel:
            self.baker.cancel()
            return
        json_path = self.baker.finish()
        add_modifier(self.baker.ob, self.path, self.baker.start)
        self.report({'INFO'}, "rbcloth: baked %d frames to %s (scene %s)%s" % (
            self.baker.frames, self.path, os.path.basename(json_path),
            "; " + self.note if self.note else ""))

    def execute(self, context):
        # The whole bake in one call (scripts, background mode).
        if not self._begin(context):
            return {'CANCELLED'}
        while True:
            more = self._step(context)
            if more is None:
                return {'CANCELLED'}
            if not more:
                break
        self._end(context, cancel=False)
        return {'FINISHED'}

    def invoke(self, context, event):
        # In the UI: a frame per timer event, so the progress shows and Esc cancels.
        if not self._begin(context):
            return {'CANCELLED'}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.001, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC':
            self._stop_timer(context)
            self._end(context, cancel=True)
            self.report({'WARNING'}, "rbcloth: bake cancelled, nothing written")
            return {'CANCELLED'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        more = self._step(context)
        if more is None:
            self._stop_timer(context)
            return {'CANCELLED'}
        if not more:
            self._stop_timer(context)
            self._end(context, cancel=False)
            return {'FINISHED'}
        return {'RUNNING_MODAL'}

    def _stop_timer(self, context):
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None


class RBCLOTH_PT_physics(bpy.types.Panel):
    bl_label = "rbcloth"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "physics"

    @classmethod
    def poll(cls, context):
        return context.object is not None

    def draw(self, context):
        ob, s, layout = context.object, context.object.rbcloth, self.layout
        layout.prop(s, "collider")
        if s.collider != 'NONE':
            layout.prop(s, "friction")
            return
        if ob.type != 'MESH':
            layout.label(text="Cloth needs a mesh object")
            return
        layout.prop_search(s, "pin_group", ob, "vertex_groups")
        layout.prop(s, "preset")
        row = layout.row()
        row.prop(s, "use_target_strain")
        row.prop(s, "target_strain")
        row = layout.row(align=True)
        row.prop(s, "frame_start")
        row.prop(s, "frame_end")
        col = layout.column(align=True)
        for name in ("stiffness", "vertex_mass", "damping", "thickness", "friction"):
            col.prop(s, name)
        layout.prop(s, "cache_path")
        layout.operator(RBCLOTH_OT_bake.bl_idname, icon='PHYSICS')


classes = (RbclothSettings, RBCLOTH_OT_bake, RBCLOTH_PT_physics)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Object.rbcloth = bpy.props.PointerProperty(type=RbclothSettings)


def unregister():
    del bpy.types.Object.rbcloth
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
