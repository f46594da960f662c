// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void transform_shapes(const Model<D>&, const State<D>&, Contacts<D>&, double) { throw std::logic_error("transform_shapes: not ported"); }
template void transform_shapes(const Model<2>&, const State<2>&, Contacts<2>&, double);
}  // namespace rbsim
