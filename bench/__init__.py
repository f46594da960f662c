"""Benchmarks: rbsim against pymunk on the same scenes, in the same process."""


def print_header(columns: str) -> None:
    """Print a table's column line and a rule of its width under it."""
    print(columns)
    print("-" * len(columns))
