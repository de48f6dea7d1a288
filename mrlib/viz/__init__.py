"""Pictures: matplotlib figures (``plots``), 3D renders and players (``render``, pyvista)
and notebook widgets (``widgets``, ipywidgets). The only package that imports a drawing
library; each does so inside the function that draws, so importing it stays light.
"""

from mrlib.viz import plots, render

__all__ = ["plots", "render"]
