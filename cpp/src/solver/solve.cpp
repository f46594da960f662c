// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void solve_contacts(const Model<D>&, State<D>&, Contacts<D>&, double, bool, double, double, const std::int32_t*, std::int64_t) { throw std::logic_error("solve: not ported"); }
template void solve_contacts(const Model<2>&, State<2>&, Contacts<2>&, double, bool, double, double, const std::int32_t*, std::int64_t);
}  // namespace rbsim
