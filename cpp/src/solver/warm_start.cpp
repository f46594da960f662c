// Warm start: last substep's accumulated impulses applied again at the start of the
// substep's solve (they are impulses per substep, so the solver starts from the answer
// of the last one and only corrects it).
#include "rbsim/stages.hpp"
#include "rbsim/wide.hpp"
#include "solver/row.hpp"

namespace rbsim {

namespace {

// 3D: each point's normal impulse and its friction impulse, a world vector in the tangent
// plane (taken in the plane of this step's normal: the part along n is dropped, so that a
// normal turned since the impulse was stored adds no push), on each body's v and L.
// The manifolds order[first..last), or, with order null, manifolds first..last.
void warm_start_3d(const Model<3>& model, State<3>& st, Contacts<3>& c,
                   const std::int32_t* order, std::int64_t first, std::int64_t last) {
  const auto& im = model.body_inv_mass;
  for (std::int64_t o = first; o < last; ++o) {
    const std::int64_t m = order ? order[o] : o;
    // a manifold that holds no impulse has none to apply (in a heap, half of them: the
    // speculative contacts of neighbours not yet touching)
    if (!holds_any(c, m)) continue;
    const int a = c.body_a[m], b = c.body_b[m];
    const auto& row = c.solver_row[m];
    const Vec3 n = row.normal, t1 = row.t1, t2 = row.t2;
    // each point's impulse along n, t1 and t2 (N·s; a point past the count: zero), the
    // points in lanes; its moment about a's COM is r_a × (j n + j1 t1 + j2 t2) =
    // j (r_a × n) + j1 (r_a × t1) + j2 (r_a × t2), the row's levers (b's likewise)
    alignas(32) double e1[4] = {0.0, 0.0, 0.0, 0.0}, e2[4] = {0.0, 0.0, 0.0, 0.0};
    for (int k = 0; k < c.points[m]; ++k) {
      const Vec3 jt = c.tangent_impulse[m][k];
      e1[k] = dot(jt, t1);
      e2[k] = dot(jt, t2);
    }
    const SolverRow<3>::Points& P = row.point;
    const Lanes j = select(first_lanes(c.points[m]), load_lanes(c.normal_impulse[m].data()), splat(0.0));
    const Lanes j1 = load_lanes(e1), j2 = load_lanes(e2);
    auto moment = [&](const double* rn, const double* r1, const double* r2) {
      return j * load_lanes(rn) + j1 * load_lanes(r1) + j2 * load_lanes(r2);
    };
    const Lanes s0 = sum_lanes(j, j1, j2, moment(P.rna.x, P.rt1a.x, P.rt2a.x));
    const Lanes s1 = sum_lanes(moment(P.rna.y, P.rt1a.y, P.rt2a.y), moment(P.rna.z, P.rt1a.z, P.rt2a.z),
                               moment(P.rnb.x, P.rt1b.x, P.rt2b.x), moment(P.rnb.y, P.rt1b.y, P.rt2b.y));
    const double lbz = [&] {
      const Lanes z = moment(P.rnb.z, P.rt1b.z, P.rt2b.z);
      return (z[0] + z[1]) + (z[2] + z[3]);
    }();
    const Vec3 p = s0[0] * n + (s0[1] * t1 + s0[2] * t2);  // N·s
    const Vec3 la{s0[3], s1[0], s1[1]}, lb{s1[2], s1[3], lbz};  // N·m·s
    if (im[a] != 0.0) {
      st.body_v[a] += im[a] * p;
      add_momentum(st, a, row.inv_ia, la);
    }
    if (im[b] != 0.0) {
      st.body_v[b] -= im[b] * p;
      add_momentum(st, b, row.inv_ib, -lb);
    }
  }
}

}  // namespace

template <int D>
void warm_start(const Model<D>& model, State<D>& st, Contacts<D>& c) {
  if constexpr (D == 3) {
    warm_start_3d(model, st, c, nullptr, 0, c.count.manifolds);
  } else {
  using Vec = typename Dim<D>::Vec;
  const auto& im = model.body_inv_mass;
  const auto& ii = model.body_inv_inertia;
  const std::int64_t n_man = c.count.manifolds;
  for (std::int64_t m = 0; m < n_man; ++m) {
    const int a = c.body_a[m], b = c.body_b[m];
    const auto& row = c.solver_row[m];
    const Vec n = row.normal;
    const Vec t = cross(n, 1.0);  // (n_y, −n_x)
    // the manifold's impulse (N·s) and its moments on each body (N·m·s)
    Vec p{};
    double ta = 0.0, tb = 0.0;
    const int npts = c.points[m];
    for (int k = 0; k < npts; ++k) {
      const auto& pt = row.point[k];
      const double jn = c.normal_impulse[m][k], jt = c.tangent_impulse[m][k];
      p += jn * n + jt * t;
      ta += jn * pt.rna + jt * pt.rta;
      tb += jn * pt.rnb + jt * pt.rtb;
    }
    const double ma = im[a], mb = im[b], ia = ii[a], ib = ii[b];
    // a fixed body is not written (see solve_contacts)
    if (ma != 0.0 || ia != 0.0) {
      st.body_v[a] += ma * p;
      st.body_w[a] += ia * ta;
    }
    if (mb != 0.0 || ib != 0.0) {
      st.body_v[b] -= mb * p;
      st.body_w[b] -= ib * tb;
    }
  }
  }
}

template void warm_start(const Model<2>&, State<2>&, Contacts<2>&);
template void warm_start(const Model<3>&, State<3>&, Contacts<3>&);

namespace {

// One batch of a wave (waves.cpp): the same impulses, LANES manifolds at a time. A wave's
// manifolds share no dynamic body, so the order in which their impulses reach the bodies
// changes only the rounding of the sums.
template <bool TWO>
void warm_start_batch(State<2>& st, const WideBatch& B, unsigned only = ALL_LANES) {
  static_assert(LANES == 4, "the gathers below are written for four lanes");
  const Lanes nx = B.nx, ny = B.ny;
  const Lanes tx = ny, ty = -nx;  // t = (n_y, −n_x)
  // the impulses are the batch's own (take_impulses); a one-point batch's point 1 is zero
  const Lanes jn0 = B.n0, jt0 = B.t0, jn1 = TWO ? B.n1 : splat(0.0), jt1 = TWO ? B.t1 : splat(0.0);
  // a batch whose manifolds hold nothing has nothing to apply (find_waves packs those
  // that hold an impulse first: in a pyramid, the speculative contacts between the
  // boxes side by side, a quarter of its manifolds; in a pile, the neighbours not yet
  // touching)
  const Lanes zero = splat(0.0);
  if (!any((jn0 != zero) | (jt0 != zero) | (jn1 != zero) | (jt1 != zero))) return;
  // the manifold's impulse (N·s) and its moments on each body (N·m·s)
  Lanes px = jn0 * nx + jt0 * tx, py = jn0 * ny + jt0 * ty;
  Lanes ta = jn0 * B.p0.rna + jt0 * B.p0.rta, tb = jn0 * B.p0.rnb + jt0 * B.p0.rtb;
  if constexpr (TWO) {
    px += jn1 * nx + jt1 * tx;
    py += jn1 * ny + jt1 * ty;
    ta += jn1 * B.p1.rna + jt1 * B.p1.rta;
    tb += jn1 * B.p1.rnb + jt1 * B.p1.rtb;
  }
  const Lanes ma = B.ma, mb = B.mb, ia = B.ia, ib = B.ib;
  const Lanes dvax = ma * px, dvay = ma * py, dwa = ia * ta;
  const Lanes dvbx = mb * px, dvby = mb * py, dwb = ib * tb;
  Vec2* v = st.body_v.data();
  double* w = st.body_w.data();
  const std::uint32_t writes = B.writes & (only | only << LANES);  // (a lane not taken: none)
  if (writes == ALL_WRITES) {  // every lane's two bodies, as whole vectors
    const int a0 = B.a[0], a1 = B.a[1], a2 = B.a[2], a3 = B.a[3];
    const int b0 = B.b[0], b1 = B.b[1], b2 = B.b[2], b3 = B.b[3];
    Lanes vax, vay, vbx, vby;
    gather_pairs(&v[a0].x, &v[a1].x, &v[a2].x, &v[a3].x, vax, vay);
    gather_pairs(&v[b0].x, &v[b1].x, &v[b2].x, &v[b3].x, vbx, vby);
    const Lanes wa = Lanes{w[a0], w[a1], w[a2], w[a3]} + dwa;
    const Lanes wb = Lanes{w[b0], w[b1], w[b2], w[b3]} - dwb;
    scatter_pairs(&v[a0].x, &v[a1].x, &v[a2].x, &v[a3].x, vax + dvax, vay + dvay);
    scatter_scalars(&w[a0], &w[a1], &w[a2], &w[a3], wa);
    scatter_pairs(&v[b0].x, &v[b1].x, &v[b2].x, &v[b3].x, vbx - dvbx, vby - dvby);
    scatter_scalars(&w[b0], &w[b1], &w[b2], &w[b3], wb);
    return;
  }
  for (int l = 0; l < LANES; ++l) {
    // a fixed body is not written (see solve_contacts)
    if (writes & (1u << l)) {
      v[B.a[l]] += Vec2{dvax[l], dvay[l]};
      w[B.a[l]] += dwa[l];
    }
    if (writes & (1u << (LANES + l))) {
      v[B.b[l]] -= Vec2{dvbx[l], dvby[l]};
      w[B.b[l]] -= dwb[l];
    }
  }
}

}  // namespace

template <int D>
void warm_start_waves(const Model<D>& model, State<D>& st, Contacts<D>& c) {
  if constexpr (D == 3) {
    warm_start(model, st, c);  // 3D: manifold by manifold (its batches are the solve's)
    return;
  } else {
    take_impulses(c);
    warm_start_range(model, st, c, 0, c.wave_count);
    give_impulses(c);
  }
}

template void warm_start_waves(const Model<2>&, State<2>&, Contacts<2>&);
template void warm_start_waves(const Model<3>&, State<3>&, Contacts<3>&);

template <int D>
void warm_start_range(const Model<D>& model, State<D>& st, Contacts<D>& c, std::int64_t first,
                      std::int64_t last, CutLanes lanes) {
  if constexpr (D == 3) {
    warm_start_3d(model, st, c, c.solve_order.data(), first, last);
  } else {
    for (std::int64_t g = first; g < last; ++g) {
      const std::int64_t single = c.wave_single_batch[g];
      for (std::int64_t i = c.wave_batch[g]; i < c.wave_batch[g + 1]; ++i) {
        const WideBatch& B = c.batches[i];
        const unsigned only = cut_lanes_taken(lanes, B.cut);
        if (only == 0) continue;
        if (i < single)
          warm_start_batch<true>(st, B, only);
        else
          warm_start_batch<false>(st, B, only);
      }
    }
  }
}

template void warm_start_range(const Model<2>&, State<2>&, Contacts<2>&, std::int64_t,
                               std::int64_t, CutLanes);
template void warm_start_range(const Model<3>&, State<3>&, Contacts<3>&, std::int64_t,
                               std::int64_t, CutLanes);

}  // namespace rbsim
