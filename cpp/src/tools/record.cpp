#include "record.hpp"

#include <cstring>

namespace rbsim {
namespace {

// Copy a plain aggregate of doubles (Vec, Rot, Ang) into dst[0..k).
template <class T>
inline void put(double* dst, const T& v) {
  static_assert(sizeof(T) % sizeof(double) == 0);
  std::memcpy(dst, &v, sizeof(T));
}

}  // namespace

template <int D>
void record_frame(const World<D>& world, const FrameRow<D>& row) {
  using W = FrameWidth<D>;
  using Vec = typename Dim<D>::Vec;
  using Ang = typename Dim<D>::Ang;
  const auto& m = world.model;
  const auto& s = world.state;
  const int n = m.body_count();
  for (int i = 0; i < n; ++i) {
    const Vec x = s.body_x[i];
    const auto q = s.body_q[i];
    // the origin sits at -com from the COM, turned by q
    if (row.position) put(row.position + W::vec * i, x - rotate(q, m.body_com[i]));
    if (row.orientation) put(row.orientation + W::rot * i, q);
    if constexpr (D == 2) {
      if (row.angle) row.angle[i] = s.body_angle[i];
    }
    if (row.velocity) put(row.velocity + W::vec * i, s.body_v[i]);
    if (row.angular_velocity) put(row.angular_velocity + W::ang * i, s.body_w[i]);
    if constexpr (D == 3) {
      if (row.body_angular_momentum) put(row.body_angular_momentum + 3 * i, s.body_l[i]);
    }
  }
  // sums over the dynamic bodies, in body order
  double translational = 0, rotational = 0, potential = 0;
  Vec p{};
  Ang orbital = Dim<D>::angular_zero(), spin = Dim<D>::angular_zero();
  for (int i = 0; i < n; ++i) {
    if (!m.is_dynamic(i)) continue;
    const double mass = m.body_mass[i];
    const Vec x = s.body_x[i], v = s.body_v[i];
    const Ang w = s.body_w[i];
    translational += mass * dot(v, v);
    potential -= mass * dot(x, m.gravity);
    p += mass * v;
    orbital += mass * cross(x, v);
    if constexpr (D == 2) {
      rotational += m.body_inertia[i] * w * w;
      spin += m.body_inertia[i] * w;
    } else {
      // ω·L = ωᵀ I_w ω, with L the state
      rotational += dot(w, s.body_l[i]);
      spin += s.body_l[i];
    }
  }
  if (row.kinetic_energy) *row.kinetic_energy = 0.5 * (translational + rotational);
  if (row.potential_energy) *row.potential_energy = potential;
  if (row.linear_momentum) put(row.linear_momentum, p);
  if (row.angular_momentum) put(row.angular_momentum, orbital + spin);
  if (row.contact_count) *row.contact_count = world.contact_count();
}

template <int D>
std::int64_t record_contacts(const World<D>& world, const ContactRows<D>& rows) {
  using Vec = typename Dim<D>::Vec;
  if (!world.model.has_shapes) return 0;
  const auto& c = world.contacts;
  const auto& s = world.state;
  const std::int64_t m = c.count.manifolds;
  // the same points as store_impulses counts: those that pushed in the step
  std::int64_t count = 0;
  for (std::int64_t i = 0; i < m; ++i)
    for (int k = 0; k < c.points[i]; ++k)
      if (pushed_in_step(c, i, k)) ++count;
  if (count > rows.capacity) return count;
  // 1/s: the step's impulse over the step (its mean force), where the step kept it
  // (Contacts::record_impulses), else the last substep's over the substep
  const double per_time = c.record_impulses ? 1.0 / world.config.dt  // 1/s
                                            : world.config.substeps / world.config.dt;
  std::int64_t r = 0;
  for (std::int64_t i = 0; i < m; ++i) {
    const int a = c.body_a[i], b = c.body_b[i];
    // the anchors are world-frame lever arms at the step's start: turn them with each
    // body's rotation since then (body_delta), from its COM now
    const auto& da = c.body_delta[a];
    const auto& db = c.body_delta[b];
    const Vec n = -c.normal[i];  // the store's normal points from b towards a
    for (int k = 0; k < c.points[i]; ++k) {
      if (!pushed_in_step(c, i, k)) continue;
      const Vec pa = s.body_x[a] + rotate(da.dq, c.anchor_a[i][k]);
      const Vec pb = s.body_x[b] + rotate(db.dq, c.anchor_b[i][k]);
      if (rows.body) {
        rows.body[2 * r] = a;
        rows.body[2 * r + 1] = b;
      }
      if (rows.position) put(rows.position + D * r, 0.5 * (pa + pb));
      if (rows.normal) put(rows.normal + D * r, n);
      if (rows.force)
        rows.force[r] = (c.record_impulses ? c.step_impulse[i][k] : c.normal_impulse[i][k]) * per_time;
      ++r;
    }
  }
  return count;
}

template void record_frame(const World<2>&, const FrameRow<2>&);
template void record_frame(const World<3>&, const FrameRow<3>&);
template std::int64_t record_contacts(const World<2>&, const ContactRows<2>&);
template std::int64_t record_contacts(const World<3>&, const ContactRows<3>&);

}  // namespace rbsim
