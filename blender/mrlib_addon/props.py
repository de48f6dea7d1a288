"""The add-on's settings: its preferences (which Python runs mrlib) and the scene's
``mrlib`` settings (clips, training, generation)."""

from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from . import core

ADDON = __package__


def prefs(context=None):
    context = context or bpy.context
    return context.preferences.addons[ADDON].preferences


class MRLIB_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    python: StringProperty(
        name="mrlib's Python",
        description="The Python that has mrlib installed: its executable, or the virtual "
        "environment's folder (e.g. the mrlib checkout's .venv). Torch runs there, never "
        "inside Blender",
        subtype="FILE_PATH",
    )
    threads: IntProperty(
        name="Threads",
        description="torch threads of each mrlib command (0: mrlib's default)",
        default=0,
        min=0,
        max=256,
    )

    def draw(self, context):
        col = self.layout.column()
        col.prop(self, "python")
        col.prop(self, "threads")
        col.operator("mrlib.check_python", icon="CHECKMARK")


def _armature_poll(self, obj):
    return obj.type == "ARMATURE"


def _curve_poll(self, obj):
    return obj.type == "CURVE"


def _labels(self, context, edit_text):
    settings = context.scene.mrlib
    labels = core.split_labels(settings.labels)
    return [lab for lab in labels if edit_text.lower() in lab.lower()] or labels


class MRLIB_PG_clip(bpy.types.PropertyGroup):
    armature: PointerProperty(name="Armature", type=bpy.types.Object, poll=_armature_poll)
    action: PointerProperty(name="Action", type=bpy.types.Action)
    filepath: StringProperty(name="File", description="a motion file (instead of an action)",
                             subtype="FILE_PATH")  # fmt: skip
    label: StringProperty(name="Label", description="The clip's label (condition)")
    use: BoolProperty(name="Use", default=True)


class MRLIB_PG_settings(bpy.types.PropertyGroup):
    # -- training
    clips: CollectionProperty(type=MRLIB_PG_clip)
    clip_index: IntProperty()
    preset: EnumProperty(
        name="Preset",
        items=[
            ("demo", "demo", "the clips at 30 fps, 1200/800/300/200 iterations (~8 min on a CPU)"),
            ("preview", "preview", "15 fps, 800/600/400/300 iterations (~5 min on a CPU)"),
            ("tutorial", "tutorial", "800 iterations per block (~20 min on a CPU)"),
            ("paper", "paper", "the paper's schedule (use a GPU)"),
        ],
        default="demo",
    )
    iterations: IntProperty(
        name="Iterations", description="iterations per block (0: the preset's)", default=0, min=0
    )
    levels: IntProperty(
        name="Levels", description="pyramid levels (0: the preset's)", default=0, min=0, max=16
    )
    out_dir: StringProperty(
        name="Output folder",
        description="Where the clips, the model and the generated motion go",
        default="//mrlib_run",
        subtype="DIR_PATH",
    )
    joint_map: StringProperty(
        name="Joint map",
        description="A JSON joint map {smpl_joint: bone} for rigs mrlib does not recognise "
        "(empty: mrlib's shipped maps or its recognition)",
        subtype="FILE_PATH",
    )
    accept_retarget_error: BoolProperty(
        name="Accept retarget error",
        description="Train even on clips mrlib retargets with a large error",
        default=False,
    )
    overwrite: BoolProperty(
        name="Overwrite", description="Replace a model already in the output folder"
    )
    # -- the model
    checkpoint: StringProperty(name="Checkpoint", subtype="FILE_PATH")
    labels: StringProperty(name="Labels", description="the model's labels, comma-separated")
    num_levels: IntProperty(name="Levels of the model", default=0, min=0)
    # -- generation
    mode: EnumProperty(
        name="Condition",
        items=[
            ("label", "Label", "one label at every level"),
            ("crossover", "Crossover", "a coarse label's motion with a fine label's detail"),
            ("blend", "Blend", "two labels' embeddings interpolated"),
        ],
        default="label",
    )
    label: StringProperty(name="Label", search=_labels)
    coarse: StringProperty(name="Coarse", description="label of levels 1..k", search=_labels)
    fine: StringProperty(name="Fine", description="label of the levels above k", search=_labels)
    level: IntProperty(name="Crossover level", description="k", default=2, min=1)
    weight: FloatProperty(name="Blend weight", description="weight of the second label",
                          default=0.5, min=0.0, max=1.0)  # fmt: skip
    seconds: FloatProperty(name="Seconds", description="length (0: a training clip's)",
                           default=0.0, min=0.0, soft_max=60.0)  # fmt: skip
    seed: IntProperty(name="Seed", default=0, min=0)
    loop: BoolProperty(name="Loop", description="a seamless loop (--loop)")
    path_curve: PointerProperty(name="Path", description="walk along this curve (--path)",
                                type=bpy.types.Object, poll=_curve_poll)  # fmt: skip
    hold_keys: BoolProperty(
        name="Hold keys",
        description="hold the poses the armature's action keys on the timeline, at their "
        "frames from the start frame (--keyframes); Seconds 0: up to the last key",
    )
    continue_action: BoolProperty(
        name="Continue",
        description="the armature's action followed by Seconds of new motion (--continue)",
    )
    raw: BoolProperty(name="Raw", description="skip mrlib's foot-contact clean-up")
    body_mesh: BoolProperty(
        name="Body mesh",
        description="also import mrlib's skinned body (SMPL topology, glTF, --glb) moving "
        "with the result",
    )
    start_frame: IntProperty(name="Start frame", default=1)
    # -- restyle
    restyle_label: StringProperty(name="Label", search=_labels)
    restyle_level: IntProperty(name="Level", description="0: mrlib's default (L - 2)",
                               default=0, min=0)  # fmt: skip
    restyle_keep: EnumProperty(
        name="Keep",
        items=[
            ("coarse", "Coarse", "the action's coarse motion, the label's detail"),
            ("detail", "Detail", "the label's coarse motion, the action's detail"),
        ],
        default="coarse",
    )


CLASSES = (MRLIB_AP_preferences, MRLIB_PG_clip, MRLIB_PG_settings)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.mrlib = PointerProperty(type=MRLIB_PG_settings)


def unregister():
    del bpy.types.Scene.mrlib
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
