// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> std::int64_t support_order(const Model<D>&, Contacts<D>&) { throw std::logic_error("support_order: not ported"); }
template <int D> std::int64_t deep_region(const Model<D>&, Contacts<D>&, int) { throw std::logic_error("deep_region: not ported"); }
template <int D> void propagate_shock(const Model<D>&, State<D>&, Contacts<D>&, std::int64_t, double, double) { throw std::logic_error("shock: not ported"); }
template std::int64_t support_order(const Model<2>&, Contacts<2>&);
template std::int64_t deep_region(const Model<2>&, Contacts<2>&, int);
template void propagate_shock(const Model<2>&, State<2>&, Contacts<2>&, std::int64_t, double, double);
}  // namespace rbsim
