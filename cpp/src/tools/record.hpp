// One output frame of a world, written into the rows of caller-owned arrays: the body
// origins and rotations, velocities, and the observables summed over the dynamic bodies.
// The run loop fills a block of frames this way in one call (advance_recording), so that
// writing every step costs no Python per frame.
//
// The quaternion's sign is written as the engine holds it; the trajectory writer makes
// it continuous from frame to frame (rbsim/io/trajectory.py), for every engine alike.
#pragma once

#include <cstdint>

#include "rbsim/world.hpp"

namespace rbsim {

// Doubles per body of each series, by dimension.
template <int D>
struct FrameWidth {
  static constexpr int vec = D;                // position, velocity
  static constexpr int rot = D == 2 ? 2 : 4;   // orientation: (cos θ, sin θ) / (w, x, y, z)
  static constexpr int ang = D == 2 ? 1 : 3;   // angular velocity and momentum
};

// Row pointers for one frame of N bodies. Each may be null (not recorded).
template <int D>
struct FrameRow {
  double* position = nullptr;          // (N,D) m, body origin: x - R(q) com
  double* orientation = nullptr;       // (N,2) (cos θ, sin θ) / (N,4) (w, x, y, z)
  double* angle = nullptr;             // (N,) rad, unwrapped (2D only)
  double* velocity = nullptr;          // (N,D) m/s, centre of mass
  double* angular_velocity = nullptr;  // (N,) / (N,3) rad/s, world frame
  double* body_angular_momentum = nullptr;  // (N,3) kg m²/s, world frame about each COM (3D only)
  double* kinetic_energy = nullptr;    // J: ½ m v² + ½ I ω² (2D) / ½ m v² + ½ ω·L (3D)
  double* potential_energy = nullptr;  // J, -m g·x
  double* linear_momentum = nullptr;   // (D,) kg m/s
  double* angular_momentum = nullptr;  // (1,) / (3,) kg m²/s about the world origin: Σ x × p + spin
  std::int64_t* contact_count = nullptr;
};
using FrameRow2 = FrameRow<2>;
using FrameRow3 = FrameRow<3>;

template <int D>
void record_frame(const World<D>& world, const FrameRow<D>& row);

// Rows for the contact points of frames (output.contacts: points), caller-owned, with
// room for `capacity` points from these pointers on. Each pointer may be null.
template <int D>
struct ContactRows {
  std::int64_t capacity = 0;
  std::int64_t* body = nullptr;  // (C,2) the two bodies (a, b), scene order
  double* position = nullptr;    // (C,D) m, world frame, at the end of the step
  double* normal = nullptr;      // (C,D) unit, from body a towards body b (b is pushed along it)
  double* force = nullptr;       // (C,) N, the normal impulse of the step's last substep / h
};

// The contact points of the last step that pushed (those contact_count counts), written
// into `rows` when they fit in its capacity. Returns how many there are (written or not).
// A point is the midpoint of its anchors on the two bodies, carried with each body's
// motion through the step, so that it sits where the bodies meet at the frame's time.
template <int D>
std::int64_t record_contacts(const World<D>& world, const ContactRows<D>& rows);

}  // namespace rbsim
