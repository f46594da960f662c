// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void store_impulses(Contacts<D>&) { throw std::logic_error("store_impulses: not ported"); }
template void store_impulses(Contacts<2>&);
}  // namespace rbsim
