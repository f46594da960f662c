// The only code that knows Python: rbsim._core, the engine's World over numpy arrays.
//
// A world is built from the flat arrays of rbsim's scene compiler (a dict of numpy
// arrays, checked here for dtype and shape as they cross), keeps its own storage, and
// shows its state and storage as numpy views that share memory with it (no copies).
// C++ exceptions surface as Python exceptions with their message.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <chrono>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "rbsim/constants.hpp"
#include "rbsim/world.hpp"
#include "../src/collide/narrow2d.hpp"
#include "../src/tools/checkpoint.hpp"
#include "../src/tools/record.hpp"
#include "../src/tools/separation.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace rbsim {
namespace {

// How an element type lies in memory: its scalar type and the trailing shape it adds.
template <class T>
struct Layout {
  using scalar = T;
  static constexpr std::size_t rank = 0;
  static void shape(std::size_t*) {}
};
template <class T, std::size_t K>
struct Layout<std::array<T, K>> {
  using scalar = typename Layout<T>::scalar;
  static constexpr std::size_t rank = 1 + Layout<T>::rank;
  static void shape(std::size_t* out) {
    out[0] = K;
    Layout<T>::shape(out + 1);
  }
};
#define RBSIM_FLAT_LAYOUT(Type, Scalar, Width)         \
  template <>                                          \
  struct Layout<Type> {                                \
    using scalar = Scalar;                             \
    static constexpr std::size_t rank = 1;             \
    static void shape(std::size_t* out) { out[0] = Width; } \
  };
RBSIM_FLAT_LAYOUT(Vec2, double, 2)
RBSIM_FLAT_LAYOUT(Vec3, double, 3)
RBSIM_FLAT_LAYOUT(Rot2, double, 2)
RBSIM_FLAT_LAYOUT(Quat, double, 4)
RBSIM_FLAT_LAYOUT(Sym3, double, 6)
RBSIM_FLAT_LAYOUT(SolverRow<2>, double, 32)
RBSIM_FLAT_LAYOUT(Aabb<2>, double, 4)
RBSIM_FLAT_LAYOUT(Aabb<3>, double, 6)
RBSIM_FLAT_LAYOUT(BodyDelta<2>, double, 4)
RBSIM_FLAT_LAYOUT(BodyDelta<3>, double, 7)
RBSIM_FLAT_LAYOUT(ContactCounts, std::int64_t, 12)
RBSIM_FLAT_LAYOUT(GridMeta<2>, std::int64_t, 7)
RBSIM_FLAT_LAYOUT(GridMeta<3>, std::int64_t, 9)
#undef RBSIM_FLAT_LAYOUT
template <>
struct Layout<BodyType> : Layout<std::int8_t> {};
template <>
struct Layout<ShapeKind> : Layout<std::int32_t> {};

static_assert(sizeof(BodyDelta<2>) == 4 * sizeof(double));
static_assert(sizeof(GridMeta<2>) == 7 * sizeof(std::int64_t));
static_assert(sizeof(BodyDelta<3>) == 7 * sizeof(double));
static_assert(sizeof(GridMeta<3>) == 9 * sizeof(std::int64_t));
static_assert(sizeof(ContactCounts) == 12 * sizeof(std::int64_t));

using Array = nb::ndarray<nb::numpy>;

// A numpy view of n elements of type T at data, kept alive by owner. flag: show a uint8
// array as numpy bool.
template <class T>
Array view(T* data, std::size_t n, nb::handle owner, bool leading = true, bool flag = false) {
  using L = Layout<T>;
  std::size_t shape[8];
  std::size_t ndim = 0;
  if (leading) shape[ndim++] = n;
  L::shape(shape + ndim);
  ndim += L::rank;
  auto dtype = flag ? nb::dtype<bool>() : nb::dtype<typename L::scalar>();
  return Array(static_cast<void*>(data), ndim, shape, owner, nullptr, dtype);
}
template <class T>
Array view(std::vector<T>& v, nb::handle owner, bool flag = false) {
  return view(v.data(), v.size(), owner, true, flag);
}

// Copy a numpy array into dst, checking its dtype and shape: (n, trailing...) with n
// given (n < 0: any).
template <class T>
void load(std::vector<T>& dst, nb::handle obj, const char* name, long n = -1) {
  using L = Layout<T>;
  using S = typename L::scalar;
  nb::ndarray<nb::ro, nb::c_contig, nb::device::cpu> a;  // read only: it is copied
  if (!nb::try_cast(obj, a)) throw std::invalid_argument(std::string(name) + ": not a C-contiguous array");
  if (a.dtype() != nb::dtype<S>())
    throw std::invalid_argument(std::string(name) + ": wrong dtype");
  std::size_t trailing[8];
  L::shape(trailing);
  if (a.ndim() != 1 + L::rank) throw std::invalid_argument(std::string(name) + ": wrong number of dimensions");
  for (std::size_t k = 0; k < L::rank; ++k)
    if (a.shape(k + 1) != trailing[k]) throw std::invalid_argument(std::string(name) + ": wrong shape");
  if (n >= 0 && a.shape(0) != static_cast<std::size_t>(n))
    throw std::invalid_argument(std::string(name) + ": expected " + std::to_string(n) + " rows");
  dst.resize(a.shape(0));
  if (!dst.empty()) std::memcpy(static_cast<void*>(dst.data()), a.data(), dst.size() * sizeof(T));
}

template <class T>
T load_value(nb::dict d, const char* key) {
  if (!d.contains(key)) throw std::invalid_argument(std::string("missing key ") + key);
  T value{};
  if (!nb::try_cast(d[key], value)) {
    const char* kind = std::is_same_v<T, bool>       ? "a bool"
                       : std::is_integral_v<T>       ? "an integer"
                       : std::is_floating_point_v<T> ? "a number"
                                                     : "a string";
    throw std::invalid_argument(std::string(key) + ": not " + kind);
  }
  return value;
}

using World2 = World<2>;

// The storage arrays by name (the numba engine's names), for tests and diagnostics. In
// 3D the solver's rows (SolverRow<3>) are left out.
template <int D>
nb::dict storage(World<D>& w, nb::handle owner) {
  nb::dict d;
  auto& c = w.contacts;
  d["count"] = view(&c.count, 1, owner, false);
  d["carried"] = view(c.carried, owner, true);
#define RBSIM_VIEW(name) d[#name] = view(c.name, owner);
  RBSIM_VIEW(pairs) RBSIM_VIEW(shape_a) RBSIM_VIEW(shape_b) RBSIM_VIEW(body_a) RBSIM_VIEW(body_b)
  RBSIM_VIEW(key) RBSIM_VIEW(normal) RBSIM_VIEW(points) RBSIM_VIEW(friction) RBSIM_VIEW(restitution)
  RBSIM_VIEW(anchor_a) RBSIM_VIEW(anchor_b) RBSIM_VIEW(base_separation) RBSIM_VIEW(ref_separation)
  RBSIM_VIEW(sep_anchor_a) RBSIM_VIEW(sep_anchor_b)
  RBSIM_VIEW(feature) RBSIM_VIEW(normal_impulse) RBSIM_VIEW(start_impulse) RBSIM_VIEW(tangent_impulse)
  RBSIM_VIEW(normal_mass) RBSIM_VIEW(approach_velocity)
  RBSIM_VIEW(approach_separation) RBSIM_VIEW(max_normal_impulse) RBSIM_VIEW(prev_key)
  RBSIM_VIEW(prev_points) RBSIM_VIEW(prev_feature) RBSIM_VIEW(prev_normal_impulse)
  RBSIM_VIEW(prev_tangent_impulse) RBSIM_VIEW(prev_normal) RBSIM_VIEW(prev_anchor_a)
  RBSIM_VIEW(prev_anchor_b) RBSIM_VIEW(prev_ref_separation) RBSIM_VIEW(ref_offset)
  RBSIM_VIEW(prev_ref_offset)
  RBSIM_VIEW(ref_turn_a) RBSIM_VIEW(ref_turn_b)
  RBSIM_VIEW(body_delta) RBSIM_VIEW(vert_world)
  RBSIM_VIEW(norm_world) RBSIM_VIEW(shape_margin) RBSIM_VIEW(body_level) RBSIM_VIEW(support)
  RBSIM_VIEW(body_load) RBSIM_VIEW(shock_side)
  RBSIM_VIEW(shock_order) RBSIM_VIEW(solve_order) RBSIM_VIEW(adj_start) RBSIM_VIEW(adj)
  RBSIM_VIEW(queue) RBSIM_VIEW(bounce_kind) RBSIM_VIEW(body_mark) RBSIM_VIEW(solve_impulse)
  RBSIM_VIEW(bounce_list) RBSIM_VIEW(relax_list) RBSIM_VIEW(body_reach)
  RBSIM_VIEW(wave_order) RBSIM_VIEW(manifold_wave) RBSIM_VIEW(wave_start) RBSIM_VIEW(wave_batch)
  RBSIM_VIEW(wave_single) RBSIM_VIEW(wave_single_batch) RBSIM_VIEW(wave_idle)
  RBSIM_VIEW(shape_size) RBSIM_VIEW(shape_scale) RBSIM_VIEW(body_scale)
#undef RBSIM_VIEW
  if constexpr (D == 2) d["solver_row"] = view(c.solver_row, owner);
  if constexpr (D == 3) {
    d["face_world"] = view(c.face_world, owner);
    // 1/(kg·m²): each body's world inverse tensor (xx yy zz xy xz yz) and the rotation
    // it was made at
    d["body_inv_inertia_world"] = view(c.body_inv_inertia_world, owner);
    d["body_inertia_q"] = view(c.body_inertia_q, owner);
    // each face batch's point count (WideFace3::count; 0: its manifolds go one at a
    // time), as a list (a copy). The batches are packed anew in every step, and a
    // checkpoint restores the waves' counts but not them (checkpoint.cpp): only the
    // batches this world has packed are read
    nb::list counts;
    const std::int64_t batches =
        c.wave_count >= 0 && static_cast<std::size_t>(c.wave_count) < c.wave_single_batch.size()
            ? std::min<std::int64_t>(c.wave_single_batch[c.wave_count], static_cast<std::int64_t>(c.faces3.size()))
            : 0;
    for (std::int64_t i = 0; i < batches; ++i) counts.append(c.faces3[i].count);
    d["face_batch_points"] = counts;
  }
  d["wave_count"] = view(&c.wave_count, 1, owner, false);
  // the regions of the threaded passes (regions.cpp)
  d["region_count"] = view(&c.region_count, 1, owner, false);
  d["body_region"] = view(c.body_region, owner);
  d["segment_order"] = view(c.segment_order, owner);
  d["segment_wave"] = view(c.segment_wave, owner);
  d["segment_shock"] = view(c.segment_shock, owner);
  auto& g = w.grid;
  nb::dict gd;
  gd["inv_cell"] = view(&g.inv_cell, 1, owner, false);
  gd["shape_moved"] = view(g.shape_moved, owner, true);
  gd["shape_big"] = view(g.shape_big, owner, true);
#define RBSIM_VIEW(name) gd[#name] = view(g.name, owner);
  RBSIM_VIEW(shape_aabb) RBSIM_VIEW(shape_fat) RBSIM_VIEW(shape_cell) RBSIM_VIEW(shape_bucket)
  RBSIM_VIEW(entry_shape) RBSIM_VIEW(entry_cell) RBSIM_VIEW(entry_fat) RBSIM_VIEW(entry_tag)
  RBSIM_VIEW(bucket_start) RBSIM_VIEW(big_list) RBSIM_VIEW(new_keys) RBSIM_VIEW(kept)
  RBSIM_VIEW(sort_scratch) RBSIM_VIEW(sort_count)
#undef RBSIM_VIEW
  gd["span"] = view(&g.span, 1, owner, false);
  gd["frame_origin"] = view(&g.frame_origin, 1, owner, false);
  gd["frame_offset"] = view(&g.frame_offset, 1, owner, false);
  gd["meta"] = view(&g.meta, 1, owner, false);
  d["grid"] = gd;
  return d;
}

// A dict entry, or std::invalid_argument naming the missing key (a ValueError in Python).
nb::handle item(nb::dict d, const char* key) {
  if (!d.contains(key)) throw std::invalid_argument(std::string("missing key ") + key);
  return d[key];
}

// A (D,) float64 array as a vector (gravity).
template <int D>
typename Dim<D>::Vec load_vector(nb::dict d, const char* key) {
  std::vector<double> g;
  load(g, item(d, key), key, D);
  typename Dim<D>::Vec v{};
  std::memcpy(static_cast<void*>(&v), g.data(), sizeof v);
  return v;
}

// Inertia tensors (N,3,3) float64 into Sym3, checking that each is symmetric (to 1e-9
// of its largest finite entry: a tensor built as P diag(moments) Pᵀ rounds its two
// halves differently) with finite off-diagonal entries; the two halves are averaged.
// Non-dynamic bodies carry diag(inf, inf, inf) (inertia) or zeros (inverse).
void load_tensors(std::vector<Sym3>& dst, nb::handle obj, const char* name, long n) {
  std::vector<std::array<std::array<double, 3>, 3>> a;
  load(a, obj, name, n);
  dst.resize(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const auto& t = a[i];
    double scale = 0.0;
    for (const auto& r : t)
      for (double x : r)
        if (std::isfinite(x)) scale = std::max(scale, std::abs(x));
    for (int j = 0; j < 3; ++j)
      for (int k = j + 1; k < 3; ++k) {
        if (!std::isfinite(t[j][k]) || !std::isfinite(t[k][j]) ||
            std::abs(t[j][k] - t[k][j]) > 1e-9 * scale)
          throw std::invalid_argument(std::string(name) + ": row " + std::to_string(i) +
                                      " is not a symmetric tensor with finite off-diagonal entries");
      }
    dst[i] = {t[0][0], t[1][1], t[2][2], 0.5 * (t[0][1] + t[1][0]), 0.5 * (t[0][2] + t[2][0]),
              0.5 * (t[1][2] + t[2][1])};
  }
}

// The model's mass properties by dimension: (N,) scalars in 2D; (N,3,3) tensors, the
// principal axes (N,4) and moments (N,3) in 3D (the split rotation update turns about them).
void load_inertia(Model<2>& m, nb::dict model, long n) {
  load(m.body_inertia, item(model, "body_inertia"), "body_inertia", n);
  load(m.body_inv_inertia, item(model, "body_inv_inertia"), "body_inv_inertia", n);
}
void load_inertia(Model<3>& m, nb::dict model, long n) {
  load_tensors(m.body_inertia, item(model, "body_inertia"), "body_inertia", n);
  load_tensors(m.body_inv_inertia, item(model, "body_inv_inertia"), "body_inv_inertia", n);
  load(m.body_axes, item(model, "body_axes"), "body_axes", n);
  load(m.body_moments, item(model, "body_moments"), "body_moments", n);
  for (long i = 0; i < n; ++i) {
    if (!m.is_dynamic(static_cast<int>(i))) continue;
    const Quat p = m.body_axes[i];
    const Vec3 k = m.body_moments[i];
    if (!(std::abs(p.w * p.w + p.x * p.x + p.y * p.y + p.z * p.z - 1.0) < 1e-9))
      throw std::invalid_argument("body_axes: row " + std::to_string(i) + " is not a unit quaternion");
    if (!(k.x > 0.0 && k.y > 0.0 && k.z > 0.0 && std::isfinite(k.x + k.y + k.z)))
      throw std::invalid_argument("body_moments: row " + std::to_string(i) +
                                  " of a dynamic body must be positive and finite");
  }
}

// The 3D shapes' geometry as the narrowphase reads it, checked after the vertex ranges:
// each kind's vertex count (sphere and plane 1, capsule 2, box 8, convex >= 4), a
// plane's unit normal, a box's corners a box (three orthogonal edges of positive length
// in BOX_SIGNS order, to 1e-9 of its size), a convex shape's triangles (face_local (F,3)
// int32, shape_fstart / shape_fcount (S,) int32, or all three empty when no shape is
// convex) inside its vertex rows and closing a convex surface; then the hull topology.
// The shapes' kinds and vertex ranges are checked before.
void load_shapes_3d(Model<3>& m, nb::dict model) {
  const long s = m.shape_count();
  if (model.contains("face_local")) load(m.face_local, model["face_local"], "face_local");
  const long nf = static_cast<long>(m.face_local.size());
  if (model.contains("shape_fstart") || model.contains("shape_fcount")) {
    load(m.shape_fstart, item(model, "shape_fstart"), "shape_fstart");
    const long rows = static_cast<long>(m.shape_fstart.size());
    if (rows != s && !(rows == 0 && nf == 0))
      throw std::invalid_argument("shape_fstart: expected " + std::to_string(s) + " rows");
    load(m.shape_fcount, item(model, "shape_fcount"), "shape_fcount", rows);
  }
  const bool faces = !m.shape_fstart.empty();
  auto where = [](long i) { return "shape " + std::to_string(i) + ": "; };
  for (long i = 0; i < s; ++i) {
    const int v0 = m.shape_vstart[i], count = m.shape_vcount[i];
    const ShapeKind kind = m.shape_kind[i];
    const int need = kind == ShapeKind::Capsule ? 2 : kind == ShapeKind::Box ? 8 : 1;
    if (kind == ShapeKind::Convex ? count < 4 : count != need)
      throw std::invalid_argument(where(i) + "wrong vertex count for its kind");
    if (faces) {
      const long f0 = m.shape_fstart[i], fc = m.shape_fcount[i];
      if (f0 < 0 || fc < 0 || f0 + fc > nf) throw std::invalid_argument(where(i) + "triangles out of range");
      for (long f = f0; f < f0 + fc; ++f)
        for (int k = 0; k < 3; ++k)
          if (m.face_local[f][k] < 0 || m.face_local[f][k] >= count)
            throw std::invalid_argument(where(i) + "triangle vertex out of range");
    }
    const Vec3* p = m.vertex_local.data() + v0;
    if (kind == ShapeKind::Plane) {
      const Vec3 n = m.normal_local[v0];
      if (!(std::abs(dot(n, n) - 1.0) < 1e-9)) throw std::invalid_argument(where(i) + "a plane's normal must be a unit vector");
    }
    if (kind == ShapeKind::Box) {
      const Vec3 e[3] = {p[1] - p[0], p[2] - p[0], p[4] - p[0]};
      const double size = length(p[7] - p[0]);  // m
      bool ok = size > 0.0 && std::isfinite(size);
      for (int a = 0; a < 3 && ok; ++a) {
        ok = length(e[a]) > 1e-9 * size && std::abs(dot(e[a], e[(a + 1) % 3])) <= 1e-9 * size * size;
      }
      for (int k = 0; k < 8 && ok; ++k) {
        const Vec3 corner = p[0] + (k & 1 ? 1.0 : 0.0) * e[0] + (k & 2 ? 1.0 : 0.0) * e[1] +
                            (k & 4 ? 1.0 : 0.0) * e[2];
        ok = length(corner - p[k]) <= 1e-9 * size;
      }
      if (!ok) throw std::invalid_argument(where(i) + "a box's 8 corners must be a box's, in BOX_SIGNS order");
    }
  }
  std::string error;
  if (!build_shape_hulls(m, &error)) throw std::invalid_argument(error);
}

// The angular state: ω (and the unwrapped angle) in 2D; ω and L in 3D.
void load_angular(State<2>& st, nb::dict state, long n) {
  load(st.body_angle, item(state, "body_angle"), "body_angle", n);
  load(st.body_w, item(state, "body_w"), "body_w", n);
}
void load_angular(State<3>& st, nb::dict state, long n) {
  if (state.contains("body_angle")) load(st.body_angle, state["body_angle"], "body_angle", 0);
  load(st.body_w, item(state, "body_w"), "body_w", n);
  load(st.body_l, item(state, "body_l"), "body_l", n);
}

// A world of dimension D from the scene compiler's dicts (rbsim.scene.compile's Model and
// State as dicts of arrays; config: rbsim.config.Config as a dict), every array checked.
template <int D>
std::unique_ptr<World<D>> make_world(nb::dict model, nb::dict state, nb::dict config) {
  auto w = std::make_unique<World<D>>();
  auto& m = w->model;
  load(m.body_type, item(model, "body_type"), "body_type");
  const long n = static_cast<long>(m.body_type.size());
  for (long i = 0; i < n; ++i) {
    int t = static_cast<int>(m.body_type[i]);
    if (t < 0 || t > 2) throw std::invalid_argument("body_type out of range");
  }
  load(m.body_mass, item(model, "body_mass"), "body_mass", n);
  load(m.body_inv_mass, item(model, "body_inv_mass"), "body_inv_mass", n);
  load_inertia(m, model, n);
  load(m.body_com, item(model, "body_com"), "body_com", n);
  load(m.body_force, item(model, "body_force"), "body_force", n);
  load(m.body_force_arm, item(model, "body_force_arm"), "body_force_arm", n);
  load(m.body_torque, item(model, "body_torque"), "body_torque", n);
  load(m.shape_body, item(model, "shape_body"), "shape_body");
  const long s = static_cast<long>(m.shape_body.size());
  load(m.shape_kind, item(model, "shape_kind"), "shape_kind", s);
  load(m.shape_radius, item(model, "shape_radius"), "shape_radius", s);
  load(m.shape_vstart, item(model, "shape_vstart"), "shape_vstart", s);
  load(m.shape_vcount, item(model, "shape_vcount"), "shape_vcount", s);
  load(m.shape_friction, item(model, "shape_friction"), "shape_friction", s);
  load(m.shape_restitution, item(model, "shape_restitution"), "shape_restitution", s);
  load(m.vertex_local, item(model, "vertex_local"), "vertex_local");
  const long nv = static_cast<long>(m.vertex_local.size());
  load(m.normal_local, item(model, "normal_local"), "normal_local", nv);
  m.gravity = load_vector<D>(model, "gravity");
  m.linear_damping = load_value<double>(model, "linear_damping");
  m.angular_damping = load_value<double>(model, "angular_damping");
  m.has_forces = load_value<bool>(model, "has_forces");
  m.has_shapes = load_value<bool>(model, "has_shapes");
  // the model's indices must stay inside the arrays they index
  for (long i = 0; i < s; ++i) {
    if (m.shape_body[i] < 0 || m.shape_body[i] >= n) throw std::invalid_argument("shape_body out of range");
    if (!valid_shape_kind<D>(static_cast<int>(m.shape_kind[i])))
      throw std::invalid_argument("shape_kind out of range for a " + std::to_string(D) + "D world");
    if (m.shape_vstart[i] < 0 || m.shape_vcount[i] < 1 || m.shape_vstart[i] + m.shape_vcount[i] > nv)
      throw std::invalid_argument("shape vertices out of range");
  }
  if constexpr (D == 3) load_shapes_3d(m, model);
  auto& st = w->state;
  load(st.body_x, item(state, "body_x"), "body_x", n);
  load(st.body_q, item(state, "body_q"), "body_q", n);
  load(st.body_v, item(state, "body_v"), "body_v", n);
  load_angular(st, state, n);
  auto& cf = w->config;
  cf.dt = load_value<double>(config, "dt");
  cf.substeps = load_value<int>(config, "substeps");
  cf.iterations = load_value<int>(config, "iterations");
  if (!(cf.dt > 0.0) || cf.substeps < 1 || cf.iterations < 1)
    throw std::invalid_argument("dt, substeps and iterations must be positive");
  cf.explicit_euler = load_value<bool>(config, "explicit");
  // the codes of rbsim.scene.types.ROTATION_CODE; in 2D split turns as exact does
  const int rotation = load_value<int>(config, "rotation");
  if (rotation < 0 || rotation > static_cast<int>(Rotation::Split))
    throw std::invalid_argument("rotation must be 0 (normalize), 1 (exact) or 2 (split)");
  cf.rotation = static_cast<Rotation>(rotation);
  cf.restitution_threshold = load_value<double>(config, "restitution_threshold");
  cf.friction_rule = static_cast<MixRule>(load_value<int>(config, "friction_rule"));
  cf.restitution_rule = static_cast<MixRule>(load_value<int>(config, "restitution_rule"));
  cf.elastic = load_value<bool>(config, "elastic");
  // the step's threads (solver.threads, resolved by rbsim.config); a config without the
  // key runs on one
  cf.threads = config.contains("threads") ? load_value<int>(config, "threads") : 1;
  if (cf.threads < 1 || cf.threads > THREADS_MAX)
    throw std::invalid_argument("threads must be between 1 and " + std::to_string(THREADS_MAX));
  // and whether each step picks between one thread and those (solver.threads not set)
  cf.choose_threads =
      config.contains("choose_threads") && load_value<bool>(config, "choose_threads");
  set_contact_softness(cf);
  w->allocate();
  return w;
}

// The manifold order a solve_contacts stage goes through (args["order"]: "relax_list",
// "wave_order", else the solve order).
template <int D>
const std::int32_t* stage_order(const Contacts<D>& c, nb::dict args) {
  const std::string list = load_value<std::string>(args, "order");
  return list == "relax_list"   ? c.relax_list.data()
         : list == "wave_order" ? c.wave_order.data()
                                : c.solve_order.data();
}

// One stage by name, on the world's current storage: for tests that hold each stage
// against the numba engine's. The step itself is step.cpp's.
nb::object run_stage(World2& w, const std::string& name, nb::dict args) {
  auto& m = w.model;
  auto& st = w.state;
  auto& c = w.contacts;
  auto& cf = w.config;
  auto num = [&](const char* key) { return load_value<double>(args, key); };
  auto flag = [&](const char* key) { return load_value<bool>(args, key); };
  if (name == "transform_shapes") {
    transform_shapes(m, st, c, cf.dt);
  } else if (name == "find_pairs") {
    return nb::int_(find_pairs(m, w.grid, c));
  } else if (name == "update_manifolds") {
    update_manifolds(m, st, c, w.grid, load_value<std::int64_t>(args, "n_pairs"), cf.friction_rule,
                     cf.restitution_rule, cf.dt);
  } else if (name == "prepare_contacts") {
    prepare_contacts(m, st, c, cf);
  } else if (name == "support_order") {
    return nb::int_(support_order(m, c));
  } else if (name == "deep_region") {
    return nb::int_(deep_region(m, c, load_value<int>(args, "reach")));
  } else if (name == "propagate_shock") {
    propagate_shock(m, st, c, load_value<std::int64_t>(args, "n_order"), num("inv_h"), num("threshold"));
  } else if (name == "integrate_velocities") {
    integrate_velocities(m, st, num("h"));
  } else if (name == "integrate_positions") {
    integrate_positions(m, st, c.body_delta, num("h"), flag("exact") ? Rotation::Exact : Rotation::Normalize);
  } else if (name == "warm_start") {
    warm_start(m, st, c);
  } else if (name == "solve_contacts") {
    std::int64_t n = load_value<std::int64_t>(args, "n");
    if (n < 0 || n > c.capacity()) throw std::invalid_argument("n out of range");
    solve_contacts(m, st, c, num("inv_h"), flag("use_bias"), num("shift"), num("threshold"),
                   stage_order(c, args), n);
  } else if (name == "find_waves") {
    return nb::int_(find_waves(m, c));
  } else if (name == "warm_start_waves") {
    warm_start_waves(m, st, c);
  } else if (name == "solve_waves") {
    solve_waves(m, st, c, num("inv_h"), flag("use_bias"), num("shift"), num("threshold"));
  } else if (name == "keep_solve_impulses") {
    keep_solve_impulses(c);
  } else if (name == "apply_restitution") {
    apply_restitution(m, st, c, num("threshold"), num("h"), num("sign"));
  } else if (name == "limit_static_overlap") {
    limit_static_overlap(m, st, c, num("max_overlap"));
  } else if (name == "limit_dynamic_overlap") {
    const int passes = load_value<int>(args, "passes");
    return nb::int_(limit_dynamic_overlap(m, st, c, num("max_overlap"), passes));
  } else if (name == "store_impulses") {
    store_impulses(c);
  } else {
    throw std::invalid_argument("no stage named " + name);
  }
  return nb::none();
}

// The collision stages of a 3D world by name (tests, and the measures of the 3D
// broadphase and manifolds while the 3D step does not take them yet).
nb::object run_stage3(World<3>& w, const std::string& name, nb::dict args) {
  auto& c = w.contacts;
  auto& cf = w.config;
  auto num = [&](const char* key) { return load_value<double>(args, key); };
  auto flag = [&](const char* key) { return load_value<bool>(args, key); };
  if (name == "transform_shapes") {
    transform_shapes(w.model, w.state, c, cf.dt);
  } else if (name == "find_pairs") {
    const std::int64_t n = find_pairs(w.model, w.grid, c);
    c.count.pairs = n;
    return nb::int_(n);
  } else if (name == "update_manifolds") {
    const std::int64_t n = load_value<std::int64_t>(args, "n_pairs");
    if (n < 0 || n > c.capacity() || n > c.count.pairs) throw std::invalid_argument("n_pairs out of range");
    update_manifolds(w.model, w.state, c, w.grid, n, cf.friction_rule, cf.restitution_rule, cf.dt);
  } else if (name == "store_impulses") {
    store_impulses(c);
  } else if (name == "grow") {
    w.grow(load_value<std::int64_t>(args, "capacity"));
  } else if (name == "find_waves") {
    return nb::int_(find_waves(w.model, c));
  } else if (name == "solve_contacts") {
    const std::int64_t n = load_value<std::int64_t>(args, "n");
    if (n < 0 || n > c.count.manifolds) throw std::invalid_argument("n out of range");
    solve_contacts(w.model, w.state, c, num("inv_h"), flag("use_bias"), num("shift"),
                   num("threshold"), stage_order(c, args), n);
  } else if (name == "solve_waves") {
    // the batches are the step's scratch, packed by find_waves (a checkpoint keeps the
    // waves' counts, not the batches): solving waves that were not packed read past them
    const auto n = static_cast<std::size_t>(c.wave_count);
    if (n >= c.wave_batch.size() || n >= c.wave_single_batch.size() ||
        static_cast<std::size_t>(c.wave_batch[n]) > c.batches3.size() ||
        static_cast<std::size_t>(c.wave_single_batch[n]) > c.faces3.size())
      throw std::invalid_argument("solve_waves: the waves are not packed (run find_waves first)");
    solve_waves(w.model, w.state, c, num("inv_h"), flag("use_bias"), num("shift"), num("threshold"));
  } else {
    throw std::invalid_argument("no 3D stage named " + name);
  }
  return nb::none();
}

// ---- narrowphase test entry (rbsim._core.collide2d) ------------------------------------
// One manifold from collide2d on the caller's world-frame verts/norms (V,2) float64, for
// tests that hold the C++ narrowphase against rbsim.narrowphase.collide. Rows past the
// point count are NaN (ids -1).
nb::ndarray<nb::c_contig, nb::device::cpu> narrow_rows(nb::handle obj, const char* name) {
  nb::ndarray<nb::c_contig, nb::device::cpu> a;
  if (!nb::try_cast(obj, a)) throw std::invalid_argument(std::string(name) + ": not a C-contiguous array");
  if (a.dtype() != nb::dtype<double>()) throw std::invalid_argument(std::string(name) + ": wrong dtype");
  if (a.ndim() != 2 || a.shape(1) != 2) throw std::invalid_argument(std::string(name) + ": expected shape (V,2)");
  return a;
}

template <class T>
Array owned_array(std::initializer_list<std::size_t> shape, const T* src) {
  std::size_t n = 1;
  for (auto k : shape) n *= k;
  T* buf = new T[n];
  std::memcpy(buf, src, n * sizeof(T));
  nb::capsule owner(buf, [](void* p) noexcept { delete[] static_cast<T*>(p); });
  return Array(buf, shape, owner, {}, nb::dtype<T>());
}

nb::tuple collide2d_py(int kind_a, int start_a, int count_a, double radius_a, int kind_b,
                       int start_b, int count_b, double radius_b, nb::handle verts_obj,
                       nb::handle norms_obj, double speculative) {
  auto verts = narrow_rows(verts_obj, "verts");
  auto norms = narrow_rows(norms_obj, "norms");
  const long nv = static_cast<long>(verts.shape(0));
  if (static_cast<long>(norms.shape(0)) != nv) throw std::invalid_argument("norms: expected as many rows as verts");
  auto check = [nv](int kind, int start, int count, const char* which) {
    if (start < 0 || count < 1 || static_cast<long>(start) + count > nv)
      throw std::invalid_argument(std::string(which) + ": start+count outside verts");
    // a segment's pair functions read its second vertex
    if (kind == static_cast<int>(ShapeKind::Segment) && count < 2)
      throw std::invalid_argument(std::string(which) + ": a segment needs 2 vertices");
  };
  check(kind_a, start_a, count_a, "shape a");
  check(kind_b, start_b, count_b, "shape b");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Manifold2 m{{nan, nan}, {Vec2{nan, nan}, Vec2{nan, nan}}, {nan, nan}, {-1, -1}};
  const ShapeRef2 a{static_cast<ShapeKind>(kind_a), start_a, count_a, radius_a};
  const ShapeRef2 b{static_cast<ShapeKind>(kind_b), start_b, count_b, radius_b};
  const int n = collide2d(a, b, static_cast<const Vec2*>(verts.data()),
                          static_cast<const Vec2*>(norms.data()), speculative, m);
  return nb::make_tuple(n, owned_array<double>({2}, &m.normal.x),
                        owned_array<double>({2, 2}, &m.point[0].x),
                        owned_array<double>({2}, m.separation.data()),
                        owned_array<std::int64_t>({2}, m.id.data()));
}
// ---- end narrowphase test entry ---------------------------------------------------------

// ---- output frames (the run loop's blocks) ----------------------------------------
// Between two steps of a long call, and inside a long step (World::interrupt), every
// 20 ms: run Python's signal handlers (taking the GIL for it) and ask `stop` (a callable,
// or None). True when a handler raised (its error left set, or cleared with `clear`) or
// stop() is true.
class SignalPoll {
 public:
  bool operator()(nb::handle stop, bool clear) {
    const auto now = std::chrono::steady_clock::now();
    if (now - checked_ <= std::chrono::milliseconds(20)) return false;
    checked_ = now;
    nb::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) {
      if (clear) PyErr_Clear();
      return true;
    }
    return !stop.is_none() && nb::cast<bool>(stop());
  }

