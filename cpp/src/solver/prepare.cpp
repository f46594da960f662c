// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void prepare_contacts(const Model<D>&, const State<D>&, Contacts<D>&, Soft, Soft) { throw std::logic_error("prepare: not ported"); }
template void prepare_contacts(const Model<2>&, const State<2>&, Contacts<2>&, Soft, Soft);
}  // namespace rbsim
