"""The sidebar panel: View3D > Sidebar (N) > mrlib."""

from __future__ import annotations

import bpy

from .ops import RUN, running


class MRLIB_UL_clips(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_prop, index=0):
        row = layout.row(align=True)
        row.prop(item, "use", text="")
        row.prop(item, "label", text="", emboss=False, icon="ACTION")
        sub = row.row()
        sub.enabled = False
        if item.filepath:
            sub.label(text=bpy.path.basename(item.filepath), icon="FILE")
            return
        arm = item.armature.name if item.armature else "?"
        act = item.action.name if item.action else "?"
        sub.label(text=f"{arm} / {act}")


class _Panel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "mrlib"


class MRLIB_PT_main(_Panel, bpy.types.Panel):
    bl_label = "mrlib"

    def draw(self, context):
        layout = self.layout
        pipe = running()
        if pipe is not None:
            box = layout.box()
            percent = f"{RUN['title']}: {100 * pipe.fraction:.0f} %"
            if hasattr(box, "progress"):  # Blender 4.0+
                box.progress(factor=pipe.fraction, type="BAR", text=percent)
            else:
                box.label(text=percent, icon="TIME")
            step = pipe.job.status if pipe.job is not None else pipe.status
            box.label(text=f"{step} ({pipe.job.elapsed() if pipe.job else 0:.0f} s)")
            box.operator("mrlib.cancel", icon="CANCEL")
        elif RUN["pipeline"] is not None:
            last = RUN["pipeline"]
            if last.cancelled:
                layout.label(text=f"{RUN['title']}: cancelled", icon="CANCEL")
            elif last.error:
                layout.label(text=last.error, icon="ERROR")
            elif RUN["message"]:
                layout.label(text=RUN["message"], icon="INFO")
        s = context.scene.mrlib
        col = layout.column(align=True)
        col.label(text="Output folder")
        col.prop(s, "out_dir", text="")
        col.label(text="Joint map (optional)")
        col.prop(s, "joint_map", text="")
        col.label(text="Checkpoint")
        row = col.row(align=True)
        row.prop(s, "checkpoint", text="")
        row.operator("mrlib.labels", text="", icon="FILE_REFRESH")
        if s.labels:
            layout.label(text=f"{s.num_levels} levels: {s.labels}")


class MRLIB_PT_train(_Panel, bpy.types.Panel):
    bl_label = "Train"
    bl_parent_id = "MRLIB_PT_main"

    def draw(self, context):
        layout = self.layout
        s = context.scene.mrlib
        row = layout.row()
        row.template_list("MRLIB_UL_clips", "", s, "clips", s, "clip_index", rows=3)
        col = row.column(align=True)
        col.operator("mrlib.clip_add_selected", text="", icon="ADD")
        col.operator("mrlib.clip_add_files", text="", icon="FILEBROWSER")
        col.operator("mrlib.clip_remove", text="", icon="REMOVE")
        layout.prop(s, "preset")
        col = layout.column(align=True)
        col.prop(s, "iterations")
        col.prop(s, "levels")
        layout.prop(s, "accept_retarget_error")
        layout.prop(s, "overwrite")
        row = layout.row(align=True)
        row.enabled = running() is None
        row.operator("mrlib.train", icon="PLAY")
        row.operator("mrlib.resume", icon="RECOVER_LAST")


class MRLIB_PT_generate(_Panel, bpy.types.Panel):
    bl_label = "Generate"
    bl_parent_id = "MRLIB_PT_main"

    def draw(self, context):
        layout = self.layout
        s = context.scene.mrlib
        layout.prop(s, "mode", expand=True)
        if s.mode == "label":
            layout.prop(s, "label")
        else:
            layout.prop(s, "coarse", text="Coarse" if s.mode == "crossover" else "Label A")
            layout.prop(s, "fine", text="Fine" if s.mode == "crossover" else "Label B")
            if s.mode == "crossover":
                layout.prop(s, "level")
                if s.num_levels:
                    layout.label(text=f"levels 1-{s.level}: coarse, {s.level + 1}-{s.num_levels}: fine")  # fmt: skip
            else:
                layout.prop(s, "weight")
        col = layout.column(align=True)
        col.prop(s, "seconds")
        col.prop(s, "seed")
        layout.prop(s, "path_curve")
        row = layout.row(align=True)
        row.prop(s, "loop")
        row.prop(s, "raw")
        row = layout.row(align=True)
        row.prop(s, "hold_keys")
        row.prop(s, "continue_action")
        layout.prop(s, "body_mesh")
        layout.prop(s, "start_frame")
        arm = context.active_object
        target = arm.name if arm is not None and arm.type == "ARMATURE" else None
        col = layout.column()
        col.enabled = running() is None and target is not None
        col.operator("mrlib.generate", text=f"Generate onto {target or '(select an armature)'}",
                     icon="ARMATURE_DATA")  # fmt: skip


class MRLIB_PT_restyle(_Panel, bpy.types.Panel):
    bl_label = "Restyle"
    bl_parent_id = "MRLIB_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        s = context.scene.mrlib
        layout.prop(s, "restyle_label")
        row = layout.row(align=True)
        row.prop(s, "restyle_level")
        row.prop(s, "restyle_keep", text="")
        col = layout.column()
        col.enabled = running() is None
        col.operator("mrlib.restyle", icon="MOD_TIME")
        col.operator("mrlib.write_joint_map", icon="GROUP_BONE")


CLASSES = (MRLIB_UL_clips, MRLIB_PT_main, MRLIB_PT_train, MRLIB_PT_generate, MRLIB_PT_restyle)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
