import bpy

bpy.context.preferences.view.show_splash = False
bpy.ops.wm.save_userpref()
bpy.ops.wm.quit_blender()
