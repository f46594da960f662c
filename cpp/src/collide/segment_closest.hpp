// Closest points of two segments, for any vector type with dot, +, − and scaling (Vec2,
// Vec3): the 3D narrowphase's edge–edge and capsule cases. It is the arithmetic of
// narrow2d.cpp's segment_closest_fractions (Vec2), written once over the vector type so
// that the 2D narrowphase can take it too.
#pragma once

#include <algorithm>

#include "rbsim/constants.hpp"

namespace rbsim {

struct SegmentFractions {
  double s, t;
};

// Fractions (s, t) of the closest points p1 + s (q1 − p1) and p2 + t (q2 − p2).
//
// An end point is reported exactly as 0.0 or 1.0 (by clamping); parallel segments start
// from s = 0; a segment shorter than LINEAR_EPSILON (m) is its first point.
template <class Vec>
inline SegmentFractions segment_closest_fractions(Vec p1, Vec q1, Vec p2, Vec q2) {
  const auto clamp01 = [](double x) { return std::min(std::max(x, 0.0), 1.0); };
  const Vec d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
  constexpr double tiny = constants::LINEAR_EPSILON * constants::LINEAR_EPSILON;
  if (a <= tiny && e <= tiny) return {0.0, 0.0};
  if (a <= tiny) return {0.0, clamp01(f / e)};
  const double c = dot(d1, r);
  if (e <= tiny) return {clamp01(-c / a), 0.0};
  const double b = dot(d1, d2);
  const double denom = a * e - b * b;
  double s = 0.0;
  if (denom > 1.0e-12 * a * e) s = clamp01((b * f - c * e) / denom);
  double t = (b * s + f) / e;
  if (t < 0.0) {
    t = 0.0;
    s = clamp01(-c / a);
  } else if (t > 1.0) {
    t = 1.0;
    s = clamp01((b - c) / a);
  }
  return {s, t};
}

}  // namespace rbsim
