// Vectors, rotations and inertias for both dimensions, and the Dim<D> traits that the
// generic stages are written over (Rapier's dim2/dim3 aliases, as C++ templates).
//
//            Dim<2>                         Dim<3>
//   Vec      Vec2 (x, y)                    Vec3 (x, y, z)
//   Rot      Rot2: unit complex (c, s)      Quat: unit quaternion (w, x, y, z)
//   Ang      double (rad/s, N·m, kg·m²/s)   Vec3
//   Inertia  double (kg·m²)                 Sym3: symmetric 3×3 (kg·m²)
//   Tangent  double (along the one tangent)  Vec3 (in the tangent plane, world frame)
//
// Every type is a plain aggregate of doubles with no padding, so a std::vector of them
// is a C array that numpy can view as (n, k) float64.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace rbsim {

struct Vec2 {
  double x = 0.0, y = 0.0;
};
struct Vec3 {
  double x = 0.0, y = 0.0, z = 0.0;
};

constexpr Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
constexpr Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
constexpr Vec2 operator-(Vec2 a) { return {-a.x, -a.y}; }
constexpr Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
constexpr Vec2 operator*(Vec2 a, double s) { return {s * a.x, s * a.y}; }
constexpr Vec2& operator+=(Vec2& a, Vec2 b) { a.x += b.x; a.y += b.y; return a; }
constexpr Vec2& operator-=(Vec2& a, Vec2 b) { a.x -= b.x; a.y -= b.y; return a; }
constexpr double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
// a × b, the z component of the 3D cross product.
constexpr double cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
// ω × r for an angular velocity ω about z: (−ω r_y, ω r_x).
constexpr Vec2 cross(double w, Vec2 r) { return {-w * r.y, w * r.x}; }
// r × s for a scalar s about z: (s r_y, −s r_x).
constexpr Vec2 cross(Vec2 r, double s) { return {s * r.y, -s * r.x}; }
// The left perpendicular (−y, x): the tangent of a normal, turned a quarter counter-clockwise.
constexpr Vec2 perp(Vec2 a) { return {-a.y, a.x}; }
inline double length_squared(Vec2 a) { return dot(a, a); }
inline double length(Vec2 a) { return std::sqrt(dot(a, a)); }

constexpr Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
constexpr Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
constexpr Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
constexpr Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
constexpr Vec3 operator*(Vec3 a, double s) { return {s * a.x, s * a.y, s * a.z}; }
constexpr Vec3& operator+=(Vec3& a, Vec3 b) { a.x += b.x; a.y += b.y; a.z += b.z; return a; }
constexpr Vec3& operator-=(Vec3& a, Vec3 b) { a.x -= b.x; a.y -= b.y; a.z -= b.z; return a; }
constexpr double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
constexpr Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length_squared(Vec3 a) { return dot(a, a); }
inline double length(Vec3 a) { return std::sqrt(dot(a, a)); }

// A rotation in the plane as the unit complex number q = (cos θ, sin θ).
struct Rot2 {
  double c = 1.0, s = 0.0;
};
constexpr Vec2 rotate(Rot2 q, Vec2 p) { return {q.c * p.x - q.s * p.y, q.s * p.x + q.c * p.y}; }
constexpr Vec2 inv_rotate(Rot2 q, Vec2 p) { return {q.c * p.x + q.s * p.y, -q.s * p.x + q.c * p.y}; }
// The product q r: first r, then q.
constexpr Rot2 mul(Rot2 q, Rot2 r) { return {q.c * r.c - q.s * r.s, q.s * r.c + q.c * r.s}; }
inline Rot2 normalize(Rot2 q) {
  double inv = 1.0 / std::sqrt(q.c * q.c + q.s * q.s);
  return {q.c * inv, q.s * inv};
}

// A rotation in space as the unit quaternion (w, x, y, z).
struct Quat {
  double w = 1.0, x = 0.0, y = 0.0, z = 0.0;
};
constexpr Quat mul(Quat a, Quat b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
          a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}
inline Quat normalize(Quat q) {
  double inv = 1.0 / std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w * inv, q.x * inv, q.y * inv, q.z * inv};
}
// R(q) p = p + 2w (u × p) + 2 u × (u × p), u the vector part.
constexpr Vec3 rotate(Quat q, Vec3 p) {
  Vec3 u{q.x, q.y, q.z};
  Vec3 t = 2.0 * cross(u, p);
  return p + q.w * t + cross(u, t);
}
constexpr Vec3 inv_rotate(Quat q, Vec3 p) { return rotate(Quat{q.w, -q.x, -q.y, -q.z}, p); }

