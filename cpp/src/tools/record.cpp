#include "record.hpp"

namespace rbsim {

void record_frame(const World<2>& world, const FrameRow2& row) {
  const auto& m = world.model;
  const auto& s = world.state;
  const int n = m.body_count();
  for (int i = 0; i < n; ++i) {
    const Vec2 x = s.body_x[i];
    const Rot2 q = s.body_q[i];
    if (row.position) {
      const Vec2 c = m.body_com[i];
      // the origin sits at -com from the COM, turned by q
      row.position[2 * i] = x.x - (q.c * c.x - q.s * c.y);
      row.position[2 * i + 1] = x.y - (q.s * c.x + q.c * c.y);
    }
    if (row.orientation) {
      row.orientation[2 * i] = q.c;
      row.orientation[2 * i + 1] = q.s;
    }
    if (row.angle) row.angle[i] = s.body_angle[i];
    if (row.velocity) {
      row.velocity[2 * i] = s.body_v[i].x;
      row.velocity[2 * i + 1] = s.body_v[i].y;
    }
    if (row.angular_velocity) row.angular_velocity[i] = s.body_w[i];
  }
  // sums over the dynamic bodies, in body order
  double translational = 0, rotational = 0, potential = 0, px = 0, py = 0, orbital = 0, spin = 0;
  for (int i = 0; i < n; ++i) {
    if (!m.is_dynamic(i)) continue;
    const double mass = m.body_mass[i], inertia = m.body_inertia[i];
    const Vec2 x = s.body_x[i], v = s.body_v[i];
    const double w = s.body_w[i];
    translational += mass * (v.x * v.x + v.y * v.y);
    rotational += inertia * w * w;
    potential -= mass * (x.x * m.gravity.x + x.y * m.gravity.y);
    px += mass * v.x;
    py += mass * v.y;
    orbital += mass * (x.x * v.y - x.y * v.x);
    spin += inertia * w;
  }
  if (row.kinetic_energy) *row.kinetic_energy = 0.5 * (translational + rotational);
  if (row.potential_energy) *row.potential_energy = potential;
  if (row.linear_momentum) {
    row.linear_momentum[0] = px;
    row.linear_momentum[1] = py;
  }
  if (row.angular_momentum) *row.angular_momentum = orbital + spin;
  if (row.contact_count) *row.contact_count = world.contact_count();
}

}  // namespace rbsim
