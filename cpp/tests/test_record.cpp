// tools/record.cpp and tools/checkpoint.cpp in 3D: a frame's series and observables,
// its contact points, and a checkpoint that restores a 3D world bit for bit.
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "check.hpp"
#include "scene_builder3d.hpp"
#include "tools/checkpoint.hpp"
#include "tools/record.hpp"

using namespace rbsim;

namespace {

// Two bodies: a dynamic box with its COM off its origin, turned, moving and spinning,
// and a static body that the sums leave out.
World<3> two_bodies() {
  World<3> w;
  auto& m = w.model;
  m.body_type = {BodyType::Dynamic, BodyType::Static};
  m.body_mass = {2.0, INFINITY};
  m.body_inv_mass = {0.5, 0.0};
  m.body_inertia = {Sym3{1.0, 2.0, 3.0, 0.0, 0.0, 0.0}, Sym3{INFINITY, INFINITY, INFINITY, 0, 0, 0}};
  m.body_inv_inertia = {Sym3{1.0, 0.5, 1.0 / 3.0, 0.0, 0.0, 0.0}, Sym3{}};
  m.body_axes = {Quat{}, Quat{}};
  m.body_moments = {Vec3{1.0, 2.0, 3.0}, Vec3{INFINITY, INFINITY, INFINITY}};
  m.body_com = {Vec3{0.1, 0.0, 0.0}, Vec3{}};
  m.body_force.resize(2);
  m.body_force_arm.resize(2);
  m.body_torque.resize(2);
  m.gravity = {0.0, -9.81, 0.0};
  auto& s = w.state;
  const double c = std::cos(0.25), sn = std::sin(0.25);  // half of 0.5 rad about z
  s.body_x = {Vec3{1.0, 2.0, 3.0}, Vec3{0.0, -1.0, 0.0}};
  s.body_q = {Quat{c, 0.0, 0.0, sn}, Quat{}};
  s.body_v = {Vec3{0.5, -1.0, 2.0}, Vec3{}};
  s.body_l = {Vec3{0.3, 4.0, -0.6}, Vec3{}};
  s.body_w = {Dim<3>::apply_inv_inertia(m.body_inv_inertia[0], s.body_q[0], s.body_l[0]), Vec3{}};
  w.allocate();
  return w;
}

}  // namespace

// The frame holds the body origin x − R(q) com, the quaternion, v, ω and L as they are;
// the observables are ½ m v² + ½ ω·L, −m g·x, m v and x × m v + L of the dynamic body.
TEST(frame_3d_holds_the_series_and_observables) {
  World<3> w = two_bodies();
  double pos[6], ori[8], vel[6], ang[6], mom[6], ke = 0, pe = 0, p[3], l[3];
  std::int64_t contacts = -1;
  FrameRow3 row{pos, ori, nullptr, vel, ang, mom, &ke, &pe, p, l, &contacts};
  record_frame(w, row);
  // com (0.1, 0, 0) turned by 0.5 rad about z
  CHECK_NEAR(pos[0], 1.0 - 0.1 * std::cos(0.5), 1e-15);
  CHECK_NEAR(pos[1], 2.0 - 0.1 * std::sin(0.5), 1e-15);
  CHECK_NEAR(pos[2], 3.0, 1e-15);
  CHECK(pos[4] == -1.0);
  CHECK(ori[0] == std::cos(0.25) && ori[3] == std::sin(0.25) && ori[4] == 1.0);
  CHECK(vel[2] == 2.0 && mom[1] == 4.0 && ang[3] == 0.0);
  const Vec3 om = w.state.body_w[0], L = w.state.body_l[0];
  CHECK(ang[0] == om.x && ang[1] == om.y && ang[2] == om.z);
  CHECK_NEAR(ke, 0.5 * 2.0 * (0.25 + 1.0 + 4.0) + 0.5 * dot(om, L), 1e-13);
  CHECK_NEAR(pe, 2.0 * 9.81 * 2.0, 1e-13);
  CHECK(p[0] == 1.0 && p[1] == -2.0 && p[2] == 4.0);
  const Vec3 orbital = cross(Vec3{1.0, 2.0, 3.0}, Vec3{1.0, -2.0, 4.0});
  CHECK_NEAR(l[0], orbital.x + L.x, 1e-14);
  CHECK_NEAR(l[1], orbital.y + L.y, 1e-14);
  CHECK_NEAR(l[2], orbital.z + L.z, 1e-14);
  CHECK(contacts == 0);
}

