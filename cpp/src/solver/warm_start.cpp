// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void warm_start(const Model<D>&, State<D>&, Contacts<D>&) { throw std::logic_error("warm_start: not ported"); }
template void warm_start(const Model<2>&, State<2>&, Contacts<2>&);
}  // namespace rbsim
