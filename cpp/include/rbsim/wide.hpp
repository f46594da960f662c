// Several manifolds solved at once, one in each lane of a vector register.
//
// The manifolds of one wave (waves.cpp) share no dynamic body, so they can be solved
// together: the solver gathers their bodies' velocities into lanes, computes every
// lane's impulses with one instruction per operation, and scatters the velocities back.
// A batch holds LANES manifolds of one wave and what their rows say, laid out lane by
// lane (structure of arrays), so that it loads as whole vectors. A lane past the end of a
// wave is empty: its manifold index is -1 and nothing of it is written.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "rbsim/math.hpp"

namespace rbsim {

inline constexpr int LANES = 4;
inline constexpr std::uint32_t ALL_WRITES = (1u << (2 * LANES)) - 1;
inline constexpr unsigned ALL_LANES = (1u << LANES) - 1;  // bit l: lane l, every lane

// LANES doubles, one per lane (GCC/Clang vector extension: + − × ÷ and comparisons act
// lane by lane; on x86-64 with AVX one ymm register).
using Lanes = double __attribute__((vector_size(LANES * sizeof(double))));
// the result of a lane-wise comparison: all bits set where true
using LaneMask = std::int64_t __attribute__((vector_size(LANES * sizeof(double))));

inline Lanes splat(double x) { return Lanes{x, x, x, x}; }  // (one broadcast)
inline Lanes select(LaneMask m, Lanes a, Lanes b) { return m ? a : b; }
inline Lanes vmax(Lanes a, Lanes b) { return a > b ? a : b; }
inline Lanes vmin(Lanes a, Lanes b) { return a < b ? a : b; }
// whether any lane is set
inline bool any(LaneMask m) {
#if defined(__AVX__)
  return __builtin_ia32_movmskpd256((Lanes)m) != 0;  // the lanes' sign bits
#else
  return (m[0] | m[1] | m[2] | m[3]) != 0;
#endif
}

// √x lane by lane (correctly rounded, as std::sqrt).
inline Lanes vsqrt(Lanes x) {
#if defined(__AVX__)
  return __builtin_ia32_sqrtpd256(x);
#else
  return Lanes{std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3])};
#endif
}

// whether every lane is set
inline bool all(LaneMask m) {
#if defined(__AVX__)
  return __builtin_ia32_movmskpd256((Lanes)m) == (1 << LANES) - 1;
#else
  return (m[0] & m[1] & m[2] & m[3]) != 0;
#endif
}