 private:
  std::chrono::steady_clock::time_point checked_ = std::chrono::steady_clock::now();
};

// For the length of one advance call: the world asks `poll` inside a long step too
// (World::interrupt). An exception poll raises there (stop() raising) is kept, the step
// stopped, and the exception rethrown once the engine has returned (`rethrow`).
template <int D>
class Interrupts {
 public:
  Interrupts(World<D>& w, SignalPoll& poll, nb::handle stop, bool clear) : w_(w) {
    w_.interrupt = [this, &poll, stop, clear] {
      try {
        return poll(stop, clear);
      } catch (...) {
        error_ = std::current_exception();
        return true;
      }
    };
  }
  ~Interrupts() { w_.interrupt = nullptr; }
  Interrupts(const Interrupts&) = delete;
  Interrupts& operator=(const Interrupts&) = delete;
  bool operator()() { return w_.interrupt(); }
  void rethrow() {
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }

 private:
  World<D>& w_;
  std::exception_ptr error_;
};

// What stepping or saving a torn world (World::torn) raises.
template <int D>
std::string torn_message(const World<D>& w) {
  return "step " + std::to_string(w.step_index + 1) +
         " was stopped inside (Ctrl-C during a long step): the state is partway through it; "
         "load a checkpoint or build the world again to go on";
}

