// Move a dynamic body out of a static or kinematic one where it overlaps by more than
// max_overlap (m, times the contact's scale: SCALE_LENGTH), along the contact normal,
// without touching its velocity.
//
// The soft contacts push overlaps out at a bounded speed, which a pile under permanent
// pressure (more bodies than fit in their box) can outrun: bodies were squeezed into the
// walls until the wall's normal flipped and they left the box. A surface that cannot move
// is rigid, so here the overlap is taken off the position directly. Resting contacts
// overlap far less than max_overlap (a fraction of a millimetre on static ground), so
// this acts only in such overload.
//
// Between two dynamic bodies (limit_dynamic_overlap) the soft contacts carry any resting
// load well within DYNAMIC_OVERLAP_LIMIT, but a body wedged between others (against a
// wall and its neighbour, or between two columns of a pile) is pushed out of both at once
// and held where the pushes balance, centimetres deep, step after step. There both are
// moved apart along the normal by the overlap beyond the limit, a body's share its inverse
// mass's (a heavy body moves little), as Box2D v2's position solver moves them; a few
// passes over the deep pairs let a wedge of three settle. Velocities are not touched, so
// no push-out speed is left to carry up a stack.
//
// The limits are scaled by the shapes' size, which says nothing of how thin a shape is:
// the static limit also lets no step drive a shape deeper than OVERLAP_DEPTH_FRACTION of
// its depth (Model::shape_depth), so that a thin body's core does not reach the static
// surface.
#include <algorithm>
#include <cmath>

#include "collide/toi.hpp"
#include "rbsim/constants.hpp"
#include "rbsim/stages.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace C = constants;

namespace {

// (norm1 and chord, math.hpp: bounds without square roots, for a test made on every
// manifold)

// How far manifold m's deepest point lies beyond `limit` (m) now, its bodies moved as far
// as contacts.body_delta says; <= 0 within it.
template <int D>
double excess_overlap(const Contacts<D>& c, std::int64_t m, double limit) {
  const int a = c.body_a[m], b = c.body_b[m];
  double deepest = 0.0;  // m
  for (int k = 0; k < c.points[m]; ++k)
    deepest = std::min(deepest, point_separation(c, m, k, a, b, c.normal[m]));
  return -deepest - limit;
}

// Move body i by d (m), its motion since the step's start with it.
template <int D>
void shift(State<D>& st, Contacts<D>& c, int i, typename Dim<D>::Vec d) {
  st.body_x[i] += d;
  c.body_delta[i].dx += d;
}

}  // namespace

template <int D>
void limit_static_overlap(const Model<D>& model, State<D>& st, Contacts<D>& c,
                          double max_overlap) {
  using Vec = typename Dim<D>::Vec;
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const bool a_fixed = !model.is_dynamic(a);
    const bool b_fixed = !model.is_dynamic(b);
    if (a_fixed == b_fixed) continue;  // two dynamic bodies (limit_dynamic_overlap) or two fixed
    const int i = b_fixed ? a : b;                        // the moving body
    const Vec out = b_fixed ? c.normal[m] : -c.normal[m];  // the way out for it
    const double scaled = c.scale[m] * max_overlap;       // m
    double push = excess_overlap(c, m, scaled);           // m
    // and no deeper than a fraction of the moving shape's depth where the step itself
    // drove it in (a thin shape let in deeper has its core at the surface, where the next
    // face's normal takes over; one placed that deep, or squeezed there over many steps,
    // is the soft contacts' and the scaled limit's: pushed out of the floor at once, a
    // chip wedged under a wall's foot went up into the wall and was put back by the
    // continuous stage, step after step)
    const double depth = model.shape_depth[b_fixed ? c.shape_a[m] : c.shape_b[m]];
    const double thin = std::max(C::OVERLAP_DEPTH_FRACTION * depth, c.scale[m] * C::LINEAR_SLOP);
    if (thin < scaled) {
      const double driven = -dot(out, c.body_delta[i].dx);  // m: its move in, this step
      if (driven > 0.0) push = std::max(push, std::min(push + (scaled - thin), driven));
    }
    if (push <= 0.0) continue;
    shift(st, c, i, push * out);
  }
}

template <int D>
std::int64_t limit_dynamic_overlap(const Model<D>& model, State<D>& st, Contacts<D>& c,
                                   double max_overlap, int passes) {
  using Vec = typename Dim<D>::Vec;
  const std::int64_t n_man = c.count.manifolds;
  const double* im = model.body_inv_mass.data();
  // the pairs that may be that deep now: their deepest point at the step's start less the
  // most the two bodies' motion since can have closed it. A body's motion bounds how far
  // any point of its shapes has moved (a separation anchor lies within its shape's core
  // reach of the body's centre); the largest of them passes over most manifolds of a
  // resting scene on one comparison each
  auto& motion = c.body_motion;  // m
  std::fill(motion.begin(), motion.end(), 0.0);
  double fastest = 0.0;  // m
  for (int s = 0; s < model.shape_count(); ++s) {
    const int i = model.shape_body[s];
    if (!model.is_dynamic(i)) continue;
    const BodyDelta<D>& d = c.body_delta[i];
    motion[i] = std::max(motion[i], norm1(d.dx) + chord(d.dq) * core_reach(model, s));
    fastest = std::max(fastest, motion[i]);
  }
  std::int64_t n_deep = 0;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const double limit = -c.scale[m] * max_overlap;  // m
    if (c.start_separation[m] - 2.0 * fastest >= limit) continue;
    const int a = c.body_a[m], b = c.body_b[m];
    if (!model.is_dynamic(a) || !model.is_dynamic(b)) continue;
    if (c.start_separation[m] - motion[a] - motion[b] < limit)
      c.overlap_list[n_deep++] = static_cast<std::int32_t>(m);
  }
  std::int64_t moves = 0;
  for (int pass = 0; pass < passes; ++pass) {
    std::int64_t moved = 0;
    for (std::int64_t o = 0; o < n_deep; ++o) {
      const std::int32_t m = c.overlap_list[o];
      // (a pair at the limit, to rounding, is left: another pass would move it by 1e-17 m)
      const double push = excess_overlap(c, m, c.scale[m] * max_overlap);  // m
      if (push <= c.scale[m] * C::LINEAR_EPSILON) continue;
      // the normal points from b to a: a moves along +n, b along -n
      const int a = c.body_a[m], b = c.body_b[m];
      const Vec n = c.normal[m];
      const double share_a = im[a] / (im[a] + im[b]);
      shift(st, c, a, (share_a * push) * n);
      shift(st, c, b, -(((1.0 - share_a) * push) * n));
      ++moved;
    }
    moves += moved;
    if (moved == 0) break;
  }
  return moves;
}

template std::int64_t limit_dynamic_overlap(const Model<2>&, State<2>&, Contacts<2>&, double, int);
template std::int64_t limit_dynamic_overlap(const Model<3>&, State<3>&, Contacts<3>&, double, int);
template void limit_static_overlap(const Model<2>&, State<2>&, Contacts<2>&, double);
template void limit_static_overlap(const Model<3>&, State<3>&, Contacts<3>&, double);

}  // namespace rbsim
