"""Pictures of trajectory files: render (GIF, frames), player (a self-contained HTML
page) and plot (observables), in 2D and 3D (mesh: shapes as faces, shading and the
camera; render3d: the 3D GIF). Reads rbsim.io only."""
