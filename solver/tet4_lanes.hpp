// Lanes of GCC vector types for the tetrahedron's element loop (tet4_kernels.cpp): one element per
// lane, W lanes (8 with AVX-512, 4 with AVX2, 2 with SSE2), and the few helpers the hand-vectorised
// loop uses. Everything here is always inlined into the per-ISA loop functions: no vector crosses
// a call (a file that includes this is built with -Wno-psabi for that reason).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <utility>

#include "continuum.hpp"
#include "node_layout.hpp"
#include "vector_math.hpp"

namespace softshock::tet4_lanes {

// W lanes of doubles, floats and 64-bit masks: one tetrahedron per lane (W = 8 with AVX-512, 4 with
// AVX2, 2 with SSE2).
template <std::size_t W>
struct Lanes {
  typedef double D __attribute__((vector_size(8 * W)));
  typedef float F __attribute__((vector_size(4 * W)));
  typedef int64_t M __attribute__((vector_size(8 * W)));
};

template <class V>
SOFTSHOCK_ALWAYS_INLINE V load_lanes(const double* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V>
SOFTSHOCK_ALWAYS_INLINE void store_lanes(double* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}
// Single-precision storage, double arithmetic.
template <class V, class F>
SOFTSHOCK_ALWAYS_INLINE V load_float_lanes(const float* p) {
  F v;
  std::memcpy(&v, p, sizeof v);
  return __builtin_convertvector(v, V);
}
template <class V, class F>
SOFTSHOCK_ALWAYS_INLINE void store_float_lanes(float* p, const V& v) {
  const F narrow = __builtin_convertvector(v, F);
  std::memcpy(p, &narrow, sizeof narrow);
}
// The vector {f(0), ..., f(W - 1)}.
template <class V, class F, std::size_t... L>
SOFTSHOCK_ALWAYS_INLINE V make_lanes(F f, std::index_sequence<L...>) {
  return V{f(L)...};
}
// A scalar function of doubles applied lane by lane: GCC vectorises the loop (trip count W) into
// vector instructions, and calls libmvec's W-lane exp, log and cbrt (vector_math.hpp) -- so the
// scalar laws of continuum.hpp (square roots, quotients, the switches) are written once.
template <class V, class Fn, class... A>
SOFTSHOCK_ALWAYS_INLINE V lanewise(Fn fn, const A&... a) {
  constexpr int kW = sizeof(V) / sizeof(double);
  V r;
#pragma omp simd
  for (int l = 0; l < kW; ++l) r[l] = fn(a[l]...);
  return r;
}

// A node row's first four entries: x, y, z, mean stress.
SOFTSHOCK_ALWAYS_INLINE Lanes<4>::D row_head(const PackedNode3& row) {
  typedef double Head __attribute__((vector_size(32), may_alias));
  return *reinterpret_cast<const Head*>(&row.lanes);
}

// The 4 x 4 transpose of four 4-lane vectors (rows in, columns out): node rows (x, y, z, mean
// stress) into the lanes of four elements, and the elements' corner forces back into rows.
SOFTSHOCK_ALWAYS_INLINE void transpose4(const Lanes<4>::D (&in)[4], Lanes<4>::D (&out)[4]) {
  using V = Lanes<4>::D;
  using Index = Lanes<4>::M;
  const V t0 = __builtin_shuffle(in[0], in[1], Index{0, 4, 2, 6});  // a0 b0 a2 b2
  const V t1 = __builtin_shuffle(in[0], in[1], Index{1, 5, 3, 7});  // a1 b1 a3 b3
  const V t2 = __builtin_shuffle(in[2], in[3], Index{0, 4, 2, 6});  // c0 d0 c2 d2
  const V t3 = __builtin_shuffle(in[2], in[3], Index{1, 5, 3, 7});  // c1 d1 c3 d3
  out[0] = __builtin_shuffle(t0, t2, Index{0, 1, 4, 5});
  out[1] = __builtin_shuffle(t1, t3, Index{0, 1, 4, 5});
  out[2] = __builtin_shuffle(t0, t2, Index{2, 3, 6, 7});
  out[3] = __builtin_shuffle(t1, t3, Index{2, 3, 6, 7});
}

}  // namespace softshock::tet4_lanes
