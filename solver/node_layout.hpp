// Per-node rows the hot loops gather from and scatter to: one vector load or store per corner
// instead of one scalar per field and array (indexed node access was the element loop's largest
// cost). GCC lane vectors, so the corner arithmetic runs on all lanes at once; wrapped in structs
// so that std::vector holds them with their alignment.
#pragma once

namespace softshock {

typedef double NodeLanes __attribute__((vector_size(32)));
typedef double ForceLanes __attribute__((vector_size(16)));

// What the element passes read of a node: its current position (written by the predictor, or
// pack_positions) and, for the average nodal pressure element, its Tait state (written by the
// last nodal pass, pack_nodal_state; zero otherwise).
struct alignas(32) PackedNode {
  NodeLanes lanes;  // x, y (m), mean stress (Pa), bulk modulus (Pa)
};

// The internal force on a node, N/m (per metre of thickness).
struct alignas(16) NodeForce {
  ForceLanes lanes;  // x, y
  NodeForce& operator+=(const NodeForce& other) {
    lanes += other.lanes;
    return *this;
  }
};

// The same rows for tetrahedra: one 64-byte row (a cache line) per node, one 32-byte force.
typedef double NodeLanes3 __attribute__((vector_size(64)));
typedef double ForceLanes3 __attribute__((vector_size(32)));

struct alignas(64) PackedNode3 {
  NodeLanes3 lanes;  // x, y, z (m), mean stress (Pa), bulk modulus (Pa), unused x 3
};

// The internal force on a node, N.
struct alignas(32) NodeForce3 {
  ForceLanes3 lanes;  // x, y, z, unused
  NodeForce3& operator+=(const NodeForce3& other) {
    lanes += other.lanes;
    return *this;
  }
};

}  // namespace softshock