// advance_recording's status when a signal handler raised (not an engine Status)
constexpr int INTERRUPTED = 100;
// advance_recording's status when a frame's contact points did not fit in the block's
// contact rows: the step is taken, its frame not recorded (grow the rows, then record)
constexpr int CONTACTS_FULL = 101;

// A block's arrays for a world of dimension D, as pointers at row 0.
template <int D>
struct Block {
  std::int64_t rows = -1;
  std::int64_t* step = nullptr;
  double* time = nullptr;
  FrameRow<D> base;  // pointers at row 0
  std::int64_t n = 0;
  // the contact points (output.contacts): per frame its first row and count (B,), and
  // the rows of every frame in the block, C of them from row 0
  std::int64_t* contact_start = nullptr;
  std::int64_t* contact_points = nullptr;
  ContactRows<D> contacts;  // at row 0, capacity C
};

// A contact row array of the block: (C, *trailing), C the same for all of them.
template <class S>
S* contact_array(nb::dict d, const char* key, std::int64_t trailing, std::int64_t& rows) {
  if (!d.contains(key)) return nullptr;
  nb::ndarray<nb::c_contig, nb::device::cpu> a;
  if (!nb::try_cast(d[key], a)) throw std::invalid_argument(std::string("block ") + key + ": not a C-contiguous array");
  if (a.dtype() != nb::dtype<S>()) throw std::invalid_argument(std::string("block ") + key + ": wrong dtype");
  if (a.ndim() != (trailing == 1 ? 1u : 2u) || (trailing != 1 && static_cast<std::int64_t>(a.shape(1)) != trailing))
    throw std::invalid_argument(std::string("block ") + key + ": wrong shape");
  const auto c = static_cast<std::int64_t>(a.shape(0));
  if (rows >= 0 && c != rows) throw std::invalid_argument(std::string("block ") + key + ": rows differ from the other contact arrays'");
  rows = c;
  return static_cast<S*>(a.data());
}

