"""What the add-on reads from and writes to the Blender scene (needs ``bpy``): armature
actions out as BVH clips (Blender's own BVH exporter), a curve out as a path, and a motion
the bridge put onto a rig in as a new action (pose-bone keys)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import bpy
from mathutils import Quaternion

from . import core, rig


def action_frame_range(action) -> tuple[int, int]:
    lo, hi = action.frame_range
    return int(round(lo)), max(int(round(hi)), int(round(lo)) + 1)


def export_bvh(scene, arm, path: str | Path, action=None) -> Path:
    """``arm`` playing ``action`` (default: its own; none: its current pose, two frames)
    written as a BVH by Blender's exporter: armature space, Blender units, each bone's own
    rotation order. The armature's action, the scene's frame and range are restored."""
    from io_anim_bvh import export_bvh as exporter

    bad = core.bvh_unsafe_names(b.name for b in arm.data.bones)
    if bad:
        raise core.SetupError(
            f"{arm.name}: bone names a BVH cannot hold (spaces or braces): {', '.join(bad[:5])}"
        )
    if not arm.data.bones:
        raise core.SetupError(f"{arm.name}: the armature has no bones")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if arm.animation_data is None:
        arm.animation_data_create()
    ad = arm.animation_data
    old_action, frame = ad.action, scene.frame_current
    try:
        if action is not None:
            ad.action = action
        if ad.action is not None:
            start, end = action_frame_range(ad.action)
        else:
            start, end = frame, frame + 1
        exporter.write_armature(
            SimpleNamespace(object=arm, scene=scene), str(path), start, end,
            global_scale=1.0, rotate_mode="NATIVE", root_transform_only=False,
        )  # fmt: skip
    finally:
        if ad.action != old_action:
            ad.action = old_action
        scene.frame_set(frame)
    return path


def clip_actions(arm) -> list:
    """The actions of an armature: its active one, then those of its NLA strips."""
    out = []
    ad = arm.animation_data
    if ad is None:
        return out
    if ad.action is not None:
        out.append(ad.action)
    for track in ad.nla_tracks:
        for strip in track.strips:
            if strip.action is not None and strip.action not in out:
                out.append(strip.action)
    return out


def action_fcurves(action) -> list:
    """The F-curves of ``action``: its own list, or those of its layers' strips (the
    layered actions of Blender 4.4+, where the list may be gone)."""
    fcurves = getattr(action, "fcurves", None)
    if fcurves is not None:
        return list(fcurves)
    out = []
    for layer in getattr(action, "layers", ()):
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", ()):
                out.extend(bag.fcurves)
    return out


def keyed_frames(action) -> list[float]:
    """The frames at which ``action`` keys any pose bone (its keyframes on the timeline)."""
    frames = set()
    for fc in action_fcurves(action):
        if fc.data_path.startswith("pose.bones["):
            frames.update(float(k.co[0]) for k in fc.keyframe_points)
    return sorted(frames)


def drives_pose(action, arm) -> bool:
    """Whether ``action`` keys the rotations ``arm``'s bones read (an action keyed in Euler
    angles does not move bones set to quaternions since)."""
    prop = {"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}
    keyed = {fc.data_path for fc in action_fcurves(action)}
    for pb in arm.pose.bones:
        path = f'pose.bones["{bpy.utils.escape_identifier(pb.name)}"]'
        rotations = {p for p in keyed if p.startswith(path + ".rotation_")}
        if rotations and f"{path}.{prop.get(pb.rotation_mode, 'rotation_euler')}" not in rotations:
            return False
    return True


def curve_ground_points(curve, arm) -> list[tuple[float, float]]:
    """The points of ``curve`` (evaluated, in order) in ``arm``'s armature space, on the
    ground: ``(x, y)``."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = curve.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        to_arm = arm.matrix_world.inverted() @ curve.matrix_world
        pts = [to_arm @ v.co for v in mesh.vertices]
    finally:
        ev.to_mesh_clear()
    out: list[tuple[float, float]] = []
    for p in pts:
        if not out or (p.x - out[-1][0]) ** 2 + (p.y - out[-1][1]) ** 2 > 1e-12:
            out.append((p.x, p.y))
    return out


