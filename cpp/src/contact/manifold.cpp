// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void update_manifolds(const Model<D>&, const State<D>&, Contacts<D>&, const Grid<D>&, std::int64_t, MixRule, MixRule, double) { throw std::logic_error("update_manifolds: not ported"); }
template void update_manifolds(const Model<2>&, const State<2>&, Contacts<2>&, const Grid<2>&, std::int64_t, MixRule, MixRule, double);
}  // namespace rbsim