template <class S, int D>
S* block_array(nb::dict d, const char* key, Block<D>& b, std::vector<std::int64_t> trailing) {
  if (!d.contains(key)) return nullptr;
  nb::ndarray<nb::c_contig, nb::device::cpu> a;
  if (!nb::try_cast(d[key], a)) throw std::invalid_argument(std::string("block ") + key + ": not a C-contiguous array");
  if (a.dtype() != nb::dtype<S>()) throw std::invalid_argument(std::string("block ") + key + ": wrong dtype");
  if (a.ndim() != 1 + trailing.size()) throw std::invalid_argument(std::string("block ") + key + ": wrong number of dimensions");
  std::size_t k = 1;
  for (auto t : trailing)
    if (static_cast<std::int64_t>(a.shape(k++)) != t) throw std::invalid_argument(std::string("block ") + key + ": wrong shape");
  const auto rows = static_cast<std::int64_t>(a.shape(0));
  if (b.rows >= 0 && rows != b.rows) throw std::invalid_argument(std::string("block ") + key + ": rows differ from the other arrays'");
  b.rows = rows;
  return static_cast<S*>(a.data());
}

// The trailing shape of a per-body series of k doubles per body: (N,) when k is 1 (2D
// angles and angular velocities), else (N, k).
std::vector<std::int64_t> per_body(std::int64_t n, int k) {
  return k == 1 ? std::vector<std::int64_t>{n} : std::vector<std::int64_t>{n, k};
}
std::vector<std::int64_t> per_frame(int k) {
  return k == 1 ? std::vector<std::int64_t>{} : std::vector<std::int64_t>{k};
}

