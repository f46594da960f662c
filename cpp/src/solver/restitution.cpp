// PLACEHOLDER: being ported from the numba engine; replaced before this lands.
#include <stdexcept>
#include "rbsim/stages.hpp"
namespace rbsim {
template <int D> void keep_solve_impulses(Contacts<D>&) { throw std::logic_error("keep: not ported"); }
template <int D> void apply_restitution(const Model<D>&, State<D>&, Contacts<D>&, double, double, double) { throw std::logic_error("restitution: not ported"); }
template void keep_solve_impulses(Contacts<2>&);
template void apply_restitution(const Model<2>&, State<2>&, Contacts<2>&, double, double, double);
}  // namespace rbsim
