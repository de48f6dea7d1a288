"""Pictures: matplotlib figures (``plots``; those of condition control in
``control_plots``), 3D renders and players (``render``: stick figures; ``meshes``: mesh
stills and GIFs; ``player``: the playable notebook view) and notebook widgets
(``widgets``: crossover and restyle; ``constraint_views``: paths, body parts,
in-betweens; their shared plumbing in ``widget_kit``). The only package that imports a
drawing library (matplotlib, pyvista, ipywidgets), each inside the function that draws,
so importing it stays light. The names below are what a notebook needs:
``mrlib.viz.render_meshes(...)``, ``mrlib.viz.interactive_crossover(...)``.
"""

from mrlib.viz.constraint_views import interactive_inbetween, interactive_parts, interactive_path
from mrlib.viz.control_plots import (
    plot_condition_fidelity,
    plot_crossover_evidence,
    plot_ground_paths,
    plot_nearest_sequence,
)
from mrlib.viz.meshes import (
    crop_to_bodies,
    evenly_spaced_frames,
    render_mesh_animation,
    render_meshes,
    save_gif,
)
from mrlib.viz.player import play_motion
from mrlib.viz.plots import (
    plot_contacts,
    plot_coverage_strip,
    plot_evaluation,
    plot_quality_curve,
    plot_segmentation,
    save_titled_image,
    segmentation_frame_map,
)
from mrlib.viz.render import animate_skeleton, plot_skeleton_strip
from mrlib.viz.widgets import interactive_crossover, interactive_restyle

__all__ = [
    # figures
    "plot_contacts",
    "plot_evaluation",
    "plot_coverage_strip",
    "plot_segmentation",
    "segmentation_frame_map",
    "plot_quality_curve",
    "save_titled_image",
    "plot_crossover_evidence",
    "plot_nearest_sequence",
    "plot_condition_fidelity",
    "plot_ground_paths",
    # 3D
    "render_meshes",
    "render_mesh_animation",
    "save_gif",
    "evenly_spaced_frames",
    "crop_to_bodies",
    "plot_skeleton_strip",
    "animate_skeleton",
    "play_motion",
    # widgets
    "interactive_crossover",
    "interactive_restyle",
    "interactive_path",
    "interactive_parts",
    "interactive_inbetween",
]
