// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "narrow2d.hpp"
namespace rbsim {
int collide2d(const ShapeRef2&, const ShapeRef2&, const Vec2*, const Vec2*, double, Manifold2&) {
  throw std::logic_error("collide2d: not ported");
}
}  // namespace rbsim
