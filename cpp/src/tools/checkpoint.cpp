#include "checkpoint.hpp"

#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace rbsim {
namespace {

// The last byte is the format: E since a 2D batch may hold the manifolds of a cut between
// regions in lanes of their own (WideBatch::cut, contacts.cut_lanes); D: each manifold
// keeps the bodies' offset and rotations it was found at, and no body a reference pose
// (C: the offset only, each body a reference rotation; B: a solver row, and a batch's
// lanes, keep the row's friction load and the counts whether any row holds one; A: the
// contact store keeps each manifold's deepest separation at the step's start and the
// dynamic overlap limit's list; 9: a 2D batch holds its manifolds' impulses while the
// passes run, WideBatch::n0 ...; 8: the contact store keeps each hull's plane offsets and
// vertex spread and no longer the time of impact's room; 7: a solver row, and a 2D
// batch's lanes, keeps the distance within which its points touch and have friction; 6:
// the contact store keeps which manifolds touch and the load each body bears; 5 and
// before: without them; a checkpoint of another format is refused with a message saying
// so).
constexpr char MAGIC[8] = {'R', 'B', 'S', 'I', 'M', 'C', 'K', 'E'};

// Every member of the world that changes while it runs, in one fixed order. A member
// added to State, Grid or Contacts must be added here too: the static_asserts on their
// sizes below fail until it is (and the resume tests check the result bit for bit).
template <int D, class W, class F>
void visit(W& w, F&& f) {
  f(w.step_index);
  auto& s = w.state;
  f(s.body_x), f(s.body_q), f(s.body_angle), f(s.body_v), f(s.body_w), f(s.body_l);
  auto& g = w.grid;
  f(g.inv_cell), f(g.shape_aabb), f(g.shape_fat), f(g.shape_moved), f(g.shape_big);
  f(g.shape_cell), f(g.shape_bucket), f(g.entry_shape), f(g.entry_cell), f(g.entry_fat);
  f(g.entry_tag), f(g.bucket_start), f(g.big_list), f(g.span), f(g.frame_origin), f(g.frame_offset), f(g.meta), f(g.new_keys);
  f(g.kept), f(g.sort_scratch), f(g.sort_count);
  auto& c = w.contacts;
  f(c.count), f(c.carried), f(c.pairs), f(c.shape_a), f(c.shape_b), f(c.body_a), f(c.body_b);
  f(c.key), f(c.normal), f(c.points), f(c.friction), f(c.restitution), f(c.anchor_a);
  f(c.anchor_b), f(c.base_separation), f(c.ref_separation), f(c.feature), f(c.normal_impulse);
  f(c.start_separation), f(c.overlap_list), f(c.body_motion);
  f(c.start_impulse), f(c.tangent_impulse), f(c.normal_mass), f(c.solver_row);
  f(c.approach_velocity), f(c.approach_separation), f(c.max_normal_impulse), f(c.prev_key);
  f(c.prev_points), f(c.prev_feature), f(c.prev_normal_impulse), f(c.prev_tangent_impulse);
  f(c.prev_normal), f(c.prev_anchor_a), f(c.prev_anchor_b), f(c.prev_ref_separation);
  f(c.ref_offset), f(c.prev_ref_offset), f(c.ref_turn_a), f(c.ref_turn_b);
  f(c.prev_ref_turn_a), f(c.prev_ref_turn_b);
  f(c.sep_anchor_a), f(c.sep_anchor_b), f(c.prev_sep_anchor_a), f(c.prev_sep_anchor_b);
  f(c.scale), f(c.shape_size), f(c.shape_scale), f(c.body_scale);
  f(c.body_delta), f(c.body_inv_inertia_world);
  f(c.body_inertia_q);
  f(c.vert_world), f(c.norm_world), f(c.face_world), f(c.face_offset), f(c.shape_spread);
  f(c.shape_margin), f(c.shape_turn);
  f(c.body_level);
  f(c.support), f(c.prev_support), f(c.body_load), f(c.shock_side);
  f(c.shock_order), f(c.solve_order), f(c.adj_start), f(c.adj), f(c.queue), f(c.bounce_kind);
  f(c.body_mark), f(c.solve_impulse), f(c.bounce_list), f(c.relax_list), f(c.body_reach);
  f(c.wave_count), f(c.waves_valid), f(c.heavy_on_light), f(c.unit_scale), f(c.wave_order), f(c.manifold_wave), f(c.body_wave);
  f(c.wave_start), f(c.wave_batch), f(c.wave_single), f(c.wave_single_batch), f(c.batches);
  f(c.cut_lanes);
  f(c.region_count), f(c.body_region), f(c.segment_order), f(c.segment_wave), f(c.segment_shock);
  f(c.wave_idle);  // (3D: made anew in every step, as batches3 and faces3, but sized by the store)
  // (not c.batches3, c.faces3: 3D packs them anew in every step, before any pass reads them;
  // not c.impulses_in_lanes: false between steps, the store holding the impulses, and the
  // batches' copies taken anew by the next step's passes; not c.step_impulse,
  // c.shock_impulse, c.shock_points and c.record_impulses: a step's own, set to zero at its
  // start, and the run's setting; not c.body_carried: made anew by each step's
  // friction_loads before the shock pass reads it; not c.body_supporters: made anew by
  // each step's support_order; not c.prev_pending, c.prev_swapped: false between advance
  // calls (settle_prev); not c.body_row_remade: used
  // within a step; not c.turn_watch: made from the model at allocate, its rotations at each
  // step's start)
}

constexpr std::size_t VEC = sizeof(std::vector<int>);
static_assert(sizeof(State<2>) == 6 * VEC, "State changed: update visit()");
static_assert(sizeof(State<3>) == 6 * VEC, "State changed: update visit()");
static_assert(sizeof(Grid<2>) == 8 + 16 * VEC + 3 * sizeof(Vec2) + sizeof(GridMeta<2>),
              "Grid changed: update visit()");
static_assert(sizeof(Grid<3>) == 8 + 16 * VEC + 3 * sizeof(Vec3) + sizeof(GridMeta<3>),
              "Grid changed: update visit()");
static_assert(sizeof(Contacts<2>) == sizeof(ContactCounts) + 98 * VEC + 8 + 8 + 8,
              "Contacts changed: update visit()");
static_assert(sizeof(Contacts<3>) == sizeof(ContactCounts) + 98 * VEC + 8 + 8 + 8,
              "Contacts changed: update visit()");

template <class T>
struct is_vector : std::false_type {};
template <class T, class A>
struct is_vector<std::vector<T, A>> : std::true_type {};

// Elements of v up to its last one that is not all zero bytes. The store's arrays have
// room for more manifolds and pairs than a step holds, and room never used is zeros:
// the checkpoint writes an array's length and its elements up to there only (a pile of
// 40,000 circles: 2.1 GB of room, about half of it never used).
template <class T>
std::size_t used_length(const std::vector<T>& v) {
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(v.data());
  std::size_t end = v.size() * sizeof(T);
  for (std::uint64_t word = 0; end >= 8; end -= 8) {  // 8 bytes at a time, then 1
    std::memcpy(&word, bytes + end - 8, 8);
    if (word != 0) break;
  }
  while (end > 0 && bytes[end - 1] == 0) --end;
  return (end + sizeof(T) - 1) / sizeof(T);
}

// Writes at `out` (room for checkpoint_size's count), or, with out null, only counts.
struct Writer {
  std::uint8_t* out = nullptr;
  std::size_t size = 0;
  void bytes(const void* p, std::size_t n) {
    if (out && n) std::memcpy(out + size, p, n);
    size += n;
  }
  template <class T>
  void operator()(const T& v) {
    if constexpr (is_vector<T>::value) {
      static_assert(std::is_trivially_copyable_v<typename T::value_type>);
      const std::uint64_t n = v.size(), k = used_length(v);
      bytes(&n, sizeof n);
      bytes(&k, sizeof k);
      bytes(v.data(), k * sizeof(typename T::value_type));
    } else {
      static_assert(std::is_trivially_copyable_v<T>);
      bytes(&v, sizeof v);
    }
  }
};

struct Reader {
  const std::uint8_t* p;
  const std::uint8_t* end;
  void bytes(void* dst, std::size_t n) {
    if (static_cast<std::size_t>(end - p) < n) throw std::invalid_argument("checkpoint: truncated");
    if (n) std::memcpy(dst, p, n);
    p += n;
  }
  template <class T>
  void operator()(T& v) {
    if constexpr (is_vector<T>::value) {
      std::uint64_t n = 0, k = 0;
      bytes(&n, sizeof n);
      bytes(&k, sizeof k);
      using E = typename T::value_type;
      // the room (n) at most 1 TB: far above any store, and a corrupt length cannot ask
      // for exabytes
      if (k > n || k > static_cast<std::uint64_t>(end - p) / sizeof(E) ||
          n > (std::uint64_t{1} << 40) / sizeof(E))
        throw std::invalid_argument("checkpoint: truncated");
      v.resize(n);
      bytes(v.data(), k * sizeof(E));
      // the bytes after the k elements written are zeros, as they were (resize's new
      // elements are their type's defaults, which need not be zeros)
      if (n > k) std::memset(static_cast<void*>(v.data() + k), 0, (n - k) * sizeof(E));
    } else {
      bytes(&v, sizeof v);
    }
  }
};

struct Sizes {
  std::int64_t dimension, bodies, shapes, vertices;
};

template <int D>
Sizes sizes_of(const World<D>& w) {
  return {D, w.model.body_count(), w.model.shape_count(), w.model.vertex_count()};
}

template <int D>
void write_all(const World<D>& world, Writer& wr) {
  wr.bytes(MAGIC, sizeof MAGIC);
  const Sizes sz = sizes_of(world);
  wr.bytes(&sz, sizeof sz);
  visit<D>(world, wr);
}

}  // namespace

