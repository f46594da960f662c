"""Files and what is measured into them: the trajectory file (H5MD layout; its public
reader and writer) and the observables written with every frame."""