// Moving values between memory and lanes: whole records loaded and transposed in
// registers, instead of one scalar load and insert per lane and field (a batch's bodies
// and impulses are scattered over their arrays, one record per lane).
using LanePair = double __attribute__((vector_size(2 * sizeof(double))));
inline Lanes load_lanes(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline LanePair load_pair(const double* p) {
  LanePair v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store_pair(double* p, LanePair v) { std::memcpy(p, &v, sizeof v); }
// The records (x, y) of two doubles at p0..p3 (lanes 0..3) as the lanes x and y.
inline void gather_pairs(const double* p0, const double* p1, const double* p2, const double* p3,
                         Lanes& x, Lanes& y) {
  const Lanes even = __builtin_shufflevector(load_pair(p0), load_pair(p2), 0, 1, 2, 3);
  const Lanes odd = __builtin_shufflevector(load_pair(p1), load_pair(p3), 0, 1, 2, 3);
  x = __builtin_shufflevector(even, odd, 0, 4, 2, 6);
  y = __builtin_shufflevector(even, odd, 1, 5, 3, 7);
}
// The lanes x and y stored as the records (x, y) at p0..p3: gather_pairs reversed.
inline void scatter_pairs(double* p0, double* p1, double* p2, double* p3, Lanes x, Lanes y) {
  const Lanes even = __builtin_shufflevector(x, y, 0, 4, 2, 6);  // x0 y0 x2 y2
  const Lanes odd = __builtin_shufflevector(x, y, 1, 5, 3, 7);   // x1 y1 x3 y3
  store_pair(p0, __builtin_shufflevector(even, even, 0, 1));
  store_pair(p1, __builtin_shufflevector(odd, odd, 0, 1));
  store_pair(p2, __builtin_shufflevector(even, even, 2, 3));
  store_pair(p3, __builtin_shufflevector(odd, odd, 2, 3));
}
// The 4×4 transpose: record r0..r3 (one per lane, four fields each) as the lanes of
// fields f0..f3.
inline void transpose_quads(Lanes r0, Lanes r1, Lanes r2, Lanes r3, Lanes& f0, Lanes& f1,
                            Lanes& f2, Lanes& f3) {
  const Lanes t0 = __builtin_shufflevector(r0, r1, 0, 4, 2, 6);  // f0 of lanes 0 1, f2 of 0 1
  const Lanes t1 = __builtin_shufflevector(r0, r1, 1, 5, 3, 7);  // f1, f3 of lanes 0 1
  const Lanes t2 = __builtin_shufflevector(r2, r3, 0, 4, 2, 6);
  const Lanes t3 = __builtin_shufflevector(r2, r3, 1, 5, 3, 7);
  f0 = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
  f2 = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
  f1 = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
  f3 = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
}
// The records (f0, f1, f2, f3) of four doubles at p0..p3 as the lanes f0..f3.
inline void gather_quads(const double* p0, const double* p1, const double* p2, const double* p3,
                         Lanes& f0, Lanes& f1, Lanes& f2, Lanes& f3) {
  transpose_quads(load_lanes(p0), load_lanes(p1), load_lanes(p2), load_lanes(p3), f0, f1, f2, f3);
}
// The Vec3 records at p0..p3 (scattered) as the lanes x, y and z: each record loaded as
// three doubles (a masked load, which reads nothing past the record: the last body of an
// array has no neighbour to read into), then transposed (transpose_quads).
inline void gather_xyz(const Vec3* p0, const Vec3* p1, const Vec3* p2, const Vec3* p3, Lanes& x,
                       Lanes& y, Lanes& z) {
#if defined(__AVX__)
  using I = long long __attribute__((vector_size(32)));
  const I three = {-1, -1, -1, 0};
  auto load3 = [&three](const Vec3* p) {
    return (Lanes)__builtin_ia32_maskloadpd256(reinterpret_cast<const Lanes*>(&p->x), three);
  };
  Lanes unused;  // (the fourth field: the masked-off zero)
  transpose_quads(load3(p0), load3(p1), load3(p2), load3(p3), x, y, z, unused);
#else
  x = Lanes{p0->x, p1->x, p2->x, p3->x};
  y = Lanes{p0->y, p1->y, p2->y, p3->y};
  z = Lanes{p0->z, p1->z, p2->z, p3->z};
#endif
}
// The x, y and z of the Vec3 records p[0..3] (12 doubles in a row), one record in each
// lane; store_xyz writes them back.
struct LanesXYZ {
  Lanes x, y, z;
};
// a · b lane by lane, the products summed x, y, z as math.hpp's dot() sums them (a Vec3
// the same in every lane)
inline Lanes dot(const LanesXYZ& a, const LanesXYZ& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Lanes dot(Vec3 a, const LanesXYZ& b) {
  return splat(a.x) * b.x + splat(a.y) * b.y + splat(a.z) * b.z;
}
inline LanesXYZ load_xyz(const Vec3* p) {
  const double* d = &p->x;
  const Lanes a = load_lanes(d), b = load_lanes(d + 4), c = load_lanes(d + 8);
  // a = x0 y0 z0 x1, b = y1 z1 x2 y2, c = z2 x3 y3 z3
  const Lanes tx = __builtin_shufflevector(a, b, 0, 3, 6, 6);
  const Lanes ty = __builtin_shufflevector(a, b, 1, 4, 7, 7);
  const Lanes tz = __builtin_shufflevector(a, b, 2, 5, 5, 5);
  return {__builtin_shufflevector(tx, c, 0, 1, 2, 5), __builtin_shufflevector(ty, c, 0, 1, 2, 6),
          __builtin_shufflevector(tz, c, 0, 1, 4, 7)};
}
inline void store_xyz(Vec3* p, const LanesXYZ& v) {
  const Lanes t0 = __builtin_shufflevector(v.x, v.z, 0, 4, 1, 1);  // x0 z0 x1 -
  const Lanes t1 = __builtin_shufflevector(v.y, v.z, 1, 5, 2, 6);  // y1 z1 y2 z2
  const Lanes t2 = __builtin_shufflevector(v.x, v.y, 3, 7, 3, 7);  // x3 y3 - -
  const Lanes a = __builtin_shufflevector(t0, v.y, 0, 4, 1, 2);    // x0 y0 z0 x1
  const Lanes b = __builtin_shufflevector(t1, v.x, 0, 1, 6, 2);    // y1 z1 x2 y2
  const Lanes c = __builtin_shufflevector(t2, v.z, 6, 0, 1, 7);    // z2 x3 y3 z3
  double* d = &p->x;
  std::memcpy(d, &a, sizeof a);
  std::memcpy(d + 4, &b, sizeof b);
  std::memcpy(d + 8, &c, sizeof c);
}
// Lane l of x stored at p[l] (four scalars at scattered addresses).
inline void scatter_scalars(double* p0, double* p1, double* p2, double* p3, Lanes x) {
  *p0 = x[0];
  *p1 = x[1];
  *p2 = x[2];
  *p3 = x[3];
}

// The sums of the lanes of a, b, c and d, as the lanes of one vector (Σa, Σb, Σc, Σd).
inline Lanes sum_lanes(Lanes a, Lanes b, Lanes c, Lanes d) {
  const Lanes ab = __builtin_shufflevector(a, b, 0, 4, 2, 6) + __builtin_shufflevector(a, b, 1, 5, 3, 7);
  const Lanes cd = __builtin_shufflevector(c, d, 0, 4, 2, 6) + __builtin_shufflevector(c, d, 1, 5, 3, 7);
  return __builtin_shufflevector(ab, cd, 0, 1, 4, 5) + __builtin_shufflevector(ab, cd, 2, 3, 6, 7);
}
// bit l set where lane l is set
inline unsigned lane_bits(LaneMask m) {
#if defined(__AVX__)
  return static_cast<unsigned>(__builtin_ia32_movmskpd256((Lanes)m));  // the lanes' sign bits
#else
  return (m[0] != 0 ? 1u : 0u) | (m[1] != 0 ? 2u : 0u) | (m[2] != 0 ? 4u : 0u) |
         (m[3] != 0 ? 8u : 0u);
#endif
}
// all bits set in lane l where bit l of `bits` is
inline LaneMask lanes_of_bits(unsigned bits) {
  static_assert(LANES == 4, "written for four lanes");
  auto lane = [bits](int l) { return -static_cast<std::int64_t>(bits >> l & 1u); };
  return LaneMask{lane(0), lane(1), lane(2), lane(3)};
}
// how many lanes are set
inline int count_lanes(LaneMask m) { return __builtin_popcount(lane_bits(m)); }
// all bits set in lanes 0..n-1
inline LaneMask first_lanes(int n) {
  const Lanes index = {0.0, 1.0, 2.0, 3.0};
  return index < splat(static_cast<double>(n));
}

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
  Lanes load;                // N·s: the rows' friction_load
  Lanes max_push, deep;      // m/s and m, < 0: the rows' push-out bound and deep overlap
  Lanes touch;               // m: the rows' touching distance (SolverRow::touch)
  Lanes ma, mb, ia, ib;      // inverse masses (1/kg) and inertias (1/(kg·m²))
  Lanes two;                 // 1 where the manifold has two points, else 0
  WidePoint p0, p1;          // p1: a two-point batch's (a one-point batch never reads it)
  LaneMask live;             // all bits set in a lane that holds a manifold
  std::int32_t m[LANES];     // manifold index, -1 for an empty lane
  // bit l: the solver moves lane l's body a (a dynamic body: its velocity is written
  // back), bit LANES + l: its body b. ALL_WRITES: every lane's two bodies
  std::uint32_t writes;
  std::int32_t a[LANES], b[LANES];  // body indices (0 for an empty lane)
  // packed among the manifolds that held no impulse at the step's start: mostly idle in
  // the passes (solve_batch leaves a batch whose lanes all are); find_waves packs the
  // waves again once too many such batches hold one
  bool idle;
  // bit l: lane l holds a manifold that joins two regions (a cut's, placed in a region's
  // batch after its bodies' manifolds there: waves.cpp, schedule_units); on threads the
  // region's task leaves these lanes and the cut's pass takes them after the regions
  std::uint8_t cut;
  // The lanes' impulses while the passes run (take_impulses, give_impulses): the
  // accumulated normal and tangent impulses (N·s), the largest normal impulse applied
  // this step (N·s) and the approach speed where the point engaged (m/s), of points 0 and
  // 1 (a one-point batch's point 1 is zero); an empty lane's are zero
  Lanes n0, n1, t0, t1, x0, x1, ap0, ap1;
};

// 3D: one point of LANES rows (SolverRow<3>::Points, point k of each), lane by lane.
struct WidePoint3 {
  Lanes rax, ray, raz, rbx, rby, rbz;              // m: separation anchors
  Lanes rnax, rnay, rnaz, rnbx, rnby, rnbz;        // m: r × n
  Lanes rt1ax, rt1ay, rt1az, rt2ax, rt2ay, rt2az;  // m: friction's levers on a
  Lanes rt1bx, rt1by, rt1bz, rt2bx, rt2by, rt2bz;  // and on b
  Lanes kn, base, tm11, tm12, tm22, tangent_mass;
};

// 3D: what every row of a batch has, lane by lane (SolverRow<3>); every member up to
// `live` is a Lanes (an empty lane is zeroed member by member: waves.cpp).
struct WideRow3 {
  Lanes nx, ny, nz;     // the normal, from b towards a
  Lanes t1x, t1y, t1z;  // the tangent basis
  Lanes t2x, t2y, t2z;
  Lanes ma, mb;         // inverse masses (1/kg)
  Lanes gamma, bias_rate, friction, max_push, deep, touch;
  Lanes load;           // N·s: the rows' friction_load
};

// The lanes' manifolds and bodies, after a batch's rows.
struct WideLanes3 {
  LaneMask live;              // all bits set in a lane that holds a manifold
  std::int32_t m[LANES];      // manifold index, -1 for an empty lane
  // bit l: lane l's body a is dynamic (written back), bit LANES + l: its body b
  std::uint32_t writes;
  std::int32_t a[LANES], b[LANES];  // body indices (0 for an empty lane)
};

// 3D: LANES one-point manifolds of one wave (a sphere or a capsule on another, on a box's
// face or on a plane). The rows' world inverse inertia tensors are not here: in a
// one-point manifold they only turn the local ω after friction, which nothing reads (ω
// is written back from L).
struct WideBatch3 : WideRow3 {
  WidePoint3 p;
  Lanes wnax, wnay, wnaz, wnbx, wnby, wnbz;  // 1/(kg·m): I⁻¹ (r × n)
  WideLanes3 lanes;
};

// 3D: LANES manifolds of one wave with the same count of points (2 to 4: a face, an edge),
// for solve.cpp's block solve of a face's points.
struct WideFace3 : WideRow3 {
  struct Factor {  // a BlockFactor, lane by lane (what a solve reads of it)
    Lanes l[6], inv_d[4], ok;
  };
  Lanes iaxx, iayy, iazz, iaxy, iaxz, iayz;  // 1/(kg·m²): the rows' world inverse tensors
  Lanes ibxx, ibyy, ibzz, ibxy, ibxz, ibyz;
  Lanes k[10];           // 1/kg: the normal block's upper triangle (SolverRow<3>::k)
  Factor rigid, soft;    // its factors (SolverRow<3>::rigid, soft)
  Lanes coupling[6][4];  // SolverRow<3>::tangent_coupling
  WidePoint3 p[4];
  WideLanes3 lanes;
  // the lanes' point count (2 to 4), or 0: manifolds lanes.m (-1: none) left to the solve
  // of one manifold at a time, their rows not packed (faces that hold no impulse, and a
  // batch of fewer than FACE_LANES_MIN: waves.cpp)
  std::int32_t count;
};

}  // namespace rbsim