// A block of B frames of N bodies: a dict of C-contiguous arrays whose first dimension is
// B. Keys (each optional): step (B,) int64, time (B,) float64 s, position and velocity
// (B,N,D), orientation (B,N,2) / (B,N,4), angular_velocity (B,N) / (B,N,3), in 2D angle
// (B,N), in 3D body_angular_momentum (B,N,3), all float64; kinetic_energy,
// potential_energy (B,), linear_momentum (B,D), angular_momentum (B,) / (B,3) float64;
// contact_count (B,) int64. With contact points (output.contacts): contact_start and
// contact_points (B,) int64, each frame's first row and count (filled by the recorder),
// and the rows, C of them: contact_body (C,2) int64, contact_position and contact_normal
// (C,D), contact_force (C,) float64 (record_contacts).
template <int D>
Block<D> make_block(World<D>& w, nb::dict d) {
  using Wd = FrameWidth<D>;
  Block<D> b;
  const std::int64_t n = w.model.body_count();
  b.n = n;
  b.step = block_array<std::int64_t>(d, "step", b, {});
  b.time = block_array<double>(d, "time", b, {});
  b.base.position = block_array<double>(d, "position", b, {n, Wd::vec});
  b.base.orientation = block_array<double>(d, "orientation", b, {n, Wd::rot});
  if constexpr (D == 2) b.base.angle = block_array<double>(d, "angle", b, {n});
  b.base.velocity = block_array<double>(d, "velocity", b, {n, Wd::vec});
  b.base.angular_velocity = block_array<double>(d, "angular_velocity", b, per_body(n, Wd::ang));
  if constexpr (D == 3)
    b.base.body_angular_momentum = block_array<double>(d, "body_angular_momentum", b, {n, 3});
  b.base.kinetic_energy = block_array<double>(d, "kinetic_energy", b, {});
  b.base.potential_energy = block_array<double>(d, "potential_energy", b, {});
  b.base.linear_momentum = block_array<double>(d, "linear_momentum", b, {Wd::vec});
  b.base.angular_momentum = block_array<double>(d, "angular_momentum", b, per_frame(Wd::ang));
  b.base.contact_count = block_array<std::int64_t>(d, "contact_count", b, {});
  b.contact_start = block_array<std::int64_t>(d, "contact_start", b, {});
  b.contact_points = block_array<std::int64_t>(d, "contact_points", b, {});
  if ((b.contact_start == nullptr) != (b.contact_points == nullptr))
    throw std::invalid_argument("block contact_start and contact_points: give both or neither");
  std::int64_t c = -1;
  b.contacts.body = contact_array<std::int64_t>(d, "contact_body", 2, c);
  b.contacts.position = contact_array<double>(d, "contact_position", D, c);
  b.contacts.normal = contact_array<double>(d, "contact_normal", D, c);
  b.contacts.force = contact_array<double>(d, "contact_force", 1, c);
  b.contacts.capacity = c < 0 ? 0 : c;
  if (b.rows < 0) b.rows = 0;
  return b;
}

