// The penetration ruler of the hard cases and the reports (rbsim/reference.py's
// penetration): the separation (m) of pairs of shapes at a pose, given their world
// vertices. A pure function over arrays, outside the step: the engine does not use it.
//
// A shape is a core (its vertices: one for a circle, two for a segment, three or more
// for a convex polygon, counter-clockwise) swollen by its radius. The separation of two
// shapes is the signed distance of their cores minus both radii: negative when they
// overlap, by the overlap's depth.
#pragma once

#include <array>
#include <cstdint>

#include "rbsim/math.hpp"

namespace rbsim {

// Separation (m) of shapes a and b: SAT over both cores' edge normals for two polygons or
// segments (exact when they overlap, a lower bound of the gap otherwise), the exact
// distance from a circle's centre to the other core, minus the radii. verts (V,) world
// vertices (m); shape s owns verts[vstart[s] .. vstart[s] + vcount[s]); radius (S,) m.
double pair_separation(const Vec2* verts, const std::int32_t* vstart, const std::int32_t* vcount,
                       const double* radius, std::int32_t a, std::int32_t b);

// out[p] = pair_separation of pairs[p] for p < n_pairs (the caller checks the indices).
void min_separation(const Vec2* verts, const std::int32_t* vstart, const std::int32_t* vcount,
                    const double* radius, const std::array<std::int32_t, 2>* pairs,
                    std::int64_t n_pairs, double* out);

}  // namespace rbsim
