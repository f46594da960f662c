"""Benchmarks: rbsim against pymunk on the same scenes, in the same process."""