def import_body(path: str | Path, name: str) -> list:
    """The objects of a .glb mrlib wrote (its skinned body and the body's skeleton), imported
    by Blender's glTF importer; the parentless ones named after ``name``."""
    import addon_utils

    addon_utils.enable("io_scene_gltf2", default_set=False)
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=str(path))
    new = [o for o in bpy.data.objects if o not in before]
    for o in new:
        if o.parent is None:
            o.name = f"{name} body"
    return new


def _new_fcurve(action, obj, data_path: str, index: int, group: str):
    if hasattr(action, "fcurve_ensure_for_datablock"):  # Blender 4.4+: layered actions
        try:  # group_name: Blender 5.0; 4.4 and 4.5 group nothing
            return action.fcurve_ensure_for_datablock(obj, data_path, index=index, group_name=group)  # fmt: skip
        except TypeError:
            return action.fcurve_ensure_for_datablock(obj, data_path, index=index)
    return action.fcurves.new(data_path, index=index, action_group=group)


def _key(fc, frames: list[float], values: list[float]) -> None:
    fc.keyframe_points.add(len(frames))
    co = [c for f, v in zip(frames, values, strict=True) for c in (f, v)]
    fc.keyframe_points.foreach_set("co", co)
    fc.update()


def apply_rig_motion(scene, arm, motion: rig.RigMotion, name: str, start: float = 1.0):
    """A new action ``name`` on ``arm`` holding ``motion`` (keys at every motion frame, at
    the scene's frame rate from ``start``), made the armature's active action. Bones the
    motion does not drive keep no keys; their location is reset to the rest pose."""
    bones = arm.pose.bones
    missing = motion.missing_bones(b.name for b in bones)
    if missing:
        raise core.SetupError(
            f"{arm.name} has no bones {missing[:5]}: the armature changed since its clip was "
            "exported"
        )
    fps = scene.render.fps / scene.render.fps_base
    frames = rig.key_frames(motion.num_frames, motion.fps, fps, start)
    action = bpy.data.actions.new(name)
    if arm.animation_data is None:
        arm.animation_data_create()
    old = arm.animation_data.action
    if old is not None and old.users <= 1:  # the new action replaces it: keep it in the file
        old.use_fake_user = True
    arm.animation_data.action = action
    for bone_name in motion.bones:
        if bone_name not in bones:  # the exporter's dummy root
            continue
        pb = bones[bone_name]
        rest = tuple(pb.bone.matrix_local.to_quaternion())
        quats = rig.continuous(rig.basis_from_local(q, rest) for q in motion.rotations[bone_name])
        path = f'pose.bones["{bpy.utils.escape_identifier(bone_name)}"]'
        mode = pb.rotation_mode
        if mode == "QUATERNION":
            channels, prop = list(zip(*quats, strict=True)), "rotation_quaternion"
        elif mode == "AXIS_ANGLE":
            aa = []
            for q in quats:
                axis, angle = Quaternion(q).to_axis_angle()
                aa.append((angle, *axis))
            channels, prop = list(zip(*aa, strict=True)), "rotation_axis_angle"
        else:
            eulers, prev = [], None
            for q in quats:
                e = (
                    Quaternion(q).to_euler(mode)
                    if prev is None
                    else Quaternion(q).to_euler(mode, prev)
                )
                eulers.append(tuple(e))
                prev = e
            channels, prop = list(zip(*eulers, strict=True)), "rotation_euler"
        for i, values in enumerate(channels):
            _key(_new_fcurve(action, arm, f"{path}.{prop}", i, bone_name), frames, list(values))
        if bone_name == motion.mover:
            head = tuple(pb.bone.head_local)
            locs = [rig.root_location(p, head, rest) for p in motion.positions]
            for i, values in enumerate(zip(*locs, strict=True)):
                _key(
                    _new_fcurve(action, arm, f"{path}.location", i, bone_name), frames, list(values)
                )
        else:
            pb.location = (0.0, 0.0, 0.0)
    action.use_fake_user = False
    scene.frame_set(int(start))
    return action
