"""The engine's tuning constants, as the compiled engine has them.

cpp/include/rbsim/constants.hpp defines every one once, with its unit, a typical value
and what changing it does; the front reads them from the engine, so the two cannot
disagree. Values are SI: metres, seconds, radians.
"""

from __future__ import annotations

from .core import CONSTANTS as _ENGINE

# the tolerances below hold for shapes of SCALE_LENGTH (m) and larger (constants.hpp)
SCALE_LENGTH: float = _ENGINE["SCALE_LENGTH"]  # m
STIFFNESS_LENGTH: float = _ENGINE["STIFFNESS_LENGTH"]  # m: smaller pairs are stiffer
HEAVY_RATIO: float = _ENGINE["HEAVY_RATIO"]  # a heavy body on a light one
SPECULATIVE_DISTANCE: float = _ENGINE["SPECULATIVE_DISTANCE"]  # m
LINEAR_SLOP: float = _ENGINE["LINEAR_SLOP"]  # m, the collision tolerance
AABB_MARGIN: float = _ENGINE["AABB_MARGIN"]  # m
FLUSH_DISTANCE: float = _ENGINE["FLUSH_DISTANCE"]  # m: static faces this near are one surface
COVERED_MIN_SCALE: float = _ENGINE["COVERED_MIN_SCALE"]  # and only for pairs this large
CONTACT_HERTZ: float = _ENGINE["CONTACT_HERTZ"]  # Hz, soft contact stiffness
CONTACT_DAMPING_RATIO: float = _ENGINE["CONTACT_DAMPING_RATIO"]
CONTACT_PUSH_MAX_VELOCITY: float = _ENGINE["CONTACT_PUSH_MAX_VELOCITY"]  # m/s
DEEP_OVERLAP: float = _ENGINE["DEEP_OVERLAP"]  # m
DEEP_RELAX_FACTOR: int = _ENGINE["DEEP_RELAX_FACTOR"]
DEEP_RELAX_REACH: int = _ENGINE["DEEP_RELAX_REACH"]  # contacts
STATIC_OVERLAP_LIMIT: float = _ENGINE["STATIC_OVERLAP_LIMIT"]  # m
DYNAMIC_OVERLAP_LIMIT: float = _ENGINE["DYNAMIC_OVERLAP_LIMIT"]  # m: between dynamic bodies
OVERLAP_LIMIT_PASSES: int = _ENGINE["OVERLAP_LIMIT_PASSES"]
STILL_DISTANCE: float = _ENGINE["STILL_DISTANCE"]  # m
STILL_ANGLE: float = _ENGINE["STILL_ANGLE"]  # rad
MAX_ROTATION: float = _ENGINE["MAX_ROTATION"]  # rad: 3D, a body's most turn in a substep
RESTITUTION_PASSES: int = _ENGINE["RESTITUTION_PASSES"]
IMPACT_GAP: float = _ENGINE["IMPACT_GAP"]  # m: an impact at a wall is resolved within it
REFERENCE_FACE_TOLERANCE: float = _ENGINE["REFERENCE_FACE_TOLERANCE"]  # m
SEGMENT_SKIN: float = _ENGINE["SEGMENT_SKIN"]  # m
BIG_MAX: int = _ENGINE["BIG_MAX"]  # broadphase: shapes tested against every shape
