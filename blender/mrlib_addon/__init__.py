"""mrlib for Blender: train mrlib's multi-resolution motion GANs on your armatures' actions
and generate new motion onto your rig, from View3D > Sidebar > mrlib.

No torch inside Blender: every mrlib step runs in a child process with the Python that
has mrlib installed (Edit > Preferences > Add-ons > mrlib), through mrlib's command line
(``python -m mrlib ...``) and the add-on's ``bridge.py``. ``core`` (no ``bpy``) holds the
logic that needs no Blender; ``props``, ``ops``, ``scene_io`` and ``panel`` the Blender
side. Documentation: docs/blender.md in the mrlib repository.
"""

bl_info = {
    "name": "mrlib",
    "author": "mrlib contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > mrlib",
    "description": "Train multi-resolution motion GANs on your actions and generate new "
    "motion onto your rig, through mrlib's command line (no torch in Blender)",
    "category": "Animation",
}

_MODULES = ("props", "ops", "panel")


def register():
    import importlib

    for name in _MODULES:
        importlib.import_module(f"{__package__}.{name}").register()


def unregister():
    import importlib

    for name in reversed(_MODULES):
        importlib.import_module(f"{__package__}.{name}").unregister()
