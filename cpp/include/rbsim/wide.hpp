// Several manifolds solved at once, one in each lane of a vector register.
//
// The manifolds of one wave (waves.cpp) share no dynamic body, so they can be solved
// together: the solver gathers their bodies' velocities into lanes, computes every
// lane's impulses with one instruction per operation, and scatters the velocities back.
// A batch holds LANES manifolds of one wave and what their rows say, laid out lane by
// lane (structure of arrays), so that it loads as whole vectors. A lane past the end of a
// wave is empty: its manifold index is -1 and nothing of it is written.
#pragma once

#include <cstdint>

namespace rbsim {

inline constexpr int LANES = 4;

// LANES doubles, one per lane (GCC/Clang vector extension: + − × ÷ and comparisons act
// lane by lane; on x86-64 with AVX one ymm register).
using Lanes = double __attribute__((vector_size(LANES * sizeof(double))));
// the result of a lane-wise comparison: all bits set where true
using LaneMask = std::int64_t __attribute__((vector_size(LANES * sizeof(double))));

inline Lanes splat(double x) {
  Lanes v = {};
  return v + x;
}
inline Lanes select(LaneMask m, Lanes a, Lanes b) { return m ? a : b; }
inline Lanes vmax(Lanes a, Lanes b) { return a > b ? a : b; }
inline Lanes vmin(Lanes a, Lanes b) { return a < b ? a : b; }
// whether any lane is set
inline bool any(LaneMask m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }

// One point of a batch's rows (as SolverRow<2>::Point, lane by lane).
struct WidePoint {
  Lanes rna, rnb, rta, rtb;  // m: lever arms
  Lanes kn;                  // 1/kg
  Lanes tangent_mass;        // kg
  Lanes rax, ray, rbx, rby;  // m: anchors
  Lanes base;                // m: base separation
};

// LANES manifolds of one wave.
struct WideBatch {
  Lanes nx, ny;              // the normal, from b towards a
  Lanes k01, gamma, bias_rate, friction;
  Lanes max_push, deep;      // m/s and m, < 0: the rows' push-out bound and deep overlap
  Lanes ma, mb, ia, ib;      // inverse masses (1/kg) and inertias (1/(kg·m²))
  Lanes two;                 // 1 where the manifold has two points, else 0
  WidePoint p0, p1;          // a one-point manifold's p1 is all zero
  std::int32_t m[LANES];     // manifold index, -1 for an empty lane
  std::int32_t a[LANES], b[LANES];  // body indices (0 for an empty lane)
};

}  // namespace rbsim