// A symmetric 3×3 matrix (an inertia tensor, kg·m², or its inverse).
struct Sym3 {
  double xx = 0.0, yy = 0.0, zz = 0.0, xy = 0.0, xz = 0.0, yz = 0.0;
};
constexpr Vec3 operator*(const Sym3& m, Vec3 v) {
  return {m.xx * v.x + m.xy * v.y + m.xz * v.z, m.xy * v.x + m.yy * v.y + m.yz * v.z,
          m.xz * v.x + m.yz * v.y + m.zz * v.z};
}
// A 3×3 matrix by rows (a rotation).
struct Mat3 {
  double r[3][3];
};
// The rotation matrix R of the unit quaternion q: R p = rotate(q, p) (to rounding), in
// 9 products where rotate takes 18, for a body's many points.
inline Mat3 rotation_matrix(Quat q) {
  const double xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
  const double xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z;
  const double wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
  return {{{1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)},
           {2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)},
           {2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)}}};
}
constexpr Vec3 operator*(const Mat3& m, Vec3 p) {
  return {m.r[0][0] * p.x + m.r[0][1] * p.y + m.r[0][2] * p.z,
          m.r[1][0] * p.x + m.r[1][1] * p.y + m.r[1][2] * p.z,
          m.r[2][0] * p.x + m.r[2][1] * p.y + m.r[2][2] * p.z};
}

// R M Rᵀ: a body-frame tensor seen in the world frame, through the rotation matrix R of
// the unit quaternion q.
inline Sym3 world_tensor(Quat q, const Sym3& m) {
  const Mat3 rm = rotation_matrix(q);
  const auto& r = rm.r;
  if (m.xy == 0.0 && m.xz == 0.0 && m.yz == 0.0) {
    // a diagonal M (a body's axes its principal axes): (R M Rᵀ)_ij = Σ_k R_ik M_k R_jk
    const double d[3] = {m.xx, m.yy, m.zz};
    auto at = [&](int i, int j) {
      return r[i][0] * d[0] * r[j][0] + r[i][1] * d[1] * r[j][1] + r[i][2] * d[2] * r[j][2];
    };
    return {at(0, 0), at(1, 1), at(2, 2), at(0, 1), at(0, 2), at(1, 2)};
  }
  const double s[3][3] = {{m.xx, m.xy, m.xz}, {m.xy, m.yy, m.yz}, {m.xz, m.yz, m.zz}};
  double a[3][3];  // R M
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a[i][j] = r[i][0] * s[0][j] + r[i][1] * s[1][j] + r[i][2] * s[2][j];
  auto at = [&](int i, int j) { return a[i][0] * r[j][0] + a[i][1] * r[j][1] + a[i][2] * r[j][2]; };
  return {at(0, 0), at(1, 1), at(2, 2), at(0, 1), at(0, 2), at(1, 2)};
}

// Bounds without square roots: |v| at most its components' absolute sum (m, m/s, ...);
// |R - I| of a rotation (the most it moves a point at unit distance from its centre,
// 2 sin(θ/2)) at most the sum over the unit complex number's (c - 1, s) or twice the
// quaternion's vector part's.
inline double norm1(Vec2 v) { return std::fabs(v.x) + std::fabs(v.y); }
inline double norm1(Vec3 v) { return std::fabs(v.x) + std::fabs(v.y) + std::fabs(v.z); }
inline double chord(Rot2 q) { return std::fabs(q.c - 1.0) + std::fabs(q.s); }
inline double chord(Quat q) { return 2.0 * (std::fabs(q.x) + std::fabs(q.y) + std::fabs(q.z)); }

template <int D>
struct Dim;

template <>
struct Dim<2> {
  static constexpr int dim = 2;
  // contact points per manifold (a face of a polygon touches at two)
  static constexpr int max_points = 2;
  using Vec = Vec2;
  using Rot = Rot2;
  using Ang = double;
  using Inertia = double;
  // a contact point's friction impulse: along the manifold's one tangent (N·s)
  using Tangent = double;
  // a body's rotation as a manifold keeps it, to tell whether the body has turned since
  // the manifold was found: its unwrapped angle (rad) (Contacts::ref_turn_a)
  using RefTurn = double;
  static constexpr Ang angular_zero() { return 0.0; }
  // world-frame inverse inertia times an angular quantity: in the plane, a scalar product
  static constexpr Ang apply_inv_inertia(double inv_i, Rot2, Ang a) { return inv_i * a; }
};

template <>
struct Dim<3> {
  static constexpr int dim = 3;
  static constexpr int max_points = 4;
  using Vec = Vec3;
  using Rot = Quat;
  using Ang = Vec3;
  using Inertia = Sym3;
  // a contact point's friction impulse: a world-frame vector in the tangent plane (N·s),
  // so that warm starting needs no tangent basis carried from step to step
  using Tangent = Vec3;
  using RefTurn = Quat;  // (Contacts::ref_turn_a; q and −q alike)
  static constexpr Ang angular_zero() { return {}; }
  // ω = R I_b⁻¹ Rᵀ a: the body-frame inverse tensor applied in the world frame
  static Ang apply_inv_inertia(const Sym3& inv_i, Quat q, Ang a) {
    return rotate(q, inv_i * inv_rotate(q, a));
  }
};

}  // namespace rbsim
