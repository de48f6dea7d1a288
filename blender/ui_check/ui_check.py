"""Runs inside a windowed Blender (``run.sh`` under Xvfb): installs the add-on zip, imports
two walks as armatures, then from a timer, as a user would from the panel: Train (modal,
polled), Generate a crossover onto the first armature, a long Train cancelled after 8 s;
screenshots while training, after generating and after cancelling; a log of the progress
fraction and status at each poll (``ui_log.json``)."""

import builtins
import json
import os
import sys
import time
import traceback

import addon_utils
import bpy

args = sys.argv[sys.argv.index("--") + 1 :]
zip_path, mrlib_python, work, clip_a, clip_b, out_dir = args
log = {"events": []}


def note(*a):
    log["events"].append(" ".join(str(x) for x in a))
    print("UI:", *a, flush=True)


addon_utils.enable("io_anim_bvh", default_set=True)
import io_anim_bvh.import_bvh as ib  # noqa: E402  (after the add-on is enabled)

ib.open = lambda f, mode="r", *a, **k: builtins.open(f, mode.replace("U", ""), *a, **k)
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
addon_utils.enable("mrlib_addon", default_set=True)
from mrlib_addon import ops as mops  # noqa: E402  (after the add-on is installed)

prefs = bpy.context.preferences.addons["mrlib_addon"].preferences
prefs.python, prefs.threads = mrlib_python, 1
scene = bpy.context.scene
for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
scene.render.fps = 15
rigs = []
for clip, name in ((clip_a, "walk_sad"), (clip_b, "walk_happy")):
    bpy.ops.import_anim.bvh(
        filepath=clip, global_scale=0.01, rotate_mode="NATIVE", axis_forward="-Z", axis_up="Y"
    )
    arm = bpy.context.active_object
    arm.name = "rig_" + name
    arm.animation_data.action.name = name
    rigs.append(arm)
rigs[1].location.x = 1.0
for o in bpy.context.view_layer.objects:
    o.select_set(o in rigs)
bpy.context.view_layer.objects.active = rigs[0]
bpy.ops.mrlib.clip_add_selected()
s = scene.mrlib
s.preset, s.iterations, s.levels, s.overwrite = "demo", 60, 4, True
s.out_dir = os.path.join(work, "run")


def view3d():
    win = bpy.context.window_manager.windows[0]
    for area in win.screen.areas:
        if area.type == "VIEW_3D":
            region = next(r for r in area.regions if r.type == "WINDOW")
            return win, area, region
    raise RuntimeError("no 3D view")


win, area, region = view3d()
space = area.spaces.active
space.show_region_ui = True
ui = next(r for r in area.regions if r.type == "UI")
try:
    ui.active_panel_category = "mrlib"
    note("category set", ui.active_panel_category)
except Exception as e:
    note("category not settable:", e)


def shot(name):
    path = os.path.join(out_dir, name)
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.screen.screenshot(filepath=path)
    note("screenshot", path)


def invoke(op, **kw):
    with bpy.context.temp_override(
        window=win, area=area, region=region, active_object=bpy.context.view_layer.objects.active
    ):
        r = op("INVOKE_DEFAULT", **kw)
    note("invoke", op.idname(), r)
    return r


state = {"phase": "start", "t0": time.monotonic(), "shots": 0}


def step():
    try:
        return _step()
    except Exception:
        note("EXC", traceback.format_exc())
        finish()
        return None


def finish():
    # where the sidebar and the status bar are in the screenshots (compose.py crops them)
    log["window"] = [win.width, win.height]
    log["sidebar"] = [ui.x - win.x if ui.x >= win.x else ui.x, ui.y, ui.width, ui.height]
    bar = next((a for a in win.screen.areas if a.type == "STATUSBAR"), None)
    log["statusbar"] = [bar.x, bar.y, bar.width, bar.height] if bar else None
    json.dump(log, open(os.path.join(out_dir, "ui_log.json"), "w"), indent=1)
    bpy.ops.wm.quit_blender()


def _step():
    ph = state["phase"]
    pipe = mops.RUN["pipeline"]
    t = time.monotonic() - state["t0"]
    if ph == "start":
        invoke(bpy.ops.mrlib.train)
        state.update(phase="training", t1=time.monotonic())
        return 0.5
    if ph == "training":
        note(
            f"t={t:.1f} training fraction={pipe.fraction:.2f} status={pipe.status!r} finished={pipe.finished} ws_status"
        )
        if not pipe.finished and state["shots"] == 0 and time.monotonic() - state["t1"] > 4:
            shot("ui_training.png")
            state["shots"] = 1
        if pipe.finished:
            note(
                "train done error=", pipe.error, "msg=", mops.RUN["message"], "ckpt=", s.checkpoint
            )
            for o in bpy.context.view_layer.objects:
                o.select_set(o == rigs[0])
            bpy.context.view_layer.objects.active = rigs[0]
            s.mode, s.coarse, s.fine, s.level, s.seconds, s.seed = (
                "crossover",
                "walk_sad",
                "walk_happy",
                2,
                3.0,
                3,
            )
            invoke(bpy.ops.mrlib.generate)
            state["phase"] = "generating"
        return 0.5
    if ph == "generating":
        note(f"t={t:.1f} generate fraction={pipe.fraction:.2f} status={pipe.status!r}")
        if pipe.finished:
            note(
                "generate done error=",
                pipe.error,
                "msg=",
                mops.RUN["message"],
                "action=",
                rigs[0].animation_data.action.name,
            )
            scene.frame_set(10)
            state["phase"] = "shot2"
        return 0.5
    if ph == "shot2":
        shot("ui_generated.png")
        s.iterations, s.overwrite = 5000, True
        s.out_dir = os.path.join(work, "run_cancel")
        invoke(bpy.ops.mrlib.train)
        state.update(phase="to_cancel", t2=time.monotonic())
        return 0.5
    if ph == "to_cancel":
        note(f"t={t:.1f} long train fraction={pipe.fraction:.2f} status={pipe.status!r}")
        if time.monotonic() - state["t2"] > 8 and not pipe.cancelled:
            with bpy.context.temp_override(window=win, area=area, region=region):
                note("cancel ->", bpy.ops.mrlib.cancel())
            state["t3"] = time.monotonic()
        if pipe.finished:
            job = pipe.job
            note(
                "after cancel: finished",
                pipe.finished,
                "cancelled",
                pipe.cancelled,
                "rc",
                job.returncode if job else None,
                "secs to stop",
                round(time.monotonic() - state.get("t3", 0), 1),
                "status",
                pipe.status,
            )
            ck = os.path.join(work, "run_cancel", "model", "checkpoint.pt")
            note("checkpoint after cancel exists:", os.path.exists(ck))
            shot("ui_cancelled.png")
            finish()
            return None
        return 0.5


open(os.path.join(out_dir, "ready"), "w").write("1")
bpy.app.timers.register(step, first_interval=6.0)