template <int D>
std::size_t checkpoint_size(const World<D>& world) {
  Writer count;
  write_all(world, count);
  return count.size;
}

template <int D>
void save_checkpoint_to(const World<D>& world, std::uint8_t* out) {
  Writer wr{out};
  write_all(world, wr);
}

template <int D>
std::vector<std::uint8_t> save_checkpoint(const World<D>& world) {
  std::vector<std::uint8_t> out(checkpoint_size(world));
  save_checkpoint_to(world, out.data());
  return out;
}

template <int D>
void load_checkpoint(World<D>& world, const std::uint8_t* data, std::size_t size) {
  Reader rd{data, data + size};
  char magic[8];
  rd.bytes(magic, sizeof magic);
  if (std::memcmp(magic, MAGIC, sizeof MAGIC - 1) == 0 && magic[7] != MAGIC[7])
    throw std::invalid_argument(std::string("checkpoint: made by another version of rbsim's engine "
                                            "(format ") + magic[7] + ", this one reads " +
                                MAGIC[7] + "): resume it with the version that wrote it");
  if (std::memcmp(magic, MAGIC, sizeof MAGIC) != 0)
    throw std::invalid_argument("checkpoint: not an rbsim engine checkpoint");
  Sizes sz{}, want = sizes_of(world);
  rd.bytes(&sz, sizeof sz);
  if (std::memcmp(&sz, &want, sizeof sz) != 0)
    throw std::invalid_argument(
        "checkpoint: made for a world of " + std::to_string(sz.bodies) + " bodies, " +
        std::to_string(sz.shapes) + " shapes (this one has " + std::to_string(want.bodies) +
        ", " + std::to_string(want.shapes) + ")");
  World<D> copy;  // read into a copy, so that a bad checkpoint leaves the world as it was
  copy.model = world.model;
  copy.config = world.config;
  visit<D>(copy, rd);
  if (rd.p != rd.end) throw std::invalid_argument("checkpoint: trailing bytes");
  // the step's own arrays, not in the checkpoint: room as the store's, and the run's setting
  auto& c = copy.contacts;
  const std::size_t room = c.normal_impulse.size();
  c.step_impulse.assign(room, {});
  c.shock_impulse.assign(room, 0.0);
  c.shock_points.assign(room, 0);
  c.body_carried.assign(c.body_load.size(), -1);
  c.record_impulses = world.contacts.record_impulses;
  world = std::move(copy);
}

template std::size_t checkpoint_size(const World<2>&);
template std::size_t checkpoint_size(const World<3>&);
template void save_checkpoint_to(const World<2>&, std::uint8_t*);
template void save_checkpoint_to(const World<3>&, std::uint8_t*);
template std::vector<std::uint8_t> save_checkpoint(const World<2>&);
template void load_checkpoint(World<2>&, const std::uint8_t*, std::size_t);
template std::vector<std::uint8_t> save_checkpoint(const World<3>&);
template void load_checkpoint(World<3>&, const std::uint8_t*, std::size_t);

}  // namespace rbsim
