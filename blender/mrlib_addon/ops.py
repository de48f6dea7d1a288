"""The add-on's operators. Each mrlib command runs in a child process (``core.Pipeline``)
with mrlib's own Python; from a button the operator is modal, polling the child from a
window-manager timer, so Blender's UI never waits: progress goes to the status bar, the
window manager's progress and the panel, and the panel's Cancel stops the child. Called
from a script (``bpy.ops.mrlib.train()``, ``EXEC_DEFAULT``) or in background mode, an
operator waits for its command instead (headless use and tests)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import bpy
from bpy.props import CollectionProperty, StringProperty

from . import core, rig, scene_io
from .props import prefs

# the one command running (one at a time): its pipeline, title and last message
RUN: dict = {"pipeline": None, "title": "", "message": ""}


def running() -> core.Pipeline | None:
    p = RUN["pipeline"]
    return p if p is not None and not p.finished else None


def abs_dir(path: str) -> Path:
    """A folder setting as an absolute path; ``//`` (relative to an unsaved .blend) goes
    to the temporary folder."""
    path = path or "//mrlib_run"
    if path.startswith("//") and not bpy.data.filepath:
        return Path(tempfile.gettempdir()) / "mrlib_blender" / path[2:]
    return Path(bpy.path.abspath(path))


def abs_file(path: str) -> Path | None:
    return Path(bpy.path.abspath(path)) if path.strip() else None


def python(context) -> str:
    return core.resolve_python(prefs(context).python)


def threads(context) -> int | None:
    return prefs(context).threads or None


def new_run_folder(root: Path, stem: str) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    n = 1
    while (root / f"{stem}_{n:03d}").exists():
        n += 1
    folder = root / f"{stem}_{n:03d}"
    folder.mkdir()
    return folder


def _redraw() -> None:
    wm = bpy.context.window_manager
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type in ("VIEW_3D", "STATUSBAR"):
                area.tag_redraw()


class _Command:
    """Runs the ``core.Pipeline`` that ``build`` returns: modal from the UI, to the end
    from a script."""

    bl_options = {"REGISTER"}
    title = "mrlib"
    _timer = None

    def build(self, context) -> core.Pipeline:
        raise NotImplementedError

    def _start(self, context) -> core.Pipeline | None:
        if running() is not None:
            self.report({"ERROR"}, f"mrlib: {RUN['title']} is still running")
            return None
        try:
            pipe = self.build(context)
        except core.SetupError as e:
            self.report({"ERROR"}, f"mrlib: {e}")
            return None
        except OSError as e:
            where = f"{e.filename}: " if getattr(e, "filename", None) else ""
            self.report({"ERROR"}, f"mrlib: {where}{e.strerror or e}")
            return None
        RUN.update(pipeline=pipe, title=self.title, message="")
        return pipe

    def _finish(self, context, pipe: core.Pipeline) -> set[str]:
        for text in list(dict.fromkeys(pipe.warnings))[:3]:
            self.report({"WARNING"}, f"mrlib: {text}")
        if pipe.cancelled:
            self.report({"WARNING"}, f"mrlib: {self.title} cancelled")
            return {"CANCELLED"}
        if pipe.error is not None:
            self.report({"ERROR"}, f"mrlib: {pipe.error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"mrlib: {RUN['message'] or self.title + ' done'}")
        return {"FINISHED"}

    def execute(self, context):
        pipe = self._start(context)
        if pipe is None:
            return {"CANCELLED"}
        pipe.wait(on_event=lambda e: print(f"mrlib: {e.text}") if e.kind == "task" else None)
        return self._finish(context, pipe)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        pipe = self._start(context)
        if pipe is None:
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.25, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        pipe = RUN["pipeline"]
        pipe.poll()
        wm = context.window_manager
        wm.progress_update(int(100 * pipe.fraction))
        if context.workspace is not None:
            context.workspace.status_text_set(f"{pipe.status}  (Cancel: mrlib panel)")
        _redraw()
        if not pipe.finished:
            return {"PASS_THROUGH"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        return self._finish(context, pipe)


# -- training -------------------------------------------------------------------------------------
class MRLIB_OT_clip_add_selected(bpy.types.Operator):
    """Add the actions of the selected armatures (active action and NLA strips) as
    training clips, labelled by action name"""

    bl_idname = "mrlib.clip_add_selected"
    bl_label = "Add Selected Armatures' Actions"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.mrlib
        have = {(c.armature, c.action) for c in s.clips}
        added = 0
        for obj in context.selected_objects:
            if obj.type != "ARMATURE":
                continue
            for action in scene_io.clip_actions(obj):
                if (obj, action) in have:
                    continue
                clip = s.clips.add()
                clip.armature, clip.action, clip.label = obj, action, action.name
                added += 1
        if not added:
            self.report({"WARNING"}, "mrlib: no new action on the selected armatures")
            return {"CANCELLED"}
        s.clip_index = len(s.clips) - 1
        return {"FINISHED"}


class MRLIB_OT_clip_add_files(bpy.types.Operator):
    """Add motion files (BVH, SMPL/AMASS .npz) as training clips, labelled by file name"""

    bl_idname = "mrlib.clip_add_files"
    bl_label = "Add Motion Files"
    bl_options = {"REGISTER", "UNDO"}

    directory: StringProperty(subtype="DIR_PATH")
    files: CollectionProperty(type=bpy.types.OperatorFileListElement)
    filter_glob: StringProperty(default="*.bvh;*.npz", options={"HIDDEN"})

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        s = context.scene.mrlib
        have = {bpy.path.abspath(c.filepath) for c in s.clips if c.filepath}
        paths = [Path(bpy.path.abspath(self.directory)) / f.name for f in self.files if f.name]
        bad = [p.name for p in paths if p.suffix.lower() not in (".bvh", ".npz") or not p.is_file()]
        if bad:
            self.report({"ERROR"}, f"mrlib: not a .bvh or .npz file: {', '.join(bad[:3])}")
            return {"CANCELLED"}
        for path in paths:
            if str(path) not in have:
                clip = s.clips.add()
                clip.filepath, clip.label = str(path), path.stem
        s.clip_index = len(s.clips) - 1
        return {"FINISHED"}


class MRLIB_OT_clip_remove(bpy.types.Operator):
    """Remove the clip selected in the list"""

    bl_idname = "mrlib.clip_remove"
    bl_label = "Remove Clip"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.mrlib
        if 0 <= s.clip_index < len(s.clips):
            s.clips.remove(s.clip_index)
            s.clip_index = min(s.clip_index, len(s.clips) - 1)
        return {"FINISHED"}


def _model_trained(checkpoint: Path, labels: list[str]):
    def after() -> None:
        s = bpy.context.scene.mrlib
        s.checkpoint = str(checkpoint)
        s.labels = ",".join(dict.fromkeys(labels))
        s.num_levels = core.checkpoint_levels(checkpoint) or 0
        RUN["message"] = f"trained {checkpoint}"

    return after


class MRLIB_OT_train(_Command, bpy.types.Operator):
    """Export the clips as BVH (Blender's exporter) and train a model on them with mrlib's
    command line (mrlib train), in the background"""

    bl_idname = "mrlib.train"
    bl_label = "Train"
    title = "train"

    def build(self, context):
        s, scene = context.scene.mrlib, context.scene
        clips = [c for c in s.clips if c.use and (c.filepath or (c.armature and c.action))]
        if not clips:
            raise core.SetupError("no clips: add armatures' actions or motion files")
        py = python(context)
        out = abs_dir(s.out_dir)
        labels = [c.label.strip() or Path(c.filepath).stem or c.action.name for c in clips]
        stems = core.unique_stems(labels)
        paths = [
            Path(bpy.path.abspath(c.filepath)) if c.filepath
            else scene_io.export_bvh(scene, c.armature, out / "clips" / f"{stem}.bvh", c.action)
            for c, stem in zip(clips, stems, strict=True)
        ]  # fmt: skip
        model = out / "model"
        jm = abs_file(s.joint_map)
        argv = core.mrlib_command(py, *core.train_args(
            paths, labels, model, preset=s.preset, iterations=s.iterations or None,
            levels=s.levels or None, joint_map=jm, overwrite=s.overwrite,
            accept_retarget_error=s.accept_retarget_error, threads=threads(context),
        ))  # fmt: skip
        after = _model_trained(model / "checkpoint.pt", labels)
        return core.Pipeline([core.Step("train", argv, after=after)], name="mrlib train")


class MRLIB_OT_resume(_Command, bpy.types.Operator):
    """Continue training the checkpoint where it stopped (mrlib train --resume)"""

    bl_idname = "mrlib.resume"
    bl_label = "Resume"
    title = "resume"

    def build(self, context):
        s = context.scene.mrlib
        ckpt = _checkpoint(context)
        argv = core.mrlib_command(
            python(context), *core.resume_args(ckpt, threads=threads(context))
        )
        labels = core.split_labels(s.labels)
        return core.Pipeline(
            [core.Step("train", argv, after=_model_trained(ckpt, labels))], name="mrlib resume"
        )


class MRLIB_OT_labels(_Command, bpy.types.Operator):
    """Read the checkpoint's labels and levels (loads it in mrlib's Python)"""

    bl_idname = "mrlib.labels"
    bl_label = "Read Labels"
    title = "labels"

    def build(self, context):
        ckpt = _checkpoint(context)
        out = Path(tempfile.mkdtemp(prefix="mrlib_labels_")) / "labels.json"
        argv = core.bridge_args(python(context), "labels", ckpt, "--out", out)

        def after() -> None:
            import json

            d = json.loads(out.read_text(encoding="utf-8"))
            s2 = bpy.context.scene.mrlib
            s2.labels = ",".join(d["labels"])
            s2.num_levels = int(d["num_levels"])
            RUN["message"] = f"labels {', '.join(d['labels'])}; {d['num_levels']} levels"

        return core.Pipeline([core.Step("labels", argv, after=after)], name="mrlib labels")


class MRLIB_OT_check_python(_Command, bpy.types.Operator):
    """Check that the Python set in the preferences imports mrlib"""

    bl_idname = "mrlib.check_python"
    bl_label = "Check mrlib's Python"
    title = "check"

    def build(self, context):
        py = python(context)
        code = "import mrlib, sys; print('mrlib', mrlib.__file__, 'Python', sys.version.split()[0])"
        step = core.Step("check", [py, "-c", code])

        def after() -> None:
            lines = [e.text for e in RUN["pipeline"].job.events if e.kind == "info"]
            RUN["message"] = lines[-1] if lines else "mrlib imports"

        step.after = after
        return core.Pipeline([step], name="mrlib check")


# -- generation onto the rig ---------------------------------------------------------------------
def _target(context):
    arm = context.active_object
    if arm is None or arm.type != "ARMATURE":
        raise core.SetupError("make your armature the active object")
    return arm


def _rig_clip(context, arm, folder: Path) -> Path:
    """A BVH of ``arm`` whose reading calibrates the transfer: its training clip when it
    has one that still drives its bones (the calibration training used), else its action,
    else its current pose."""
    s = context.scene.mrlib
    action = next((c.action for c in s.clips if c.armature == arm and c.action
                   and scene_io.drives_pose(c.action, arm)), None)  # fmt: skip
    return scene_io.export_bvh(context.scene, arm, folder / "rig.bvh", action)


def _onto_rig_steps(
    context, arm, run: Path, produce: core.Step, action_name: str, before=()
) -> core.Pipeline:
    """The steps ``before``, ``produce`` (a command writing one .npz to ``run/sample``),
    then the bridge putting it onto ``arm``, then the new action."""
    s = context.scene.mrlib
    py = python(context)
    rig_bvh = _rig_clip(context, arm, run)
    jm = abs_file(s.joint_map)
    arm_name, start, body = arm.name, s.start_frame, s.body_mesh
    if body:
        argv = produce.argv
        produce.argv = (lambda: [*argv(), "--glb"]) if callable(argv) else [*argv, "--glb"]
    sample_dir = run / "sample"
    found: dict = {}

    def onto_rig_argv():
        npz = core.find_outputs(sample_dir, ".npz")
        if len(npz) != 1:
            raise core.SetupError(f"{sample_dir}: expected one .npz from mrlib, found {len(npz)}")
        found["npz"] = npz[0]
        return core.onto_rig_args(py, rig_bvh, npz[0], run / "rig_motion.json",
                                  out_bvh=run / f"{core.safe_file_stem(arm_name)}.bvh",
                                  joint_map=jm)  # fmt: skip

    def apply() -> None:
        motion = rig.RigMotion.from_json(run / "rig_motion.json")
        target = bpy.data.objects.get(arm_name)
        if target is None:
            raise core.SetupError(f"the armature {arm_name!r} is gone")
        name = action_name or found["npz"].stem
        action = scene_io.apply_rig_motion(bpy.context.scene, target, motion, name, start)
        RUN["message"] = (
            f"{action.name} on {arm_name}: {motion.num_frames} frames at {motion.fps:g} fps ({run})"
        )
        glb = core.find_outputs(sample_dir, ".glb")
        if body and glb:
            try:
                scene_io.import_body(glb[0], action.name)
                RUN["message"] += f"; body mesh from {glb[0].name}"
            except Exception as e:  # the importer's own failure: the action stands
                why = " ".join(str(e).split())[-160:]
                RUN["pipeline"].warnings.append(
                    f"the body mesh was not imported (Blender's glTF importer: {why}); "
                    f"it is in {glb[0]}"
                )

    onto = core.Step("onto rig", onto_rig_argv, after=apply)
    return core.Pipeline([*before, produce, onto], name=f"mrlib {produce.name}")


def _checkpoint(context) -> Path:
    ckpt = abs_file(context.scene.mrlib.checkpoint)
    if ckpt is None or not ckpt.is_file():
        raise core.SetupError(f"no checkpoint at {ckpt}: train a model first, or choose one")
    return ckpt


class MRLIB_OT_generate(_Command, bpy.types.Operator):
    """Generate motion with mrlib (mrlib sample) and put it on the active armature as a
    new action"""

    bl_idname = "mrlib.generate"
    bl_label = "Generate"
    title = "generate"

    action_name: StringProperty(name="Action name", description="empty: mrlib's file name")

    def build(self, context):
        s = context.scene.mrlib
        arm = _target(context)
        ckpt = _checkpoint(context)
        levels = s.num_levels or core.checkpoint_levels(ckpt) or 0
        cond = core.Condition(s.mode, label=s.label.strip(), coarse=s.coarse.strip(),
                              fine=s.fine.strip(), level=s.level, num_levels=levels,
                              weight=s.weight)  # fmt: skip
        cond.args()  # refuses a bad condition before anything is written
        action = arm.animation_data.action if arm.animation_data else None
        if (s.hold_keys or s.continue_action) and action is None:
            what = "keyframes to hold" if s.hold_keys else "action to continue"
            raise core.SetupError(f"{arm.name} has no {what}")
        # a bad combination of controls is refused before anything is written
        core.sample_args(ckpt, "-", cond, seconds=1.0, loop=s.loop, path=s.path_curve is not None,
                         keyframes=s.hold_keys, prefix=s.continue_action)  # fmt: skip
        fps = context.scene.render.fps / context.scene.render.fps_base
        seconds, keyframes, prefix, before = s.seconds, None, None, []
        if s.hold_keys:
            first = scene_io.action_frame_range(action)[0]
            keys = core.timeline_keys(scene_io.keyed_frames(action), first, s.start_frame, fps)
            seconds = core.keyframe_seconds(keys, s.seconds, fps)
        elif s.continue_action:
            first, last = scene_io.action_frame_range(action)
            seconds = s.seconds or (last - first + 1) / fps
        run = new_run_folder(abs_dir(s.out_dir) / "generated", core.safe_file_stem(arm.name))
        path = None
        if s.path_curve is not None:
            path = run / "path.csv"
            pts = scene_io.curve_ground_points(s.path_curve, arm)
            path.write_text(core.path_csv(pts), encoding="utf-8")
        py, jm = python(context), abs_file(s.joint_map)
        if s.hold_keys:
            clip, keyframes = scene_io.export_bvh(context.scene, arm, run / "keys.bvh"), run / "keys.npz"  # fmt: skip
            argv = core.keyframes_args(py, clip, ckpt, keys, keyframes, joint_map=jm)
            before.append(core.Step("keyframes", argv, weight=0.2))
        elif s.continue_action:
            clip, prefix = scene_io.export_bvh(context.scene, arm, run / "action.bvh"), run / "action.npz"  # fmt: skip
            before.append(core.Step("read action", core.read_args(py, clip, prefix, joint_map=jm), 0.1))  # fmt: skip
        argv = core.mrlib_command(py, *core.sample_args(
            ckpt, run / "sample", cond, seconds=seconds or None, seed=s.seed, loop=s.loop,
            path=path, keyframes=keyframes, prefix=prefix, raw=s.raw, threads=threads(context),
        ))  # fmt: skip
        sample = core.Step("sample", argv)
        return _onto_rig_steps(context, arm, run, sample, self.action_name, before=before)


class MRLIB_OT_restyle(_Command, bpy.types.Operator):
    """Restyle the active armature's action towards a label (mrlib restyle) into a new
    action"""

    bl_idname = "mrlib.restyle"
    bl_label = "Restyle Action"
    title = "restyle"

    action_name: StringProperty(name="Action name", description="empty: mrlib's file name")

    def build(self, context):
        s = context.scene.mrlib
        arm = _target(context)
        if arm.animation_data is None or arm.animation_data.action is None:
            raise core.SetupError(f"{arm.name} has no action to restyle")
        ckpt = _checkpoint(context)
        run = new_run_folder(abs_dir(s.out_dir) / "restyled", core.safe_file_stem(arm.name))
        clip = scene_io.export_bvh(context.scene, arm, run / "clip.bvh")
        py, jm, axes = python(context), abs_file(s.joint_map), run / "rig_axes.json"
        label, level, keep, seed = s.restyle_label.strip(), s.restyle_level, s.restyle_keep, s.seed
        n_threads = threads(context)
        core.restyle_args(ckpt, clip, label, run / "sample", keep=keep)  # its checks, now

        def restyle_argv():  # the action read in the axes of the clip the transfer uses
            return core.mrlib_command(py, *core.restyle_args(
                ckpt, clip, label, run / "sample", level=level or None, keep=keep, seed=seed,
                joint_map=jm, threads=n_threads, up_axis=core.read_up_axis(axes),
            ))  # fmt: skip

        # run / "rig.bvh": written by _onto_rig_steps before any step runs
        before = [core.Step("rig axes", core.axes_args(py, run / "rig.bvh", axes, joint_map=jm), 0.1)]  # fmt: skip
        restyle = core.Step("restyle", restyle_argv)
        return _onto_rig_steps(context, arm, run, restyle, self.action_name, before=before)


class MRLIB_OT_write_joint_map(_Command, bpy.types.Operator):
    """Write the joint map mrlib reads the active armature with (mrlib info --write-map),
    to edit and use as the joint map"""

    bl_idname = "mrlib.write_joint_map"
    bl_label = "Write Joint Map"
    title = "joint map"

    def build(self, context):
        s = context.scene.mrlib
        arm = _target(context)
        folder = abs_dir(s.out_dir)
        clip = _rig_clip(context, arm, folder / "joint_map")
        out = folder / f"joint_map_{core.safe_file_stem(arm.name)}.json"
        args = ["info", clip, "--write-map", out, "--overwrite"]
        if abs_file(s.joint_map):
            args += ["--joint-map", abs_file(s.joint_map)]
        argv = core.mrlib_command(python(context), *args)

        def after() -> None:
            bpy.context.scene.mrlib.joint_map = str(out)
            RUN["message"] = f"joint map of {arm.name}: {out}"

        return core.Pipeline([core.Step("info", argv, after=after)], name="mrlib info")


class MRLIB_OT_cancel(bpy.types.Operator):
    """Stop the running mrlib command (training saves its checkpoint: Resume continues)"""

    bl_idname = "mrlib.cancel"
    bl_label = "Cancel"

    @classmethod
    def poll(cls, context):
        return running() is not None

    def execute(self, context):
        pipe = running()
        if pipe is not None:
            pipe.cancel()
        return {"FINISHED"}


CLASSES = (
    MRLIB_OT_clip_add_selected,
    MRLIB_OT_clip_add_files,
    MRLIB_OT_clip_remove,
    MRLIB_OT_train,
    MRLIB_OT_resume,
    MRLIB_OT_labels,
    MRLIB_OT_check_python,
    MRLIB_OT_generate,
    MRLIB_OT_restyle,
    MRLIB_OT_write_joint_map,
    MRLIB_OT_cancel,
)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    pipe = running()
    if pipe is not None:
        pipe.cancel()
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