// Record the world's current state as frame r of the block. Returns 0, or, when the
// block records contacts and this frame's do not fit in its contact rows, how many more
// rows it needs (the frame is then not recorded: grow the rows and record it again).
template <int D>
std::int64_t record_row(const World<D>& w, const Block<D>& b, std::int64_t r) {
  using Wd = FrameWidth<D>;
  if (b.contact_start) {
    // this frame's rows follow the block's earlier frames'
    const std::int64_t first = r == 0 ? 0 : b.contact_start[r - 1] + b.contact_points[r - 1];
    if (first < 0 || first > b.contacts.capacity)
      throw std::invalid_argument("block contact_start: rows outside the contact arrays");
    ContactRows<D> rows = b.contacts;
    rows.capacity = b.contacts.capacity - first;
    auto shift = [first](auto* p, std::int64_t width) { return p ? p + first * width : nullptr; };
    rows.body = shift(rows.body, 2);
    rows.position = shift(rows.position, D);
    rows.normal = shift(rows.normal, D);
    rows.force = shift(rows.force, 1);
    const std::int64_t count = record_contacts(w, rows);
    if (count > rows.capacity) return count - rows.capacity;
    b.contact_start[r] = first;
    b.contact_points[r] = count;
  }
  auto at = [r](auto* p, std::int64_t width) { return p ? p + r * width : nullptr; };
  const std::int64_t n = b.n;
  FrameRow<D> row{at(b.base.position, Wd::vec * n),  at(b.base.orientation, Wd::rot * n),
                  at(b.base.angle, n),               at(b.base.velocity, Wd::vec * n),
                  at(b.base.angular_velocity, Wd::ang * n),
                  at(b.base.body_angular_momentum, 3 * n),
                  at(b.base.kinetic_energy, 1),      at(b.base.potential_energy, 1),
                  at(b.base.linear_momentum, Wd::vec), at(b.base.angular_momentum, Wd::ang),
                  at(b.base.contact_count, 1)};
  record_frame(w, row);
  if (b.step) b.step[r] = w.step_index;
  if (b.time) b.time[r] = static_cast<double>(w.step_index) * w.config.dt;
  return 0;
}
// ---- end output frames ---------------------------------------------------------------

