// Vocabularies shared by the model, the stages and the bindings, defined once. The
// integer values are the ones the Python front writes into the model's arrays
// (rbsim/constants.py says the same).
#pragma once

#include <cstdint>

namespace rbsim {

enum class ShapeKind : std::int32_t { Circle = 0, Polygon = 1, Segment = 2 };
inline constexpr int SHAPE_KIND_COUNT = 3;

enum class BodyType : std::int8_t { Dynamic = 0, Static = 1, Kinematic = 2 };

// How two shapes' coefficients combine into one contact's.
enum class MixRule : std::int32_t { Sqrt = 0, Multiply = 1, Min = 2, Max = 3 };

// What World::advance returns.
enum class Status : std::int32_t { Ok = 0, NeedCapacity = 1, NonFinite = 2 };

}  // namespace rbsim
