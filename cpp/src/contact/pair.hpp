// One pair's narrowphase as the manifold stage runs it (manifold.cpp), for a stage that
// collides a pair of its own (collide/continuous.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "collide/narrow2d.hpp"
#include "collide/narrow3d.hpp"
#include "rbsim/contacts.hpp"
#include "rbsim/model.hpp"
#include "rbsim/state.hpp"

namespace rbsim {

template <int D>
using PairOut = std::conditional_t<D == 2, Manifold2, Manifold3>;

// Combine two shapes' coefficients by the scene's mixing rule.
inline double mix(double a, double b, MixRule rule) {
  switch (rule) {
    case MixRule::Sqrt:
      // one material's (a = b): √(a·a) rounds to a itself in binary floating point where
      // a² neither overflows nor underflows, so no root is taken (a pile's every pair)
      if (a == b && a >= 0x1p-500 && a <= 0x1p500) return a;
      return std::sqrt(a * b);
    case MixRule::Multiply: return a * b;
    case MixRule::Min: return std::min(a, b);
    default: return std::max(a, b);
  }
}

// Shapes a and b at the step's start (the transform stage's world shapes), at the
// tolerance scale `scale` and speculative distance `spec` (m): the manifold's point count
// (0: apart beyond spec), its normal from b towards a.
template <int D>
int collide_pair(const Model<D>& model, const Contacts<D>& c, int a, int b, double scale,
                 double spec, PairOut<D>& out);

// Whether the manifold `out` (npts points) of shapes a and b is one the manifold stage
// drops because a neighbour holds the body there: a static segment's joint with the one
// that continues it (2D), or a face of a static polytope that others cover.
template <int D>
bool held_by_neighbour_at(const Model<D>& model, const State<D>& st, const Contacts<D>& c, int a,
                          int b, const PairOut<D>& out, int npts);

}  // namespace rbsim
