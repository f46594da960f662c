// Vocabularies shared by the model, the stages and the bindings, defined once. The
// integer values are the ones the Python front writes into the model's arrays
// (rbsim/constants.py says the same).
#pragma once

#include <cstdint>

namespace rbsim {

// Shape kinds as Model.shape_kind stores them: the 2D kinds first, then the 3D kinds
// (rbsim/scene/types.py: SHAPE_KIND_CODE, SHAPE_KIND_CODE_3D).
enum class ShapeKind : std::int32_t {
  Circle = 0, Polygon = 1, Segment = 2,                         // 2D
  Sphere = 3, Box = 4, Capsule = 5, Convex = 6, Plane = 7,      // 3D
};
// The 2D kinds are [0, SHAPE_KIND_COUNT): the 2D narrowphase's [kind][kind] table is
// this size. The 3D kinds are [SHAPE_KIND_FIRST_3D, SHAPE_KIND_END_3D).
inline constexpr int SHAPE_KIND_COUNT = 3;
inline constexpr int SHAPE_KIND_FIRST_3D = 3;
inline constexpr int SHAPE_KIND_END_3D = 8;

// The shape kinds a world of dimension D takes.
template <int D>
constexpr bool valid_shape_kind(int kind) {
  return D == 2 ? (kind >= 0 && kind < SHAPE_KIND_COUNT)
                : (kind >= SHAPE_KIND_FIRST_3D && kind < SHAPE_KIND_END_3D);
}

enum class BodyType : std::int8_t { Dynamic = 0, Static = 1, Kinematic = 2 };

// How two shapes' coefficients combine into one contact's.
enum class MixRule : std::int32_t { Sqrt = 0, Multiply = 1, Min = 2, Max = 3 };

// How a body's rotation is advanced over a substep h (dynamics/integrate.cpp).
//   Normalize: the notes' q <- normalize(q + h ω×q) (2D) / normalize(q + (h/2) ω q) (3D);
//   Exact: q <- exp(h ω) q with ω held over the substep;
//   Split (3D): the free rigid body split into rotations about its principal axes,
//     symmetric (1-2-3-2-1), each exact; keeps L exactly and is symplectic. In 2D it is
//     Exact (one axis: the split is exact).
enum class Rotation : std::int32_t { Normalize = 0, Exact = 1, Split = 2 };

// What World::advance returns.
// TooManyPairs: a step would hold more contact pairs than World::pair_limit (no step is
// taken). Interrupted: World::interrupt asked advance to stop (between two steps, or
// inside a long one, which leaves the world torn). Torn: advance was asked to step a
// torn world (World::torn).
enum class Status : std::int32_t {
  Ok = 0, NeedCapacity = 1, NonFinite = 2, TooManyPairs = 3, Interrupted = 4, Torn = 5
};

}  // namespace rbsim
