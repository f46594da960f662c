// One output frame of a world, written into the rows of caller-owned arrays: the body
// origins and rotations, velocities, and the observables summed over the dynamic bodies.
// The run loop fills a block of frames this way in one call (advance_recording), so that
// writing every step costs no Python per frame.
#pragma once

#include <cstdint>

#include "rbsim/world.hpp"

namespace rbsim {

// Row pointers for one frame of N bodies (2D). Each may be null (not recorded).
struct FrameRow2 {
  double* position = nullptr;          // (N,2) m, body origin: x - R(q) com
  double* orientation = nullptr;       // (N,2) (cos θ, sin θ)
  double* angle = nullptr;             // (N,) rad, unwrapped
  double* velocity = nullptr;          // (N,2) m/s, centre of mass
  double* angular_velocity = nullptr;  // (N,) rad/s
  double* kinetic_energy = nullptr;    // J
  double* potential_energy = nullptr;  // J, -m g·x
  double* linear_momentum = nullptr;   // (2,) kg m/s
  double* angular_momentum = nullptr;  // kg m²/s about the world origin
  std::int64_t* contact_count = nullptr;
};

void record_frame(const World<2>& world, const FrameRow2& row);

}  // namespace rbsim
