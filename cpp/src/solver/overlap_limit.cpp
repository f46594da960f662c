// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void limit_static_overlap(const Model<D>&, State<D>&, Contacts<D>&, double) { throw std::logic_error("overlap: not ported"); }
template void limit_static_overlap(const Model<2>&, State<2>&, Contacts<2>&, double);
}  // namespace rbsim