// A 3D world restored from its checkpoint takes the next steps bit for bit as the world
// it was saved from (L and the quaternion included); a checkpoint of another size is
// refused and leaves the world as it was.
TEST(checkpoint_3d_restores_bit_for_bit) {
  for (Rotation r : {Rotation::Normalize, Rotation::Exact, Rotation::Split}) {
    World<3> a = two_bodies();
    a.config.dt = 1e-3;
    a.config.substeps = 2;
    a.config.rotation = r;
    std::int64_t taken = 0, bad = -1;
    a.advance(500, &taken, &bad);
    const auto bytes = save_checkpoint(a);
    World<3> b = two_bodies();
    b.config = a.config;
    load_checkpoint(b, bytes.data(), bytes.size());
    CHECK(b.step_index == 500);
    a.advance(300, &taken, &bad);
    b.advance(300, &taken, &bad);
    CHECK(std::memcmp(a.state.body_q.data(), b.state.body_q.data(), 2 * sizeof(Quat)) == 0);
    CHECK(std::memcmp(a.state.body_l.data(), b.state.body_l.data(), 2 * sizeof(Vec3)) == 0);
    CHECK(std::memcmp(a.state.body_x.data(), b.state.body_x.data(), 2 * sizeof(Vec3)) == 0);
  }
  World<3> a = two_bodies();
  World<2> flat;
  flat.model.body_type = {BodyType::Dynamic};
  const auto bytes = save_checkpoint(flat);
  bool refused = false;
  try {
    load_checkpoint(a, bytes.data(), bytes.size());
  } catch (const std::invalid_argument&) {
    refused = true;
  }
  CHECK(refused && a.step_index == 0 && a.state.body_l[0].y == 4.0);
}

// Shape kinds: each dimension takes its own (types.hpp), so a 2D table stays 2D-sized.
TEST(shape_kinds_by_dimension) {
  CHECK(valid_shape_kind<2>(0) && valid_shape_kind<2>(2) && !valid_shape_kind<2>(3));
  CHECK(valid_shape_kind<3>(3) && valid_shape_kind<3>(7) && !valid_shape_kind<3>(2));
  CHECK(!valid_shape_kind<3>(8) && !valid_shape_kind<2>(-1));
}

// A 1 m box of 1 kg resting on the plane y <= 0: after a step its four bottom corners are
// the contact points, on the plane (less half the soft contact's sag), the normal from
// the plane (the first body) up into the box, and their forces carry its weight.
TEST(contacts_of_a_resting_box_are_its_corners_with_normals_up) {
  test::SceneBuilder3 s;
  s.plane({0, 1, 0}, 0.0);
  s.box({0.25, 0.5, -0.5}, {0.5, 0.5, 0.5}, 1.0);
  World<3>& w = s.finish();
  std::int64_t taken = 0, bad = -1;
  CHECK(w.advance(30, &taken, &bad) == Status::Ok);
  std::int64_t body[8];
  double pos[12], normal[12], force[4];
  ContactRows<3> rows{4, body, pos, normal, force};
  CHECK(record_contacts(w, rows) == 4 && w.contact_count() == 4);
  double total = 0.0;
  for (int k = 0; k < 4; ++k) {
    CHECK(body[2 * k] == 0 && body[2 * k + 1] == 1);
    CHECK(normal[3 * k] == 0.0 && normal[3 * k + 1] == 1.0 && normal[3 * k + 2] == 0.0);
    CHECK(std::abs(pos[3 * k + 1]) < 1e-4);  // the sag of a 1 kg box: micrometres
    CHECK_NEAR(std::abs(pos[3 * k] - 0.25), 0.5, 1e-9);  // the corners, which stay put
    CHECK_NEAR(std::abs(pos[3 * k + 2] + 0.5), 0.5, 1e-9);
    total += force[k];
  }
  CHECK_NEAR(total, 9.81, 1e-9);  // N: the weight, at rest to round-off
  // rows too few for the frame: nothing written, the count returned
  force[0] = -1.0;
  ContactRows<3> short_rows{3, body, pos, normal, force};
  CHECK(record_contacts(w, short_rows) == 4 && force[0] == -1.0);
}

RBSIM_TEST_MAIN
