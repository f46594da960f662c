// The state: what changes every step (MuJoCo's mjData), at the centre of mass.
//
// In 2D body_w is the angular velocity (rad/s) and body_angle the accumulated,
// unwrapped angle. In 3D the angular state is body_l, the angular momentum (kg·m²/s,
// world frame, about the COM), as the notes recommend; body_w = R I_b⁻¹ Rᵀ L is kept
// beside it for the solver and output, and body_angle is empty.
#pragma once

#include <vector>

#include "math.hpp"

namespace rbsim {

template <int D>
struct State {
  using Vec = typename Dim<D>::Vec;
  using Rot = typename Dim<D>::Rot;
  using Ang = typename Dim<D>::Ang;

  std::vector<Vec> body_x;         // (N,) m, COM position
  std::vector<Rot> body_q;         // (N,) unit complex / unit quaternion
  std::vector<double> body_angle;  // (N,) rad, unwrapped (2D only)
  std::vector<Vec> body_v;         // (N,) m/s, COM velocity
  std::vector<Ang> body_w;         // (N,) rad/s, world frame
  std::vector<Ang> body_l;         // (N,) kg·m²/s, world frame about the COM (3D only)
};

// Each body's motion since the start of the step: the displacement of its COM and the
// rotation it turned through. The contact solver tracks separations with it.
template <int D>
struct BodyDelta {
  typename Dim<D>::Vec dx{};
  typename Dim<D>::Rot dq{};
};

}  // namespace rbsim