// The methods World2 and World3 share: building, stepping, recording frames,
// checkpoints, the step index, the state as views.
template <int D>
nb::class_<World<D>> bind_world(nb::module_& mod, const char* name, const char* doc) {
  using W = World<D>;
  nb::class_<W> cls(mod, name, doc);
  cls.def("__init__",
          [](W* self, nb::dict model, nb::dict state, nb::dict config) {
            auto w = make_world<D>(model, state, config);
            new (self) W(std::move(*w));
          },
          "model"_a, "state"_a, "config"_a,
          "Build from the scene compiler's arrays (SI units); arrays are copied and checked "
          "(ValueError naming the array when one has the wrong dtype or shape).")
      .def(
          "advance",
          [](W& w, std::int64_t n) {
            if (n < 0) throw std::invalid_argument("n_steps must be >= 0");
            if (w.torn) throw std::runtime_error(torn_message(w));
            std::int64_t taken = 0, bad = -1;
            Status status = Status::Ok;
            bool signalled = false;
            {
              // one step at a time, with the signal handlers run every 20 ms between two
              // steps (Ctrl-C stops a long chunk); the steps are the same as in one call
              // (None as a plain handle: no reference counting while the GIL is released)
              const nb::handle no_stop(Py_None);
              nb::gil_scoped_release release;
              SignalPoll poll;
              Interrupts<D> interrupted(w, poll, no_stop, false);
              while (taken < n && status == Status::Ok) {
                std::int64_t one = 0;
                status = w.advance(1, &one, &bad);
                taken += one;
                if (status == Status::Interrupted || (taken < n && interrupted())) {
                  signalled = true;
                  break;
                }
              }
              interrupted.rethrow();
            }
            // a handler raised: the state is whole steps, or the world is torn (a long
            // step stopped inside)
            if (signalled) throw nb::python_error();
            return std::make_tuple(static_cast<int>(status), taken, bad);
          },
          "n_steps"_a,
          "Take up to n_steps steps; returns (status, steps taken, bad body). Between steps, "
          "and inside a step that may take a quarter of a second or more, the signal "
          "handlers run (every 20 ms); an exception one raises propagates (inside a step: "
          "the world is then torn, see `torn`).")
      .def(
          "advance_recording",
          [](W& w, std::int64_t n, std::int64_t every, std::int64_t last, nb::dict block,
             std::int64_t row, nb::object stop) {
            if (n < 0) throw std::invalid_argument("n_steps must be >= 0");
            if (every < 1) throw std::invalid_argument("every must be >= 1");
            if (w.torn) throw std::runtime_error(torn_message(w));
            Block<D> b = make_block(w, block);
            if (row < 0 || row > b.rows) throw std::invalid_argument("row outside the block");
            if (b.contact_start) w.contacts.record_impulses = true;  // (their mean forces)
            std::int64_t taken = 0, bad = -1, written = 0;
            Status status = Status::Ok;
            bool signalled = false, full = false;
            {
              // the signal handlers run every 20 ms between two steps; one that raises
              // (the run's, for Ctrl-C) ends the call after whole steps, with every
              // frame recorded so far, and the call returns INTERRUPTED
              nb::gil_scoped_release release;
              SignalPoll poll;
              Interrupts<D> interrupted(w, poll, stop, true);
              while (taken < n && row + written < b.rows) {
                std::int64_t one = 0;
                status = w.advance(1, &one, &bad);
                taken += one;
                if (status == Status::Interrupted) {
                  signalled = true;
                  break;
                }
                if (status != Status::Ok) break;
                if (w.step_index % every == 0 || w.step_index == last) {
                  if (record_row(w, b, row + written) > 0) {
                    full = true;
                    break;
                  }
                  ++written;
                }
                if (taken < n && interrupted()) {
                  signalled = true;
                  break;
                }
              }
              interrupted.rethrow();
            }
            const int code =
                signalled ? INTERRUPTED : full ? CONTACTS_FULL : static_cast<int>(status);
            return std::make_tuple(code, taken, written, bad);
          },
          "n_steps"_a, "every"_a, "last_step"_a, "block"_a, "row"_a, "stop"_a = nb::none(),
          "Take up to n_steps steps, recording a frame into block (a dict of arrays, rows "
          "from `row` on) after each step that is a multiple of `every` or is `last_step`; "
          "stops early when the block is full, or with status INTERRUPTED when, between two "
          "steps or inside a long one (every 20 ms; inside a step it leaves the world torn), "
          "a signal handler raised or stop() is true, or with status "
          "CONTACTS_FULL when a frame's contact points do not fit in the block's contact rows "
          "(the step is taken, its frame not recorded). Returns (status, steps taken, "
          "frames recorded, bad body).")
      .def(
          "record",
          [](W& w, nb::dict block, std::int64_t row) {
            Block<D> b = make_block(w, block);
            if (row < 0 || row >= b.rows) throw std::invalid_argument("row outside the block");
            return record_row(w, b, row);
          },
          "block"_a, "row"_a,
          "Record the current state as frame `row` of block. Returns 0, or, when the "
          "frame's contact points do not fit in the block's contact rows, how many more "
          "rows it needs (the frame is then not recorded).")
      .def(
          "save_checkpoint",
          [](const W& w) {
            if (w.torn) throw std::runtime_error(torn_message(w));
            // written straight into the bytes object (a large store's checkpoint is
            // hundreds of MB: one copy, not two)
            const std::size_t size = checkpoint_size(w);
            PyObject* out = PyBytes_FromStringAndSize(nullptr, static_cast<Py_ssize_t>(size));
            if (out == nullptr) throw nb::python_error();
            save_checkpoint_to(w, reinterpret_cast<std::uint8_t*>(PyBytes_AS_STRING(out)));
            return nb::steal<nb::bytes>(out);
          },
          "The world's whole changing state (state, step index, broadphase, contact store) "
          "as bytes.")
      .def("checkpoint_size", [](const W& w) { return checkpoint_size(w); },
           "Bytes save_checkpoint would return now.")
      .def(
          "load_checkpoint",
          [](W& w, nb::bytes data) {
            load_checkpoint(w, reinterpret_cast<const std::uint8_t*>(data.c_str()), data.size());
          },
          "data"_a, "Restore a checkpoint of a world built from the same scene.")
      .def("step", &W::step, "One step; False when the contact store must grow first.")
      .def("grow", [](W& w, std::int64_t capacity) { w.grow(capacity); }, "capacity"_a,
           "Room for `capacity` manifolds and pairs.")
      .def("grow_store", [](W& w, std::int64_t manifolds, std::int64_t pairs) {
             w.grow_store(manifolds, pairs);
           }, "manifolds"_a, "pairs"_a,
           "Room for at least `manifolds` manifolds and `pairs` pairs (what lacks it grows).")
      .def_prop_ro("contact_count", &W::contact_count)
      .def_rw("step_index", &W::step_index)
      .def("pair_limit", &W::pair_limit,
           "The most contact pairs a step may hold; advance stops with TOO_MANY_PAIRS beyond.")
      .def_ro("pairs_wanted", &W::pairs_wanted,
              "The contact pairs of the step refused with TOO_MANY_PAIRS.")
      .def_rw("last_step_seconds", &W::last_step_seconds,
              "Wall time (s) of the last step taken (-1 before any); a step after one of a "
              "quarter of a second or more is asked for signals inside too.")
      .def_ro("torn", &W::torn,
              "True after a long step was stopped inside by a signal: the state is partway "
              "through it, and advance and save_checkpoint raise RuntimeError.")
      .def_rw("profile", &W::profile, "Accumulate each stage's wall time (stage_times).")
      .def_prop_rw(
          "record_contact_impulses", [](const W& w) { return w.contacts.record_impulses; },
          [](W& w, bool on) { w.contacts.record_impulses = on; },
          "Keep each contact point's normal impulse over the whole step, so that recorded "
          "contact points (record, advance_recording) carry their mean force over the step "
          "(N); off, the last substep's. advance_recording turns it on for a block with "
          "contact rows. Reading only: the steps are the same either way.")
      .def(
          "stage_times",
          [](W& w) {
            nb::dict d;
            for (int k = 0; k < static_cast<int>(StageId::Count); ++k)
              d[STAGE_NAMES[k]] = w.stage_seconds[k];
            return d;
          },
          "Seconds spent in each stage since profiling began.")
      .def_ro("parallel_seconds", &W::parallel_seconds,
              "Seconds (wall) since profiling began of the work the step splits over its "
              "threads (what more threads shorten; the stages' other time is serial).")
      .def_prop_ro(
          "region_task_seconds",
          [](const W& w) {
            nb::dict d;
            d["alone"] = nb::make_tuple(w.region_task_seconds[0], w.region_task_passes[0]);
            d["paired"] = nb::make_tuple(w.region_task_seconds[1], w.region_task_passes[1]);
            return d;
          },
          "With profile set, the solver's region tasks (a scene of more than one region): "
          "(seconds summed over the tasks, passes) run one after the other on one thread "
          "(alone) and side by side on the threads (paired).")
      .def_prop_ro("threads", [](const W& w) { return w.config.threads; },
                   "Threads the step may run on (solver.threads, else the cores).")
      .def_prop_ro("threads_chosen", &W::threads_chosen,
                   "Threads the steps run on: threads, or where the step chooses (solver.threads "
                   "not set) the last trial's faster of one thread and threads.")
      .def_prop_ro("thread_trials",
                   [](const W& w) { return w.thread_choice ? w.thread_choice->trials() : 0; },
                   "The trials of one thread against threads so far (where the step chooses).");
  // the state as views of the engine's arrays (no copies): body_angle is empty in 3D,
  // body_l in 2D
#define RBSIM_STATE(name, doc) \
  cls.def_prop_ro(#name, [](nb::handle self) { return view(nb::cast<W&>(self).state.name, self); }, doc);
  if constexpr (D == 2) {
    RBSIM_STATE(body_x, "(N,2) m, COM positions (a view)")
    RBSIM_STATE(body_q, "(N,2) (cos θ, sin θ) (a view)")
    RBSIM_STATE(body_angle, "(N,) rad, unwrapped (a view)")
    RBSIM_STATE(body_v, "(N,2) m/s, COM velocities (a view)")
    RBSIM_STATE(body_w, "(N,) rad/s (a view)")
    RBSIM_STATE(body_l, "(0,): the 2D angular state is body_w (a view)")
  } else {
    RBSIM_STATE(body_x, "(N,3) m, COM positions (a view)")
    RBSIM_STATE(body_q, "(N,4) unit quaternions (w, x, y, z) (a view)")
    RBSIM_STATE(body_angle, "(0,): no unwrapped angle in 3D (a view)")
    RBSIM_STATE(body_v, "(N,3) m/s, COM velocities (a view)")
    RBSIM_STATE(body_w, "(N,3) rad/s, world frame, R I_b⁻¹ Rᵀ L (a view)")
    RBSIM_STATE(body_l, "(N,3) kg m²/s, angular momentum, world frame about the COM (a view)")
  }
#undef RBSIM_STATE
  return cls;
}

}  // namespace
}  // namespace rbsim

