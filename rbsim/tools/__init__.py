"""Tools over the engines, each reaching them through rbsim.engines' one interface:
compare (rbsim against pymunk), sweep (speed against error), reference (the exact
answers the sweep measures against), measure (one penetration ruler), hard (the hard
cases), report (the work-precision report)."""
