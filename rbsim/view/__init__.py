"""Pictures of trajectory files: render (GIF, frames), player (a self-contained HTML
page) and plot (observables). Reads rbsim.io only."""