NB_MODULE(_core, mod) {
  using namespace rbsim;
  mod.doc() = "rbsim's compiled engine (C++20). Built by the package; imported by rbsim.core only.";
  bind_world<2>(mod, "World2", "A 2D scene ready to step: model, state and stage storage.")
      .def("stage", &run_stage, "name"_a, "args"_a = nb::dict(), "Run one stage (tests).")
      .def("storage", [](nb::handle self) { return storage(nb::cast<World2&>(self), self); },
           "The stages' storage arrays by name, as views (valid until the next step, which "
           "may swap the store's arrays, or until the store grows).");
  bind_world<3>(mod, "World3",
                "A 3D scene ready to step: model, state and stage storage (the collision "
                "stages also run one by one through `stage`, for tests).")
      .def("stage", &run_stage3, "name"_a, "args"_a = nb::dict(),
           "Run one collision stage (transform_shapes, find_pairs, update_manifolds, "
           "store_impulses) or grow the store (tests).")
      .def("storage", [](nb::handle self) { return storage(nb::cast<World<3>&>(self), self); },
           "The stages' storage arrays by name, as views (valid until the next step, which "
           "may swap the store's arrays, or until the store grows).");
  {
    // the tuning constants, from the one header that defines them (units there)
    namespace C = rbsim::constants;
    nb::dict k;
#define RBSIM_CONSTANT(name) k[#name] = C::name;
    RBSIM_CONSTANT(SPECULATIVE_DISTANCE) RBSIM_CONSTANT(LINEAR_SLOP) RBSIM_CONSTANT(AABB_MARGIN)
    RBSIM_CONSTANT(FLUSH_DISTANCE) RBSIM_CONSTANT(COVERED_MIN_SCALE)
    RBSIM_CONSTANT(CONTACT_HERTZ) RBSIM_CONSTANT(CONTACT_DAMPING_RATIO)
    RBSIM_CONSTANT(CONTACT_PUSH_MAX_VELOCITY) RBSIM_CONSTANT(DEEP_OVERLAP)
    RBSIM_CONSTANT(DEEP_RELAX_FACTOR) RBSIM_CONSTANT(DEEP_RELAX_REACH)
    RBSIM_CONSTANT(STATIC_OVERLAP_LIMIT) RBSIM_CONSTANT(DYNAMIC_OVERLAP_LIMIT)
    RBSIM_CONSTANT(OVERLAP_LIMIT_PASSES) RBSIM_CONSTANT(STILL_DISTANCE) RBSIM_CONSTANT(STILL_ANGLE)
    RBSIM_CONSTANT(RESTITUTION_PASSES) RBSIM_CONSTANT(IMPACT_GAP) RBSIM_CONSTANT(TOI_TOLERANCE) RBSIM_CONSTANT(TOI_ITERATIONS)
    RBSIM_CONSTANT(TOI_FINISH) RBSIM_CONSTANT(REFERENCE_FACE_TOLERANCE) RBSIM_CONSTANT(SEGMENT_SKIN)
    RBSIM_CONSTANT(LINEAR_EPSILON) RBSIM_CONSTANT(SHOCK_COS) RBSIM_CONSTANT(SHOCK_MIN_APPROACH)
    RBSIM_CONSTANT(CELL_SIZES) RBSIM_CONSTANT(TABLE_PER_SHAPE) RBSIM_CONSTANT(BIG_MAX)
    RBSIM_CONSTANT(BIG_CELLS_MAX) RBSIM_CONSTANT(RADIX_BITS) RBSIM_CONSTANT(INSERTION_SORT_MAX)
    RBSIM_CONSTANT(ATAN_SERIES_MAX) RBSIM_CONSTANT(SCALE_LENGTH) RBSIM_CONSTANT(STIFFNESS_LENGTH)
    RBSIM_CONSTANT(HEAVY_RATIO) RBSIM_CONSTANT(SOLVER_REGIONS) RBSIM_CONSTANT(REGION_MIN_BODIES)
    RBSIM_CONSTANT(PAIRS_PER_SHAPE) RBSIM_CONSTANT(PAIRS_FLOOR) RBSIM_CONSTANT(PAIR_WORK_MAX)
    RBSIM_CONSTANT(PAIR_WORK_MAX_3D) RBSIM_CONSTANT(MAX_ROTATION)
#undef RBSIM_CONSTANT
    mod.attr("constants") = k;
  }
  mod.attr("OK") = static_cast<int>(Status::Ok);
  mod.attr("THREADS_MAX") = THREADS_MAX;

  // ---- narrowphase test entry ----
  mod.def("collide2d", &collide2d_py, "kind_a"_a, "start_a"_a, "count_a"_a, "radius_a"_a,
          "kind_b"_a, "start_b"_a, "count_b"_a, "radius_b"_a, "verts"_a, "norms"_a,
          "speculative"_a,
          "One narrowphase manifold (tests): (count, normal (2,), points (2,2), "
          "separations (2,), ids (2,) int64); rows past count are NaN / -1.");
  // ---- end narrowphase test entry ----
  mod.attr("NON_FINITE") = static_cast<int>(Status::NonFinite);
  mod.attr("TOO_MANY_PAIRS") = static_cast<int>(Status::TooManyPairs);
  mod.attr("INTERRUPTED") = INTERRUPTED;
  mod.attr("CONTACTS_FULL") = CONTACTS_FULL;
  mod.attr("POSITION_LIMIT") = POSITION_LIMIT;  // m: beyond it advance reports NON_FINITE

  // ---- tools outside the step: the penetration ruler (cpp/src/tools/separation.cpp) ----
  mod.def(
      "min_separation",
      [](nb::handle verts_in, nb::handle vstart_in, nb::handle vcount_in, nb::handle radius_in,
         nb::handle pairs_in) {
        std::vector<Vec2> verts;
        std::vector<std::int32_t> vstart, vcount;
        std::vector<double> radius;
        std::vector<std::array<std::int32_t, 2>> pairs;
        load(verts, verts_in, "verts");
        load(vstart, vstart_in, "vstart");
        const long s = static_cast<long>(vstart.size());
        load(vcount, vcount_in, "vcount", s);
        load(radius, radius_in, "radius", s);
        load(pairs, pairs_in, "pairs");
        const long nv = static_cast<long>(verts.size());
        for (long i = 0; i < s; ++i)
          if (vstart[i] < 0 || vcount[i] < 1 || vstart[i] + static_cast<long>(vcount[i]) > nv)
            throw std::invalid_argument("min_separation: shape vertices out of range");
        for (const auto& p : pairs)
          if (p[0] < 0 || p[0] >= s || p[1] < 0 || p[1] >= s)
            throw std::invalid_argument("min_separation: pair index out of range");
        const std::size_t n = pairs.size();
        double* out = new double[n > 0 ? n : 1];
        nb::capsule owner(out, [](void* p) noexcept { delete[] static_cast<double*>(p); });
        min_separation(verts.data(), vstart.data(), vcount.data(), radius.data(), pairs.data(),
                       static_cast<std::int64_t>(n), out);
        std::size_t shape[1] = {n};
        return nb::ndarray<nb::numpy, double>(out, 1, shape, owner);
      },
      "verts"_a, "vstart"_a, "vcount"_a, "radius"_a, "pairs"_a,
      "Separation (m) of each shape pair (P,2) int32 from world vertices (V,2) float64, "
      "each shape's first vertex and vertex count (S,) int32 and radius (S,) float64: the "
      "signed distance of the cores minus both radii (reference.py's penetration ruler).");
}
